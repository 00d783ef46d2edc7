"""gagen: a symbolic code-generation compiler for geometric algebra in robotics.

``gagen.kernel`` declares a Python function over multivectors as a kernel (see ``gagen.frontend``)
and ``gagen.compile`` compiles it (``gagen.build``); ``gagen.load(folder)`` opens a generated module
(``gagen.runtime``). Subpackages: ``algebra`` (algebra descriptions, kinds, exact blade rules, sparse
symbolic multivectors, the names of scalars), ``symbolic`` (exact scalar layer, flattening, op
counts), ``interp`` (the independent dense reference interpreter), ``model`` (the geometry, written
once), ``codegen`` (what the backends take, and the backends: printers, templates, loaders).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from gagen.runtime import GeneratedModule

__version__ = "0.1.0"


def load(folder: str | Path) -> GeneratedModule:
    """The generated module in ``folder`` (any working directory; see ``gagen.runtime``). Imports the
    runtime (numpy, ctypes) on first use, so ``import gagen`` stays cheap."""
    from gagen.runtime import load as _load

    return _load(folder)


# the front-end's names, and gagen.compile (a build into the cache), by the module that defines them
_FRONT_END = {**dict.fromkeys(("kernel", "scalars", "blades", "matrix", "along", "KernelError",
                               "KernelFunction"), "gagen.frontend"), "compile": "gagen.build"}


def __getattr__(name: str) -> Any:
    """The front-end (``gagen.kernel``, ``gagen.compile``, …) loads on first use (it imports CasADi)."""
    if name in _FRONT_END:
        from importlib import import_module

        return getattr(import_module(_FRONT_END[name]), name)
    raise AttributeError(f"module 'gagen' has no attribute {name!r}")
