"""The MuJoCo walk rendered offscreen into a GIF: MuJoCo's own renderer on the model's geoms (body box,
capsule links, sphere feet, the checkered ground), the camera following the body.

As in :mod:`gagen.dynamics.mujoco_render`, MuJoCo fixes its OpenGL backend (``MUJOCO_GL``) when it is
first imported, so the frames are drawn in a child process (``python -m
gagen.apps.hexapod.mujoco_animation FOLDER``), with EGL first, then OSMesa (software rendering);
:class:`~gagen.dynamics.mujoco_render.RenderUnavailable` says what to install when neither starts.
The GIF is written by Pillow with one adaptive palette for all frames (small files)."""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from gagen.dynamics.mujoco_render import BACKENDS, INSTALL, NO_BACKEND, TIMEOUT, RenderUnavailable


def render_walk(xml: str, qpos: ArrayLike, path: str | Path, *, fps: float = 10.0,
                size: tuple[int, int] = (320, 240), still: str | Path | None = None) -> Path:
    """Render the frames ``qpos`` (frames × nq) of the model ``xml`` into the GIF ``path`` (and the
    middle frame into the PNG ``still``, when given): the GIF's path. RenderUnavailable when no
    backend starts."""
    frames = np.asarray(qpos, dtype=float)
    if frames.ndim != 2 or len(frames) == 0 or not np.all(np.isfinite(frames)):
        raise ValueError(f"qpos must be a finite (frames, nq) array, got shape {frames.shape}")
    path = Path(path)
    failures = []
    with tempfile.TemporaryDirectory(prefix="gagen-walk-") as folder:
        work = Path(folder)
        (work / "model.xml").write_text(xml)
        np.savez(work / "frames.npz", qpos=frames, fps=fps, size=np.asarray(size))
        for backend in BACKENDS:
            env = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
            done = subprocess.run([sys.executable, "-m", "gagen.apps.hexapod.mujoco_animation", str(work)],
                                  env=env, capture_output=True, text=True, timeout=TIMEOUT)
            if done.returncode == 0 and (work / "out.gif").exists():
                path.parent.mkdir(parents=True, exist_ok=True)
                (work / "out.gif").replace(path)
                if still is not None:
                    (work / "still.png").replace(still)
                return path
            told = work / "error.txt"
            last = told.read_text().strip() if told.exists() else \
                (done.stderr.strip().splitlines() or ["no output"])[-1].strip()
            told.unlink(missing_ok=True)
            if done.returncode != NO_BACKEND:
                raise RuntimeError(f"rendering {path.name} with MuJoCo ({backend}) failed: {last[:300]}")
            failures.append(f"{backend}: {last[:160]}")
    raise RenderUnavailable(f"MuJoCo's offscreen renderer could not start ({'; '.join(failures)}): {INSTALL}")


def _main(folder: Path) -> None:
    from PIL import Image

    try:
        mujoco: Any = importlib.import_module("mujoco")
    except Exception as e:
        (folder / "error.txt").write_text(f"{type(e).__name__}: {e}".splitlines()[0])
        raise SystemExit(NO_BACKEND) from e
    stored = np.load(folder / "frames.npz")
    model = mujoco.MjModel.from_xml_string((folder / "model.xml").read_text())
    data = mujoco.MjData(model)
    width, height = (int(v) for v in stored["size"])
    model.vis.global_.offwidth, model.vis.global_.offheight = max(width, 640), max(height, 480)
    try:
        renderer = mujoco.Renderer(model, height, width)
    except Exception as e:  # no EGL device, no libOSMesa
        (folder / "error.txt").write_text(f"{type(e).__name__}: {e}".splitlines()[0])
        raise SystemExit(NO_BACKEND) from e
    camera = mujoco.MjvCamera()
    camera.distance, camera.azimuth, camera.elevation = 1.1, 130.0, -25.0
    images = []
    for qpos in stored["qpos"]:
        data.qpos[:] = qpos
        mujoco.mj_forward(model, data)
        camera.lookat[:] = data.qpos[:3]  # the free base's position: the camera follows the body
        renderer.update_scene(data, camera)
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False  # speckled shadows bloat the GIF
        images.append(Image.fromarray(renderer.render()))
    images[len(images) // 2].save(folder / "still.png", optimize=True)
    palette = images[len(images) // 2].quantize(colors=64, method=Image.Quantize.MEDIANCUT)
    frames = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in images]
    frames[0].save(folder / "out.gif", save_all=True, append_images=frames[1:],
                   duration=round(1000 / float(stored["fps"])), loop=0, optimize=True)


if __name__ == "__main__":
    try:
        _main(Path(sys.argv[1]))
    except SystemExit:
        raise
    except Exception as error:
        (Path(sys.argv[1]) / "error.txt").write_text(f"{type(error).__name__}: {error}".splitlines()[0])
        raise
