"""Shared fixtures of the hexapod tests: the bundled spec, its Hexapod, and its module (the committed
generated/hexapod, built on first use; compiling tests only)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gagen.apps.hexapod.spec import Hexapod, load_hexapod

SPEC = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "hexapod" / "robots" / "hexapod.yaml"


@pytest.fixture(scope="session")
def hexapod() -> Hexapod:
    return load_hexapod(SPEC)


@pytest.fixture(scope="session")
def hexapod_module():
    """The bundled hexapod's generated module (C, SIMD batch and CasADi), built on first use
    (``gagen.apps.hexapod.gait.hexapod_module``: the committed generated/hexapod)."""
    from gagen.apps.hexapod.gait import hexapod_module

    return hexapod_module(SPEC)
