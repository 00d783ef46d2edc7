"""The bundled cooperative systems: the YAML specs in ``robots/``, loaded and validated."""

from __future__ import annotations

from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

from gagen import registry
from gagen.robots.spec import load_system
from gagen.robots.system import System

if TYPE_CHECKING:
    from gagen.runtime import GeneratedModule

ROBOTS = Path(__file__).resolve().parent / "robots"  # shipped with the package; robots/ links here


@cache
def bundled_specs() -> dict[str, Path]:
    """System name -> spec file, for every ``robots/*.yaml`` (the application's registered bundle)."""
    return registry.bundled_specs("cooperative")


@cache
def _load(name: str) -> tuple[System, dict[str, list[float]]]:
    return load_system(bundled_specs()[name])


def bundled_systems() -> dict[str, System]:
    return {name: _load(name)[0] for name in bundled_specs()}


def system_module(name: str) -> GeneratedModule:
    """The generated module of the bundled system ``name``, loaded: built on first use
    (``gagen.modules.bundled_module``: the committed ``generated/<name>`` in a checkout for the
    representative systems, the gagen cache for the others), once per process."""
    from gagen.modules import bundled_module

    return bundled_module(bundled_specs()[name])


def ready_configuration(system: System) -> list[float]:
    """The spec's ``ready`` configuration."""
    return _load(system.name)[1]["ready"]
