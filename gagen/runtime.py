"""Loading a generated module: its manifest, CasADi Functions, and the compiled C through ctypes.

A C kernel is called through its ``*_argv`` entry point with two pointer arrays that are built once,
over input and output buffers the kernel owns: a call copies the inputs into those buffers and
makes one ctypes call, so no per-call conversion or allocation happens. The returned arrays are the
kernel's output buffers (overwritten by the next call; copy what you keep). ``batch`` allocates.
"""

from __future__ import annotations

import ctypes
import json
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

MANIFEST = "manifest.json"


class CKernel:
    """One compiled kernel: ``kernel(*inputs) -> outputs`` and ``kernel.batch(*inputs)``."""

    def __init__(self, library: ctypes.CDLL, entry: dict[str, Any]) -> None:
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
        # buffers and pointer arrays, built once: a call passes two integers
        self._in = [np.zeros(r * c) for r, c in self._in_shapes]
        self._out = [np.zeros((r, c), order="F") for r, c in self._out_shapes]
        self._argv = (ctypes.c_void_p * len(self._in))(*[a.ctypes.data for a in self._in])
        self._resv = (ctypes.c_void_p * len(self._out))(*[a.ctypes.data for a in self._out])
        self._argv_address, self._resv_address = ctypes.addressof(self._argv), ctypes.addressof(self._resv)
        self._views = tuple(a[:, 0] if a.shape[1] == 1 else a for a in self._out)

    def __repr__(self) -> str:
        return f"<C kernel {self.name}({', '.join(self.inputs)}) -> {', '.join(self.outputs)}>"

    def __call__(self, *args: Any) -> Any:
        """Evaluate once; vectors come back 1-D, matrices (rows, cols); one output comes back alone."""
        if len(args) != len(self._in):
            raise TypeError(f"{self.name} takes {len(self._in)} inputs ({', '.join(self.inputs)}), "
                            f"got {len(args)}")
        for buffer, value in zip(self._in, args, strict=True):
            buffer[:] = value
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

        return ca.Function.load(str(self.folder / self._entry(name)["casadi"]))

    @cached_property
    def library(self) -> ctypes.CDLL:
        """The compiled library; compiled here first if the folder has only the source."""
        from gagen.codegen.compiler import compile_shared

        library = self.folder / self.manifest["library"]
        if not library.exists():
            compile_shared(self.folder / self.manifest["c_source"], library)
        return ctypes.CDLL(str(library))

    def _load_c(self, name: str) -> CKernel:
        return CKernel(self.library, self._entry(name))


def load(folder: str | Path) -> GeneratedModule:
    """The generated module in ``folder`` (e.g. ``generated/three_pandas_circle``)."""
    return GeneratedModule(Path(folder))
