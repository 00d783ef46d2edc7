"""The backends as packages: the registry (order, requirements, templates), a backend added by one
registry entry (rendered, listed in the manifest, loaded as a namespace), and the content tag that
names compiled files (two modules of one name and different contents, loaded in one process)."""

from __future__ import annotations

import hashlib
import json
import re

import casadi as ca
import numpy as np
import pytest

from gagen.build import build_source, render
from gagen.codegen.backends import BACKENDS, Backend, Output, module_tag, select
from gagen.codegen.backends.c import library
from gagen.codegen.backends.cpython import binding_module
from gagen.codegen.compiler import library_name
from gagen.codegen.ir import ModuleSource, Port, make_kernel
from gagen.runtime import load

QUIET = {"progress": lambda _: None}


def _source(name: str, scale: float) -> ModuleSource:
    """A module of one kernel, y = scale * x (no key: the build keys it by the kernel's content)."""
    x = ca.SX.sym("x", 2)
    kernel = make_kernel("scaled", "x times a constant", [(Port("x", ("a", "b")), x)],
                         [(Port("y", ("a", "b")), scale * x)])
    return ModuleSource(name, f"a test module (scale {scale})", {"scaled": kernel}, "<test>",
                        hashlib.sha256(b"").hexdigest())


def test_the_registry_lists_casadi_c_cpython_cuda_and_jax_in_build_order():
    assert list(BACKENDS) == ["casadi", "c", "cpython", "cuda", "jax"]
    order = list(BACKENDS)
    for backend in BACKENDS.values():
        assert all(order.index(r) < order.index(backend.name) for r in backend.requires), backend
        if backend.templates is not None:
            assert sorted(backend.templates.glob("*.j2")), backend
    namespaces = [b.namespace for b in BACKENDS.values() if b.namespace]
    assert namespaces == ["casadi", "c", "cuda", "jax"]
    with pytest.raises(ValueError, match="unknown backend"):
        select(["fortran"])
    with pytest.raises(ValueError, match="cpython needs c"):
        select(["casadi", "cpython"])


class TextBackend(Backend):
    """A backend as a user would add one: a text file of the kernels' docs, and a namespace that reads it."""

    name = "text"
    namespace = "text"

    def render(self, source, context):
        lines = [f"{k.name}: {k.doc}" for k in source.kernels.values()]
        path = f"{source.name}.txt"
        return Output({path: ("\n".join(lines) + "\n").encode()}, {"text": path},
                      {name: {"text_line": i} for i, name in enumerate(source.kernels)})

    def load(self, module, kernel):
        lines = module.path(module.manifest["text"]).read_text().splitlines()
        return lines[module.entry(kernel)["text_line"]]


def test_a_backend_added_to_the_registry_is_built_listed_and_loaded(tmp_path, monkeypatch):
    monkeypatch.setitem(BACKENDS, "text", TextBackend())
    out = tmp_path / "twin"
    build_source(_source("twin", 2.0), out, backends=["casadi", "text"], **QUIET)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["backends"] == ["casadi", "text"] and manifest["text"] == "twin.txt"
    assert sorted(manifest["files"]) == ["__init__.py", "casadi/scaled.casadi.gz", "twin.txt"]
    assert "casadi = _MODULE.casadi\ntext = _MODULE.text" in (out / "__init__.py").read_text()
    module = load(out)
    assert module.text.scaled == "scaled: x times a constant"
    assert np.allclose(module.casadi.scaled([1, 2]).full().ravel(), [2, 4])
    assert not hasattr(module, "c")


def test_rendering_is_deterministic_and_names_carry_no_hash():
    files = render(_source("twin", 2.0))
    assert files == render(_source("twin", 2.0))
    assert sorted(files) == ["__init__.py", "casadi/scaled.casadi.gz", "manifest.json", "twin.c", "twin.cu",
                             "twin.h", "twin_binding.c", "twin_jax.py", "twin_simd.c"]
    assert render(_source("twin", 3.0))["twin.c"] != files["twin.c"]


@pytest.mark.compiling
def test_two_modules_of_one_name_and_different_contents_load_side_by_side(tmp_path):
    """Compiled files carry the content tag: the library and the binding of each module have their own
    names (dlopen and sys.modules key by them), so both modules give their own results in one process;
    the tag is 12 hex digits over the manifest's files."""
    folders = {scale: tmp_path / f"m{scale:g}" / "twin" for scale in (2.0, 3.0)}
    modules = {}
    for scale, folder in folders.items():
        build_source(_source("twin", scale), folder, **QUIET)
        modules[scale] = load(folder)
    tags = {scale: module_tag(m.manifest) for scale, m in modules.items()}
    assert tags[2.0] != tags[3.0] and all(re.fullmatch(r"[0-9a-f]{12}", t) for t in tags.values())
    for scale, m in modules.items():
        assert library(m.manifest) == library_name(f"twin_{tags[scale]}")
        assert binding_module(m.manifest) == f"_gagen_twin_{tags[scale]}"
        assert m.binding.__name__ == f"_gagen_twin_{tags[scale]}"
        assert m.c.scaled.fast is not None  # through the binding
        np.testing.assert_array_equal(m.c.scaled(np.array([1.0, 2.0])), [scale, 2 * scale])
    assert modules[2.0].binding is not modules[3.0].binding


def test_a_manifest_without_backends_or_with_an_unknown_one_is_refused(tmp_path):
    """A module written before the backends were listed, or by a gagen with a backend this one lacks:
    a message saying what to do, not a KeyError on first use."""
    out = tmp_path / "twin"
    build_source(_source("twin", 2.0), out, compile_c=False, **QUIET)
    manifest = json.loads((out / "manifest.json").read_text())
    for backends, message in ((None, "older gagen"), (["casadi", "fortran"], "'fortran' unknown")):
        edited = {k: v for k, v in manifest.items() if k != "backends"}
        if backends is not None:
            edited["backends"] = backends
        (out / "manifest.json").write_text(json.dumps(edited))
        with pytest.raises(ValueError, match=message):
            load(out)
