"""Calling the C kernels from Python: ``module.c.<kernel>`` is a :class:`CKernel` (or the CPython
binding's kernel object, whose attributes are a CKernel's), and the ctypes path every call takes that
the binding does not (see ``gagen.runtime`` for the calling convention: shapes, dtypes, ``out=``,
``bind``, batches).

:class:`Signature` holds a kernel's ports and the rules that turn call arguments into what the C
function reads and writes; ``_CtypesSingle`` is one call through ctypes into per-thread buffers.
"""

from __future__ import annotations

import ctypes
import functools
import threading
from collections.abc import Callable, Sequence
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.codegen.backends.base import LoadedModule
from gagen.symbolic.flatten import Port

Array = NDArray[np.float64]


def port(entry: dict[str, Any]) -> Port:
    """A port of the manifest (``{"name", "rows", "cols", ...}``)."""
    return Port(entry["name"], tuple(entry["rows"]), int(entry["cols"]))


def _real(value: Any, what: str) -> NDArray[Any]:
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


def _address(a: NDArray[Any]) -> int:
    address: int = a.__array_interface__["data"][0]
    return address


class Signature:
    """A kernel's ports and the rules that turn call arguments into what the C function reads and
    writes. Used by the ctypes path and, for every call the binding's fast path does not take, by
    the binding too (so both paths give the same results and the same errors)."""

    def __init__(self, entry: dict[str, Any]) -> None:
        self.name: str = entry["name"]
        self.inputs = [port(p) for p in entry["inputs"]]
        self.outputs = [port(p) for p in entry["outputs"]]

    def arity(self, args: tuple[Any, ...], what: str = "") -> None:
        if len(args) != len(self.inputs):
            raise TypeError(f"{self.name}{what} takes {len(self.inputs)} inputs "
                            f"({', '.join(p.name for p in self.inputs)}), got {len(args)}")

    def single_input(self, port: Port, value: Any) -> Array:
        """The port's values, flat and column-major, float64 and contiguous (``value`` itself when it
        already is)."""
        a = _real(value, f"{self.name}: input {port.name}")
        rows, cols = port.shape
        if cols == 1:
            vector = (rows,), (rows, 1), (1, rows)
            if a.shape not in vector and not (rows == 1 and a.ndim == 0):
                raise ValueError(f"{self.name}: input {port.name} needs {rows} values, as shape "
                                 f"({rows},), ({rows}, 1) or (1, {rows}); got shape {a.shape}")
            flat = a.reshape(rows)
        elif a.shape == (rows, cols):
            flat = a.ravel(order="F")
        elif a.shape == (port.size,):
            flat = a
        else:
            raise ValueError(f"{self.name}: input {port.name} needs shape ({rows}, {cols}) (or "
                             f"({port.size},) in column-major order); got shape {a.shape}")
        return np.ascontiguousarray(flat, dtype=np.float64)

    def single_inputs(self, args: tuple[Any, ...]) -> list[Array]:
        self.arity(args)
        return [self.single_input(p, a) for p, a in zip(self.inputs, args, strict=True)]

    def empty(self) -> tuple[Array, ...]:
        return tuple(np.empty(p.array_shape, order="F") for p in self.outputs)

    def out_arrays(self, out: Any) -> tuple[Array, ...]:
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
            if a.shape != port.array_shape or not a.flags.f_contiguous:
                raise ValueError(f"{what} needs shape {port.array_shape}"
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

    def no_overlap(self, outs: tuple[Array, ...], ins: list[Array]) -> None:
        for a, port in zip(outs, self.outputs, strict=True):
            for b, inport in zip(ins, self.inputs, strict=True):
                if np.may_share_memory(a, b):
                    raise ValueError(f"{self.name}: out array for {port.name} overlaps input {inport.name}")

    def result(self, outs: tuple[Array, ...]) -> Any:
        return outs[0] if len(outs) == 1 else outs

    def samples(self, args: tuple[Any, ...], columns: bool) -> tuple[int, list[Array]]:
        """Batch inputs as C-contiguous float64 (n, size) arrays (or (size, n) for ``columns``)."""
        what = ".batch_columns" if columns else ".batch"
        self.arity(args, what)
        n: int | None = None
        arrays: list[Array] = []
        for port, value in zip(self.inputs, args, strict=True):
            a = _real(value, f"{self.name}{what}: input {port.name}")
            size, matrix = port.size, port.shape
            rows, cols = matrix
            if columns:
                if a.ndim == 2 and a.shape[0] == size:
                    flat = a
                elif cols > 1 and a.ndim == 3 and a.shape[:2] == matrix:
                    flat = a.transpose(1, 0, 2).reshape(size, a.shape[2])
                elif size == 1 and a.ndim == 1:
                    flat = a[None, :]
                else:
                    alt = f" or ({rows}, {cols}, n)" if cols > 1 else ""
                    raise ValueError(f"{self.name}{what}: input {port.name} needs shape ({size}, n){alt}; "
                                     f"got shape {a.shape}")
                count = flat.shape[1]
            else:
                if a.ndim == 2 and a.shape[1] == size:
                    flat = a
                elif cols > 1 and a.ndim == 3 and a.shape[1:] == matrix:
                    flat = a.transpose(0, 2, 1).reshape(a.shape[0], size)
                elif size == 1 and a.ndim == 1:
                    flat = a[:, None]
                else:
                    alt = f" or (n, {rows}, {cols})" if cols > 1 else ""
                    raise ValueError(f"{self.name}{what}: input {port.name} needs shape (n, {size}){alt}; "
                                     f"got shape {a.shape}")
                count = flat.shape[0]
            if n is None:
                n = count
            elif count != n:
                raise ValueError(f"{self.name}{what}: input {port.name} has {count} samples, "
                                 f"{self.inputs[0].name} has {n}")
            arrays.append(np.ascontiguousarray(flat, dtype=np.float64))
        return (0 if n is None else n), arrays


def _pointers(arrays: Sequence[NDArray[Any]]) -> ctypes.Array[ctypes.c_void_p]:
    """A fresh array of the data pointers (per call: nothing shared between calls or threads)."""
    return (ctypes.c_void_p * len(arrays))(*[_address(a) for a in arrays])


class _Buffers:
    """One thread's input and output buffers for a kernel's ctypes calls, with their pointer arrays
    built once (taking an array's address from Python costs microseconds)."""

    def __init__(self, sig: Signature) -> None:
        self.ins = [np.empty(p.size) for p in sig.inputs]
        self.outs = [np.empty(p.array_shape, order="F") for p in sig.outputs]
        self.argv, self.resv = _pointers(self.ins), _pointers(self.outs)
        self.busy = False


class _CtypesSingle:
    """One call through ctypes: the inputs converted by the rules and copied into this thread's
    buffers, the kernel run, its outputs copied into fresh arrays (or into ``out``). The buffers are
    per thread (and a reentrant call in the same thread, from a signal handler, gets its own), and
    results never alias them: nothing is shared between calls."""

    def __init__(self, sig: Signature, function: Any) -> None:
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
    ``kernel.batch(*inputs)`` and ``kernel.batch_columns(*inputs)`` (see ``gagen.runtime``)."""

    def __init__(self, library: ctypes.CDLL, entry: dict[str, Any], binding: Any = None,
                 module: LoadedModule | None = None) -> None:
        self.module, self._entry = module, entry
        self._sig = sig = Signature(entry)
        self.name = sig.name
        self.inputs = [p.name for p in sig.inputs]
        self.outputs = [p.name for p in sig.outputs]
        self._in_shapes = [p.shape for p in sig.inputs]
        self._out_shapes = [p.shape for p in sig.outputs]
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
        return (self.module.folder / str(self.module.manifest["c_source"])).read_text()

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
            bound: Callable[..., Any] = self._make(result, None)
            return bound
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
