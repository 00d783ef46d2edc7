"""Loading a generated module (``gagen.load(path)``): its manifest, CasADi Functions, the C kernels and
the JAX kernels.

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
import ctypes
import functools
import json
import os
import sys
import threading
import warnings
from collections.abc import Callable, Iterator
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

MANIFEST = "manifest.json"


class _Port:
    """One input or output: its name and (rows, cols); calls return (rows,) for vectors."""

    __slots__ = ("cols", "name", "rows", "shape", "size")

    def __init__(self, entry: dict[str, Any]) -> None:
        self.name, self.rows, self.cols = entry["name"], len(entry["rows"]), int(entry["cols"])
        self.size = self.rows * self.cols
        self.shape = (self.rows,) if self.cols == 1 else (self.rows, self.cols)


def _real(value: Any, what: str) -> np.ndarray:
    """``value`` as an array of real numbers (float up to 64 bits, or integers), else TypeError."""
    try:
        a = np.asarray(value)  # ndarray subclasses (np.matrix) become plain arrays
    except (TypeError, ValueError) as e:  # ragged lists and the like
        raise TypeError(f"{what}: expected an array of real numbers, got {type(value).__name__} ({e})") \
            from None
    kind = a.dtype.kind
    if kind in "iu" or (kind == "f" and a.dtype.itemsize <= 8):
        return a
    raise TypeError(f"{what}: expected real numbers (float64; float16/32 and integers are converted), "
                    f"got dtype {a.dtype}")


def _address(a: np.ndarray) -> int:
    return a.__array_interface__["data"][0]


class _Signature:
    """A kernel's ports and the rules that turn call arguments into what the C function reads and
    writes. Used by the ctypes path and, for every call the binding's fast path does not take, by
    the binding too (so both paths give the same results and the same errors)."""

    def __init__(self, entry: dict[str, Any]) -> None:
        self.name = entry["name"]
        self.inputs = [_Port(p) for p in entry["inputs"]]
        self.outputs = [_Port(p) for p in entry["outputs"]]

    def arity(self, args: tuple, what: str = "") -> None:
        if len(args) != len(self.inputs):
            raise TypeError(f"{self.name}{what} takes {len(self.inputs)} inputs "
                            f"({', '.join(p.name for p in self.inputs)}), got {len(args)}")

    def single_input(self, port: _Port, value: Any) -> np.ndarray:
        """The port's values, flat and column-major, float64 and contiguous (``value`` itself when it
        already is)."""
        a = _real(value, f"{self.name}: input {port.name}")
        if port.cols == 1:
            vector = (port.rows,), (port.rows, 1), (1, port.rows)
            if a.shape not in vector and not (port.rows == 1 and a.ndim == 0):
                raise ValueError(f"{self.name}: input {port.name} needs {port.rows} values, as shape "
                                 f"({port.rows},), ({port.rows}, 1) or (1, {port.rows}); got shape {a.shape}")
            flat = a.reshape(port.rows)
        elif a.shape == (port.rows, port.cols):
            flat = a.ravel(order="F")
        elif a.shape == (port.size,):
            flat = a
        else:
            raise ValueError(f"{self.name}: input {port.name} needs shape ({port.rows}, {port.cols}) (or "
                             f"({port.size},) in column-major order); got shape {a.shape}")
        return np.ascontiguousarray(flat, dtype=np.float64)

    def single_inputs(self, args: tuple) -> list[np.ndarray]:
        self.arity(args)
        return [self.single_input(p, a) for p, a in zip(self.inputs, args, strict=True)]

    def empty(self) -> tuple[np.ndarray, ...]:
        return tuple(np.empty(p.shape, order="F") for p in self.outputs)

    def out_arrays(self, out: Any) -> tuple[np.ndarray, ...]:
        """Check caller-owned outputs: one writeable, aligned, native float64 Fortran-ordered array of
        the returned shape per output."""
        if isinstance(out, np.ndarray):
            out = (out,)
        try:
            arrays = tuple(out)
        except TypeError:
            names = ", ".join(p.name for p in self.outputs)
            raise TypeError(f"{self.name}: out must be a tuple of {len(self.outputs)} arrays ({names}), "
                            f"got {type(out).__name__}") from None
        if len(arrays) != len(self.outputs):
            raise TypeError(f"{self.name}: out needs {len(self.outputs)} arrays "
                            f"({', '.join(p.name for p in self.outputs)}), got {len(arrays)}")
        for a, port in zip(arrays, self.outputs, strict=True):
            what = f"{self.name}: out array for {port.name}"
            if not isinstance(a, np.ndarray) or a.dtype != np.float64 or not a.dtype.isnative:
                raise TypeError(f"{what} must be a float64 numpy array, got "
                                f"{getattr(a, 'dtype', type(a).__name__)}")
            if a.shape != port.shape or not a.flags.f_contiguous:
                raise ValueError(f"{what} needs shape {port.shape}"
                                 f"{' in Fortran order' if port.cols > 1 else ''}, contiguous; got shape "
                                 f"{a.shape}{'' if a.flags.f_contiguous else ' (not Fortran-contiguous)'}")
            if not a.flags.writeable or not a.flags.aligned:
                raise ValueError(f"{what} must be writeable and aligned")
        for j, a in enumerate(arrays):
            for i in range(j):
                if np.may_share_memory(a, arrays[i]):
                    raise ValueError(f"{self.name}: out arrays for {self.outputs[i].name} and "
                                     f"{self.outputs[j].name} overlap")
        return arrays

    def no_overlap(self, outs: tuple[np.ndarray, ...], ins: list[np.ndarray]) -> None:
        for a, port in zip(outs, self.outputs, strict=True):
            for b, inport in zip(ins, self.inputs, strict=True):
                if np.may_share_memory(a, b):
                    raise ValueError(f"{self.name}: out array for {port.name} overlaps input {inport.name}")

    def result(self, outs: tuple[np.ndarray, ...]) -> Any:
        return outs[0] if len(outs) == 1 else outs

    def samples(self, args: tuple, columns: bool) -> tuple[int, list[np.ndarray]]:
        """Batch inputs as C-contiguous float64 (n, size) arrays (or (size, n) for ``columns``)."""
        what = ".batch_columns" if columns else ".batch"
        self.arity(args, what)
        n, arrays = None, []
        for port, value in zip(self.inputs, args, strict=True):
            a = _real(value, f"{self.name}{what}: input {port.name}")
            size, matrix = port.size, (port.rows, port.cols)
            if columns:
                if a.ndim == 2 and a.shape[0] == size:
                    flat = a
                elif port.cols > 1 and a.ndim == 3 and a.shape[:2] == matrix:
                    flat = a.transpose(1, 0, 2).reshape(size, a.shape[2])
                elif size == 1 and a.ndim == 1:
                    flat = a[None, :]
                else:
                    alt = f" or ({port.rows}, {port.cols}, n)" if port.cols > 1 else ""
                    raise ValueError(f"{self.name}{what}: input {port.name} needs shape ({size}, n){alt}; "
                                     f"got shape {a.shape}")
                count = flat.shape[1]
            else:
                if a.ndim == 2 and a.shape[1] == size:
                    flat = a
                elif port.cols > 1 and a.ndim == 3 and a.shape[1:] == matrix:
                    flat = a.transpose(0, 2, 1).reshape(a.shape[0], size)
                elif size == 1 and a.ndim == 1:
                    flat = a[:, None]
                else:
                    alt = f" or (n, {port.rows}, {port.cols})" if port.cols > 1 else ""
                    raise ValueError(f"{self.name}{what}: input {port.name} needs shape (n, {size}){alt}; "
                                     f"got shape {a.shape}")
                count = flat.shape[0]
            if n is None:
                n = count
            elif count != n:
                raise ValueError(f"{self.name}{what}: input {port.name} has {count} samples, "
                                 f"{self.inputs[0].name} has {n}")
            arrays.append(np.ascontiguousarray(flat, dtype=np.float64))
        return n, arrays


def _pointers(arrays: list[np.ndarray] | tuple[np.ndarray, ...]) -> ctypes.Array:
    """A fresh array of the data pointers (per call: nothing shared between calls or threads)."""
    return (ctypes.c_void_p * len(arrays))(*[_address(a) for a in arrays])


class _Buffers:
    """One thread's input and output buffers for a kernel's ctypes calls, with their pointer arrays
    built once (taking an array's address from Python costs microseconds)."""

    def __init__(self, sig: _Signature) -> None:
        self.ins = [np.empty(p.size) for p in sig.inputs]
        self.outs = [np.empty(p.shape, order="F") for p in sig.outputs]
        self.argv, self.resv = _pointers(self.ins), _pointers(self.outs)
        self.busy = False


class _CtypesSingle:
    """One call through ctypes: the inputs converted by the rules and copied into this thread's
    buffers, the kernel run, its outputs copied into fresh arrays (or into ``out``). The buffers are
    per thread (and a reentrant call in the same thread, from a signal handler, gets its own), and
    results never alias them: nothing is shared between calls."""

    def __init__(self, sig: _Signature, function: Any) -> None:
        self.sig, self.function, self.local = sig, function, threading.local()

    def __call__(self, *args: Any, out: Any = None) -> Any:
        sig = self.sig
        flat = sig.single_inputs(args)
        outs = None if out is None else sig.out_arrays(out)
        if outs is not None:
            sig.no_overlap(outs, flat)
        buffers = getattr(self.local, "buffers", None)
        if buffers is None:
            buffers = self.local.buffers = _Buffers(sig)
        if buffers.busy:
            buffers = _Buffers(sig)
        buffers.busy = True
        try:
            for buffer, values in zip(buffers.ins, flat, strict=True):
                buffer[:] = values
            self.function(buffers.argv, buffers.resv)  # ctypes releases the GIL during the call
            if outs is None:
                outs = tuple(o.copy(order="F") for o in buffers.outs)
            else:
                for o, buffer in zip(outs, buffers.outs, strict=True):
                    o[...] = buffer
        finally:
            buffers.busy = False
        return sig.result(outs)


class CKernel:
    """One compiled kernel: ``kernel(*inputs, out=None)``, ``kernel.bind(out)``, ``kernel.fast``,
    ``kernel.batch(*inputs)`` and ``kernel.batch_columns(*inputs)`` (see the module docstring)."""

    def __init__(self, library: ctypes.CDLL, entry: dict[str, Any], binding: Any = None,
                 module: GeneratedModule | None = None) -> None:
        self.module, self._entry = module, entry
        self._sig = sig = _Signature(entry)
        self.name = sig.name
        self.inputs = [p.name for p in sig.inputs]
        self.outputs = [p.name for p in sig.outputs]
        self._in_shapes = [(p.rows, p.cols) for p in sig.inputs]
        self._out_shapes = [(p.rows, p.cols) for p in sig.outputs]
        c_name = entry["c_name"]
        # the C function itself (inputs, then outputs, as flat double arrays), for C code that calls the
        # kernel directly (the iLQR loop of gagen.control.ilqr)
        self.address: int = ctypes.cast(getattr(library, c_name), ctypes.c_void_p).value or 0
        single = getattr(library, f"{c_name}_argv")
        single.argtypes, single.restype = [ctypes.c_void_p, ctypes.c_void_p], None
        self._batch = getattr(library, f"{c_name}_batch_argv")
        self._batch.argtypes = [ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p]
        self._batch.restype = None
        self._columns = getattr(library, f"{c_name}_batch_columns_argv")
        self._columns.argtypes = [ctypes.c_long, ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p]
        self._columns.restype = None
        # the ctypes path holds no reference to this object or the binding's (no reference cycle through C)
        self._slow = _CtypesSingle(sig, single)
        self.binding = binding is not None
        self._make = None
        if binding is not None:
            address = self.address
            # make(out, info) -> the binding's kernel object f(*inputs, out=None) (vectorcall, attributes
            # from info): k(...) and k(..., out=...) go straight into C
            self._make = functools.partial(getattr(binding, f"make_{self.name}"), address, self._slow)
            self._own = self._make(None, None)  # holds no reference back to self

    @property
    def op_count(self) -> dict[str, Any]:
        """The kernel's scalar operations (mul, add, neg, div, flops, calls), as the manifest lists them."""
        return dict(self._entry["op_count"])

    @property
    def casadi(self) -> Any:
        """The same kernel as a casadi.Function (from the module's casadi backend)."""
        if self.module is None:
            raise AttributeError(f"{self.name}: loaded without its module")
        return getattr(self.module.casadi, self.name)

    @property
    def c_source(self) -> str:
        """The C source of the module this kernel was compiled from (every kernel of the module)."""
        if self.module is None:
            raise AttributeError(f"{self.name}: loaded without its module")
        return (self.module.folder / self.module.manifest["c_source"]).read_text()

    def entry_point(self) -> Any:
        """What ``module.c.<kernel>`` hands out: the binding's kernel object, whose attributes are this
        object's; or this object itself without the binding."""
        return self if self._make is None else self._make(None, self)

    def __repr__(self) -> str:
        return f"<C kernel {self.name}({', '.join(self.inputs)}) -> {', '.join(self.outputs)}>"

    def __call__(self, *args: Any, out: Any = None) -> Any:
        """Evaluate once into fresh arrays, or into ``out``: vectors come back 1-D, matrices (rows, cols);
        one output comes back alone."""
        if self._make is None:
            return self._slow(*args, out=out)
        return self._own(*args, out=out)  # module.c.<kernel> is that object itself: no Python frame

    def empty(self) -> Any:
        """A fresh set of output arrays for ``out=`` or ``bind`` (uninitialised)."""
        return self._sig.result(self._sig.empty())

    def bind(self, out: Any = None) -> Callable[..., Any]:
        """``f(*inputs)`` writing into ``out`` (checked now; allocated if None) and returning it: no
        allocation per call. The caller owns ``out``: each thread should bind its own."""
        outs = self._sig.empty() if out is None else self._sig.out_arrays(out)
        result = self._sig.result(outs)
        if self._make is not None:
            return self._make(result, None)
        return functools.partial(self._slow, out=result)

    @cached_property
    def fast(self) -> Callable[..., Any] | None:
        """``self.bind()`` made once (the binding's path; None without the binding): every call
        overwrites and returns the same arrays, shared by all users of this kernel object."""
        return self.bind() if self._make is not None else None

    def batch(self, *args: Any) -> Any:
        """Evaluate n samples: each input has shape (n, size); outputs come back (n, rows[, cols])."""
        n, arrays = self._sig.samples(args, columns=False)
        outs = [np.empty((n, c, r)) for r, c in self._out_shapes]  # per sample column-major
        self._batch(n, _pointers(arrays), _pointers(outs))
        views = tuple(o[:, 0, :] if o.shape[1] == 1 else o.transpose(0, 2, 1) for o in outs)
        return views[0] if len(views) == 1 else views

    def batch_columns(self, *args: Any) -> Any:
        """Evaluate n samples given as columns: each input has shape (size, n); outputs come back
        (rows, n) or (rows, cols, n), views into 64-byte-aligned arrays padded to a multiple of 8
        samples. The SIMD kernels load and store whole vectors in this layout, and stream large
        outputs past the caches: the fastest batch for large n."""
        n, flat = self._sig.samples(args, columns=True)
        ld = -(-n // 8) * 8 or 8
        arrays = []
        for a in flat:
            padded = _aligned((a.shape[0], ld))
            padded[:, :n] = a
            padded[:, n:] = 0.0  # the padding is computed on too: keep it finite and deterministic
            arrays.append(padded)
        outs = [_aligned((c, r, ld)) for r, c in self._out_shapes]  # per sample column-major
        self._columns(n, ld, _pointers(arrays), _pointers(outs))
        views = tuple(o[0, :, :n] if o.shape[0] == 1 else o.transpose(1, 0, 2)[:, :, :n] for o in outs)
        return views[0] if len(views) == 1 else views


def _aligned(shape: tuple[int, ...], alignment: int = 64) -> np.ndarray:
    """An uninitialised C-contiguous float64 array whose data starts on an ``alignment``-byte boundary."""
    count = int(np.prod(shape))
    raw = np.empty(count + alignment // 8)
    offset = (-raw.ctypes.data % alignment) // 8
    return raw[offset:offset + count].reshape(shape)


class _Namespace:
    """Attribute access to kernels by name, loaded on first use."""

    def __init__(self, names: list[str], load) -> None:
        self._names, self._load, self._cache = names, load, {}
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
        for backend in self.backends.values():
            if backend.namespace:
                if backend.namespace.startswith("_") or hasattr(type(self), backend.namespace):
                    raise ValueError(f"backend {backend.name}: namespace {backend.namespace!r} is taken")
                setattr(self, backend.namespace,
                        _Namespace(self.kernel_names, functools.partial(backend.load, self)))

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
    def library(self) -> ctypes.CDLL:
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
