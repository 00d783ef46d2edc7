"""``gagen manipulability SPEC``: velocity and force ellipsoids of the cooperative similarity and their
nullspace optimisation [COOP Section 3.11, Eq. 59].

From a configuration of the spec (default ``ready``) the primitive's similarity is held (V_Sd = V_Sc(q0))
while ``gagen.control.force_manipulability.maximise`` climbs the dilation force index β_D (or the force
ellipsoid's volume) inside the self-motion manifold. Prints the ellipsoids' semi-axes and the index
before and after, and writes ``manipulability.png``:

- left: the velocity and force ellipsoids in the coordinate plane of the dilation e0∞ and the generator
  with the largest velocity range at the start (for a primitive without dilation: the two largest),
  at the start and at the optimum. The velocity ellipse is the ellipsoid's shadow on the plane (shape
  matrix M_ab, the 2 × 2 block of M_S), the force ellipse its section {F : Fᵀ M_ab F ≤ 1}: the force
  ellipse meets the e0∞ axis at ±β_D;
- middle: the r principal semi-axes, σ_i (velocity) and 1/σ_i (force), start and optimum;
- right: β_D (or the volume) and ‖e‖ along the ascent.

    gagen manipulability three_pandas_circle --out plots/manipulability [--steps 60] [--objective volume]
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.control import force_manipulability as fm
from gagen.control.differential import CONTROLLABLE_DIMENSION
from gagen.model.conformal import SIMILARITY_GENERATOR

Array = NDArray[np.float64]
LABELS = {"e12": "e12", "e13": "e13", "e23": "e23", "e0inf": "e0∞", "e1inf": "e1∞", "e2inf": "e2∞",
          "e3inf": "e3∞"}
PLOT_NAME = "manipulability.png"


@dataclass(frozen=True)
class Analysis:
    """The ascent of ``system`` and the kernels' J_G at its ends, with the ``rank`` r used."""

    system: str
    kind: str
    rank: int
    result: fm.OptimisationResult
    J_start: Array
    J_end: Array

    def plane(self) -> tuple[int, int]:
        """The two generator rows drawn: e0∞ and the largest other M_S diagonal (no dilation: the two
        largest)."""
        diagonal = np.diag(fm.velocity_ellipsoid(self.J_start)).copy()
        if self.kind in fm.DILATING:
            diagonal[fm.DILATION_ROW] = -1.0
            return fm.DILATION_ROW, int(np.argmax(diagonal))
        first, second = np.argsort(diagonal)[::-1][:2]
        return int(first), int(second)


def analyse(system: str, *, objective: str | None = None, configuration: str = "ready", steps: int = 60,
            step_size: float = 0.05, verbose: bool = False) -> Analysis:
    """Run the ascent on ``system`` (a bundled name or a spec file; its generated module is built on first
    use). ``objective`` defaults to ``dilation`` for primitives that dilate, else ``volume``."""
    from gagen.apps.cooperative.scenarios import _loaded, module, spec_of

    loaded, named = _loaded(system)
    kind = loaded.kind
    objective = objective or ("dilation" if kind in fm.DILATING else "volume")
    if objective == "dilation" and kind not in fm.DILATING:
        raise ValueError(f"--objective dilation: {system} spans a {kind}, which has no dilation (only a "
                         "point pair, circle or sphere does); use --objective volume")
    if configuration not in named:
        raise ValueError(f"--configuration: {spec_of(system)} has no configuration {configuration!r} (it has "
                         f"{', '.join(named) or 'none'})")
    if verbose:
        print(f"{system}: {objective} ascent in the nullspace, {steps} steps of at most {step_size} rad",
              flush=True)
    m = module(system)
    q0 = np.array(named[configuration], dtype=float)
    rank = min(CONTROLLABLE_DIMENSION[kind], q0.size)

    def progress(step: int, w: float) -> None:
        if verbose and (step % 10 == 0 or step == steps):
            print(f"  step {step:4d}: w = {w:.6f}", flush=True)

    result = fm.maximise(m.c.similarity, m.c.task, q0, name=objective, rank=rank, steps=steps,
                         step_size=step_size, progress=progress)
    J = [np.array(m.c.similarity(x)[2]) for x in (result.q[0], result.q[-1])]
    return Analysis(system, kind, rank, result, J[0], J[1])


def _ellipse(shape: Array, samples: int = 181) -> Array:
    """(samples, 2) boundary of {x : xᵀ shape⁻¹ x ≤ 1} (``shape`` 2 × 2, positive definite)."""
    values, vectors = np.linalg.eigh(shape)
    angles = np.linspace(0.0, 2 * np.pi, samples)
    circle = np.stack([np.cos(angles), np.sin(angles)])
    boundary: Array = (vectors * np.sqrt(values)) @ circle
    return boundary.T


def figure(analysis: Analysis) -> Any:
    """The Figure (Agg canvas). Lines carry gids: ``velocity:start``, ``force:end``, …, ``objective``,
    ``dilation``, ``error``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(13, 4.2), layout="constrained")
    FigureCanvasAgg(fig)
    ax_e, ax_b, ax_w = fig.subplots(1, 3, width_ratios=(1.1, 1, 1.1))
    a, b = analysis.plane()
    names = [LABELS[SIMILARITY_GENERATOR[i]] for i in (a, b)]
    for when, J, style in (("start", analysis.J_start, "--"), ("end", analysis.J_end, "-")):
        block: Array = fm.velocity_ellipsoid(J)[np.ix_([a, b], [a, b])]
        ax_e.plot(*_ellipse(block).T, color="tab:blue", linestyle=style, gid=f"velocity:{when}",
                  label=f"velocity (shadow), {when}")
        inverse: Array = np.asarray(np.linalg.inv(block), dtype=np.float64)
        ax_e.plot(*_ellipse(inverse).T, color="tab:orange", linestyle=style, gid=f"force:{when}",
                  label=f"force (section), {when}")
    ax_e.set(ylabel=f"{names[1]} coefficient", aspect="equal",
             title=f"ellipsoids in the {names[0]} (x) – {names[1]} (y) plane")
    ax_e.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.3), ncol=2)
    ax_e.grid(True, linewidth=0.3)

    r = analysis.rank
    width = 0.2
    index = np.arange(1, r + 1)
    for offset, when, J in ((-1.5, "start", analysis.J_start), (0.5, "end", analysis.J_end)):
        found = fm.ellipsoids(J, r)
        ax_b.bar(index + offset * width, found.velocity_lengths, width, label=f"σ_i (velocity), {when}",
                 color="tab:blue", alpha=0.5 if when == "start" else 1.0)
        ax_b.bar(index + (offset + 1) * width, found.force_lengths, width, label=f"1/σ_i (force), {when}",
                 color="tab:orange", alpha=0.5 if when == "start" else 1.0)
    ax_b.set(yscale="log", xlabel="principal axis i", ylabel="semi-axis", xticks=index,
             title=f"principal semi-axes (rank {r})")
    ax_b.legend(fontsize=7)

    result = analysis.result
    steps = np.arange(len(result.objective))
    shown = result.dilation if result.name == "dilation" else result.volume
    label = "dilation force index β_D" if result.name == "dilation" else "force ellipsoid volume"
    ax_w.plot(steps, shown, color="tab:orange", gid="objective" if result.name == "volume" else "dilation")
    ax_w.set(xlabel="nullspace step", ylabel=label, title=f"ascent of {label} with the primitive held")
    twin = ax_w.twinx()
    twin.plot(steps, np.maximum(result.error_norm, 1e-17), color="0.5", linestyle=":", gid="error")
    twin.set(yscale="log", ylabel="‖e(q)‖ (dotted)")
    fig.suptitle(f"{analysis.system}: velocity and force manipulability of the cooperative {analysis.kind} "
                 "[COOP Sec. 3.11]", fontsize=10)
    return fig


def plot(analysis: Analysis, out_folder: str | Path) -> Path:
    folder = Path(out_folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / PLOT_NAME
    figure(analysis).savefig(path, dpi=80)
    return path


def _describe(label: str, J: Array, rank: int, kind: str) -> str:
    found = fm.ellipsoids(J, rank)
    beta = f", β_D {fm.dilation_force_index(J):.4f}" if kind in fm.DILATING else ""
    return (f"{label}: velocity semi-axes {np.array2string(found.velocity_lengths, precision=4)}, force "
            f"semi-axes {np.array2string(found.force_lengths, precision=4)}, force volume "
            f"{fm.force_volume(J, rank):.4g}{beta}")


def run_command(args: argparse.Namespace) -> int:
    """``gagen manipulability`` on its parsed arguments (``gagen.apps.cooperative.commands``)."""
    analysis = analyse(args.system, objective=args.objective, configuration=args.configuration,
                       steps=args.steps, step_size=args.step_size, verbose=True)
    result = analysis.result
    print(_describe("start", analysis.J_start, analysis.rank, analysis.kind))
    print(_describe("end  ", analysis.J_end, analysis.rank, analysis.kind))
    print(f"objective {result.name}: {result.objective[0]:.6f} -> {result.objective[-1]:.6f} in "
          f"{len(result.objective) - 1} steps; ‖e‖ max {result.error_norm.max():.3e}")
    print(f"plot: {plot(analysis, args.out)}")
    return 0
