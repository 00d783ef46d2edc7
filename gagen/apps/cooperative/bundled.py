"""The bundled cooperative systems: the YAML specs in ``robots/``, loaded and validated."""

from __future__ import annotations

from functools import cache
from pathlib import Path

from gagen.apps.cooperative.spec import load_system
from gagen.apps.cooperative.system import System

ROBOTS = Path(__file__).resolve().parent / "robots"  # shipped with the package; robots/ links here
_CHECKOUT = Path(__file__).resolve().parents[3]  # the repository root, when gagen runs from a checkout


def generated_folder() -> Path:
    """Where the bundled systems' generated modules are: the checkout's committed ``generated/``, else
    ``generated/`` in the working directory (where ``gagen build`` writes by default)."""
    committed = _CHECKOUT / "generated"
    if (committed / "panda_point" / "manifest.json").is_file():
        return committed
    return Path("generated").resolve()


@cache
def bundled_specs() -> dict[str, Path]:
    """System name -> spec file, for every ``robots/*.yaml``."""
    return {path.stem: path for path in sorted(ROBOTS.glob("*.yaml"))}


@cache
def _load(name: str) -> tuple[System, dict[str, list[float]]]:
    return load_system(bundled_specs()[name])


def bundled_systems() -> dict[str, System]:
    return {name: _load(name)[0] for name in bundled_specs()}


def ready_configuration(system: System) -> list[float]:
    """The spec's ``ready`` configuration."""
    return _load(system.name)[1]["ready"]
