"""The C backend: the kernels as C99 (``<name>.h``, ``<name>.c``, and ``<name>_simd.c`` with the batched
forms of the smaller kernels), from the statements our printer (``printer.py``) replays from each
kernel's flat CasADi graph; compiled into ``lib<name>_<tag>.so`` and called through ctypes
(``module.c.<kernel>``: ``loader.py``, or through the CPython binding when the module has the
``cpython`` backend).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gagen.codegen.backends.base import (
    Backend,
    Context,
    LoadedModule,
    Output,
    ReservedNames,
    module_name,
    module_tag,
)

if TYPE_CHECKING:
    from gagen.codegen.ir import Kernel, ModuleSource, Port

# kernels up to this many C statements also get a SIMD batch (the chains' FK and FK + Jacobian): it
# runs GAGEN_W samples at once, and doubles the kernel's code and compile time
SIMD_MAX_STATEMENTS = 1500


def c_name(module: str, kernel: Kernel) -> str:
    """The C function of ``kernel`` in ``module``: ``<module>_<kernel>``."""
    return f"{module}_{kernel.name}"


def c_ports(kernel: Kernel) -> tuple[list[Port], list[Port]]:
    """The kernel's inputs and outputs under their C parameter names, ``in_<name>`` and ``out_<name>``:
    a user's name (``s``, ``n``, ``w0``, ``sin``, ``NAN``…) can then never meet an identifier of the
    generated code (its locals ``w<i>``, the templates' ``gagen_*``) or of libm and its macros."""
    return ([dataclasses.replace(p, name=f"in_{p.name}") for p in kernel.inputs],
            [dataclasses.replace(p, name=f"out_{p.name}") for p in kernel.outputs])


def params(kernel: Kernel, restrict: str) -> str:
    """The C parameter list: ``const double *<restrict> in_<input>, ..., double *<restrict> out_<output>,
    ...``."""
    ins, outs = c_ports(kernel)
    return ", ".join([f"const double *{restrict} {p.name}" for p in ins] +
                     [f"double *{restrict} {p.name}" for p in outs])


def _check_size_macros(source: ModuleSource) -> None:
    """The header's ``<MODULE>_<KERNEL>_<PORT>_SIZE`` macros must not define one name twice with two
    sizes (ports ``R`` and ``r``, or kernel ``a_b`` with port ``c`` beside kernel ``a`` with port
    ``b_c``); two with the same size (a vector ``b`` and a bivector ``B`` in ga3d) are one macro."""
    seen: dict[str, tuple[str, int]] = {}
    for kernel in source.kernels.values():
        for p in (*kernel.inputs, *kernel.outputs):
            macro = f"{c_name(source.name, kernel)}_{p.name}".upper()
            where = f"kernel {kernel.name}, {p.name} (size {p.size})"
            if macro in seen and seen[macro][1] != p.size:
                raise ValueError(f"{source.name}: {where} and {seen[macro][0]} give the same C macro "
                                 f"{macro}_SIZE; rename one of them")
            seen[macro] = where, p.size


def library(manifest: Mapping[str, Any]) -> str:
    """The library's file name, ``lib<name>_<tag>.so`` (``.dylib`` on macOS)."""
    from gagen.codegen.compiler import library_name

    return library_name(f"{module_name(manifest)}_{module_tag(manifest)}")


# the macro families of the C headers the kernels include (math.h, stdint.h, float.h, stdlib.h) and the
# compiler's own names: ``M`` + ``PI`` would define ``M_PI``
LIBC_PREFIXES = ("M_", "FP_", "FLT_", "DBL_", "LDBL_", "MATH_", "EXIT_", "RAND_", "SIZE_", "PTRDIFF_",
                 "SIG_ATOMIC_", "WCHAR_", "WINT_", "INTPTR_", "UINTPTR_", "INTMAX_", "UINTMAX_",
                 *(f"{u}INT{bits}_" for u in ("", "U") for bits in (8, 16, 32, 64)),
                 *(f"{u}INT_{kind}{bits}_" for u in ("", "U") for kind in ("LEAST", "FAST")
                   for bits in (8, 16, 32, 64)), "__", "_mm", "_MM")

# the C functions each kernel's files define, after <module>_<kernel> (kernels.c.j2, simd.c.j2)
KERNEL_SUFFIXES = ("", "_argv", "_batch", "_batch_argv", "_batch_columns", "_batch_columns_argv",
                   "_columns_from", "_block", "_block_columns")


class CBackend(Backend):
    name = "c"

    def symbols(self, module: str, kernel: str) -> tuple[str, ...]:
        return tuple(f"{module}_{kernel}{suffix}" for suffix in KERNEL_SUFFIXES)

    def reserved(self) -> ReservedNames:
        own = super().reserved()
        return ReservedNames(own.exact, own.prefixes + LIBC_PREFIXES)
    namespace = "c"
    templates = Path(__file__).with_name("templates")

    def render(self, source: ModuleSource, context: Context) -> Output:
        from gagen.codegen.backends.c import printer

        contexts, entries = [], {}
        _check_size_macros(source)
        for i, kernel in enumerate(source.kernels.values(), 1):
            start = time.perf_counter()
            ins, outs = c_ports(kernel)
            names = ([p.name for p in ins], [p.name for p in outs])
            body = printer.emit_body(kernel.function, *names)
            # the SIMD batch doubles a kernel's code: only kernels up to SIMD_MAX_STATEMENTS get one
            vector = (printer.emit_body(kernel.function, *names, vector=True)
                      if len(body.statements) <= SIMD_MAX_STATEMENTS else None)
            ops = kernel.op_count
            function = c_name(source.name, kernel)
            contexts.append({"c_name": function, "doc": kernel.doc, "inputs": kernel.inputs,
                             "outputs": kernel.outputs, "c_inputs": ins, "c_outputs": outs,
                             "ops": str(ops), "locals": body.locals,
                             "statements": body.statements, "trig": body.trig,
                             "vector_locals": vector.locals if vector else (),
                             "vector_statements": vector.statements if vector else (),
                             "params": params(kernel, "restrict"),
                             "params_h": params(kernel, "GAGEN_RESTRICT")})
            entries[kernel.name] = {"c_name": function}
            context.progress(f"  [{i}/{len(source.kernels)}] {kernel.name}: {ops.flops} flops, "
                             f"{len(body.statements)} C statements ({time.perf_counter() - start:.2f} s)")
        variables = {**context.variables, "kernels": contexts}
        name = source.name
        files = {
            f"{name}.h": self.template("kernels.h.j2").render(**variables, guard=f"GAGEN_{name.upper()}_H"),
            f"{name}.c": self.template("kernels.c.j2").render(**variables),
            f"{name}_simd.c": self.template("simd.c.j2").render(**variables),
        }
        return Output({path: text.encode() for path, text in files.items()},
                      {"c_source": f"{name}.c", "c_header": f"{name}.h"}, entries)

    def artefacts(self, folder: Path, manifest: Mapping[str, Any]) -> list[Path]:
        return [folder / library(manifest)]

    def compile(self, folder: Path, manifest: Mapping[str, Any]) -> None:
        from gagen.codegen.compiler import compile_shared

        compile_shared(folder / manifest["c_source"], folder / library(manifest))

    def open(self, module: LoadedModule) -> Any:
        import ctypes

        module.compile_missing()
        return ctypes.CDLL(str(module.path(library(module.manifest))))

    def load(self, module: LoadedModule, kernel: str) -> Any:
        from gagen.codegen.backends.c.loader import CKernel

        library, binding = module.handle("c"), module.handle("cpython")
        return CKernel(library, module.entry(kernel), binding, module).entry_point()


BACKEND = CBackend()
