"""Reaching OCP against the honest baseline: gagen's ``task`` kernel vs the error a CasADi user writes.

    python benchmarks/ocp_conventional.py [--N 100] [--rounds 15] [--mx] [--scenarios]

The three-Panda circle (21 DOF), N = 100, T = 2.5 s: the same NLP (``gagen.control.ocp.ReachingOCP``:
multiple shooting, double integrator, uᵀRu, terminal ‖e(q_N) − s‖²_Q, joint limits as bounds, exact
Hessian, multiplier updates until ‖e(q_N)‖ <= 1e-9, IPOPT with the same options, start and target),
solved with the terminal error from

1. ``gagen``: the generated ``task`` CasADi Function (``expand=True``: one flat SX graph, as ``reach``
   does);
2. ``conventional``: adam-robotics' CasADi FK of the URDF + the circumcircle and the similarity error in
   3-vectors and quaternions (``benchmarks/conventional.py``; its e equals gagen's to ~1e-15), likewise
   ``expand=True``;
3. with ``--mx``: gagen's GA formulas run on the interpreter's operations over MX symbols, unflattened
   (``benchmarks/mx_baseline.py``): the formulation the README's old "8.7×" row compared against.

Each round solves every variant once from cold (interleaved, so a busy machine slows all alike);
reported: build time (NLP and IPOPT's derivative Functions), IPOPT iterations (summed over the
multiplier updates), the median wall time, the part spent in the NLP's Functions (CasADi's t_wall_nlp_*),
the time per call of the Lagrangian Hessian and of the objective gradient, the final ‖e‖ (evaluated by
gagen's kernel for every variant) and the wall-time ratio to the conventional baseline. "Same iterates":
the largest difference, over the cold solve's IPOPT iterations, of the objective and the primal and dual
infeasibilities, and of the final trajectories. ``--scenarios`` adds the line, plane, hand-sphere and
humanoids-sphere scenarios (conventional vs gagen). Needs adam-robotics[casadi] (the test extra).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks import conventional  # noqa: E402
from benchmarks.run import machine, table  # noqa: E402
from gagen.apps.cooperative import scenarios  # noqa: E402
from gagen.control.ocp import ReachingOCP, target_from  # noqa: E402

CIRCLE = "circle"
OTHERS = ("line", "plane", "hand_sphere", "humanoids_sphere")


def joints(module) -> list[str]:
    entry = next(k for k in module.manifest["kernels"] if k["name"] == "task")
    return entry["inputs"][0]["rows"]


class Variant:
    """One formulation: its OCP, its target parameters and the measurements of its rounds."""

    def __init__(self, label: str, task, expand: bool, target: np.ndarray, m: int, N: int,
                 build: float = 0.0) -> None:
        self.label, self.target = label, target
        started = time.perf_counter()
        self.ocp = ReachingOCP(task, m, N=N, expand=expand)
        self.build = build + time.perf_counter() - started
        self.results: list = []
        self.calls: list[dict[str, float]] = []

    def solve(self, q0, limits) -> None:
        result = self.ocp.solve(q0, self.target, limits=limits)
        if not self.results:
            self.build += result.build_time  # the warm-start solver, built at the first multiplier update
        stats = self.ocp._solver(warm=False).stats()  # of the first, cold solve of the multiplier loop
        if not self.results:
            self.cold = stats
        self.calls.append({k: stats[f"t_wall_nlp_{k}"] / max(stats[f"n_call_nlp_{k}"], 1)
                           for k in ("hess_l", "grad_f")})
        self.results.append(result)

    def per_call(self, name: str) -> float:
        """Median over the rounds of the cold solve's time per call of NLP Function ``name``."""
        return statistics.median(c[name] for c in self.calls)

    @property
    def wall(self) -> float:
        return statistics.median(r.wall_time for r in self.results)


def history(stats: dict) -> np.ndarray:
    it = stats["iterations"]
    return np.array([it["obj"], it["inf_pr"], it["inf_du"]]).T


def compare(name: str, N: int, rounds: int, mx: bool = False) -> tuple[list[Variant], dict]:
    """Solve scenario ``name`` ``rounds`` times per variant, interleaved; (variants, agreement figures)."""
    s = scenarios.SCENARIOS[name]
    module = scenarios.module(s.system)
    kind = module.manifest["primitive"]
    q0, limits = scenarios.ready(s.system), scenarios.joint_limits(s.system)
    V_Sd = target_from(np.array(module.c.similarity(q0)[0]), s.translation, s.rotation, s.dilation, kind=kind)
    started = time.perf_counter()
    baseline_task = conventional.task(s.system, kind, joints(module))
    fk_build = time.perf_counter() - started
    points = conventional.points_function(s.system, joints(module))
    target = conventional.moved(kind, [np.array(p).ravel() for p in points(q0)], s.translation, s.rotation,
                                s.dilation)
    m = q0.size
    variants = [Variant("conventional: adam FK + 3-vector algebra + quaternion log", baseline_task, True,
                        target, m, N, build=fk_build),
                Variant("gagen: generated task kernel (flat SX)", module.casadi.task, True, V_Sd, m, N)]
    if mx:
        from benchmarks.mx_baseline import task_mx
        from gagen.apps.cooperative.bundled import bundled_systems

        variants.append(Variant("GA formulas on MX (interpreter's operations, unflattened)",
                                task_mx(bundled_systems()[s.system]), False, V_Sd, m, N))
    for k in range(rounds):
        print(f"  {name}: round {k + 1}/{rounds}", file=sys.stderr, flush=True)
        for v in variants:
            v.solve(q0, limits)
    for v in variants:  # every final error measured by gagen's kernel against the same V_Sd
        v.final = float(np.linalg.norm(np.array(module.c.task(v.results[-1].q[-1], V_Sd)[0])))
    c, g = variants[0], variants[1]
    hc, hg = history(c.cold), history(g.cold)
    steps = min(len(hc), len(hg))
    agreement = {
        "e_start": float(np.abs(np.array(baseline_task(q0, target)).ravel()
                                - np.array(module.c.task(q0, V_Sd)[0]).ravel()).max()),
        "cold_iterations": (len(hc) - 1, len(hg) - 1),
        "history": np.abs(hc[:steps] - hg[:steps]).max(axis=0),
        "w": max(float(np.abs(a.w - b.w).max()) for a, b in zip(c.results, g.results, strict=True)),
        "system": s.system, "dof": m,
    }
    return variants, agreement


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--N", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--mx", action="store_true", help="also the GA formulas on MX (unflattened)")
    parser.add_argument("--scenarios", action="store_true",
                        help=f"also {', '.join(OTHERS)} (conventional vs gagen, --rounds each)")
    args = parser.parse_args(argv)

    variants, agree = compare(CIRCLE, args.N, args.rounds, args.mx)
    base = variants[0].wall
    rows = [[v.label, f"{v.build:.2f}", v.results[-1].iterations, v.results[-1].updates, f"{v.wall:.3f}",
             f"{statistics.median(r.function_time for r in v.results):.3f} "
             f"({100 * statistics.median(r.function_time / r.wall_time for r in v.results):.0f} %)",
             f"{1e3 * v.per_call('hess_l'):.2f}", f"{1e3 * v.per_call('grad_f'):.3f}", f"{v.final:.1e}",
             f"{v.wall / base:.2f}"] for v in variants]
    print(f"\n### Reaching OCP, honest baseline: {agree['system']} ({agree['dof']} DOF), N = {args.N}, "
          f"T = 2.5 s, IPOPT (exact Hessian), {args.rounds} interleaved cold solves, median wall\n")
    print(table(["terminal error e(q_N) from", "build (s)", "IPOPT iterations", "updates", "wall (s)",
                 "of which NLP functions (s)", "Hessian (ms / call)", "gradient (ms / call)",
                 "final ‖e‖ (gagen's e)", "wall / conventional"], "lrrrrrrrrr", rows))
    c, g = variants[0], variants[1]
    print(f"\nSame iterates, conventional vs gagen: {agreement_text(agree)}. Lagrangian Hessian per call, "
          f"gagen / conventional: {g.per_call('hess_l') / c.per_call('hess_l'):.2f}×; objective gradient: "
          f"{g.per_call('grad_f') / c.per_call('grad_f'):.2f}×.")
    if args.scenarios:
        rows = []
        for name in OTHERS:
            (c, g), agree = compare(name, args.N, args.rounds)
            rows.append([name, f"{agree['system']} ({agree['dof']})",
                         f"{c.results[-1].iterations} / {g.results[-1].iterations}",
                         f"{c.wall:.3f}", f"{g.wall:.3f}", f"{g.wall / c.wall:.2f}",
                         f"{c.final:.1e} / {g.final:.1e}", agreement_text(agree)])
        print(f"\n### The other scenarios, N = {args.N}: conventional vs gagen ({args.rounds} interleaved "
              f"cold solves, median wall)\n")
        print(table(["scenario", "system (DOF)", "iterations (conv. / gagen)", "wall conventional (s)",
                     "wall gagen (s)", "gagen / conventional", "final ‖e‖ (conv. / gagen)", "same iterates"],
                    "llrrrrrl", rows))
    print()
    print(machine())
    return 0


def agreement_text(a: dict) -> str:
    h = a["history"]
    return (f"cold solve {a['cold_iterations'][0]} / {a['cold_iterations'][1]} iterations, max |Δ| over them "
            f"objective {h[0]:.0e}, inf_pr {h[1]:.0e}, inf_du {h[2]:.0e}; final trajectories |Δw| "
            f"{a['w']:.0e}; e at the start {a['e_start']:.0e}")


if __name__ == "__main__":
    sys.exit(main())
