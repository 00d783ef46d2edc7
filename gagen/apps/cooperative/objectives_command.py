"""``gagen objectives SPEC FILE``: solve a file's mixed objectives (``gagen.control.objectives``) on a
system by IK and as the terminal cost of the reaching OCP, print each term's residual, and plot.

The plot (``<out>/<system>_objectives.png``): the end points at the start and at the IK solution with
every circle's centre and every fixed line of the objective, the centre's path along the OCP; ‖r‖ over
the IK iterations; each term's ‖r_i(q_k)‖ along the OCP's trajectory.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.check import joint_limits
from gagen.control import objectives as O
from gagen.control.objectives_file import load_objectives
from gagen.control.ocp import ReachingOCP
from gagen.registry import resolve_spec
from gagen.robots.spec import load_system


def _operands(objective: O.Objective) -> list[O.Operand]:
    found: list[O.Operand] = []

    def visit(operand: O.Operand) -> None:
        if operand not in found:
            found.append(operand)
        if isinstance(operand, O.Centre):
            visit(operand.of)
        if isinstance(operand, O.Meet):
            visit(operand.a)
            visit(operand.b)

    for term in objective.terms:
        for operand in ([term.a, term.b] if isinstance(term, O.Incidence) else [term.of]):
            visit(operand)
    return found


def run_command(args: argparse.Namespace) -> int:
    system, configurations = load_system(resolve_spec(args.system, "cooperative"))
    loaded = load_objectives(args.objectives, system, configurations)
    name = args.start or loaded.start or ("ready" if "ready" in configurations else None)
    if name is not None and name not in configurations:
        raise ValueError(f"--start {name!r}: not a configuration of {system.name} "
                         f"({', '.join(configurations) or 'none stated'})")
    q0 = np.array(configurations[name], dtype=float) if name else np.zeros(system.dof)
    print(f"{system.name}: {system.dof} joints, {len(loaded.terms)} terms; building the residual …",
          flush=True)
    started = time.perf_counter()
    objective = O.Objective(system, loaded.terms)
    print(f"  built in {time.perf_counter() - started:.2f} s: {objective.size} residual rows", flush=True)
    lower, upper, _ = joint_limits(system)
    started = time.perf_counter()
    # hard terms are equality constraints, which only IPOPT takes: the default method follows the file
    method = args.method or ("ipopt" if objective.hard else "lm")
    ik = O.solve_ik(objective, q0, limits=(lower, upper), method=method)
    print(f"IK ({method}): {ik.message}; ‖r‖ = {np.linalg.norm(ik.residual):.3g}, ‖Jᵀr‖ = "
          f"{ik.gradient:.3g} in {time.perf_counter() - started:.3f} s", flush=True)
    before, after = objective.term_norms(q0), objective.term_norms(ik.q)
    for term in objective.names:
        print(f"  {term:<20} ‖r‖ {before[term]:.3e} -> {after[term]:.3e}")
    trajectory = None
    if args.N > 0:
        started = time.perf_counter()
        ocp = ReachingOCP(objective.task, system.dof, N=args.N, horizon=args.horizon)
        result = ocp.solve(q0, np.zeros(12), limits=(lower, upper))
        trajectory = result.q
        seconds = time.perf_counter() - started
        print(f"OCP (N = {args.N}, {args.horizon:g} s): {result.message} in {seconds:.2f} s", flush=True)
    path = _plot(objective, q0, ik, trajectory, args.out)
    print(f"wrote {path}")
    return 0 if ik.converged else 1


def _plot(objective: O.Objective, q0: NDArray[np.float64], ik: O.ObjectiveResult,
          trajectory: NDArray[np.float64] | None, out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure = plt.figure(figsize=(13, 4.2))
    ax: Any = figure.add_subplot(1, 3, 1, projection="3d")
    chains = [c.name for c in objective.system.chains]
    for q, colour, label in ((q0, "0.6", "start"), (ik.q, "C0", "IK solution")):
        ends = np.array([objective.position(O.end_point(c), q) for c in chains])
        ax.scatter(*ends.T, color=colour, label=f"end points ({label})")
        ring = np.vstack([ends, ends[:1]])
        ax.plot(*ring.T, color=colour, lw=0.8)
    for operand in _operands(objective):
        if isinstance(operand, O.Centre):
            centre = objective.position(operand, ik.q)
            ax.scatter(*centre, color="C3", marker="x", s=60, label="centre (solution)")
            if trajectory is not None:
                moved = np.array([objective.position(operand, q) for q in trajectory])
                ax.plot(*moved.T, color="C3", lw=1.0, label="centre along the OCP")
        if isinstance(operand, O.Fixed) and operand.kind == "line":
            a, b = (np.array(p) for p in operand.points)
            near = float((ends.mean(axis=0) - a) @ (b - a))  # about the solution's end points
            segment = np.array([a + (near - 0.4) * (b - a), a + (near + 0.4) * (b - a)])
            ax.plot(*segment.T, color="k", ls="--", lw=1.0, label="fixed line")
    shown = np.vstack([np.column_stack([np.asarray(v) for v in line.get_data_3d()]) for line in ax.lines])
    middle, half = shown.mean(axis=0), 0.55 * float(np.ptp(shown, axis=0).max())
    for k, axis in enumerate("xyz"):  # equal scales, so the circle looks round
        getattr(ax, f"set_{axis}lim")(middle[k] - half, middle[k] + half)
    handles, labels = ax.get_legend_handles_labels()
    unique = dict(zip(labels, handles, strict=True))
    ax.legend(unique.values(), unique.keys(), fontsize=7, loc="upper left")
    ax.set_title(f"{objective.system.name}: mixed objective", fontsize=9)
    ax2 = figure.add_subplot(1, 3, 2)
    if ik.ik is not None:
        ax2.semilogy(np.maximum(ik.ik.history, 1e-17), marker="o")
    ax2.set_xlabel("IK iteration")
    ax2.set_ylabel("‖r‖ (weighted, stacked)")
    ax2.grid(True, which="both", alpha=0.3)
    ax3 = figure.add_subplot(1, 3, 3)
    if trajectory is not None:
        norms = [objective.term_norms(q) for q in trajectory]
        for term in objective.names:
            ax3.semilogy([max(n[term], 1e-17) for n in norms], label=term)
        ax3.set_xlabel("OCP step k")
        ax3.set_ylabel("‖r_i(q_k)‖ per term")
        ax3.legend(fontsize=7)
        ax3.grid(True, which="both", alpha=0.3)
    figure.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{objective.system.name}_objectives.png"
    figure.savefig(path, dpi=80)
    plt.close(figure)
    return path
