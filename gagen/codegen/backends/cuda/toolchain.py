"""Compiling a generated ``.cu`` without a GPU: with nvcc (from ``$NVCC``, the PATH, or the
``nvidia-cuda-nvcc`` wheel of the ``test`` extra) into device code, and with the host C++ compiler
into a shared library of the ``*_host_f64`` / ``*_host_f32`` loops (what the tests hold against the C
kernels and the interpreter on every machine)."""

from __future__ import annotations

import ctypes
import importlib.util
import os
import shlex
import shutil
import subprocess
import threading
import types
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.codegen.backends.cuda.loader import DevicePort
from gagen.codegen.compiler import CompileError, CompilerNotFound

# the architectures the check compiles for: Ampere (A100) and Hopper (H100, H200)
ARCHITECTURES = ("sm_80", "sm_90")


def find_nvcc() -> list[str]:
    """$NVCC if set, else nvcc on PATH, else the one of the ``nvidia-cuda-nvcc`` wheel."""
    if os.environ.get("NVCC"):
        return shlex.split(os.environ["NVCC"])
    if path := shutil.which("nvcc"):
        return [path]
    spec = importlib.util.find_spec("nvidia")
    for root in (Path(p) for p in (spec.submodule_search_locations or []) if spec) if spec else ():
        for candidate in sorted(root.glob("cu*/bin/nvcc")):
            return [str(candidate)]
    raise CompilerNotFound('no nvcc found (looked for $NVCC, nvcc on PATH and the nvidia-cuda-nvcc wheel); '
                           'pip install "gagen[test]" brings one')


def _run(command: list[str]) -> None:
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise CompileError(f"{' '.join(command)} failed:\n{(result.stderr or result.stdout).strip()}")


def compile_device(source: Path, output: Path, arch: str = "sm_90", *, ptx: bool = False) -> None:
    """``source`` into a cubin for ``arch`` with nvcc (no GPU needed), or only to PTX (``ptx``: the
    front end and NVVM, not ptxas; half the time on the largest modules), warnings as errors."""
    _run([*find_nvcc(), "-std=c++17", "-ptx" if ptx else "-cubin", f"-arch={arch}", "-Werror",
          "all-warnings", "-o", str(output), str(source)])


def _nvrtc_library() -> ctypes.CDLL:
    """libnvrtc: the machine's (ldconfig), else the ``nvidia-cuda-nvrtc`` wheel's."""
    import ctypes.util

    spec = importlib.util.find_spec("nvidia")
    roots = [Path(p) for p in (spec.submodule_search_locations or [])] if spec else []
    candidates = [path for root in roots for path in sorted(root.glob("cu*/lib/libnvrtc.so*"))
                  if ".alt." not in path.name]
    found = ctypes.util.find_library("nvrtc")
    for candidate in [*(c for c in [found] if c), *map(str, candidates)]:
        try:
            # its builtins library beside it first: NVRTC dlopens it by name, which misses a wheel's folder
            for builtins in sorted(Path(candidate).parent.glob("libnvrtc-builtins.so*")):
                if ".alt." not in builtins.name:
                    ctypes.CDLL(str(builtins), mode=ctypes.RTLD_GLOBAL)
            return ctypes.CDLL(candidate)
        except OSError:
            continue
    raise CompilerNotFound('no NVRTC found (libnvrtc); pip install "gagen[test]" brings one')


def compile_nvrtc(source: str, name: str, arch: str = "sm_90", *, ptx: bool = False) -> bytes:
    """``source`` compiled by NVRTC, the compiler ``module.cuda`` uses at load time (through CuPy), with
    the loader's options, into a cubin for ``arch`` (or PTX for its virtual architecture: ``ptx``);
    CompileError with NVRTC's log."""
    from gagen.codegen.backends.cuda.loader import nvrtc_options

    nvrtc = _nvrtc_library()
    program = ctypes.c_void_p()
    status = nvrtc.nvrtcCreateProgram(ctypes.byref(program), source.encode(), name.encode(), 0, None, None)
    if status:
        raise CompileError(f"NVRTC could not take {name} (status {status})")
    try:
        target = arch.replace("sm_", "compute_") if ptx else arch
        options = [*nvrtc_options(), f"--gpu-architecture={target}"]
        array = (ctypes.c_char_p * len(options))(*(o.encode() for o in options))
        status = nvrtc.nvrtcCompileProgram(program, len(options), array)
        size = ctypes.c_size_t()
        nvrtc.nvrtcGetProgramLogSize(program, ctypes.byref(size))
        log = ctypes.create_string_buffer(size.value)
        nvrtc.nvrtcGetProgramLog(program, log)
        if status:
            raise CompileError(f"NVRTC {' '.join(options)} failed on {name}:\n{log.value.decode().strip()}")
        kind = "PTX" if ptx else "CUBIN"
        getattr(nvrtc, f"nvrtcGet{kind}Size")(program, ctypes.byref(size))
        code = ctypes.create_string_buffer(size.value)
        getattr(nvrtc, f"nvrtcGet{kind}")(program, code)
        return code.raw
    finally:
        nvrtc.nvrtcDestroyProgram(ctypes.byref(program))


def find_cxx() -> list[str]:
    """$CXX if set, else the first of c++, g++, clang++ on PATH."""
    if os.environ.get("CXX"):
        return shlex.split(os.environ["CXX"])
    for name in ("c++", "g++", "clang++"):
        if path := shutil.which(name):
            return [path]
    raise CompilerNotFound("no C++ compiler found (looked for $CXX, c++, g++, clang++); install one or "
                           "set CXX")


def compile_host(source: Path, library: Path, optimise: str = "-O0", *, float32: bool = True) -> None:
    """``source`` as host C++ into ``library``: the ``*_host_*`` loops over the same bodies, without
    fused multiply-adds (the C kernels' doubles, up to libm's sine and cosine). ``-O0`` by default: the
    same doubles as optimised code, compiled 4x faster (what the tests need); without ``float32`` only
    the float64 loops (half the compile)."""
    partial = library.with_name(library.name + f".{os.getpid()}.{threading.get_ident()}.partial")
    only = [] if float32 else ["-DGAGEN_HOST_F64_ONLY"]
    try:
        _run([*find_cxx(), "-x", "c++", "-std=c++17", optimise, *only, "-ffp-contract=off", "-fPIC",
              "-shared", "-Wall", "-Werror", "-o", str(partial), str(source)])
        partial.replace(library)
    finally:
        partial.unlink(missing_ok=True)


class HostKernel:
    """One kernel's ``*_host_f64`` (or ``_f32``) loop of a host-compiled ``.cu``, called like the C
    kernels (``module.c.<kernel>``): one sample (``kernel(*inputs)``), n samples (``kernel.batch``:
    inputs (n, size), outputs (n, rows[, cols])) or the column layout (``kernel.columns``: (size, n) in
    and out, the device kernels' own). What the tests hold against the C kernels and the interpreter."""

    def __init__(self, library: ctypes.CDLL, entry: dict[str, Any], precision: str = "f64") -> None:
        self.name = str(entry["name"])
        self.inputs = [DevicePort.of(p) for p in entry["inputs"]]
        self.outputs = [DevicePort.of(p) for p in entry["outputs"]]
        self.dtype = np.float64 if precision == "f64" else np.float32
        self._function = getattr(library, f"{entry['cuda_name']}_host_{precision}")
        self._function.restype = None

    def columns(self, *arrays: Any) -> tuple[NDArray[Any], ...]:
        """Inputs (size, n), outputs (size, n), in the kernel's precision."""
        flat = [np.ascontiguousarray(a, dtype=self.dtype).reshape(p.size, -1)
                for a, p in zip(arrays, self.inputs, strict=True)]
        n = flat[0].shape[1] if flat else 1
        outs = [np.zeros((p.size, n), dtype=self.dtype) for p in self.outputs]
        pointers = [ctypes.c_void_p(a.ctypes.data) for a in (*flat, *outs)]
        self._function(ctypes.c_long(n), ctypes.c_long(n), *pointers)
        return tuple(outs)

    def __call__(self, *args: Any) -> Any:
        columns = [np.asarray(a, dtype=float).reshape(-1, order="F")[:, None] for a in args]
        outs = tuple(o[:, 0] if p.cols == 1 else o[:, 0].reshape(p.rows, p.cols, order="F")
                     for o, p in zip(self.columns(*columns), self.outputs, strict=True))
        return outs[0] if len(outs) == 1 else outs

    def batch(self, *args: Any) -> Any:
        columns = [np.asarray(a, dtype=float).reshape(len(a), -1).T for a in args]
        outs = tuple(o.T if p.cols == 1 else o.reshape(p.cols, p.rows, -1).transpose(2, 1, 0)
                     for o, p in zip(self.columns(*columns), self.outputs, strict=True))
        return outs[0] if len(outs) == 1 else outs


def host_kernels(source: Path | None, library: Path, manifest: dict[str, Any],
                 precision: str = "f64", *, float32: bool = True) -> types.SimpleNamespace:
    """The kernels of ``manifest`` from ``source`` compiled as host C++ into ``library`` (``source``
    None: the library compiled before; ``float32``: with the float loops): a namespace of
    :class:`HostKernel` by kernel name."""
    if source is not None:
        compile_host(source, library, float32=float32)
    loaded = ctypes.CDLL(str(library))
    return types.SimpleNamespace(**{e["name"]: HostKernel(loaded, e, precision) for e in manifest["kernels"]})
