"""How many iterations the paper's reaching scenarios take, to each error level [COOP Section 4.2].

The paper says its iLQR "typically converges in five or less iterations" (Section 4.2). That holds
to a loose error only. For each scenario of Figs. 7-13 (from the spec's ``ready`` configuration to
its goal, URDF joint limits as bounds) this prints the iterations that

- ``solve_ik`` (Levenberg-Marquardt on e(q), ``gagen.control.ik``) takes until ‖e‖ first falls to
  1e-2, 1e-4, 1e-8 and 1e-12 (read from one solve's history), and
- the structured iLQR (``gagen reach --solver ilqr``; N = 250, dt = 0.01 s, the paper's 2.5 s horizon)
  takes when asked for ‖e(q_N)‖ ≤ each of those tolerances (one cold solve per tolerance),

as a markdown table (docs/paper-coop.md shows the latest).

    .venv/bin/python benchmarks/iteration_counts.py [--scenarios circle,line]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from gagen.apps.cooperative.scenario_table import SCENARIOS
from gagen.apps.cooperative.scenarios import joint_limits, module, ready
from gagen.control.goals import desired
from gagen.control.ik import solve_ik
from gagen.control.ocp import reach
from gagen.robots.goals import Goal

LEVELS = (1e-2, 1e-4, 1e-8, 1e-12)


def first_below(history: np.ndarray, level: float) -> str:
    """The first iteration whose ‖e‖ is at most ``level`` ('–' if never)."""
    hits = np.flatnonzero(history <= level)
    return str(int(hits[0])) if hits.size else "–"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", default=",".join(SCENARIOS), help="comma-separated scenario names")
    args = parser.parse_args(argv)
    levels = " / ".join(f"{v:.0e}" for v in LEVELS)
    print(f"| scenario | system | ‖e‖ at start | IK iterations to {levels} | iLQR iterations to {levels} |")
    print("|---|---|---:|---|---|")
    for name in args.scenarios.split(","):
        s = SCENARIOS[name]
        print(f"{name}: building or loading {s.system}", file=sys.stderr, flush=True)
        m = module(s.system)
        q0, limits = ready(s.system), joint_limits(s.system)
        goal = s.goal or Goal(s.name, "move", s.title, s.translation, s.rotation, s.dilation)
        V_Sd = desired(goal, np.array(m.c.similarity(q0)[0]), m.manifest["primitive"])
        ik = solve_ik(m.c.task, q0, V_Sd, tol=min(LEVELS), limits=limits, max_iterations=200)
        ik_counts = " / ".join(first_below(ik.history, level) for level in LEVELS)
        ilqr_counts = []
        for level in LEVELS:
            r = reach(m, q0, V_Sd, N=250, horizon=2.5, limits=limits, solver="ilqr", tol=level)
            reached = r.error_norm <= level
            ilqr_counts.append(str(r.iterations) if reached else f"({r.iterations}: {r.error_norm:.0e})")
        print(f"| {name} | {s.system} | {ik.history[0]:.2f} | {ik_counts} | {' / '.join(ilqr_counts)} |",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
