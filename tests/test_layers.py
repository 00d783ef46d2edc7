"""The architecture's layering contract (pyproject.toml, ``[tool.importlinter]``) holds on the package as it
is, and fails on a planted upward import and on a planted circle: the check can fail."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("importlinter")

from importlinter import configuration
from importlinter.application import use_cases
from importlinter.application.app_config import settings

PYPROJECT = Path(__file__).resolve().parents[1] / "pyproject.toml"


class _Planting:
    """The real graph builder, then the planted imports added to its graph."""

    def __init__(self, real, planted: list[tuple[str, str]]) -> None:
        self.real, self.planted = real, planted

    def build(self, **kwargs):
        graph = self.real.build(**kwargs)
        for importer, imported in self.planted:
            graph.add_import(importer=importer, imported=imported, line_number=1, line_contents="planted")
        return graph


def _lint(planted: list[tuple[str, str]], capsys) -> tuple[bool, str]:
    configuration.configure()
    real = settings.GRAPH_BUILDER
    settings.configure(GRAPH_BUILDER=_Planting(real, planted))
    try:
        passed = use_cases.lint_imports(str(PYPROJECT), cache_dir=None, no_logo=True) == use_cases.SUCCESS
    finally:
        settings.configure(GRAPH_BUILDER=real)
    return passed, capsys.readouterr().out


def test_the_package_keeps_its_layers_and_has_no_circles(capsys):
    passed, report = _lint([], capsys)
    assert passed, report
    assert "gagen's layers KEPT" in report and "no import circles between siblings KEPT" in report


@pytest.mark.parametrize(("importer", "imported"), [
    ("gagen.algebra.signature", "gagen.apps.cooperative.catalogue"),  # the core on an application
    ("gagen.check", "gagen.apps.cooperative.catalogue"),  # a library module on an application
    ("gagen.robots.system", "gagen.control.ik"),  # the robot on an algorithm over robots
    ("gagen.registry", "gagen.build"),  # the bottom layer on the build
])
def test_an_upward_import_breaks_the_layers(importer, imported, capsys):
    passed, report = _lint([(importer, imported)], capsys)
    assert not passed
    assert "gagen's layers BROKEN" in report and importer in report and imported in report


def test_a_circle_between_siblings_breaks_the_contract(capsys):
    passed, report = _lint([("gagen.control.differential", "gagen.control.ik"),
                            ("gagen.control.ik", "gagen.control.differential")], capsys)
    assert not passed
    assert "no import circles between siblings BROKEN" in report and "gagen.control" in report
