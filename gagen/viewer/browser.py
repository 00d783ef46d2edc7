"""Headless renders of a viewer scene: a real browser (Chromium, software WebGL) draws, viser reads back.

``render(scene)`` starts headless Chromium on the scene's URL, waits for it to connect, and asks it for
a frame of the 3D view from a given camera (viser's ``get_render``: the browser draws the scene with
three.js into a W × H canvas and sends the pixels back) — no window, no user, no GPU (SwiftShader).
``export_png(system, q, path)`` does it for a configuration and writes the PNG. Chromium is found as
``$GAGEN_CHROMIUM`` or ``chromium`` / ``chromium-browser`` / ``google-chrome`` on PATH (Debian:
``apt-get install chromium``); the browser is always stopped, within ``STOP_TIMEOUT`` seconds.

    python -m gagen.viewer three_pandas_circle --png frame.png
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.robots.system import System
from gagen.viewer.camera import Camera, framing
from gagen.viewer.geometry import Shape
from gagen.viewer.scene import Frames, Scene
from gagen.viewer.visuals import ChainVisuals

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
STOP_TIMEOUT = 10.0  # seconds for the browser to exit after SIGTERM, before SIGKILL
DEFAULT_TIMEOUT = 120.0  # seconds for the browser to connect, and then for each frame (a loaded CI)
BACKGROUND = (255, 255, 255)  # a render is transparent where nothing is drawn: exports sit on white


class BrowserError(RuntimeError):
    """No browser, or it did not connect or render in time (the message carries its log's tail)."""


def find_chromium() -> str | None:
    """The Chromium (or Chrome) executable to use, or None."""
    explicit = os.environ.get("GAGEN_CHROMIUM")
    if explicit:
        return shutil.which(explicit) or (explicit if os.access(explicit, os.X_OK) else None)
    return next((path for name in CHROMIUM_NAMES if (path := shutil.which(name))), None)


def chromium_command(executable: str, url: str, profile: Path, width: int, height: int) -> list[str]:
    """Headless Chromium with software WebGL (SwiftShader through ANGLE) on ``url``, in a throwaway
    profile; ``--no-sandbox`` only as root, where Chromium refuses to start with its sandbox."""
    command = [executable, "--headless=new", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
               "--ignore-gpu-blocklist", f"--user-data-dir={profile}", f"--window-size={width},{height}",
               "--no-first-run", "--no-default-browser-check", "--disable-extensions",
               "--disable-background-networking", "--disable-dev-shm-usage", "--mute-audio",
               # a headless page counts as hidden: keep its timers and animation frames at full rate
               "--disable-background-timer-throttling", "--disable-renderer-backgrounding",
               "--disable-backgrounding-occluded-windows"]
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        command.append("--no-sandbox")
    return [*command, url]


@dataclass(frozen=True)
class Browser:
    process: subprocess.Popen[bytes]
    log: Path

    def state(self, lines: int = 5) -> str:
        """Whether it still runs, and the last lines of its log (for error messages)."""
        code = self.process.poll()
        text = ""
        with contextlib.suppress(OSError):
            text = "\n".join(self.log.read_text(errors="replace").splitlines()[-lines:])
        running = "runs" if code is None else f"exited with status {code}"
        return f"the browser {running}; its log ends:\n{text}"


@contextlib.contextmanager
def headless_browser(url: str, *, width: int = 1280, height: int = 960,
                     executable: str | None = None) -> Iterator[Browser]:
    """A headless Chromium showing ``url`` for the duration of the block; stopped (SIGTERM, then SIGKILL
    after ``STOP_TIMEOUT``) and its profile removed on exit."""
    executable = executable or find_chromium()
    if executable is None:
        raise BrowserError("no Chromium found: install it (Debian: apt-get install chromium) or set "
                           "GAGEN_CHROMIUM to its executable")
    with tempfile.TemporaryDirectory(prefix="gagen-chromium-") as folder:
        log = Path(folder) / "chromium.log"
        with log.open("wb") as stderr:
            command = chromium_command(executable, url, Path(folder) / "profile", width, height)
            process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                       stderr=stderr, start_new_session=True)  # its own group: see below
            try:
                yield Browser(process, log)
            finally:
                process.terminate()
                with contextlib.suppress(subprocess.TimeoutExpired):
                    process.wait(STOP_TIMEOUT)
                # the browser's helpers (renderer, GPU process) are in the group it leads: none outlives it
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(process.pid, signal.SIGKILL)
                process.wait(STOP_TIMEOUT)


@contextlib.contextmanager
def capturing(scene: Scene, *, width: int = 1024, height: int = 768, timeout: float = DEFAULT_TIMEOUT,
              executable: str | None = None) -> Iterator[Callable[[Camera | None], NDArray[np.uint8]]]:
    """A headless Chromium connected to ``scene`` for the block, which gets a function taking a camera
    (None: the scene's framing camera for this aspect ratio) to a (height, width, 4) RGBA frame of the
    scene as it is now (transparent where nothing is drawn). Several frames share one browser."""
    # a browser that opens a connection and drops it (a prefetch) makes the websocket server log a
    # traceback at ERROR: quiet it while the browser runs
    logger = logging.getLogger("websockets.server")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        size = {"width": width + 64, "height": height + 64}  # the window holds the canvas
        with headless_browser(scene.url, **size, executable=executable) as browser:
            try:
                client = scene.wait_for_client(timeout)
            except TimeoutError as e:
                raise BrowserError(f"{e}; {browser.state()}") from e

            def frame(camera: Camera | None = None) -> NDArray[np.uint8]:
                camera = camera or scene.default_camera(width / height)
                try:
                    image = client.get_render(height, width, wxyz=camera.wxyz(),
                                              position=np.array(camera.position), fov=camera.fov,
                                              transport_format="png", timeout=timeout)
                except TimeoutError as e:
                    raise BrowserError(f"no frame of {scene.url} within {timeout:g} s; "
                                       f"{browser.state()}") from e
                return np.asarray(image, dtype=np.uint8)

            yield frame
    finally:
        logger.setLevel(level)


def render(scene: Scene, *, width: int = 1024, height: int = 768, camera: Camera | None = None,
           timeout: float = DEFAULT_TIMEOUT, executable: str | None = None) -> NDArray[np.uint8]:
    """One frame of ``scene`` drawn by headless Chromium: see :func:`capturing`."""
    with capturing(scene, width=width, height=height, timeout=timeout, executable=executable) as frame:
        return frame(camera)


def flatten(image: NDArray[np.uint8], background: Sequence[int] = BACKGROUND) -> NDArray[np.uint8]:
    """(h, w, 3) RGB: an RGBA render composited over ``background``."""
    if image.shape[-1] == 3:
        return image
    alpha = image[..., 3:4].astype(float) / 255.0
    rgb = image[..., :3].astype(float) * alpha + np.asarray(background, dtype=float) * (1.0 - alpha)
    return np.round(rgb).astype(np.uint8)


def write_png(image: NDArray[np.uint8], path: str | Path) -> Path:
    """The render, flattened onto white, as a PNG (OpenCV: BGR order on disk)."""
    import cv2

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), cv2.cvtColor(flatten(image), cv2.COLOR_RGB2BGR)):
        raise OSError(f"cannot write {path}")
    return path


def export_png(system: System, q: ArrayLike, path: str | Path, *, width: int = 1024, height: int = 768,
               camera: Camera | None = None, primitive: bool = True, frames: Frames = "ends",
               timeout: float = DEFAULT_TIMEOUT,
               visuals: Sequence[ChainVisuals | None] | None = None,
               goal: Shape | None = None) -> tuple[Path, Camera]:
    """Render ``system`` at configuration q headless and write it to ``path`` (PNG, on white); returns the
    path and the camera used (to project points into the image). ``visuals``: the links' URDF visuals
    (``gagen.viewer.visuals.load_visuals``; None: sticks); ``goal``: a target primitive to draw too."""
    start = time.monotonic()
    with Scene(system, q, port=0, frames=frames, visuals=visuals, goal=goal) as scene:
        scene.show_primitive(primitive)
        camera = camera or scene.default_camera(width / height)
        image = render(scene, width=width, height=height, camera=camera,
                       timeout=max(1.0, timeout - (time.monotonic() - start)))
    return write_png(image, path), camera


def export_frames(system: System, qs: ArrayLike, folder: str | Path, *, width: int = 1024,
                  height: int = 768, camera: Camera | None = None, stem: str = "frame",
                  timeout: float = DEFAULT_TIMEOUT,
                  visuals: Sequence[ChainVisuals | None] | None = None) -> list[Path]:
    """Render each configuration of a trajectory with one headless browser, from one camera (default:
    framing every configuration), to ``folder/<stem>_0000.png``, …; returns the paths."""
    Q = np.asarray(qs, dtype=float)
    if Q.ndim != 2 or Q.shape[0] == 0:
        raise ValueError(f"export_frames: expected an (n, {system.dof}) array of configurations, "
                         f"got shape {Q.shape}")
    paths = []
    with Scene(system, Q[0], port=0, visuals=visuals) as scene:
        if camera is None:
            points = []
            for q in Q[:: max(1, len(Q) // 50)]:  # a sample of the trajectory bounds the view
                scene.update(q)
                points.append(scene.points())
            camera = framing(np.vstack(points), aspect=width / height)
        with capturing(scene, width=width, height=height, timeout=timeout) as frame:
            for k, q in enumerate(Q):
                scene.update(q)
                paths.append(write_png(frame(camera), Path(folder) / f"{stem}_{k:04d}.png"))
    return paths
