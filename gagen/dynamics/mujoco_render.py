"""MuJoCo's own offscreen renderer for a recorded run: the model (its XML), the joint positions per frame
and, optionally, polylines to overlay per frame (the target circle), rendered into a GIF.

MuJoCo picks its OpenGL backend when it is first imported (``MUJOCO_GL``), and a backend that cannot
start cannot be swapped for another in the same process. So the frames are rendered in a child process
(``python -m gagen.dynamics.mujoco_render FOLDER``), first with EGL (a GPU's driver), then with OSMesa
(software rendering: Debian's and Ubuntu's ``libosmesa6``). The parent's own ``mujoco`` is untouched,
and a backend that fails costs one child. When neither starts, :class:`RenderUnavailable` says what to
install, in one line.

The bundled URDFs carry inertias but no geometry, so the arms are drawn as a scene overlay each frame:
a capsule from every body's parent to the body (from the floor below a base link), a sphere at every
body, a sphere at every site (the chains' end points), and a floor. A free body (a held object) is
drawn by the polylines.
"""

from __future__ import annotations

import importlib
import itertools
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

BACKENDS = ("egl", "osmesa")
INSTALL = ("install OSMesa for software rendering (Debian/Ubuntu: apt-get install libosmesa6), or run where "
           "EGL is available (an NVIDIA driver)")
TIMEOUT = 600  # s for one child
NO_BACKEND = 3  # the child's exit status when MuJoCo's renderer cannot start with its backend
# the polylines' colours in their order: magenta (a target), then teal (what was reached)
LINE_COLOURS = tuple(np.array(c, dtype=np.float32) for c in ((0.85, 0.1, 0.55, 1), (0.05, 0.6, 0.6, 1)))


class RenderUnavailable(RuntimeError):
    """No OpenGL backend of MuJoCo's could start here."""


def render_gif(xml: str, qpos: ArrayLike, path: str | Path, *, polylines: ArrayLike | None = None,
               fps: float = 20.0, size: tuple[int, int] = (480, 360), title: str = "") -> Path:
    """Render ``qpos`` (frames × nq, the model's full qpos) of the model ``xml`` into the GIF ``path``,
    with ``polylines`` (frames × lines × points × 3, optional) drawn as thin capsules (the first
    magenta, the second teal and thicker): the written path.
    RenderUnavailable when no backend starts."""
    frames = np.asarray(qpos, dtype=float)
    if frames.ndim != 2 or not np.all(np.isfinite(frames)):
        raise ValueError(f"qpos must be a finite (frames, nq) array, got shape {frames.shape}")
    lines = np.zeros((len(frames), 0, 0, 3)) if polylines is None else np.asarray(polylines, dtype=float)
    if lines.ndim != 4 or len(lines) != len(frames) or lines.shape[-1] != 3:
        raise ValueError(f"polylines must be (frames, lines, points, 3) with {len(frames)} frames, "
                         f"got shape {lines.shape}")
    path = Path(path)
    failures = []
    with tempfile.TemporaryDirectory(prefix="gagen-render-") as folder:
        work = Path(folder)
        (work / "model.xml").write_text(xml)
        np.savez(work / "frames.npz", qpos=frames, polylines=lines, fps=fps, size=np.asarray(size),
                 title=np.asarray(title))
        for backend in BACKENDS:
            env = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
            done = subprocess.run([sys.executable, "-m", "gagen.dynamics.mujoco_render", str(work)], env=env,
                                  capture_output=True, text=True, timeout=TIMEOUT)
            if done.returncode == 0 and (work / "out.gif").exists():
                path.parent.mkdir(parents=True, exist_ok=True)
                (work / "out.gif").replace(path)
                return path
            told = work / "error.txt"  # the child's own one line (stderr has OpenGL's clean-up noise too)
            last = told.read_text().strip() if told.exists() else \
                (done.stderr.strip().splitlines() or ["no output"])[-1].strip()
            told.unlink(missing_ok=True)
            if done.returncode != NO_BACKEND:  # the renderer started, and the drawing failed: a bug
                raise RuntimeError(f"rendering {path.name} with MuJoCo ({backend}) failed: {last[:300]}")
            failures.append(f"{backend}: {last[:160]}")
    raise RenderUnavailable(f"MuJoCo's offscreen renderer could not start ({'; '.join(failures)}): {INSTALL}")


def _overlay(mujoco: Any, scene: Any, model: Any, data: Any, lines: NDArray[np.float64]) -> None:
    """The arms as capsules and spheres, the polylines as thin capsules, appended to ``scene``."""
    grey, knuckle = (np.array(c, dtype=np.float32) for c in ((0.55, 0.57, 0.62, 1), (0.25, 0.27, 0.32, 1)))

    def add(kind: int, width: float, start: NDArray[np.float64], end: NDArray[np.float64],
            rgba: NDArray[np.float32]) -> None:
        if scene.ngeom >= scene.maxgeom or np.linalg.norm(end - start) < 1e-6:
            return
        geom = scene.geoms[scene.ngeom]
        if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            mujoco.mjv_initGeom(geom, kind, np.array([width, 0, 0]), start, np.eye(3).ravel(), rgba)
        else:
            mujoco.mjv_initGeom(geom, kind, np.zeros(3), np.zeros(3), np.eye(3).ravel(), rgba)
            mujoco.mjv_connector(geom, kind, width, start, end)
        scene.ngeom += 1

    capsule, sphere = mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_SPHERE
    for site in range(model.nsite):  # the chains' end points
        add(sphere, 0.03, data.site_xpos[site], data.site_xpos[site] + 1e-5,
            np.array((1.0, 0.55, 0.1, 1), dtype=np.float32))
    for body in range(1, model.nbody):
        joint = model.body_jntadr[body]
        if joint >= 0 and model.jnt_type[joint] == mujoco.mjtJoint.mjJNT_FREE:
            continue  # a free body (a held object) is no link: the polylines draw it
        position = data.xpos[body]
        parent = model.body_parentid[body]
        start = data.xpos[parent] if parent > 0 else np.array([position[0], position[1], 0.0])
        add(capsule, 0.035, start, position, grey)
        add(capsule, 0.045, position, position + 1e-5, knuckle)
    for i, line in enumerate(lines):
        for a, b in itertools.pairwise(line):
            add(capsule, 0.006 * (1 + i), a, b, LINE_COLOURS[i % len(LINE_COLOURS)])


def _no_backend(folder: Path, error: Exception) -> None:
    (folder / "error.txt").write_text(f"{type(error).__name__}: {error}".splitlines()[0])
    raise SystemExit(NO_BACKEND)


def _main(folder: Path) -> None:
    from PIL import Image

    try:
        mujoco: Any = importlib.import_module("mujoco")  # it reads MUJOCO_GL here: a bad backend fails now
    except Exception as e:
        _no_backend(folder, e)

    stored = np.load(folder / "frames.npz")
    model = mujoco.MjModel.from_xml_string((folder / "model.xml").read_text())
    data = mujoco.MjData(model)
    width, height = (int(v) for v in stored["size"])
    model.vis.global_.offwidth, model.vis.global_.offheight = max(width, 640), max(height, 480)
    model.vis.headlight.ambient[:], model.vis.headlight.diffuse[:] = 0.45, 0.55  # no lights in the URDFs
    try:
        renderer = mujoco.Renderer(model, height, width, max_geom=20000)
    except Exception as e:  # the backend: no EGL device, no libOSMesa
        _no_backend(folder, e)
    camera = mujoco.MjvCamera()
    data.qpos[:] = stored["qpos"][0]
    mujoco.mj_forward(model, data)
    spread = data.xpos[1:] if model.nbody > 1 else np.zeros((1, 3))
    camera.lookat[:] = spread.mean(axis=0)
    camera.distance = 1.8 * max(1.0, float(np.ptp(spread, axis=0).max()))
    camera.azimuth, camera.elevation = 135.0, -30.0
    images = []
    for qpos, lines in zip(stored["qpos"], stored["polylines"], strict=True):
        data.qpos[:] = qpos
        mujoco.mj_forward(model, data)
        renderer.update_scene(data, camera)
        floor = renderer.scene.geoms[renderer.scene.ngeom]
        mujoco.mjv_initGeom(floor, mujoco.mjtGeom.mjGEOM_PLANE, np.array([3.0, 3.0, 0.1]), np.zeros(3),
                            np.eye(3).ravel(), np.array([0.9, 0.9, 0.88, 1], dtype=np.float32))
        renderer.scene.ngeom += 1
        _overlay(mujoco, renderer.scene, model, data, lines)
        images.append(Image.fromarray(renderer.render()))
    duration = round(1000 / float(stored["fps"]))
    images[0].save(folder / "out.gif", save_all=True, append_images=images[1:], duration=duration, loop=0)


if __name__ == "__main__":
    try:
        _main(Path(sys.argv[1]))
    except Exception as error:
        (Path(sys.argv[1]) / "error.txt").write_text(f"{type(error).__name__}: {error}".splitlines()[0])
        raise
