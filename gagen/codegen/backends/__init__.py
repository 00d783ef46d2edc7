"""The backends, registered here and nowhere else: ``BACKENDS`` maps each name to its backend object,
in build order (a backend comes after those it requires).

- ``casadi``: every kernel as a serialised, gzipped ``casadi.Function`` (``module.casadi.<kernel>``);
- ``c``: the C kernels (header, source, SIMD batches; our printer over the flat graph), compiled into
  ``lib<name>_<tag>.so`` and called through ctypes (``module.c.<kernel>``);
- ``cpython``: the CPython binding of the C kernels (``<name>_binding.c``, compiled to
  ``_gagen_<name>_<tag>``), the fast path of ``module.c``; optional (without it: ctypes);
- ``cuda``: every kernel as CUDA C++ in ``<name>.cu`` (a ``__host__ __device__`` body per kernel over
  float and double, a batch kernel per precision), compiled by NVRTC through CuPy at first use on a
  GPU (``module.cuda.<kernel>``, device arrays in and out); nothing compiled at build time;
- ``jax``: every kernel as a pure jax.numpy function in ``<name>_jax.py`` (``module.jax.<kernel>``;
  rendered from the CasADi Functions, nothing compiled; loading it needs jax, the rest of the module
  does not). Last: nothing requires it, and the other backends' files stay as they were.

``gagen build`` renders every registered backend (or those it is given) and lists them in the
manifest's ``"backends"``; ``gagen.runtime`` builds a module's namespaces from that list through
this registry. Adding a backend: a package ``backends/<name>/`` whose ``BACKEND`` subclasses
:class:`Backend` (its templates in ``backends/<name>/templates/``), one line below, and its tests.
"""

from __future__ import annotations

from collections.abc import Sequence

from gagen.codegen.backends import c, casadi, cpython, cuda, jax
from gagen.codegen.backends.base import Backend, Context, Output, TemplateNotFound, module_name, module_tag

BACKENDS: dict[str, Backend] = {b.name: b for b in (casadi.BACKEND, c.BACKEND, cpython.BACKEND, cuda.BACKEND,
                                                  jax.BACKEND)}


def select(names: Sequence[str] | None = None) -> list[Backend]:
    """The backends of these names (default: all), in registry order; ValueError for an unknown name
    or a missing requirement."""
    if names is None:
        return list(BACKENDS.values())
    unknown = [n for n in names if n not in BACKENDS]
    if unknown:
        raise ValueError(f"unknown backend(s) {', '.join(map(repr, unknown))}; gagen has "
                         f"{', '.join(BACKENDS)}")
    chosen = [b for b in BACKENDS.values() if b.name in names]
    for b in chosen:
        missing = [r for r in b.requires if r not in names]
        if missing:
            raise ValueError(f"backend {b.name} needs {', '.join(missing)} in the same module")
    return chosen


__all__ = ["BACKENDS", "Backend", "Context", "Output", "TemplateNotFound", "module_name", "module_tag",
           "select"]
