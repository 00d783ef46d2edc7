"""Loading a generated module (``gagen.load(path)``): its manifest, and a namespace of kernels per
backend (CasADi Functions, the C kernels, the JAX kernels), each made by its backend
(``gagen.codegen.backends``; the C kernels' ctypes calls are in ``gagen.codegen.backends.c.loader``).

Calling a C kernel ``k = module.c.<kernel>``:

- ``k(*inputs)`` returns fresh output arrays (a tuple; one output comes back alone): vectors 1-D
  ``(rows,)``, matrices ``(rows, cols)`` Fortran-ordered. Results are never shared between calls.
- ``k(*inputs, out=outs)`` writes into caller-owned arrays instead and returns them: ``outs`` holds one
  writeable float64 array per output, of exactly the shape above (matrices Fortran-ordered,
  ``np.empty((rows, cols), order="F")``; ``k.empty()`` makes a set), not overlapping the inputs or
  each other. Zero allocation per call.
- ``k.bind(out=None)`` returns ``f(*inputs)`` that writes into ``out`` (allocated once if None) and
  returns it: the fastest call, for loops. ``k.fast`` is one such ``f`` owned by the kernel object,
  whose outputs every ``k.fast`` call overwrites: copy what you keep, and give each thread its own
  ``k.bind()``.
- ``k.batch(*inputs)``: n samples, each input ``(n, size)``; ``k.batch_columns(*inputs)``: samples
  last, ``(size, n)``. Both return fresh arrays.

Calls are reentrant and thread-safe: the kernels keep no state and each call has its own inputs,
outputs and pointer arrays, on both paths (the CPython binding, and the ctypes fallback used when the
binding cannot be compiled).

Inputs, the same rules on both paths and in the batches:

- a vector port of n values takes shape ``(n,)``, ``(n, 1)`` or ``(1, n)`` (the same n values in
  order; a one-value port also takes a scalar); a matrix port ``(rows, cols)`` takes exactly that
  shape, or the flat ``(rows * cols,)`` in column-major order. Anything else (e.g. ``(7, 3)`` for a
  ``(3, 7)`` port, or a ``(3, 7)`` array for a 21-vector) is a ValueError naming the input.
  ``batch`` takes ``(n, size)`` per input (matrix ports also ``(n, rows, cols)``), ``batch_columns``
  ``(size, n)`` (matrix ports also ``(rows, cols, n)``).
- dtype: float64 is read in place when contiguous (else copied); float16 and float32 are widened
  and integer arrays and Python lists/scalars of numbers are converted to float64 (exact for
  integers up to 2**53). bool, complex, str/bytes, object and long-double (float128) inputs are
  refused with a TypeError naming the input: the conversion would drop or invent information.

A JAX kernel ``module.jax.<kernel>`` (the ``jax`` backend, ``<name>_jax.py``) is a plain jax.numpy
function with the same inputs (shapes as above; bool and complex refused), returning jax arrays of the
same shapes, one output alone; float64 (loading it turns on ``jax_enable_x64``). No ``out``, ``bind``
or ``batch``: it is pure, for ``jax.jit``, ``jax.vmap`` (the batch), ``jax.grad``/``jacfwd``. The file
runs only if its sha256 is the manifest's. jax is optional: without it the module loads and
``module.jax.<kernel>`` raises an ImportError saying what to install.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import sys
import threading
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

MANIFEST = "manifest.json"


class _Namespace:
    """Attribute access to kernels by name, loaded on first use."""

    def __init__(self, names: list[str], load: Callable[[str], Any]) -> None:
        self._names, self._load = names, load
        self._cache: dict[str, Any] = {}
        self._lock = threading.Lock()

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        if name not in self._names:
            raise AttributeError(f"no kernel {name!r}; kernels are: {', '.join(self._names)}")
        kernel = self._cache.get(name)
        if kernel is None:
            with self._lock:  # one kernel object per name, also when threads ask at once
                kernel = self._cache.get(name)
                if kernel is None:
                    kernel = self._cache[name] = self._load(name)
        return kernel

    def __dir__(self) -> list[str]:
        return list(self._names)


@contextlib.contextmanager
def _folder_lock(folder: Path) -> Iterator[None]:
    """Serialise first-use compilations of one module across threads and processes (flock on the
    folder itself: no lock file is left behind). Without fcntl, the atomic renames still keep
    concurrent compilations safe, only not single."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover (Windows)
        yield
        return
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


class GeneratedModule:
    """A folder written by ``gagen build``: its manifest, and a namespace of kernels per backend that
    has one (``casadi``, ``c``, ``jax``), made from the manifest's ``"backends"`` through the registry
    (``gagen.codegen.backends``). What a backend compiles (the C library, the CPython binding) is
    compiled here on first use if the folder has only its sources."""

    def __init__(self, folder: str | Path) -> None:
        from gagen.codegen.backends import BACKENDS

        self.folder = Path(folder).expanduser().resolve()
        manifest = self.folder / MANIFEST
        if not manifest.is_file():
            what = "does not exist" if not self.folder.exists() else f"has no {MANIFEST}"
            raise FileNotFoundError(f"no generated gagen module at {self.folder}: the folder {what} "
                                    "(write one with `gagen build SPEC -o FOLDER`)")
        self.manifest = json.loads(manifest.read_text())
        if "backends" not in self.manifest:
            raise ValueError(f"{manifest}: a module written by an older gagen (its manifest lists no "
                             "backends); rebuild it with `gagen build`")
        names = self.manifest["backends"]
        unknown = [n for n in names if n not in BACKENDS]
        if unknown:
            raise ValueError(f"{manifest}: backend(s) {', '.join(map(repr, unknown))} unknown to this gagen "
                             f"(it has {', '.join(BACKENDS)}); rebuild the module with `gagen build`")
        self.backends = {n: BACKENDS[n] for n in names}
        self.kernel_names = [k["name"] for k in self.manifest["kernels"]]
        self._handles: dict[str, Any] = {}
        self._lock = threading.RLock()
        self._failed: set[str] = set()  # optional backends that did not compile here
        self._namespaces: dict[str, _Namespace] = {}
        for backend in self.backends.values():
            if backend.namespace:
                if backend.namespace.startswith("_") or hasattr(type(self), backend.namespace):
                    raise ValueError(f"backend {backend.name}: namespace {backend.namespace!r} is taken")
                self._namespaces[backend.namespace] = _Namespace(self.kernel_names,
                                                                 functools.partial(backend.load, self))

    def __getattr__(self, name: str) -> Any:
        """A backend's namespace of kernels: ``module.casadi``, ``module.c``, ``module.jax``."""
        namespace = self.__dict__.get("_namespaces", {}).get(name)
        if namespace is None:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        return namespace

    def __dir__(self) -> list[str]:
        return [*super().__dir__(), *self._namespaces]

    def __repr__(self) -> str:
        return f"<gagen module {self.manifest['module']} at {self.folder}>"

    def entry(self, name: str) -> dict[str, Any]:
        """The manifest's entry of kernel ``name``."""
        return next(k for k in self.manifest["kernels"] if k["name"] == name)

    def path(self, relative: str) -> Path:
        """``folder / relative``, refused (ValueError) unless it stays inside the folder."""
        path = self.folder / relative
        if Path(relative).is_absolute() or ".." in Path(relative).parts or \
                not path.resolve().is_relative_to(self.folder):
            raise ValueError(f"{self.folder / MANIFEST}: {relative!r} is outside the module folder")
        return path

    def handle(self, backend: str) -> Any:
        """What backend ``backend`` opened for this module (the loaded library, the binding module),
        once; None for a backend the module does not have."""
        if backend not in self.backends:
            return None
        with self._lock:
            if backend not in self._handles:
                self._handles[backend] = self.backends[backend].open(self)
            return self._handles[backend]

    def compile_missing(self) -> None:
        """Compile what the backends compile if the folder has only their sources (first use), saying
        so in one line on stderr. Threads and processes loading the same folder at once wait for one
        compilation (a lock on the folder); the compiler writes to a temporary name and renames. An
        optional backend that fails to compile (the binding without Python headers) warns once."""
        from gagen.codegen.compiler import CompileError

        def missing() -> list[tuple[Any, list[Path]]]:
            pending = []
            for b in self.backends.values():
                paths = [p for p in b.artefacts(self.folder, self.manifest) if not p.exists()]
                if paths and b.name not in self._failed:
                    pending.append((b, paths))
            return pending

        if not missing():
            return
        with _folder_lock(self.folder):
            pending = missing()
            if not pending:
                return
            names = [p.name for _, paths in pending for p in paths]
            print(f"gagen: compiling {' and '.join(names)} in {self.folder} (first use; a few seconds)",
                  file=sys.stderr, flush=True)
            for backend, paths in pending:
                try:
                    backend.compile(self.folder, self.manifest)
                except CompileError as e:  # e.g. no Python headers
                    if not backend.optional:
                        raise
                    self._failed.add(backend.name)
                    warnings.warn(f"{', '.join(p.name for p in paths)}: {e}; {backend.optional}",
                                  stacklevel=3)

    @property
    def library(self) -> Any:
        """The compiled C library (compiled here first if the folder has only the source)."""
        return self.handle("c")

    @property
    def binding(self) -> Any:
        """The CPython binding module (compiled here first if absent), or None: then ctypes."""
        return self.handle("cpython")


def load(folder: str | Path) -> GeneratedModule:
    """The generated module in ``folder`` (e.g. ``generated/three_pandas_circle``, or any ``-o`` folder;
    relative paths are taken from the current directory once, here)."""
    return GeneratedModule(folder)
