"""Shared fixtures of the hexapod tests: the bundled spec, its Hexapod, and its module built once per
session into a temporary folder (compiling tests only)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gagen.apps.hexapod.spec import Hexapod, load_hexapod

SPEC = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "hexapod" / "robots" / "hexapod.yaml"


@pytest.fixture(scope="session")
def hexapod() -> Hexapod:
    return load_hexapod(SPEC)


@pytest.fixture(scope="session")
def hexapod_module(tmp_path_factory):
    """The bundled hexapod's generated module (C, SIMD batch and CasADi), built once per session."""
    from gagen.build import build
    from gagen.runtime import load

    folder = tmp_path_factory.mktemp("hexapod") / "hexapod"
    build(SPEC, out=folder, progress=lambda _: None)
    return load(folder)
