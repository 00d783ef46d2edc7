"""The CPython backend: a binding of the C kernels (``<name>_binding.c``: a vectorcall kernel object per
kernel over numpy's C API, inputs read in place, fresh outputs or ``out=``), compiled into the extension
module ``_gagen_<name>_<tag>``. It is the fast path of ``module.c``, not a namespace of its own, and
optional: where it cannot compile (no Python headers), calls go through ctypes."""

from __future__ import annotations

import importlib.util
import sys
import warnings
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
from gagen.codegen.backends.c import c_name, params

if TYPE_CHECKING:
    from gagen.codegen.ir import ModuleSource

BINDING_ABI = 2  # the calling convention of binding.c.j2 (make_<kernel>(address, slow, out, info))


def binding_module(manifest: Mapping[str, Any]) -> str:
    """The extension module's name, ``_gagen_<name>_<tag>``: unique per content."""
    return f"_gagen_{module_name(manifest)}_{module_tag(manifest)}"


class CPythonBackend(Backend):
    name = "cpython"
    requires = ("c",)
    optional = "C kernels are called through ctypes"
    templates = Path(__file__).with_name("templates")

    def symbols(self, module: str, kernel: str) -> tuple[str, ...]:
        function = f"{module}_{kernel}"
        return (f"call_{function}", f"make_{function}", f"make_{kernel}", f"run_{function}",
                f"{function}_in_shape", f"{function}_out_shape")

    def reserved(self) -> ReservedNames:
        own = super().reserved()  # the binding includes Python.h and numpy's headers
        return ReservedNames(own.exact, (*own.prefixes, "Py", "PY_", "_Py", "NPY_", "npy_"))

    def render(self, source: ModuleSource, context: Context) -> Output:
        kernels = [{"name": k.name, "c_name": c_name(source.name, k), "inputs": k.inputs,
                    "outputs": k.outputs, "params_h": params(k, "GAGEN_RESTRICT")}
                   for k in source.kernels.values()]
        path = f"{source.name}_binding.c"
        text = self.template("binding.c.j2").render(**context.variables, kernels=kernels)
        return Output({path: text.encode()}, {"binding_source": path})

    def artefacts(self, folder: Path, manifest: Mapping[str, Any]) -> list[Path]:
        from gagen.codegen.compiler import extension_path

        return [extension_path(folder, binding_module(manifest))]

    def compile(self, folder: Path, manifest: Mapping[str, Any]) -> None:
        from gagen.codegen.compiler import compile_binding

        compile_binding(folder / manifest["binding_source"], binding_module(manifest))

    def open(self, module: LoadedModule) -> Any:
        """The binding module (compiled first if absent), or None: then ctypes."""
        from gagen.codegen.compiler import extension_path

        module.compile_missing()
        name = binding_module(module.manifest)
        path = module.path(extension_path(Path("."), name).name)
        if not path.exists():
            return None
        if name in sys.modules:  # loaded already (another module object of the same content)
            return sys.modules[name]
        try:
            spec = importlib.util.spec_from_file_location(name, path)
            if spec is None or spec.loader is None:
                raise ImportError(f"{path} cannot be loaded as an extension module")
            binding = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(binding)
        except ImportError as e:  # e.g. built against another numpy: still usable through ctypes
            warnings.warn(f"{name}: {e}; {self.optional}", stacklevel=4)
            return None
        if getattr(binding, "GAGEN_BINDING_ABI", None) != BINDING_ABI:  # built by another gagen version
            warnings.warn(f"{name}: a binding from another gagen version (rebuild the module: gagen build); "
                          f"{self.optional}", stacklevel=4)
            return None
        sys.modules[name] = binding
        return binding


BACKEND = CPythonBackend()
