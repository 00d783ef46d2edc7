"""Torque-level cooperative reaching on Crocoddyl's box-FDDP: gagen's task residual against the conventional
formulation, side by side in one run [issue 30].

    python benchmarks/torque_ocp.py [--repeats 3] [--N 100]

For a circle goal of the three Pandas and of the three iiwa 14 (21 DOF, N = 100, 2.5 s, URDF torque
and joint limits, from rest at the ready configuration): the OCP of ``gagen.control.torque`` with
- gagen's residual: the cooperative task error e(q) and J_Be of the generated C ``task`` kernel, called
  from Python (``KernelResidual``);
- the conventional residuals a Crocoddyl user writes: each chain's flange pinned by Crocoddyl's C++
  ``ResidualModelFrameTranslation`` at the points of gagen's solution (the same circle).
gagen's residual runs twice: the C++ one (``crocoddyl_residual.cpp``: the kernel called from Crocoddyl's
loop) and the Python one. Per row: the median solve time, iterations, time per iteration, the Python
residual's kernel calls' share of it (timed; the C++ residuals run inside Crocoddyl, untimed), and the
final task error ‖e‖ from gagen's kernel. Not part of the test suite.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

BENCH = Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH))

from run import machine, table  # noqa: E402 -- benchmarks/ is not a package

from gagen.apps.cooperative.scenarios import module, ready, spec_of  # noqa: E402
from gagen.control.goals import desired  # noqa: E402
from gagen.control.torque import TorqueOCP  # noqa: E402
from gagen.robots.goals import Goal  # noqa: E402

# the goal of each: the Pandas' circle scenario (lift 0.1 m, tilt 0.2 rad, ×1.3); the iiwas reach a milder
# one (lift 0.05 m, tilt 0.1 rad, ×1.1): the first is outside their joint limits, kinematically too
GOALS = {"three_pandas_circle": Goal("circle", "move", "", (0.0, 0.0, 0.1), ((1.0, 0.0, 0.0), 0.2), 1.3),
         "three_iiwas_circle": Goal("circle", "move", "", (0.0, 0.0, 0.05), ((1.0, 0.0, 0.0), 0.1), 1.1)}


class Timed:
    """A kernel whose calls are timed (the residual's share of the solve)."""

    def __init__(self, kernel) -> None:
        self.kernel, self.seconds, self.calls = kernel, 0.0, 0

    def __call__(self, *args):
        start = time.perf_counter()
        out = self.kernel(*args)
        self.seconds += time.perf_counter() - start
        self.calls += 1
        return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--N", type=int, default=100)
    args = parser.parse_args()
    rows = []
    for system, goal in GOALS.items():
        m = module(system)
        q0 = ready(system)
        V_Sd = desired(goal, np.array(m.c.similarity(q0)[0]), m.manifest["primitive"])
        task = Timed(m.c.task)
        python = TorqueOCP(spec_of(system), task, N=args.N, dt=2.5 / args.N, native=False)
        native = TorqueOCP(spec_of(system), m.c.task, N=args.N, dt=2.5 / args.N, native=True)
        points = None
        rows_of = (("gagen task residual, C++ (the C kernel called by Crocoddyl)", native, ""),
                   ("gagen task residual, Python (KernelResidual)", python, ""),
                   ("conventional: 3 frame translations (C++)", native, "points"),
                   ("conventional: circle error by 3-vector algebra (Python)", native, "circle"))
        for label, ocp, conventional in rows_of:
            times, shares = [], []
            for _ in range(args.repeats):
                task.seconds = 0.0
                result = ocp.solve(q0, V_Sd, points=points if conventional else None,
                                   circle=conventional == "circle")
                times.append(result.wall_time)
                shares.append(task.seconds)
            wall = statistics.median(times)
            share = f"{100 * statistics.median(shares) / wall:.0f} %" if ocp is python else "–"
            rows.append([system, label, f"{wall * 1e3:.0f}", result.iterations,
                         f"{wall / result.iterations * 1e3:.1f}", share,
                         f"{result.error_norm:.1e}", "yes" if result.converged else "no"])
            if points is None:
                points = ocp.end_points(result.q[-1])  # the conventional targets: gagen's solution's points
    print(f"# Torque-level reaching, box-FDDP (Crocoddyl)\n\n{machine()}\n")
    print(table(["scenario", "residual", "solve ms (median)", "iterations", "ms / iteration",
                 "residuals' share", "final ‖e‖", "converged"], "llrrrrrl", rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
