"""Closing the loop [SMC IV-VI]: the bottle moves along the paper's reference (Eq. 43: centre at
x = −0.3 + 0.1 cos 2t, y = 0.15, z = 0.25 in the base frame, axis along the base's y), the stereo rig
renders it at 30 Hz (``scene``), every frame is estimated (``pipeline``), and the latest estimate,
held between frames, is the reference of the Panda's sliding-mode pose tracking at 1 kHz (``gagen smc``'s
generated step and gains, ``gagen.control.smc.simulate``).

A frame whose estimate fails keeps the previous reference (and is listed); the run reports the
estimation error per frame (against the rendered pose) and the tracking error against both the
estimate and the true path. ``plots`` draws the paper's Figs. 6-8 for the run, the estimation error
over time and the first frame pair with the detected symmetry lines.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gagen.apps.stereo import scene
from gagen.apps.stereo.calibration import Camera, Rig
from gagen.apps.stereo.pipeline import Estimator, Failure, FrameEstimate
from gagen.control import smc

FPS = 30.0
RATE = 1000.0


def true_reference(t: float) -> np.ndarray:
    """The object's pose at t in the base frame as [centre; axis]: [SMC Eq. 43]."""
    x: np.ndarray = smc.reference(t)
    return x


def object_pose(rig: Rig, t: float) -> scene.ObjectPose:
    """The bottle at time t in the left camera's frame."""
    x = true_reference(t)
    to_left = rig.left_in_base.inverse()
    return scene.ObjectPose(to_left.apply(x[:3]), to_left.R @ x[3:])


@dataclass
class TrackRun:
    frame_times: np.ndarray  # s
    truth: np.ndarray  # (frames, 6) the object's [centre; axis] in the base frame
    estimates: np.ndarray  # (frames, 6) the held reference after each frame (base frame)
    failures: list[str] = field(default_factory=list)  # "frame k (t = …): reason"
    estimates_ok: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    simulation: smc.Simulation | None = None
    seconds: dict[str, float] = field(default_factory=dict)
    first_frame: scene.StereoFrame | None = None
    first_estimate: FrameEstimate | Failure | None = None

    @property
    def position_errors(self) -> np.ndarray:
        """Per frame: |estimated − true centre| (m)."""
        distances: np.ndarray = np.linalg.norm(self.estimates[:, :3] - self.truth[:, :3], axis=1)
        return distances

    @property
    def axis_errors(self) -> np.ndarray:
        """Per frame: the angle (rad) between the estimated and the true axis."""
        cos = np.abs(np.sum(self.estimates[:, 3:] * self.truth[:, 3:], axis=1))
        angles: np.ndarray = np.arccos(np.clip(cos, -1.0, 1.0))
        return angles


def estimate_path(rig: Rig, duration: float, *, fps: float = FPS, options: scene.SceneOptions | None = None,
                  seed: int = 0, estimator: Estimator | None = None,
                  progress: Callable[[str], None] = lambda _: None) -> TrackRun:
    """Render and estimate every frame of ``duration`` seconds at ``fps``."""
    import time

    estimator = estimator or Estimator(rig)
    options = options or scene.SceneOptions(vertex_jitter=1.0, pixel_noise=2.0)
    rng = np.random.default_rng(seed)
    times = np.arange(0.0, duration, 1.0 / fps)
    truth, held, ok, failures = [], [], [], []
    render_s = estimate_s = 0.0
    current: np.ndarray | None = None
    run = TrackRun(times, np.zeros((0, 6)), np.zeros((0, 6)))
    for k, t in enumerate(times):
        start = time.perf_counter()
        frame = scene.render(rig, object_pose(rig, t), options, rng)
        mid = time.perf_counter()
        result = estimator(frame.left, frame.right)
        estimate_s += time.perf_counter() - mid
        render_s += mid - start
        if k == 0:
            run.first_frame, run.first_estimate = frame, result
        if isinstance(result, Failure):
            failures.append(f"frame {k} (t = {t:.3f} s): {result}")
            ok.append(False)
        else:
            current = result.in_base(rig)
            ok.append(True)
        if current is None:  # nothing estimated yet: no reference to hold
            current = np.full(6, np.nan)
        truth.append(true_reference(t))
        held.append(current.copy())
        if (k + 1) % 30 == 0:
            progress(f"  frame {k + 1}/{len(times)}: {len(failures)} failed so far")
    run.truth, run.estimates, run.failures = np.array(truth), np.array(held), failures
    run.estimates_ok = np.array(ok)
    run.seconds = {"render": render_s, "estimate": estimate_s}
    return run


def close_loop(rig: Rig, duration: float = 5.0, *, fps: float = FPS, rate: float = RATE,
               options: scene.SceneOptions | None = None, seed: int = 0, latency: float = 0.0,
               progress: Callable[[str], None] = lambda _: None) -> TrackRun:
    """The whole run: frames estimated at ``fps``; the sliding-mode loop at ``rate`` with the latest
    estimate available ``latency`` seconds after its frame as its reference (held between frames)."""
    import time

    progress(f"rendering and estimating {math.ceil(duration * fps)} frame pairs at {fps:g} Hz")
    run = estimate_path(rig, duration, fps=fps, options=options, seed=seed, progress=progress)
    if not np.isfinite(run.estimates[0]).all():
        raise RuntimeError(f"the first frame gave no estimate ({run.failures[0]}): nothing to track")
    progress(f"sliding-mode tracking at {rate:g} Hz (the generated step, building on first use)")
    start = time.perf_counter()
    built = smc.build()

    def reference(t: float) -> np.ndarray:
        k = math.floor((t - latency) * fps + 1e-9)
        held: np.ndarray = run.estimates[min(max(k, 0), len(run.estimates) - 1)]
        return held

    run.simulation = smc.simulate(built.step(), built.q0, duration, 1.0 / rate, reference=reference)
    run.seconds["control"] = time.perf_counter() - start
    return run


def tracking_errors(run: TrackRun, transient: float = 0.5) -> dict[str, float]:
    """After ``transient``: the end point's largest distance from the estimate it tracks and from the
    true path, and the largest axis direction errors likewise; the estimates' own errors."""
    sim = run.simulation
    assert sim is not None
    after = sim.t >= transient
    true = np.array([true_reference(t) for t in sim.t[after]])
    x = sim.x[after]
    ok = run.estimates_ok
    axis = np.degrees(run.axis_errors[ok])
    return {
        "position_vs_estimate": float(np.linalg.norm(x[:, :3] - sim.x_ref[after, :3], axis=1).max()),
        "position_vs_truth": float(np.linalg.norm(x[:, :3] - true[:, :3], axis=1).max()),
        "direction_vs_truth": float(np.linalg.norm(x[:, 3:] - true[:, 3:], axis=1).max()),
        "estimate_position_median": float(np.median(run.position_errors[ok])) if ok.any() else math.nan,
        "estimate_position_max": float(run.position_errors[ok].max()) if ok.any() else math.nan,
        "estimate_axis_median_deg": float(np.median(axis)) if ok.any() else math.nan,
        "estimate_axis_max_deg": float(axis.max()) if ok.any() else math.nan,
    }


def plots(run: TrackRun, rig: Rig, out: str | Path, transient: float = 0.5) -> list[Path]:
    """``pose.png``, ``error.png``, ``joint_velocities.png``, ``joint_positions.png`` ([SMC] Figs. 6-8,
    ``smc.plot_run``), ``estimation_error.png`` and ``frame.png`` (the first frame pair with the detected
    and the true symmetry lines)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    assert run.simulation is not None
    csv = run.simulation.write_csv(folder / "stereo_smc_log.csv")
    written: list[Path] = smc.plot_run(csv, folder, transient=transient)

    fig = Figure(figsize=(9, 5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(2, 1, 1)
    t, ok = run.frame_times, run.estimates_ok
    ax.plot(t[ok], 1e3 * run.position_errors[ok], ".-", ms=3,
            label="position reference (mass centre on the axis)")
    ax.set_ylabel("error [mm]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax2 = fig.add_subplot(2, 1, 2)
    ax2.plot(t[ok], np.degrees(run.axis_errors[ok]), ".-", ms=3, color="C1", label="symmetry axis")
    if (~ok).any():
        for a in (ax, ax2):
            for tf in t[~ok]:
                a.axvline(tf, color="C3", lw=0.6, alpha=0.5)
    ax2.set_ylabel("angle [°]")
    ax2.set_xlabel("t [s] (frames at 30 Hz; red: a failed frame, the previous estimate held)")
    ax2.grid(alpha=0.3)
    ax2.legend(fontsize=8)
    fig.suptitle(f"Stereo estimate of the moving bottle vs the rendered pose ({len(t)} frames, "
                 f"{int((~ok).sum())} failed)")
    fig.tight_layout()
    path = folder / "estimation_error.png"
    fig.savefig(path, dpi=110)
    written.append(path)
    if run.first_frame is not None:
        written.append(_frame_picture(run, rig, folder / "frame.png"))
    return written


def _frame_picture(run: TrackRun, rig: Rig, path: Path) -> Path:
    """The first frame pair side by side, the true axis image green and the detected line magenta."""
    import cv2

    frame, estimate = run.first_frame, run.first_estimate
    assert frame is not None
    panels = []
    for which, image, camera in (("left", frame.left, rig.left), ("right", frame.right, rig.right)):
        img = image.copy()
        theta, r = getattr(frame.truth, which).line
        _draw_line(img, camera, theta, r, (0, 200, 0))
        if isinstance(estimate, FrameEstimate):
            detection = getattr(estimate, which)
            _draw_line(img, camera, detection.theta, detection.r, (255, 0, 255))
            cv2.circle(img, _px(detection.centre_px), 4, (255, 0, 255), -1)
        cv2.putText(img, which, (10, 25), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (255, 255, 255), 2)
        panels.append(img)
    cv2.imwrite(str(path), np.hstack(panels))
    return path


def _draw_line(img: np.ndarray, camera: Camera, theta: float, r: float, bgr: tuple[int, int, int]) -> None:
    """x cos θ + y sin θ = r (normalised) across the image."""
    import cv2

    c, s = math.cos(theta), math.sin(theta)
    p0 = np.array([r * c, r * s])
    d = np.array([-s, c])
    ends = camera.pixels(np.array([p0 - 3 * d, p0 + 3 * d]))
    cv2.line(img, _px(ends[0]), _px(ends[1]), bgr, 1, cv2.LINE_AA)


def _px(xy: np.ndarray) -> tuple[int, int]:
    u, v = np.rint(np.asarray(xy, dtype=float)).astype(int)
    return int(u), int(v)
