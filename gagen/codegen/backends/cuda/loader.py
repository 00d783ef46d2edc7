"""Calling the CUDA kernels from Python: ``module.cuda.<kernel>(*inputs)`` runs the batch kernel on
device arrays, one thread per sample, and returns device arrays (CuPy; hand them to PyTorch or JAX
through DLPack: ``torch.from_dlpack(out)``, ``jax.dlpack.from_dlpack(out)``).

Layout: the C kernels' ``batch_columns`` (samples last). Each input has shape ``(size, n)``, a matrix
port ``(rows, cols, n)`` too, a port of size 1 ``(n,)``; outputs come back ``(rows, n)`` or
``(rows, cols, n)``. All inputs float64 run the float64 kernel, all float32 the float32 one. Inputs
are CuPy arrays, or anything with ``__cuda_array_interface__`` or ``__dlpack__`` on the device (no
copy when C-contiguous); a numpy array is copied to the device (a host transfer, said here so that
nobody times it by accident). The launch goes on CuPy's current stream and does not synchronise.

Standalone on purpose (numpy and CuPy only, no gagen import): a GPU machine can run a built module's
``.cu`` through this file without CasADi (benchmarks/cuda_gpu.py does).
"""

from __future__ import annotations

from typing import Any, NamedTuple

INSTALL = "pip install 'gagen[cuda]' (CuPy for CUDA 13: cupy-cuda13x)"
THREADS = 128  # per block: the kernels are register-bound straight-line code, one sample a thread


def import_cupy() -> Any:
    """The cupy package, or an ImportError saying what to install."""
    try:
        import cupy
    except ImportError as e:
        raise ImportError(f"module.cuda needs CuPy, which is not installed: {INSTALL}. The module's c, "
                          "casadi and jax kernels work without it.", name="cupy") from e
    return cupy


def nvrtc_options() -> tuple[str, ...]:
    """NVRTC's options for a module: IEEE arithmetic kept except for fused multiply-adds (the device's
    default; ``GAGEN_CUDA_FMAD=0`` turns them off, for results that follow the C kernels' rounding more
    closely)."""
    import os

    fmad = () if os.environ.get("GAGEN_CUDA_FMAD", "1") != "0" else ("--fmad=false",)
    return ("--std=c++17", *fmad)


def raw_module(source: str, path: str) -> Any:
    """``source`` as a CuPy RawModule, compiled by NVRTC (``nvrtc_options``) at its first kernel."""
    cupy = import_cupy()
    return cupy.RawModule(code=source, options=nvrtc_options(), name_expressions=None)


class DevicePort(NamedTuple):
    """A port of the manifest: its name, rows and columns (a matrix is column-major per sample)."""

    name: str
    rows: int
    cols: int

    @property
    def size(self) -> int:
        return self.rows * self.cols

    @classmethod
    def of(cls, entry: dict[str, Any]) -> DevicePort:
        return cls(str(entry["name"]), len(entry["rows"]), int(entry["cols"]))


class CudaKernel:
    """One kernel's batch on the device (see the module docstring)."""

    def __init__(self, raw: Any, entry: dict[str, Any]) -> None:
        self.name: str = entry["name"]
        self.inputs = [DevicePort.of(p) for p in entry["inputs"]]
        self.outputs = [DevicePort.of(p) for p in entry["outputs"]]
        self._raw = raw
        self._symbol: str = entry["cuda_name"]
        self._functions: dict[str, Any] = {}

    def function(self, precision: str) -> Any:
        """The ``__global__`` kernel of ``precision`` (``f64`` or ``f32``), compiled at first use."""
        if precision not in self._functions:
            self._functions[precision] = self._raw.get_function(f"{self._symbol}_cuda_{precision}")
        return self._functions[precision]

    def _input(self, cupy: Any, value: Any, index: int) -> Any:
        p = self.inputs[index]
        what = f"{self.name} (cuda): input {p.name}"
        if isinstance(value, cupy.ndarray) or hasattr(value, "__cuda_array_interface__"):
            a = cupy.asarray(value)
        elif hasattr(value, "__dlpack__") and not hasattr(value, "__array_interface__"):
            a = cupy.from_dlpack(value)
        else:
            a = cupy.asarray(value)  # host data: one copy to the device
        if a.dtype not in (cupy.float64, cupy.float32):
            raise TypeError(f"{what}: expected float64 or float32, got dtype {a.dtype}")
        rows, cols = p.rows, p.cols
        if a.ndim == 2 and a.shape[0] == p.size:
            flat = a
        elif cols > 1 and a.ndim == 3 and a.shape[:2] == (rows, cols):
            flat = a.transpose(1, 0, 2).reshape(p.size, a.shape[2])
        elif p.size == 1 and a.ndim == 1:
            flat = a[None, :]
        else:
            alt = f" or ({rows}, {cols}, n)" if cols > 1 else ""
            raise ValueError(f"{what} needs shape ({p.size}, n){alt}; got shape {a.shape}")
        return cupy.ascontiguousarray(flat)

    def __call__(self, *args: Any) -> Any:
        cupy = import_cupy()
        if len(args) != len(self.inputs):
            raise TypeError(f"{self.name} (cuda) takes {len(self.inputs)} inputs "
                            f"({', '.join(p.name for p in self.inputs)}), got {len(args)}")
        arrays = [self._input(cupy, a, i) for i, a in enumerate(args)]
        dtypes = {a.dtype for a in arrays}
        if len(dtypes) > 1:
            raise TypeError(f"{self.name} (cuda): inputs mix float32 and float64; give one precision")
        counts = {a.shape[1] for a in arrays}
        if len(counts) > 1:
            raise ValueError(f"{self.name} (cuda): inputs have different sample counts {sorted(counts)}")
        n = counts.pop() if counts else 0
        dtype = dtypes.pop() if dtypes else cupy.dtype(cupy.float64)
        outs = [cupy.empty((p.size, n), dtype=dtype) for p in self.outputs]
        if n:
            precision = "f64" if dtype == cupy.float64 else "f32"
            blocks = -(-n // THREADS)
            self.function(precision)((blocks,), (THREADS,), (cupy.int64(n), cupy.int64(n), *arrays, *outs))
        views = tuple(o if p.cols == 1 else o.reshape(p.cols, p.rows, n).transpose(1, 0, 2)
                      for o, p in zip(outs, self.outputs, strict=True))
        return views[0] if len(views) == 1 else views
