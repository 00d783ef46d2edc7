"""Loading a generated module: its manifest, CasADi Functions, and the compiled C kernels.

A single call goes through the module's CPython binding: the kernel reads the input arrays in place
(float64, contiguous; anything else is converted first) and writes into output arrays registered
once, so a call allocates nothing. The returned arrays are the kernel's output buffers, overwritten
by the next call: copy what you keep. Without the binding (no Python headers at build time) calls
go through ctypes and the ``*_argv`` entry points, with the inputs copied into owned buffers.
``batch`` and ``batch_columns`` go through ctypes and allocate their outputs.
"""

from __future__ import annotations

import ctypes
import functools
import gzip
import importlib.util
import json
import warnings
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

MANIFEST = "manifest.json"


class CKernel:
    """One compiled kernel: ``kernel(*inputs) -> outputs`` and ``kernel.batch(*inputs)``."""

    def __init__(self, library: ctypes.CDLL, entry: dict[str, Any], binding: Any = None) -> None:
        self.name = entry["name"]
        self.inputs = [p["name"] for p in entry["inputs"]]
        self.outputs = [p["name"] for p in entry["outputs"]]
        self._in_shapes = [(len(p["rows"]), p["cols"]) for p in entry["inputs"]]
        self._out_shapes = [(len(p["rows"]), p["cols"]) for p in entry["outputs"]]
        c_name = entry["c_name"]
        self._single = getattr(library, f"{c_name}_argv")
        self._single.argtypes, self._single.restype = [ctypes.c_void_p, ctypes.c_void_p], None
        self._batch = getattr(library, f"{c_name}_batch_argv")
        self._batch.argtypes = [ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p]
        self._batch.restype = None
        self._columns = getattr(library, f"{c_name}_batch_columns_argv")
        self._columns.argtypes = [ctypes.c_long, ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p]
        self._columns.restype = None
        # buffers and pointer arrays, built once: a call passes two integers
        self._in = [np.zeros(r * c) for r, c in self._in_shapes]
        self._out = [np.zeros((r, c), order="F") for r, c in self._out_shapes]
        self._argv = (ctypes.c_void_p * len(self._in))(*[a.ctypes.data for a in self._in])
        self._resv = (ctypes.c_void_p * len(self._out))(*[a.ctypes.data for a in self._out])
        self._argv_address, self._resv_address = ctypes.addressof(self._argv), ctypes.addressof(self._resv)
        self._views = tuple(a[:, 0] if a.shape[1] == 1 else a for a in self._out)
        result = self._views[0] if len(self._views) == 1 else self._views
        self.fast = None  # call(*float64 arrays) with no checks beyond the binding's: the hot path
        if binding is not None:
            address = ctypes.cast(getattr(library, c_name), ctypes.c_void_p).value
            capsule = getattr(binding, f"make_{self.name}")(address, *self._out, result)
            self.fast = functools.partial(getattr(binding, f"call_{self.name}"), capsule)

    def __repr__(self) -> str:
        return f"<C kernel {self.name}({', '.join(self.inputs)}) -> {', '.join(self.outputs)}>"

    def __call__(self, *args: Any) -> Any:
        """Evaluate once; vectors come back 1-D, matrices (rows, cols); one output comes back alone."""
        if self.fast is not None:
            try:
                return self.fast(*args)
            except (TypeError, ValueError, BufferError):  # not contiguous float64 of the right size
                pass
        if len(args) != len(self._in):
            raise TypeError(f"{self.name} takes {len(self._in)} inputs ({', '.join(self.inputs)}), "
                            f"got {len(args)}")
        for buffer, value, name in zip(self._in, args, self.inputs, strict=True):
            value = np.asarray(value, dtype=float)
            if value.size != buffer.size:
                raise ValueError(f"{self.name}: input {name} needs {buffer.size} values, "
                                 f"got shape {value.shape}")
            buffer[:] = value.ravel(order="F")
        self._single(self._argv_address, self._resv_address)
        return self._views[0] if len(self._views) == 1 else self._views

    def batch(self, *args: Any) -> Any:
        """Evaluate n samples: each input has shape (n, size); outputs come back (n, rows[, cols])."""
        if len(args) != len(self._in):
            raise TypeError(f"{self.name}.batch takes {len(self._in)} inputs, got {len(args)}")
        arrays = [np.ascontiguousarray(a, dtype=float) for a in args]
        n = arrays[0].shape[0]
        for a, (rows, cols), name in zip(arrays, self._in_shapes, self.inputs, strict=True):
            if a.size != n * rows * cols:
                raise ValueError(f"{self.name}.batch: input {name} needs shape ({n}, {rows * cols}), "
                                 f"got {a.shape}")
        outs = [np.empty((n, c, r)) for r, c in self._out_shapes]  # per sample column-major
        argv = (ctypes.c_void_p * len(arrays))(*[a.ctypes.data for a in arrays])
        resv = (ctypes.c_void_p * len(outs))(*[o.ctypes.data for o in outs])
        self._batch(n, argv, resv)
        views = tuple(o[:, 0, :] if o.shape[1] == 1 else o.transpose(0, 2, 1) for o in outs)
        return views[0] if len(views) == 1 else views

    def batch_columns(self, *args: Any) -> Any:
        """Evaluate n samples given as columns: each input has shape (size, n); outputs come back
        (rows, n) or (rows, cols, n), views into 64-byte-aligned arrays padded to a multiple of 8
        samples. The SIMD kernels load and store whole vectors in this layout, and stream large
        outputs past the caches: the fastest batch for large n."""
        if len(args) != len(self._in):
            raise TypeError(f"{self.name}.batch_columns takes {len(self._in)} inputs, got {len(args)}")
        n = np.shape(args[0])[-1] if np.ndim(args[0]) else 0
        ld = -(-n // 8) * 8 or 8
        arrays = []
        for a, (rows, cols), name in zip(args, self._in_shapes, self.inputs, strict=True):
            a = np.asarray(a, dtype=float)
            if a.shape != (rows * cols, n):
                raise ValueError(f"{self.name}.batch_columns: input {name} needs shape ({rows * cols}, {n}), "
                                 f"got {a.shape}")
            padded = _aligned((rows * cols, ld))
            padded[:, :n] = a
            arrays.append(padded)
        outs = [_aligned((c, r, ld)) for r, c in self._out_shapes]  # per sample column-major
        argv = (ctypes.c_void_p * len(arrays))(*[a.ctypes.data for a in arrays])
        resv = (ctypes.c_void_p * len(outs))(*[o.ctypes.data for o in outs])
        self._columns(n, ld, argv, resv)
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

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        if name not in self._names:
            raise AttributeError(f"no kernel {name!r}; kernels are: {', '.join(self._names)}")
        if name not in self._cache:
            self._cache[name] = self._load(name)
        return self._cache[name]

    def __dir__(self) -> list[str]:
        return list(self._names)


class GeneratedModule:
    """A folder written by ``gagen build``: manifest, CasADi Functions, C source (and library)."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.manifest = json.loads((self.folder / MANIFEST).read_text())
        names = [k["name"] for k in self.manifest["kernels"]]
        self.casadi = _Namespace(names, self._load_casadi)
        self.c = _Namespace(names, self._load_c)

    def _entry(self, name: str) -> dict[str, Any]:
        return next(k for k in self.manifest["kernels"] if k["name"] == name)

    def _load_casadi(self, name: str) -> Any:
        import casadi as ca

        data = gzip.decompress((self.folder / self._entry(name)["casadi"]).read_bytes())
        return ca.Function.deserialize(data.decode())

    @cached_property
    def library(self) -> ctypes.CDLL:
        """The compiled library; compiled here first if the folder has only the source."""
        from gagen.codegen.compiler import compile_shared

        library = self.folder / self.manifest["library"]
        if not library.exists():
            compile_shared(self.folder / self.manifest["c_source"], library)
        return ctypes.CDLL(str(library))

    @cached_property
    def binding(self) -> Any:
        """The CPython binding module (compiled here first if absent), or None: then ctypes."""
        from gagen.codegen.compiler import CompileError, compile_binding, extension_path

        name = self.manifest["binding"]
        path = extension_path(self.folder, name)
        if not path.exists():
            try:
                compile_binding(self.folder / self.manifest["binding_source"])
            except CompileError as e:
                warnings.warn(f"{name}: {e}; C kernels are called through ctypes", stacklevel=2)
                return None
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module

    def _load_c(self, name: str) -> CKernel:
        return CKernel(self.library, self._entry(name), self.binding)


def load(folder: str | Path) -> GeneratedModule:
    """The generated module in ``folder`` (e.g. ``generated/three_pandas_circle``)."""
    return GeneratedModule(Path(folder))
