"""Pan-tilt visual tracking [SMC IV-VI]: the head of ``pantilt`` keeps the moving bottle centred in its
cameras, closed through the rendered scene and the stereo estimator, or (``ideal``) on the true object.

- **The object** (:class:`Trajectory`): the bottle, its axis along H's −y (upright in the images), its
  centre on a Lissajous figure 1 m in front of the head (±0.3 m across, ±0.15 m up and down, ±0.1 m in
  depth; up to 0.27 m/s), starting 22° off the optical axis.
- **The loop**: the law of ``pantilt.pursue`` at ``RATE`` (Euler steps q ← q + u dt). Vision: at ``FPS``
  the scene is rendered from the cameras' current pose (the head's forward kinematics), estimated
  (``pipeline.Estimator``: symmetry lines → CGA axis → mass centre's foot on it), and the estimate is
  carried into H with the joint angles of that frame: x_Mref is a point fixed in H, held between frames
  and extrapolated by an α-β tracker's velocity (the object moves 9 mm in a frame), so the reference
  line L_Vref of each 1 kHz tick runs from the camera's *current* centre to it. Ideal: x_Mref is the
  true centre at every tick (no vision), the loop of the reaching-time theory (:func:`reaching_bound`).
- **Measures** per frame (vision) or tick (ideal): the true axis' image line's distance from the left
  image's centre (px), the true centre's image offset (px), the angle between the optical axis and the
  direction from the camera to the object, and the estimate's errors against the rendered pose in the
  camera's frame of that moment (position of the reference point, axis angle).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gagen.apps.stereo import scene
from gagen.apps.stereo.calibration import Pose, Rig
from gagen.apps.stereo.pantilt import Head, Step
from gagen.apps.stereo.pipeline import Estimator, Failure

FPS = 30.0
RATE = 1000.0
TRANSIENT = 1.0  # s: measures "after the transient" start here
UP = np.array([0.0, -1.0, 0.0])  # the bottle's axis in H: image up
TRACKER = (0.5, 0.2)  # α, β of the estimate's α-β tracker (per frame)


@dataclass(frozen=True)
class Trajectory:
    """The object's centre in H: middle + (a_x cos ωt, a_y sin 2ωt, a_z sin ωt); axis ``UP``."""

    middle: tuple[float, float, float] = (0.125, 0.0, 1.0)
    amplitude: tuple[float, float, float] = (0.3, 0.15, 0.1)
    omega: float = 0.6  # rad/s

    def centre(self, t: float) -> np.ndarray:
        a, w = self.amplitude, self.omega
        offset = [a[0] * math.cos(w * t), a[1] * math.sin(2 * w * t), a[2] * math.sin(w * t)]
        centre: np.ndarray = np.array(self.middle) + offset
        return centre

    def velocity(self, t: float) -> np.ndarray:
        a, w = self.amplitude, self.omega
        return np.array([-a[0] * w * math.sin(w * t), 2 * a[1] * w * math.cos(2 * w * t),
                         a[2] * w * math.cos(w * t)])

    @property
    def speed(self) -> float:
        """An upper bound of |velocity|."""
        a, w = self.amplitude, self.omega
        return w * math.sqrt(a[0] ** 2 + 4 * a[1] ** 2 + a[2] ** 2)


def for_rig(rig: Rig) -> Trajectory:
    """The default trajectory centred across the rig's middle."""
    return Trajectory(middle=(float(rig.right_in_left.t[0]) / 2, 0.0, 1.0))


@dataclass
class HeadRun:
    """A run's record: ticks (t, q, u, σ, s) and measures at the sample times (frames, or every tick)."""

    mode: str  # "ideal" or "vision"
    t: np.ndarray  # (n,) tick times
    q: np.ndarray  # (n, 2)
    u: np.ndarray  # (n, 2)
    sigma: np.ndarray  # (n, 2)
    s_norm: np.ndarray  # (n,) |s|
    sample_t: np.ndarray  # (m,) times of the measures
    line_offset_px: np.ndarray  # (m,) the true axis image's distance from the image centre
    centre_offset_px: np.ndarray  # (m,) the true centre's image distance from the image centre
    angle_deg: np.ndarray  # (m,) optical axis vs the direction to the object
    estimate_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (frames,) NaN where failed
    estimate_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    failures: list[str] = field(default_factory=list)
    frames: list[np.ndarray] = field(default_factory=list)  # left images with overlays (for the GIF)
    seconds: dict[str, float] = field(default_factory=dict)

    def summary(self, transient: float = TRANSIENT) -> dict[str, float]:
        """Max and median of each measure after ``transient``; the estimator's medians and maxima."""
        after = self.sample_t >= min(transient, float(self.sample_t[-1]))  # (a run shorter than it: the last)
        out: dict[str, float] = {}
        for name in ("line_offset_px", "centre_offset_px", "angle_deg"):
            v = getattr(self, name)[after]
            out[f"{name}_max"], out[f"{name}_median"] = float(v.max()), float(np.median(v))
        for name in ("estimate_mm", "estimate_deg"):
            v = getattr(self, name)
            v = v[np.isfinite(v)]
            out[f"{name}_median"] = float(np.median(v)) if v.size else math.nan
            out[f"{name}_max"] = float(v.max()) if v.size else math.nan
        return out


def _measures(rig: Rig, camera: Pose, centre: np.ndarray) -> tuple[float, float, float]:
    """(line offset px, centre offset px, angle °) of the object at ``centre`` (H) from a camera pose."""
    c = camera.R.T @ (centre - camera.t)
    d = camera.R.T @ UP
    _, r = scene.image_line(c, d)
    cam = rig.left
    offset = cam.pixels(c[:2] / c[2]) - np.array([cam.cx, cam.cy])
    angle = math.degrees(math.acos(min(1.0, c[2] / float(np.linalg.norm(c)))))
    return abs(r) * cam.fx, float(np.linalg.norm(offset)), angle


class _Ticks:
    """The per-tick record of a run."""

    def __init__(self) -> None:
        self.q: list[np.ndarray] = []
        self.u: list[np.ndarray] = []
        self.sigma: list[np.ndarray] = []
        self.s: list[float] = []

    def add(self, q: np.ndarray, u: np.ndarray, step: Step) -> None:
        self.q.append(q.copy())
        self.u.append(u)
        self.sigma.append(step.sigma)
        self.s.append(float(np.linalg.norm(step.s)))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return np.array(self.q), np.array(self.u), np.array(self.sigma), np.array(self.s)


def run_ideal(rig: Rig, duration: float = 5.0, *, head: Head | None = None,
              trajectory: Trajectory | None = None, rate: float = RATE, q0: tuple[float, float] = (0.0, 0.0),
              law: str = "sigma") -> HeadRun:
    """The loop on the true object (no vision): x_Mref = the true centre at every tick. ``law``:
    "sigma" (u = −K tanh(ε J⁺ s)) or "paper" (u = −K J⁺ tanh(ε s))."""
    if law not in ("sigma", "paper"):
        raise ValueError(f"law must be 'sigma' or 'paper', got {law!r}")
    head = head or Head(rig)
    path = trajectory or for_rig(rig)
    times = np.arange(0.0, duration, 1.0 / rate)
    q = np.array(q0, dtype=float)
    ticks, measures = _Ticks(), []
    start = time.perf_counter()
    for t in times:
        target = path.centre(float(t))
        step = head(q, target)
        u = step.u if law == "sigma" else step.u_paper
        ticks.add(q, u, step)
        measures.append(_measures(rig, step.camera, target))
        q = q + u / rate
    line, centre, angle = np.array(measures).T
    run = HeadRun("ideal", times, *ticks.arrays(), times, line, centre, angle)
    run.seconds = {"control": time.perf_counter() - start}
    return run


class _AlphaBeta:
    """α-β tracking of the estimated point (H): x̂, v̂ updated per frame, x̂ + v̂ (t − t_k) between."""

    def __init__(self, alpha: float, beta: float, period: float) -> None:
        self.alpha, self.beta, self.period = alpha, beta, period
        self.x: np.ndarray | None = None
        self.v = np.zeros(3)
        self.t = 0.0

    def update(self, t: float, measured: np.ndarray) -> None:
        if self.x is None:
            self.x, self.t = measured.copy(), t
            return
        predicted = self.x + self.v * (t - self.t)
        residual = measured - predicted
        self.x = predicted + self.alpha * residual
        self.v = self.v + self.beta * residual / self.period
        self.t = t

    def at(self, t: float) -> np.ndarray:
        assert self.x is not None
        return self.x + self.v * (t - self.t)


def run_vision(rig: Rig, duration: float = 5.0, *, head: Head | None = None,
               estimator: Estimator | None = None, trajectory: Trajectory | None = None,
               options: scene.SceneOptions | None = None, seed: int = 0, fps: float = FPS, rate: float = RATE,
               q0: tuple[float, float] = (0.0, 0.0), tracker: tuple[float, float] | None = TRACKER,
               keep_frames: int = 0, progress: Callable[[str], None] = lambda _: None) -> HeadRun:
    """The loop closed through rendering and estimation (see the module's docstring). ``tracker``: the
    α-β gains, or None to hold each estimate unchanged; ``keep_frames``: keep every n-th left image with
    overlays (0: none)."""
    head = head or Head(rig)
    estimator = estimator or Estimator(rig)
    path = trajectory or for_rig(rig)
    options = options if options is not None else scene.SceneOptions()
    rng = np.random.default_rng(seed)
    times = np.arange(0.0, duration, 1.0 / rate)
    frame_every = max(1, round(rate / fps))
    q = np.array(q0, dtype=float)
    ab = _AlphaBeta(*(tracker or (1.0, 0.0)), 1.0 / fps)
    ticks = _Ticks()
    sample_t: list[float] = []
    measures: list[tuple[float, float, float]] = []
    errors: list[tuple[float, float]] = []
    failures: list[str] = []
    kept: list[np.ndarray] = []
    seconds = {"render": 0.0, "estimate": 0.0, "control": 0.0}
    for k, t in enumerate(times.tolist()):
        if k % frame_every == 0:
            camera = head(q, path.centre(t)).camera  # (the pose only: the target does not enter it)
            true_centre = path.centre(t)
            pose = scene.ObjectPose(camera.R.T @ (true_centre - camera.t), camera.R.T @ UP)
            clock = time.perf_counter()
            frame = scene.render(rig, pose, options, rng)
            mid = time.perf_counter()
            result = estimator(frame.left, frame.right)
            seconds["render"] += mid - clock
            seconds["estimate"] += time.perf_counter() - mid
            frame_no = len(sample_t)
            if isinstance(result, Failure):
                failures.append(f"frame {frame_no} (t = {t:.3f} s): {result}")
                errors.append((math.nan, math.nan))
            else:
                ab.update(t, camera.R @ result.reference + camera.t)
                cos = min(1.0, abs(float(result.direction @ pose.axis)))
                errors.append((1e3 * float(np.linalg.norm(result.reference - pose.centre)),
                               math.degrees(math.acos(cos))))
            sample_t.append(t)
            measures.append(_measures(rig, camera, true_centre))
            if keep_frames and frame_no % keep_frames == 0:
                kept.append(_overlay(rig, frame, result))
            if (frame_no + 1) % 30 == 0:
                progress(f"  frame {frame_no + 1}/{math.ceil(duration * fps)}: offset "
                         f"{measures[-1][0]:.2f} px, {len(failures)} failed so far")
        if ab.x is None:
            raise RuntimeError(f"the first frame gave no estimate ({failures[0]}): nothing to track")
        held = ab.at(t) if tracker else ab.x
        clock = time.perf_counter()
        step = head(q, held)
        seconds["control"] += time.perf_counter() - clock
        ticks.add(q, step.u, step)
        q = q + step.u / rate
    line, centre, angle = np.array(measures).T
    est_mm, est_deg = np.array(errors).T
    run = HeadRun("vision", times, *ticks.arrays(), np.array(sample_t), line, centre, angle, est_mm, est_deg,
                  failures, kept)
    run.seconds = seconds
    return run


# -- the reaching time [SMC Eq. 37-38 per joint] ------------------------------------------------------

@dataclass(frozen=True)
class Reaching:
    """The reaching-time bound of the ideal loop and what it rests on."""

    sigma0: float  # max_i |σ_i(0)|
    layer: float  # φ = 1/ε
    gain: float  # k tanh(εφ) = k tanh 1: the law's least push outside the layer
    drift: float  # D: the bound on |σ̇_i − γ u_i| from the object's motion
    lower: float  # γ_min: the least factor of the law's own effect
    upper: float  # γ_max
    bound: float  # (σ0 − φ) / (γ_min k tanh 1 − D): the latest reaching time
    earliest: float  # (σ0 − φ) / (γ_max k + D): the earliest


def reaching_bound(head: Head, trajectory: Trajectory, q0: tuple[float, float] = (0.0, 0.0)) -> Reaching:
    """The time the ideal loop's sliding variable takes to enter the boundary layer max_i |σ_i| ≤ φ = 1/ε,
    by the reaching condition of [SMC Eq. 37-38] taken per joint.

    Model: σ_i is the sine of the angle Δ_i between the optical axis and the direction from the camera
    centre to the object, in joint i's plane (J⁺ maps the chord d_p − d_ref onto the joint's tangent), so
    σ̇_i = cos Δ_i (1 + ρ) u_i + d_i: the camera centre, ℓ from the joint axes, moves with the joint, which
    turns the direction to the object by |ρ| ≤ ℓ / r (r the object's distance), and the object's motion
    turns it at |d_i| ≤ D = v_max / ((r_min − ℓ) cos β_max) (β the tilt). Outside the layer |u_i| ≥
    k tanh(εφ) = k tanh 1 and Δ_i ≤ Δ(0), so |σ_i| falls at least at γ_min k tanh 1 − D with
    γ_min = cos Δ(0) (1 − ℓ/r_min), and at most at γ_max k + D, γ_max = 1 + ℓ/r_min: the reaching time
    lies between (σ0 − φ)/(γ_max k + D) and (σ0 − φ)/(γ_min k tanh 1 − D) (Eq. 38's k > |ẋ_ref| + |λ|
    is γ_min k tanh 1 > D here)."""
    k, eps = (float(v) for v in head.gains)
    step = head(np.array(q0, dtype=float), trajectory.centre(0.0))
    sigma0 = float(np.abs(step.sigma).max())
    ell = max(float(np.linalg.norm(np.cross(_axis(j), step.centre - _origin(head, i))))
              for i, j in enumerate(head.joints[:2]))
    middle, amp = np.array(trajectory.middle), np.array(trajectory.amplitude)
    r_min = float(np.linalg.norm([0.0, 0.0, middle[2] - amp[2]])) - ell
    beta = math.atan2(abs(middle[1]) + amp[1], r_min)
    drift = trajectory.speed / ((r_min - ell) * math.cos(beta))
    c = step.centre
    target = trajectory.centre(0.0)
    along = float(step.camera.R[:, 2] @ (target - c)) / float(np.linalg.norm(target - c))
    delta0 = math.acos(min(1.0, along))
    lower, upper = math.cos(delta0) * (1 - ell / r_min), 1 + ell / r_min
    layer = 1.0 / eps
    push = k * math.tanh(eps * layer)
    rate = lower * push - drift
    if rate <= 0:
        raise ValueError(f"no reaching: the gain k = {k:g} rad/s is too small for the object's motion "
                         f"(γ_min k tanh 1 = {lower * push:.3f} ≤ D = {drift:.3f} rad/s; Eq. 38)")
    return Reaching(sigma0, layer, push, drift, lower, upper, max(0.0, sigma0 - layer) / rate,
                    max(0.0, sigma0 - layer) / (upper * k + drift))


def _axis(joint: Any) -> np.ndarray:
    return np.array(joint.axis, dtype=float)


def _origin(head: Head, index: int) -> np.ndarray:
    """A point of joint ``index``'s axis at q = 0 (H): the joints' offsets summed (no rpy in the head)."""
    origin: np.ndarray = np.sum([np.array(j.xyz) for j in head.joints[:index + 1]], axis=0)
    return origin


def reaching_time(run: HeadRun, layer: float) -> float:
    """The first tick at which max_i |σ_i| ≤ layer (inf if never)."""
    inside = np.nonzero(np.abs(run.sigma).max(axis=1) <= layer)[0]
    return float(run.t[inside[0]]) if inside.size else math.inf


# -- pictures -----------------------------------------------------------------------------------------

def _overlay(rig: Rig, frame: scene.StereoFrame, result: Any) -> np.ndarray:
    """The left image with the image centre's cross and the detected symmetry line (magenta)."""
    import cv2

    from gagen.apps.stereo.track import _draw_line

    img = frame.left.copy()
    cam = rig.left
    cx, cy = round(cam.cx), round(cam.cy)
    cv2.line(img, (cx - 12, cy), (cx + 12, cy), (255, 255, 255), 1)
    cv2.line(img, (cx, cy - 12), (cx, cy + 12), (255, 255, 255), 1)
    if not isinstance(result, Failure):
        _draw_line(img, cam, result.left.theta, result.left.r, (255, 0, 255))
    return img


def plot(runs: list[HeadRun], out: Path, transient: float = TRANSIENT) -> Path:
    """``offset.png``: the axis' image offset (px, log scale), the viewing angle and the joint angles."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 7))
    FigureCanvasAgg(fig)
    axes = [fig.add_subplot(3, 1, i + 1) for i in range(3)]
    for n, run in enumerate(runs):
        label = run.mode if run.mode == "ideal" else f"vision {n}"
        style = "-" if run.mode == "ideal" else ".-"
        axes[0].semilogy(run.sample_t, np.maximum(run.line_offset_px, 1e-3), style, ms=2, lw=0.8,
                         label=f"{label}: axis line")
        axes[1].semilogy(run.sample_t, np.maximum(run.angle_deg, 1e-4), style, ms=2, lw=0.8, label=label)
        for j, name in enumerate(("pan", "tilt")):
            axes[2].plot(run.t, np.degrees(run.q[:, j]), lw=0.8, label=f"{label}: {name}")
    axes[0].axhline(2.0, color="k", lw=0.6, ls="--")
    axes[0].set_ylabel("offset from the image centre [px]")
    axes[1].set_ylabel("optical axis vs object [°]")
    axes[2].set_ylabel("joint angle [°]")
    axes[2].set_xlabel(f"t [s] (measures after {transient:g} s are the tables'; dashed: 2 px)")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
    fig.suptitle("Pan-tilt visual tracking: the sliding-mode law on L_Vref [SMC Eq. 29, 33-40]")
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    path = out / "offset.png"
    fig.savefig(path, dpi=100)
    return path


def gif(frames: list[np.ndarray], path: Path, width: int = 200, fps: float = 10.0, colours: int = 16) -> Path:
    """A small looping GIF of BGR frames (smoothed and downscaled to ``width`` px, ``colours`` palette
    entries: pixel noise would otherwise defeat the GIF's compression)."""
    import cv2
    from PIL import Image

    images = []
    for f in frames:
        h = round(f.shape[0] * width / f.shape[1])
        small = cv2.resize(cv2.GaussianBlur(f, (0, 0), 1.5), (width, h), interpolation=cv2.INTER_AREA)
        rgb = Image.fromarray(np.ascontiguousarray(small[:, :, ::-1]))
        images.append(rgb.quantize(colours, method=Image.Quantize.MEDIANCUT))
    path.parent.mkdir(parents=True, exist_ok=True)
    images[0].save(path, save_all=True, append_images=images[1:], duration=round(1000 / fps), loop=0,
                   optimize=True)
    return path
