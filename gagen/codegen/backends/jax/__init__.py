"""The JAX backend: every kernel as a pure ``jax.numpy`` function, in one Python file per module,
``<name>_jax.py`` (from ``templates/kernels.py.j2``), whose statements its printer (``printer.py``)
replays from each kernel's flat CasADi graph; ``module.jax.<kernel>`` is that function.

One flat file beside the C sources (``<name>.c``, ``<name>_binding.c``), not a ``jax/`` folder: it is
importable as ``generated.<name>.<name>_jax`` and no folder named ``jax`` ever sits where it could be
taken for the jax package. The calling convention is the C kernels' (see the file's header and
``gagen.runtime``): one argument per input port (vector ports ``(n,)``, ``(n, 1)``, ``(1, n)``; matrix
ports ``(rows, cols)`` or flat column-major), vector outputs ``(rows,)``, matrices ``(rows, cols)``,
one output alone; batches through ``jax.vmap``. Float64: loading the file turns on ``jax_enable_x64``.

Rendering needs CasADi only. Loading needs jax (optional: a module without it loads, its ``c`` and
``casadi`` kernels work, and ``module.jax.<kernel>`` raises an ImportError saying what to install).
The file is executed only after its sha256 matches the manifest's (a damaged or edited file is
refused); the manifest itself is trusted, as it is for the C library.
"""

from __future__ import annotations

import hashlib
import types
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gagen.codegen.backends.base import Backend, Context, LoadedModule, Output, module_name, module_tag
from gagen.names import identifier_problem

if TYPE_CHECKING:
    from gagen.codegen.ir import Kernel, ModuleSource

INSTALL = 'pip install jax (or pip install "gagen[jax]")'


class ModifiedFile(ValueError):
    """A module file whose sha256 is not the manifest's: damaged or edited, and not executed."""


def _check(name: str, what: str) -> str:
    """``name`` if it can be written into the file as a Python name by the identifier rule of
    ``gagen.names`` (``gagen.build`` checks it first: this is the backend's own line of defence; no
    name starts with ``_``, as the file's own globals ``_Jax``, ``_Jnp``, ``_Flat`` do)."""
    if identifier_problem(name, single_underscores=False, max_length=None) is not None:
        raise ValueError(f"the jax backend cannot name a {what} {name!r}: not a plain Python identifier")
    return name


def _kernel(kernel: Kernel) -> dict[str, Any]:
    """A kernel's template variables: its ports, parameters ``in_<port>``, statements and return."""
    from gagen.codegen.backends.jax.printer import jax_body, stacked

    _check(kernel.name, "kernel")
    for p in (*kernel.inputs, *kernel.outputs):
        _check(p.name, f"port of kernel {kernel.name}")
    body = jax_body(kernel.function)
    # a vector output 1-D, a matrix (rows, cols): what the C kernels return
    outputs = [stacked(entries, rows, cols, matrix=cols > 1) for entries, rows, cols in body.outputs]
    returns = outputs[0] if len(outputs) == 1 else "(\n        " + ",\n        ".join(outputs) + ",\n    )"
    return {"name": kernel.name, "doc": kernel.doc, "inputs": kernel.inputs, "outputs": kernel.outputs,
            "params": ", ".join(f"in_{p.name}" for p in kernel.inputs),
            "statements": body.statements, "returns": returns}


def source_path(manifest: dict[str, Any]) -> str:
    """The file's path in the module folder, as the manifest lists it."""
    return str(manifest["jax_source"])


def import_jax() -> Any:
    """The jax package, or an ImportError saying how to install it."""
    try:
        import jax
    except ImportError as e:
        raise ImportError(f"module.jax needs the jax package, which is not installed: {INSTALL}. "
                          "The module's c and casadi kernels work without it.", name="jax") from e
    return jax


class JaxBackend(Backend):
    name = "jax"
    namespace = "jax"
    templates = Path(__file__).with_name("templates")

    def render(self, source: ModuleSource, context: Context) -> Output:
        kernels = [_kernel(k) for k in source.kernels.values()]
        path = f"{source.name}_jax.py"
        text = self.template("kernels.py.j2").render(**context.variables, kernels=kernels)
        compile(text, path, "exec")  # parsed, not run: a SyntaxError here rather than at a user's load
        context.progress(f"  {path}: {len(kernels)} jax.numpy kernels")
        return Output({path: text.encode()}, {"jax_source": path})

    def open(self, module: LoadedModule) -> types.ModuleType:
        """The executed file, as a module object (once per loaded module): jax imported, the bytes
        read once, checked against the manifest's sha256, and those bytes executed."""
        import_jax()
        relative = source_path(module.manifest)
        path = module.path(relative)
        data = path.read_bytes()
        expected = module.manifest["files"].get(relative)
        if hashlib.sha256(data).hexdigest() != expected:
            raise ModifiedFile(f"{path}: its sha256 is not the one in {module.folder / 'manifest.json'} "
                               "(the file was edited or damaged); not executing it. Rebuild the module: "
                               "gagen build")
        name = f"_gagen_jax_{module_name(module.manifest)}_{module_tag(module.manifest)}"
        namespace = types.ModuleType(name)
        namespace.__file__ = str(path)
        exec(compile(data, str(path), "exec"), namespace.__dict__)  # the checked bytes
        return namespace

    def load(self, module: LoadedModule, kernel: str) -> Any:
        return getattr(module.handle(self.name), kernel)


BACKEND = JaxBackend()
