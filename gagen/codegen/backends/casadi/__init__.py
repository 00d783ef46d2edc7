"""The CasADi backend: every kernel as its ``casadi.Function``, serialised and gzipped
(``casadi/<kernel>.casadi.gz``); ``module.casadi.<kernel>`` deserialises it (numbers, SX or MX: drops
into ``casadi.nlpsol``)."""

from __future__ import annotations

import gzip
from typing import TYPE_CHECKING, Any

from gagen.codegen.backends.base import Backend, Context, LoadedModule, Output

if TYPE_CHECKING:
    from gagen.codegen.ir import ModuleSource


class CasadiBackend(Backend):
    name = "casadi"
    namespace = "casadi"

    def render(self, source: ModuleSource, context: Context) -> Output:
        files, entries = {}, {}
        for kernel in source.kernels.values():
            path = f"casadi/{kernel.name}.casadi.gz"
            # about 10x smaller gzipped; mtime 0: deterministic
            files[path] = gzip.compress(kernel.function.serialize().encode(), compresslevel=9, mtime=0)
            entries[kernel.name] = {"casadi": path}
        return Output(files, kernels=entries)

    def load(self, module: LoadedModule, kernel: str) -> Any:
        import casadi as ca

        path = module.path(module.entry(kernel)["casadi"])
        if not path.is_file():  # not committed (binary): a fresh clone's committed modules have none
            raise FileNotFoundError(f"{path}: no CasADi serialisation (they are not committed); build the "
                                    f"module again (gagen build {module.manifest.get('source', 'SOURCE')}), "
                                    "or load it through gagen.modules.bundled_module, which builds it")
        data = gzip.decompress(path.read_bytes())
        return ca.Function.deserialize(data.decode())


BACKEND = CasadiBackend()
