"""Pictures of a simulated linkage (``gagen.apps.linkage.solver.Trajectory``) with matplotlib's Agg
backend (no display): ``coupler_curve.png`` (the traced curve and the mechanism at a few crank angles),
``<name>.gif`` (the mechanism over the run, the traced curve growing; Pillow, no ffmpeg) and
``solver_stats.png`` (Newton iterations, final residual, σ_min and condition number of J per step).

As in [LINK] Figure 1 the crank is green and the ground blue. A body is drawn as the polygon through
its points (a bar for two), ordered by angle about their centroid at the initial configuration, so a
rigid body keeps its outline; a slot (prismatic joint) is the segment of its travel, carried by the
body that holds it."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from gagen.apps.linkage.kernels import point_labels
from gagen.apps.linkage.solver import TOLERANCE, Trajectory
from gagen.apps.linkage.spec import GROUND, Linkage, Prismatic, Revolute

CRANK, GROUND_COLOUR = "tab:green", "tab:blue"
BODY_COLOURS = ("tab:red", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan",
                "tab:gray")
TRACE_COLOUR = "#cc00cc"  # magenta: no body, text or axis has it
SLOT_LENGTH = 2.0  # drawn length of a slot without travel limits, in units of the crank radius


def _figure(size: tuple[float, float]) -> Any:  # matplotlib's Figure (imported lazily)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size)
    FigureCanvasAgg(fig)
    return fig


# --- geometry of the drawing (no matplotlib) -------------------------------------------------------------

def body_colours(linkage: Linkage) -> dict[str, str]:
    """The crank green, the other bodies from a palette without green or blue."""
    others = iter(BODY_COLOURS * (1 + len(linkage.bodies) // len(BODY_COLOURS)))
    return {body: CRANK if body in linkage.driven else next(others) for body in linkage.bodies}


def outline(linkage: Linkage, body: str) -> list[str]:
    """A body's (or the ground's) point names in drawing order: by angle about their centroid at the
    initial configuration (a simple polygon through them all; for two points, the bar)."""
    points = linkage.ground if body == GROUND else linkage.bodies[body]
    names = list(points)
    xy = np.array([points[n] for n in names], dtype=float).reshape(-1, 2)
    d = xy - xy.mean(axis=0)
    return [names[i] for i in np.argsort(np.arctan2(d[:, 1], d[:, 0]), kind="stable")]


def body_points(linkage: Linkage, row: np.ndarray) -> dict[str, np.ndarray]:
    """Each body's points (outline order, k × 2) from one row of ``Trajectory.points``; the ground's
    pivots (outline order) under ``"ground"``."""
    row = np.asarray(row, dtype=float).reshape(-1)
    column = {label: i for i, label in enumerate(point_labels(linkage))}
    out = {body: np.array([[row[column[f"{body}_{n}_x"]], row[column[f"{body}_{n}_y"]]]
                           for n in outline(linkage, body)]) for body in linkage.bodies}
    out[GROUND] = np.array([linkage.ground[n] for n in outline(linkage, GROUND)], dtype=float).reshape(-1, 2)
    return out


def rigid_motion(initial: np.ndarray, current: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The planar rotation R and translation t with current ≈ initial R^T + t (least squares, Kabsch);
    a single point gives a pure translation."""
    initial, current = np.asarray(initial, dtype=float), np.asarray(current, dtype=float)
    a, b = initial.mean(axis=0), current.mean(axis=0)
    if len(initial) < 2:
        return np.eye(2), b - a
    H = (initial - a).T @ (current - b)
    angle = np.arctan2(H[0, 1] - H[1, 0], H[0, 0] + H[1, 1])
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    return R, b - a @ R.T


def _driver_scale(linkage: Linkage) -> float:
    """The crank's radius, or a slider's stroke length: the size of the input motion (the largest of
    k drivers')."""
    scales = [1e-9]
    for driver in linkage.drivers:
        if driver.pivot is None:
            lower, upper = linkage.stroke(driver)
            scales.append(upper - lower)
            continue
        pivot = np.array(linkage.ground[driver.pivot])
        scales += [float(np.hypot(*(np.array(p) - pivot))) for p in linkage.bodies[driver.body].values()]
    return max(scales)


def _short(linkage: Linkage, value: float | np.ndarray) -> str:
    """The driver's value for a label: the crank angle in degrees, or the slider's s (k drivers: each,
    joined by /)."""
    values = np.atleast_1d(np.asarray(value, dtype=float)).reshape(-1)
    return "/".join(f"{np.degrees(v):.0f}°" if d.pivot is not None else f"s={round(float(v), 4) + 0.0:g}"
                    for d, v in zip(linkage.drivers, values, strict=False))


def slot_segments(linkage: Linkage, row: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """Each prismatic joint's slot as (carrying body, 2 × 2 segment) in the configuration of ``row``:
    its travel (or ±``SLOT_LENGTH`` crank radii, or slider strokes) along the line, moved with the body
    that holds it."""
    points = body_points(linkage, row)
    out = []
    for joint in linkage.joints:
        if not isinstance(joint, Prismatic):
            continue
        lo, hi = joint.travel or (-SLOT_LENGTH * _driver_scale(linkage), SLOT_LENGTH * _driver_scale(linkage))
        ends = np.array(joint.through) + np.outer([lo, hi], joint.direction)
        if joint.on != GROUND:
            initial = np.array([linkage.bodies[joint.on][n] for n in outline(linkage, joint.on)])
            R, t = rigid_motion(initial, points[joint.on])
            ends = ends @ R.T + t
        out.append((joint.on, ends))
    return out


def traced(linkage: Linkage) -> list[tuple[str, str]]:
    """The points whose curves are drawn bold: the spec's ``trace``, else every point of a moving body
    other than the crank that no joint pins to the ground."""
    if linkage.trace is not None:
        return [linkage.trace]
    pinned = {j.a if j.b[0] == GROUND else j.b for j in linkage.joints
              if isinstance(j, Revolute) and GROUND in (j.a[0], j.b[0])}
    return [(b, n) for b in linkage.unknown for n in linkage.bodies[b] if (b, n) not in pinned]


def paths(linkage: Linkage, trajectory: Trajectory) -> dict[tuple[str, str], np.ndarray]:
    """The path (steps × 2) of every body point that moves, one per location (a joint's two coinciding
    points give one path)."""
    out: dict[tuple[str, str], np.ndarray] = {}
    labels = point_labels(linkage)
    for body, names in linkage.bodies.items():
        for name in names:
            i = labels.index(f"{body}_{name}_x")
            path = trajectory.points[:, i:i + 2]
            fixed = np.ptp(path, axis=0).max() < 1e-9
            if fixed or any(np.allclose(path, p, atol=1e-9) for p in out.values()):
                continue
            out[(body, name)] = path
    return out


def _extent(linkage: Linkage, trajectory: Trajectory, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    parts = [trajectory.points.reshape(len(trajectory.points), -1, 2).reshape(-1, 2),
             np.array(list(linkage.ground.values()), dtype=float).reshape(-1, 2)]
    parts += [segment for r in rows for _, segment in slot_segments(linkage, trajectory.points[r])]
    xy = np.vstack(parts)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    margin = 0.08 * max(float((hi - lo).max()), 1e-6)
    return lo - margin, hi + margin


# --- drawing --------------------------------------------------------------------------------------------

class _Mechanism:
    """The artists of one configuration (bodies, slots, ground), updated in place for an animation."""

    def __init__(self, ax: Any, linkage: Linkage, alpha: float = 1.0, zorder: float = 3) -> None:
        from matplotlib.patches import Polygon

        self.linkage, colours = linkage, body_colours(linkage)
        ground = np.array([linkage.ground[n] for n in outline(linkage, GROUND)], dtype=float).reshape(-1, 2)
        if len(ground) > 1:  # the ground link: the bar, or the outline, through its pivots
            ring = np.vstack([ground, ground[:1]]) if len(ground) > 2 else ground
            ax.plot(ring[:, 0], ring[:, 1], "-", color=GROUND_COLOUR, lw=4 if len(ground) == 2 else 2.5,
                    alpha=0.5 * alpha, zorder=zorder)
        ax.plot(ground[:, 0], ground[:, 1], "^", color=GROUND_COLOUR, ms=11, alpha=alpha, zorder=zorder + 2)
        self.slots = [ax.plot([], [], "-", lw=5, solid_capstyle="butt", alpha=0.45 * alpha, zorder=zorder,
                              color=GROUND_COLOUR if j.on == GROUND else colours[j.on])[0]
                      for j in linkage.joints if isinstance(j, Prismatic)]
        self.patches, self.lines = {}, {}
        for body in linkage.bodies:
            if len(linkage.bodies[body]) > 2:
                patch = Polygon(np.zeros((3, 2)), closed=True, facecolor=colours[body], alpha=0.25 * alpha,
                                edgecolor="none", zorder=zorder)
                ax.add_patch(patch)
                self.patches[body] = patch
            width = 3 if body in linkage.driven else 2
            self.lines[body] = ax.plot([], [], "-o", color=colours[body], lw=width, ms=4, mfc="white",
                                       alpha=alpha, zorder=zorder + 1)[0]

    def update(self, row: np.ndarray) -> None:
        points = body_points(self.linkage, row)
        for body, line in self.lines.items():
            xy = points[body]
            ring = np.vstack([xy, xy[:1]]) if len(xy) > 2 else xy
            line.set_data(ring[:, 0], ring[:, 1])
            if body in self.patches:
                self.patches[body].set_xy(xy)
        for line, (_, segment) in zip(self.slots, slot_segments(self.linkage, row), strict=True):
            line.set_data(segment[:, 0], segment[:, 1])


def _frame_axes(ax: Any, lo: np.ndarray, hi: np.ndarray) -> None:
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.grid(alpha=0.3)


def coupler_curve(linkage: Linkage, trajectory: Trajectory, path: str | Path, poses: int = 4) -> Path:
    """The traced curve(s) (bold; every other moving point's path thin) and the mechanism at ``poses``
    driver phases spread over the first cycle (the first solid, the others faded)."""
    fig = _figure((7, 6))
    ax = fig.add_subplot(1, 1, 1)
    n = len(trajectory.angles)
    phase = trajectory.phase
    turns = phase[0] + 2 * np.pi * np.arange(max(poses, 1)) / max(poses, 1)  # over one cycle
    rows = np.unique([int(np.argmin(np.abs(phase - a))) for a in turns])
    lo, hi = _extent(linkage, trajectory, np.arange(n))
    bold = set(traced(linkage))
    every = paths(linkage, trajectory)
    for key, xy in every.items():
        if key not in bold:
            ax.plot(xy[:, 0], xy[:, 1], "-", color="0.55", lw=0.7, alpha=0.6, zorder=1)
    labels = point_labels(linkage)
    for body, name in traced(linkage):
        i = labels.index(f"{body}_{name}_x")
        xy = trajectory.points[:, i:i + 2]
        ax.plot(xy[:, 0], xy[:, 1], "-", color=TRACE_COLOUR, lw=2, zorder=6, label=f"{body}.{name}")
    for k, r in enumerate(rows):
        mech = _Mechanism(ax, linkage, alpha=1.0 if k == 0 else 0.25, zorder=3 if k == 0 else 2)
        mech.update(trajectory.points[r])
        if k > 0:
            for body, name in traced(linkage):
                i = labels.index(f"{body}_{name}_x")
                ax.annotate(_short(linkage, trajectory.angles[r]), trajectory.points[r, i:i + 2],
                            textcoords="offset points", xytext=(5, 5), fontsize=8, color="0.3")
    _frame_axes(ax, lo, hi)
    ax.legend(loc="best", fontsize=8, title="traced", title_fontsize=8)
    shown = ", ".join(_short(linkage, trajectory.angles[r]) for r in rows)
    kind = linkage.driver.kind
    ax.set_title(f"{linkage.name}: traced curve; the mechanism at {kind} {shown}\n"
                 f"({kind} green, ground blue, traced curve magenta, other paths grey)", fontsize=10)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=100)
    return out


def animate(linkage: Linkage, trajectory: Trajectory, path: str | Path, frames: int = 72, size: float = 5.0,
            dpi: int = 80, fps: int = 24, progress: Callable[[str], None] = lambda _: None) -> Path:
    """A GIF of the mechanism over the run: ``frames`` steps spread evenly over it, the traced curve
    drawn up to the current step."""
    from matplotlib.animation import PillowWriter

    n, phase = len(trajectory.angles), trajectory.phase
    end = n - 1 if n > 1 and np.isclose((phase[-1] - phase[0]) % (2 * np.pi), 0) \
        and phase[-1] != phase[0] else n  # a closed loop: its last step is the first
    picks = np.unique(np.linspace(0, max(end - 1, 0), max(2, frames)).round().astype(int))
    fig = _figure((size, size))
    ax = fig.add_subplot(1, 1, 1)
    lo, hi = _extent(linkage, trajectory, np.arange(n))
    _frame_axes(ax, lo, hi)
    mech = _Mechanism(ax, linkage)
    labels = point_labels(linkage)
    columns = [labels.index(f"{b}_{p}_x") for b, p in traced(linkage)]
    curves = [ax.plot([], [], "-", color=TRACE_COLOUR, lw=1.5, zorder=6)[0] for _ in columns]
    title = ax.set_title(f"{linkage.name}: {linkage.at(np.pi)}")  # a full-width title for the layout
    fig.tight_layout()
    out = Path(path)
    writer = PillowWriter(fps=fps)
    with writer.saving(fig, str(out), dpi):
        for k, r in enumerate(picks):
            mech.update(trajectory.points[r])
            for curve, i in zip(curves, columns, strict=True):
                curve.set_data(trajectory.points[:r + 1, i], trajectory.points[:r + 1, i + 1])
            title.set_text(f"{linkage.name}: {_short(linkage, trajectory.angles[r])}, "
                           f"t = {phase[r] / abs(linkage.driver.rate):.2f} s")
            writer.grab_frame()
            if (k + 1) % 30 == 0 or k + 1 == len(picks):
                progress(f"  animation: frame {k + 1}/{len(picks)}")
    return out


def solver_stats(linkage: Linkage, trajectory: Trajectory, path: str | Path) -> Path:
    """Per step over time (the driver's phase over its rate): Newton iterations (steps with halvings
    marked), the final residual max |F| (log, the tolerance dashed, failures red) and σ_min of J with
    its condition number (log)."""
    fig = _figure((9, 8))
    time = trajectory.phase / abs(linkage.driver.rate)  # the time axis, s
    its, res, halv = fig.add_subplot(3, 1, 1), fig.add_subplot(3, 1, 2), fig.add_subplot(3, 1, 3)
    its.step(time, trajectory.iterations, where="mid", color="C0", label="Newton iterations")
    halved = trajectory.halvings > 0
    if halved.any():
        its.plot(time[halved], trajectory.iterations[halved], "v", color="C3", ms=5, label="step halved")
    from matplotlib.ticker import MaxNLocator

    its.yaxis.set_major_locator(MaxNLocator(integer=True))
    its.set_ylabel("iterations")
    its.legend(fontsize=8, loc="upper right")
    floor = 1e-18  # an exact zero on a log axis
    res.semilogy(time, np.maximum(trajectory.residuals, floor), ".", color="C0", ms=3, label="max |F|")
    res.axhline(TOLERANCE, color="C3", ls="--", lw=0.8, label=f"tolerance {TOLERANCE:g}")
    failed = trajectory.residuals >= TOLERANCE
    if failed.any():
        res.semilogy(time[failed], trajectory.residuals[failed], "x", color="C3", ms=7, label="not converged")
    res.set_ylabel("final residual")
    res.legend(fontsize=8, loc="upper right")
    sig = halv
    sig.semilogy(time, np.maximum(trajectory.sigma_min, floor), color="C2", label="σ_min(J)")
    sig.set_ylabel("σ_min(J)", color="C2")
    cond = sig.twinx()
    cond.semilogy(time, np.where(np.isfinite(trajectory.condition), trajectory.condition, np.nan), color="C1",
                  label="cond(J)")
    cond.set_ylabel("σ_max / σ_min", color="C1")
    worst = int(np.argmin(trajectory.sigma_min))
    sig.axvline(time[worst], color="0.5", ls=":", lw=0.8)
    sig.set_xlabel(f"time [s] ({'crank angle' if linkage.pivot is not None else 'stroke phase'} = "
                   f"{abs(linkage.driver.rate):g} rad/s × t)")
    for ax in (its, res, sig):
        ax.grid(alpha=0.3)
        ax.set_xlim(time[0], time[-1])
    fig.suptitle(f"{linkage.name}: Newton per {linkage.driver.kind} step ({len(time)} steps; min σ_min "
                 f"{trajectory.sigma_min[worst]:.3g} at {linkage.at(trajectory.angles[worst])})", fontsize=11)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=100)
    return out


__all__ = ["animate", "body_points", "coupler_curve", "outline", "paths", "rigid_motion", "slot_segments",
           "solver_stats", "traced"]
