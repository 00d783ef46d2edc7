"""Structured iLQR against IPOPT on the reaching scenarios, and the cooperative MPC loop [issue 18].

    python benchmarks/ilqr.py [--repeats 3] [--N 100] [--quick]

Every scenario of ``gagen reach`` (N = 100, 2.5 s, URDF limits, exact: ‖e(q_N)‖ ≤ 1e-9) solved by
IPOPT through the generated CasADi ``task`` Function (``gagen.control.ocp.reach``, cold start, the NLP
already built) and by ``gagen.control.ilqr.ILQR`` on the generated C ``task`` kernel, side by side in
one run: medians of the repeats, iterations, ‖e‖, and the running cost Σ uᵀRu of both (the same
optimum, or iLQR's lower: a different local minimum). Then the MPC demo (``gagen mpc``: three Pandas,
100 Hz, N = 50) for its solve times per tick and deadline misses. Not part of the test suite.
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

from gagen.apps.cooperative import scenarios  # noqa: E402
from gagen.apps.cooperative.bundled import bundled_systems  # noqa: E402
from gagen.apps.cooperative.mpc_demo import SYSTEM, setup  # noqa: E402
from gagen.check import joint_limits  # noqa: E402
from gagen.control.ilqr import ILQR  # noqa: E402
from gagen.control.mpc import run as mpc_run  # noqa: E402
from gagen.control.ocp import DEFAULT_R, reach, target_from  # noqa: E402


def timed(f, repeats: int):
    results, times = [], []
    for _ in range(repeats):
        started = time.perf_counter()
        results.append(f())
        times.append(time.perf_counter() - started)
    return results[-1], statistics.median(times)


def scenario_row(name: str, s: scenarios.Scenario, N: int, repeats: int) -> list[str]:
    """One table row: IPOPT (NLP built beforehand) and iLQR on one scenario, cold starts."""
    m, q0, limits = scenarios.module(s.system), scenarios.ready(s.system), scenarios.joint_limits(s.system)
    V_Sd = target_from(np.array(m.c.similarity(q0)[0]), s.translation, s.rotation, s.dilation,
                       kind=m.manifest["primitive"])
    reach(m, q0, V_Sd, N=N, limits=limits)  # build the NLP once, outside the timing
    ipopt, ipopt_s = timed(lambda: reach(m, q0, V_Sd, N=N, limits=limits), repeats)
    solver = ILQR(m.c.task, q0.size, N=N)
    ilqr, ilqr_s = timed(lambda: solver.solve(q0, V_Sd, limits=limits), repeats)
    effort = [DEFAULT_R * float(np.sum(r.u ** 2)) for r in (ipopt, ilqr)]
    print(f"  {name}: IPOPT {ipopt_s * 1e3:.0f} ms, iLQR {ilqr_s * 1e3:.1f} ms", file=sys.stderr, flush=True)
    return [f"{name} ({q0.size} DOF)", f"{ipopt_s * 1e3:.0f} ms ({ipopt.iterations} it)",
            f"{ilqr_s * 1e3:.1f} ms ({ilqr.iterations} it, {ilqr.updates} updates)",
            f"**{ipopt_s / ilqr_s:.0f}×**", f"{ipopt.error_norm:.1e} / {ilqr.error_norm:.1e}",
            f"{effort[1] / effort[0]:.6f}"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--N", type=int, default=100)
    parser.add_argument("--quick", action="store_true", help="one repeat, a 1 s MPC run")
    args = parser.parse_args()
    repeats = 1 if args.quick else args.repeats
    began = time.perf_counter()
    rows = [scenario_row(name, s, args.N, repeats) for name, s in scenarios.SCENARIOS.items()]
    module, q0, target = setup()
    limits = joint_limits(bundled_systems()[SYSTEM])[:2]
    mpc = mpc_run(module.c.task, target, q0, rate=100.0, duration=1.0 if args.quick else 4.0, limits=limits)
    solve_ms = mpc.solve_time * 1e3
    print("# iLQR and MPC benchmark\n\n`python benchmarks/ilqr.py`\n\n" + machine())
    print(f"- reaching: N = {args.N}, 2.5 s, URDF limits, ‖e(q_N)‖ ≤ 1e-9 (exact); IPOPT cold with the NLP "
          f"built, iLQR cold; medians of {repeats}\n")
    print(table(["scenario", "IPOPT (gagen task, exact Hessian)", "iLQR (structured, C task kernel)",
                 "IPOPT ÷ iLQR", "‖e‖ IPOPT / iLQR", "effort iLQR ÷ IPOPT"], "lrrrrr", rows))
    print(f"\nMPC (`gagen mpc`: three Pandas, 100 Hz, N = 50 over 0.2 s, {len(solve_ms)} ticks): solve time "
          f"median {np.median(solve_ms):.2f} ms, 95 % {np.percentile(solve_ms, 95):.2f} ms, worst "
          f"{solve_ms.max():.2f} ms; deadline misses at 100 Hz: {mpc.deadline_misses}; tracking error after "
          f"1 s: worst {mpc.tracking_error[100:].max():.2e}.")
    print(f"\n_whole run {time.perf_counter() - began:.0f} s_")
    return 0


if __name__ == "__main__":
    sys.exit(main())
