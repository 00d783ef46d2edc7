"""The CUDA backend: every kernel as CUDA C++ in ``<name>.cu`` (from ``templates/kernels.cu.j2``), the
same statements as the C kernels (the C printer with a type-generic dialect, below) in a per-sample
``__host__ __device__`` template over float and double, a ``__global__`` batch kernel per kernel and
precision (one thread per sample, column layout: coalesced loads and stores), and host loops over the
same body.

Nothing is compiled at build time: a module built on a machine without CUDA carries the source, and
``module.cuda.<kernel>`` compiles it at first use with NVRTC through CuPy (``loader.py``), on device
arrays in and out. The tests compile every generated ``.cu`` with nvcc from the ``nvidia-cuda-nvcc``
wheel and run the host loops (``toolchain.py``) against the C kernels and the interpreter, so the
bodies are checked on every machine; on a GPU the device results are held to the C kernels too.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gagen.codegen.backends.base import Backend, Context, LoadedModule, Output, ReservedNames
from gagen.codegen.backends.c import LIBC_PREFIXES, c_name, c_ports
from gagen.codegen.backends.c.printer import Dialect, c_literal, emit_body

if TYPE_CHECKING:
    from gagen.codegen.ir import Kernel, ModuleSource

# the global functions each kernel's file defines, after <module>_<kernel>
KERNEL_SUFFIXES = ("_body", "_cuda_f64", "_cuda_f32", "_host_f64", "_host_f32")

FLOAT_MIN, FLOAT_MAX = 1.1754943508222875e-38, 3.4028234663852886e+38


def constant(value: float) -> str:
    """A literal of the body's type T: ``T(0.5)``, so that float arithmetic stays float. A double
    beyond float's normal range (the graphs' guards, ``x + 1e-300``) becomes float's smallest normal or
    largest number in the float instance, so that a guard stays a guard rather than 0 or inf."""
    text = c_literal(value)
    magnitude = abs(value)
    if math.isfinite(value) and value != 0 and not FLOAT_MIN <= magnitude <= FLOAT_MAX:
        near = math.copysign(FLOAT_MIN if magnitude < FLOAT_MIN else FLOAT_MAX, value)
        return f"gagen_literal<T>({text}, {near!r}f)"
    return f"T({text})"


# the body's locals are T; its arrays are read and written with the column stride gagen_ld
DIALECT = Dialect(real="T", constant=constant,
                  element=lambda name, k: f"{name}[{k} * gagen_ld]" if k else f"{name}[0]")


def _params(kernel: Kernel, real: str) -> str:
    ins, outs = c_ports(kernel)
    return ", ".join([f"const {real} *__restrict__ {p.name}" for p in ins] +
                     [f"{real} *__restrict__ {p.name}" for p in outs])


class CudaBackend(Backend):
    name = "cuda"
    namespace = "cuda"
    templates = Path(__file__).with_name("templates")

    def symbols(self, module: str, kernel: str) -> tuple[str, ...]:
        return tuple(f"{module}_{kernel}{suffix}" for suffix in KERNEL_SUFFIXES)

    def reserved(self) -> ReservedNames:
        own = super().reserved()
        return ReservedNames(own.exact, own.prefixes + LIBC_PREFIXES)

    def render(self, source: ModuleSource, context: Context) -> Output:
        contexts: list[dict[str, Any]] = []
        for kernel in source.kernels.values():
            ins, outs = c_ports(kernel)
            body = emit_body(kernel.function, [p.name for p in ins], [p.name for p in outs], dialect=DIALECT)
            contexts.append({"kernel": kernel.name, "c_name": c_name(source.name, kernel), "doc": kernel.doc,
                             "ops": str(kernel.op_count), "inputs": kernel.inputs, "outputs": kernel.outputs,
                             "c_inputs": ins, "c_outputs": outs, "locals": body.locals,
                             "statements": body.statements,
                             "trig": body.trig, "params_t": _params(kernel, "T"),
                             "params": {real: _params(kernel, real) for real in ("double", "float")}})
        path = f"{source.name}.cu"
        text = self.template("kernels.cu.j2").render(**context.variables, kernels=contexts)
        context.progress(f"  {path}: {len(contexts)} CUDA kernels (float64 and float32)")
        return Output({path: text.encode()}, {"cuda_source": path},
                      {str(k["kernel"]): {"cuda_name": k["c_name"]} for k in contexts})

    def open(self, module: LoadedModule) -> Any:
        """The module's source compiled by NVRTC (a CuPy RawModule), once per loaded module, from
        bytes checked against the manifest's sha256."""
        from gagen.codegen.backends.cuda.loader import raw_module

        relative = str(module.manifest["cuda_source"])
        path = module.path(relative)
        data = path.read_bytes()
        if hashlib.sha256(data).hexdigest() != module.manifest["files"].get(relative):
            raise ValueError(f"{path}: its sha256 is not the one in {module.folder / 'manifest.json'} (the "
                             "file was edited or damaged); not compiling it. Rebuild the module: gagen build")
        return raw_module(data.decode(), str(path))

    def load(self, module: LoadedModule, kernel: str) -> Any:
        from gagen.codegen.backends.cuda.loader import CudaKernel

        return CudaKernel(module.handle(self.name), module.entry(kernel))


BACKEND = CudaBackend()
