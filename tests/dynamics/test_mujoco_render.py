"""MuJoCo's offscreen renderer on a recorded run (``gagen.dynamics.mujoco_render``), in a child process
with EGL or OSMesa (README's command 2 installs Debian's libosmesa6): the frames show the arms where the
joint positions put them (two postures give two pictures; the same posture the same one), the overlaid
target circle in its colour, and a machine with no backend gets one line naming what to install."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

pytest.importorskip("mujoco")

from gagen.apps.cooperative.scenarios import spec_of
from gagen.dynamics import mujoco_render
from gagen.dynamics.mujoco_model import MujocoSystem


def _frames(path):
    image = Image.open(path)
    frames = []
    for k in range(image.n_frames):
        image.seek(k)
        frames.append(np.asarray(image.convert("RGB"), dtype=int))
    return frames


def test_frames_follow_the_joints_and_show_the_target(tmp_path):
    sim = MujocoSystem(spec_of("three_iiwas_circle"))
    rest = np.array(sim.model.qpos0)
    bent = rest.copy()
    bent[sim.qpos] = 0.6
    s = np.linspace(0, 2 * np.pi, 48)
    circle = np.stack([0.5 * np.cos(s), 0.5 * np.sin(s), 0.9 + 0 * s], axis=1)
    above = circle + np.array([0, 0, 5.0])  # far above the view
    rings = np.array([[circle], [circle], [above]])
    path = mujoco_render.render_gif(sim.mjspec.to_xml(), [rest, bent, rest], tmp_path / "run.gif",
                                    polylines=rings, size=(160, 120))
    first, second, third = _frames(path)
    assert first.shape == (120, 160, 3)
    moved = np.abs(first - second).sum(axis=2) > 30
    assert moved.mean() > 0.01  # another posture: another picture
    magenta = (first[..., 0] > 150) & (first[..., 1] < 90) & (first[..., 2] > 90)
    gone = (third[..., 0] > 150) & (third[..., 1] < 90) & (third[..., 2] > 90)
    assert magenta.sum() > 20 and gone.sum() < magenta.sum() / 4  # the circle drawn where it is


def test_bad_frames_and_no_backend_are_one_line(tmp_path, monkeypatch):
    sim = MujocoSystem(spec_of("three_iiwas_circle"))
    xml = sim.mjspec.to_xml()
    with pytest.raises(ValueError, match="finite"):
        mujoco_render.render_gif(xml, [[np.nan] * sim.model.nq], tmp_path / "x.gif")
    with pytest.raises(ValueError, match="polylines"):
        mujoco_render.render_gif(xml, [sim.model.qpos0], tmp_path / "x.gif", polylines=np.zeros((2, 1, 3, 3)))
    monkeypatch.setattr(mujoco_render, "BACKENDS", ("no_such_backend",))
    with pytest.raises(mujoco_render.RenderUnavailable, match="libosmesa6") as raised:
        mujoco_render.render_gif(xml, [sim.model.qpos0], tmp_path / "x.gif")
    assert "\n" not in str(raised.value) and not (tmp_path / "x.gif").exists()
