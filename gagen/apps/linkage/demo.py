"""The ``gagen linkage`` run of one mechanism: compile its kernels, follow the crank from the initial
configuration, summarise the solver's work per step, and write the pictures (``plots``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gagen.apps.linkage import plots
from gagen.apps.linkage.solver import Trajectory, kernels, simulate
from gagen.apps.linkage.spec import Linkage

ROBOTS = Path(__file__).resolve().parent / "robots"


def bundled() -> list[Path]:
    """The bundled specs, by name."""
    return sorted(ROBOTS.glob("*.yaml"))


def crank_angles(steps: int, revolutions: int = 1) -> np.ndarray:
    """``steps`` equal crank steps per revolution from the initial configuration (0), both ends kept."""
    return np.linspace(0.0, 2 * np.pi * revolutions, steps * revolutions + 1)


def summary(linkage: Linkage, trajectory: Trajectory) -> str:
    """Steps, Newton iterations, the worst residual, the least σ_min of J and where, halvings and
    failures, in a few lines."""
    t, deg = trajectory, np.degrees(trajectory.angles)
    worst = int(np.argmin(t.sigma_min))
    halved = int(np.count_nonzero(t.halvings))
    finite = t.condition[np.isfinite(t.condition)]
    first = f" (max {int(t.halvings.max())}, first at {deg[int(np.argmax(t.halvings > 0))]:.1f}°)"
    lines = [
        f"{linkage.name}: {len(t.angles) - 1} crank steps over {deg[-1] - deg[0]:.0f}°, "
        f"{len(linkage.bodies)} bodies, {len(linkage.joints)} joints, {linkage.constraint_rows} "
        f"constraint rows",
        f"  mobility: Grübler–Kutzbach {linkage.mobility()}; constraint Jacobian rank {t.rank} for "
        f"{t.unknowns} unknowns and {linkage.constraint_rows} rows at the initial configuration",
        f"  Newton iterations per step: mean {t.iterations.mean():.2f}, max {t.iterations.max()} "
        f"(at {deg[int(np.argmax(t.iterations))]:.1f}°); max residual {t.residuals.max():.2e}",
        f"  σ_min(J): min {t.sigma_min[worst]:.3e} at crank {deg[worst]:.1f}°; max condition number "
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
    progress(f"{linkage.name}: simulating {steps * revolutions} crank steps")
    trajectory = simulate(k, linkage, crank_angles(steps, revolutions), progress=progress)
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


__all__ = ["ROBOTS", "Run", "bundled", "crank_angles", "run", "summary"]
