"""The ``gagen linkage`` run of one mechanism: compile its kernels, follow the driver from the initial
configuration (a crank through whole turns, a slider through its stroke), summarise the solver's work
per step, and write the pictures (``plots``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gagen.apps.linkage import plots
from gagen.apps.linkage.bundled import BUNDLED as ROBOTS
from gagen.apps.linkage.solver import Trajectory, kernels, simulate
from gagen.apps.linkage.spec import Linkage


def bundled() -> list[Path]:
    """The bundled specs, by name."""
    return sorted(ROBOTS.glob("*.yaml"))


def crank_angles(steps: int, revolutions: int = 1) -> np.ndarray:
    """``steps`` equal crank steps per revolution from the initial configuration (0), both ends kept."""
    return np.linspace(0.0, 2 * np.pi * revolutions, steps * revolutions + 1)


def driver_path(linkage: Linkage, steps: int, cycles: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """The driver's values over ``cycles`` cycles of ``steps`` equal phase steps, and the phases (rad):
    a crank's angle is its phase (turning backwards for a negative rate); a slider runs its stroke
    s = a sin φ from the initial configuration, a the stroke's upper end where sin φ ≥ 0 and its lower
    end's magnitude where sin φ < 0 (out to one end, back, out to the other, back). With k drivers
    (steps × k values), φ is the first driver's phase and driver i runs at rate_i / |rate_1| × φ."""
    phases = crank_angles(steps, cycles)
    columns = []
    for driver in linkage.drivers:
        phase = driver.rate / abs(linkage.driver.rate) * phases
        if driver.slide is None:
            columns.append(phase)
            continue
        lower, upper = linkage.stroke(driver)
        sine = np.sin(np.abs(phase))
        columns.append(np.where(sine >= 0, upper, -lower) * sine)
    return (columns[0] if len(columns) == 1 else np.stack(columns, axis=1)), phases


def summary(linkage: Linkage, trajectory: Trajectory) -> str:
    """Steps, Newton iterations, the worst residual, the least σ_min of J and where, halvings and
    failures, in a few lines."""
    t, deg = trajectory, np.degrees(trajectory.phase)
    worst = int(np.argmin(t.sigma_min))
    halved = int(np.count_nonzero(t.halvings))
    finite = t.condition[np.isfinite(t.condition)]
    first = f" (max {int(t.halvings.max())}, first at {linkage.at(t.angles[int(np.argmax(t.halvings > 0))])})"
    driver = linkage.driver
    steps = f"{len(t.angles) - 1} {driver.kind} steps over " + (
        f"{deg[-1] - deg[0]:.0f}°" if driver.slide is None else
        f"its stroke s ∈ [{t.angles.min():.4g}, {t.angles.max():.4g}] ({deg[-1] - deg[0]:.0f}° of phase)")
    if len(linkage.drivers) > 1:
        steps = (f"{len(t.angles) - 1} steps of {len(linkage.drivers)} drivers over {deg[-1] - deg[0]:.0f}° "
                 f"of phase")
    lines = [
        f"{linkage.name}: {steps}, {len(linkage.bodies)} bodies, {len(linkage.joints)} joints, "
        f"{linkage.constraint_rows} constraint rows",
        "  " + "; ".join(f"driver: {d.body} ({d.kind}), rate {d.rate:g} rad/s" for d in linkage.drivers)
        + f": a cycle takes {2 * np.pi / abs(driver.rate):.4g} s",
        f"  mobility: Grübler–Kutzbach {linkage.mobility()}; constraint Jacobian rank {t.rank} for "
        f"{t.unknowns} unknowns and {linkage.constraint_rows} rows at the initial configuration",
        f"  Newton iterations per step: mean {t.iterations.mean():.2f}, max {t.iterations.max()} "
        f"(at {linkage.at(t.angles[int(np.argmax(t.iterations))])}); max residual {t.residuals.max():.2e}",
        f"  σ_min(J): min {t.sigma_min[worst]:.3e} at {linkage.at(t.angles[worst])}; max condition number "
        f"{finite.max() if finite.size else np.inf:.3g}",
        f"  step halvings: {int(t.halvings.sum())} in {halved} step(s)"
        + (first if halved else ""),
        f"  failures: {len(t.failures)}" + (f"; first: {t.failures[0]}" if t.failures else ""),
        *(f"  travel: {limit}" for limit in t.limits),
    ]
    return "\n".join(lines)


@dataclass
class Run:
    linkage: Linkage
    trajectory: Trajectory
    files: list[Path] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)  # compile, simulate, plots, animation


def run(linkage: Linkage, out: str | Path, steps: int = 360, revolutions: int = 1, animation: bool = True,
        frames: int = 72, progress: Callable[[str], None] = lambda _: None) -> Run:
    """Compile, simulate and draw one mechanism into ``out`` (created): ``coupler_curve.png``,
    ``solver_stats.png`` and (with ``animation``) ``<name>.gif``."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    seconds: dict[str, float] = {}
    start = time.perf_counter()
    progress(f"{linkage.name}: compiling the kernels (gagen.compile cache)")
    k = kernels(linkage)
    seconds["compile"] = time.perf_counter() - start
    progress(f"{linkage.name}: simulating {steps * revolutions} {linkage.driver.kind} steps")
    values, phases = driver_path(linkage, steps, revolutions)
    trajectory = simulate(k, linkage, values, phases=phases, progress=progress)
    seconds["simulate"] = time.perf_counter() - start - seconds["compile"]
    mark = time.perf_counter()
    files = [plots.coupler_curve(linkage, trajectory, folder / "coupler_curve.png"),
             plots.solver_stats(linkage, trajectory, folder / "solver_stats.png")]
    seconds["plots"] = time.perf_counter() - mark
    if animation:
        mark = time.perf_counter()
        progress(f"{linkage.name}: animating {frames} frames (Pillow GIF)")
        files.append(plots.animate(linkage, trajectory, folder / f"{linkage.name}.gif", frames=frames,
                                   progress=progress))
        seconds["animation"] = time.perf_counter() - mark
    return Run(linkage, trajectory, files, seconds)


__all__ = ["ROBOTS", "Run", "bundled", "crank_angles", "driver_path", "run", "summary"]
