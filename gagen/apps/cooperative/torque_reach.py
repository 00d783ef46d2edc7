"""``gagen reach --dynamics``: the paper's reaching scenarios at the torque level (``gagen.control.torque``):
the system's rigid-body dynamics from its URDFs' inertias, torque and joint limits, Crocoddyl's box-FDDP.
Per scenario: a report line and a plot of the torques and the task error."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from gagen.apps.cooperative.scenario_table import Scenario
from gagen.apps.cooperative.scenarios import chosen_scenarios, module, ready
from gagen.control.goals import desired
from gagen.control.torque import TorqueOCP, TorqueResult
from gagen.robots.goals import Goal

MAX_ITERATIONS = 200
TOLERANCE = 1e-4  # ‖e‖ at the last node that counts as reached (the terminal cost is a penalty)


def solve(scenario: Scenario, *, N: int = 100, horizon: float = 2.5) -> TorqueResult:
    """The scenario's torque-level OCP from rest at the ready configuration."""
    m = module(scenario.system)
    q0 = ready(scenario.system)
    goal = scenario.goal or Goal(scenario.name, "move", scenario.title, scenario.translation,
                                 scenario.rotation, scenario.dilation)
    V_Sd = desired(goal, np.array(m.c.similarity(q0)[0]), m.manifest["primitive"])
    ocp = TorqueOCP(scenario.spec, m.c.task, N=N, dt=horizon / N)
    return ocp.solve(q0, V_Sd, max_iterations=MAX_ITERATIONS)


def plot(scenario: Scenario, result: TorqueResult, path: Path) -> Path:
    """Torques (each over its effort limit) and the task error over time."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(9, 6), layout="constrained")
    FigureCanvasAgg(figure)
    torques, errors = figure.subplots(2, 1, sharex=True)
    torques.plot(result.t[:-1], result.tau / result.torque_limit, linewidth=0.8)
    torques.set_ylabel("τ / effort limit")
    torques.set_title(f"{scenario.title}: torque-level OCP (box-FDDP)")
    errors.semilogy(result.t, np.maximum(result.errors, 1e-16))
    errors.set_ylabel("‖e(q)‖")
    errors.set_xlabel("t (s)")
    figure.savefig(path, dpi=110)
    return path


def run_command(args: argparse.Namespace) -> int:
    """``gagen reach --dynamics`` on its parsed arguments (``gagen.apps.cooperative.commands``)."""
    return run_scenarios(chosen_scenarios(args), args.out, N=args.N, horizon=args.horizon)


def run_scenarios(chosen: Sequence[Scenario], out: str | Path, *, N: int, horizon: float) -> int:
    """Solve each scenario, report and plot it; exit status 0 when every one is reached."""
    ok = True
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    for scenario in chosen:
        result = solve(scenario, N=N, horizon=horizon)
        reached = result.converged and result.error_norm <= TOLERANCE
        ok &= reached
        lower, upper = result.position_limits
        inside = bool(np.all((result.q >= lower - 1e-3) & (result.q <= upper + 1e-3)))
        torque = np.max(np.abs(result.tau) / result.torque_limit)
        print(f"{scenario.name} ({scenario.system}, {result.q.shape[1]} DOF, N = {N}): box-FDDP, torque "
              f"level: {result.iterations} iterations, {result.wall_time:.3f} s, final ‖e‖ = "
              f"{result.error_norm:.2e}, max |τ| / limit {torque:.2f}, joints within limits: {inside}")
        print(f"  {'reached' if reached else 'NOT reached'}"
              f"{'' if reached else f' (converged: {result.converged}, tolerance {TOLERANCE:g})'}",
              file=sys.stdout if reached else sys.stderr)
        print(f"  {plot(scenario, result, folder / f'{scenario.name}_torques.png')}")
    return 0 if ok else 1
