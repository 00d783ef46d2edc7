"""One content-based cache key for every application: a cooperative system's key covers the code its kernels
are made from (the import closure of the application's kernel modules, ``gagen.code_digest``), so an edit
of another application leaves it as it is and an edit of the model changes it. The edits are made in a
copy of the package, never in the checkout."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from gagen import code_digest, registry
from gagen.build import build_key, load_source

SPEC = registry.bundled_specs("cooperative")["panda_point"]


@pytest.fixture
def package_copy(tmp_path, monkeypatch):
    """A copy of gagen's sources that ``gagen.code_digest`` reads instead of the package."""
    copy = tmp_path / "gagen"
    shutil.copytree(code_digest.PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__", "*.so", "*.yaml",
                                                                            "*.urdf", "*.csv", "*.j2", "*.c"))
    monkeypatch.setattr(code_digest, "PACKAGE", copy)
    code_digest._imports.cache_clear()
    yield copy
    code_digest._imports.cache_clear()


def _edit(path: Path) -> None:
    path.write_text(path.read_text() + "\n# an edit\n")


def _cooperative_key() -> str:
    code_digest._imports.cache_clear()
    return build_key(load_source(SPEC))


def test_every_application_names_the_code_of_its_kernels():
    for app in registry.apps():
        assert app.kernel_modules and all(code_digest.module_file(m) for m in app.kernel_modules), app.name
    assert load_source(SPEC).code == ("gagen.apps.cooperative.module",)


def test_the_closure_is_what_the_kernels_are_made_from():
    closure = {p.relative_to(code_digest.PACKAGE).as_posix()
               for p in code_digest.import_closure(["gagen.apps.cooperative.module"])}
    assert {"apps/cooperative/catalogue.py", "robots/system.py", "model/similarity.py", "model/versors.py",
            "algebra/multivector.py", "symbolic/flatten.py", "frontend.py"} <= closure
    # the demos, the other applications and the algorithms over kernels take no part
    for outside in ("apps/cooperative/scenarios.py", "apps/cooperative/teleop.py", "apps/linkage/kernels.py",
                    "apps/hexapod/legs.py", "apps/stereo/kernels.py", "control/ocp.py", "viewer/scene.py",
                    "sweep/engine.py", "cli.py"):
        assert outside not in closure, outside


def test_editing_another_application_keeps_the_cooperative_keys(package_copy):
    before = _cooperative_key()
    for other in ("apps/linkage/kernels.py", "apps/stereo/kernels.py", "apps/hexapod/legs.py",
                  "apps/cooperative/scenarios.py", "control/ocp.py", "viewer/scene.py"):
        _edit(package_copy / other)
    assert _cooperative_key() == before


@pytest.mark.parametrize("edited", ["model/conformal.py", "apps/cooperative/catalogue.py", "robots/system.py",
                                    "symbolic/passes.py", "algebra/blade_rules.py"])
def test_editing_what_the_kernels_are_made_from_changes_them(package_copy, edited):
    before = _cooperative_key()
    _edit(package_copy / edited)
    assert _cooperative_key() != before


def test_a_function_level_import_of_the_kernel_module_is_followed(tmp_path, monkeypatch):
    """An import inside a function of a named module counts (the build calls those functions); inside a
    function of a module it merely imports, it does not."""
    package = tmp_path / "gagen"
    (package / "a").mkdir(parents=True)
    for name, text in {"__init__.py": "", "a/__init__.py": "",
                       "a/kernels.py": "import gagen.a.helper\n\ndef make():\n    import gagen.a.lazy\n",
                       "a/helper.py": "def f():\n    import gagen.a.unused\n",
                       "a/lazy.py": "", "a/unused.py": ""}.items():
        (package / name).write_text(text)
    monkeypatch.setattr(code_digest, "PACKAGE", package)
    code_digest._imports.cache_clear()
    try:
        found = {p.relative_to(package).as_posix() for p in code_digest.import_closure(["gagen.a.kernels"])}
    finally:
        code_digest._imports.cache_clear()
    assert found == {"__init__.py", "a/__init__.py", "a/kernels.py", "a/helper.py", "a/lazy.py"}
