"""Every verb on a user's spec: a copy of the three-Panda circle written into a temporary folder under
another name, with its own goal, run through ``gagen reach``, ``mpc``, ``nullspace`` and ``view`` (the
other verbs' user-spec tests: sweep in tests/sweep/test_systems.py, teleop and reach in
test_goals_spec.py, impedance in tests/dynamics/test_impedance.py, smc in tests/control/test_smc.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gagen.cli import main
from gagen.registry import bundled_specs

pytestmark = pytest.mark.compiling  # the user's module is built (and compiled) once for the file


@pytest.fixture(scope="module")
def circle_spec(tmp_path_factory):
    bundled = bundled_specs("cooperative")["three_pandas_circle"]
    text = bundled.read_text().replace("name: three_pandas_circle", "name: my_circle")
    text = text.replace("urdf: panda/", f"urdf: {bundled.parent}/panda/")
    text = text[:text.index("goals:")] + ("goals:\n  lift:\n    title: lifted by 5 cm\n"
                                          "    move: {translation: [0.0, 0.0, 0.05]}\n")
    spec = tmp_path_factory.mktemp("user") / "my_circle.yaml"
    spec.write_text(text)
    return spec


def test_reach_mpc_and_nullspace_run_on_the_users_spec(circle_spec, tmp_path, capsys):
    assert main(["reach", str(circle_spec), "--N", "20", "--solver", "ilqr", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "lift (" in out and "reached" in out
    assert main(["mpc", str(circle_spec), "--duration", "0.1", "--no-animation", "--out", str(tmp_path)]) == 0
    assert "# Cooperative MPC: my_circle tracking a moving circle" in (tmp_path / "mpc_report.md").read_text()
    assert main(["nullspace", str(circle_spec), "--steps", "5", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "nullspace_demo.png").is_file()


def test_the_users_module_is_its_own(circle_spec):
    from gagen.modules import module_folder

    manifest = json.loads((module_folder(circle_spec) / "manifest.json").read_text())
    assert manifest["system"] == "my_circle" and manifest["dof"] == 21


def test_view_renders_the_users_spec_with_its_goal(circle_spec, tmp_path):
    pytest.importorskip("viser")
    from gagen.viewer.browser import find_chromium

    if find_chromium() is None:
        pytest.skip("no Chromium on PATH")
    png = tmp_path / "view.png"
    assert main(["view", str(circle_spec), "--png", str(png), "--size", "320x240", "--goal", "lift"]) == 0
    import cv2

    image = cv2.imread(str(png))
    assert image is not None and image.shape == (240, 320, 3) and np.ptp(image) > 0
