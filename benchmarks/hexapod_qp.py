"""The hexapod's force-distribution QP (``gagen.apps.hexapod.statics``): ProxQP against OSQP on the QPs of
the bundled walk (flat and 10° slope, every sample: 3 stance feet, 9 forces, 6 balance rows, 27
inequalities), residuals recomputed here, a markdown table on stdout.

    .venv/bin/python benchmarks/hexapod_qp.py    # ~10 s; OSQP comes with the bench extra

Rows: ProxQP (dense, eps_abs 1e-12, as gagen uses it); OSQP 1.x with its defaults (eps 1e-3, no
polish), tightened (eps_abs 1e-9, eps_rel 0, 1e5 iterations) and polished (defaults + polish). The
balance residual is max |Σ f + m g|, |Σ (p − c) × f| (N, N·m); the cone violation max(C f − u, l − C f).
Times: median wall time of ``solve()`` per QP (setup excluded), Python calls included. Not part of the
test suite.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from gagen.apps.hexapod import gait, gait_statics
from gagen.apps.hexapod.mass import default_mass_model, total_mass
from gagen.apps.hexapod.spec import load_hexapod
from gagen.apps.hexapod.statics import GRAVITY, force_problem
from gagen.runtime import load


def problems() -> list[dict[str, Any]]:
    hexapod = load_hexapod(gait.SPEC)
    module = load("generated/hexapod")
    mass = default_mass_model(hexapod)
    out = []
    for slope in (0.0, 10.0):
        result = gait.walk(module, hexapod, ground=gait.Ground(math.radians(slope)))
        com = gait_statics.centre_of_mass_along(hexapod, mass, result.body, result.q)
        for k in range(len(result.t)):
            feet = result.toes[k, result.stance[k]]
            out.append(force_problem(feet, com[k], total_mass(mass), GRAVITY, result.ground.normal, 0.5))
    return out


def hard_problems(count: int = 400) -> list[dict[str, Any]]:
    """Random stances (3-6 feet on planes tilted up to 30°, mu 0.2-1, f_min 0-2 N), about half of them
    infeasible, each with scipy's HiGHS LP verdict on feasibility (``feasible``)."""
    from scipy.optimize import linprog

    rng = np.random.default_rng(0)
    out = []
    for _ in range(count):
        k, slope, azimuth = int(rng.integers(3, 7)), rng.uniform(0, 0.5), rng.uniform(0, 2 * math.pi)
        axis = np.array([math.cos(azimuth), math.sin(azimuth), 0.0])
        r = gait.rotation(axis, slope)
        angles = np.sort(rng.uniform(0, 2 * math.pi, k))
        flat = np.column_stack([0.3 * np.cos(angles), 0.3 * np.sin(angles), rng.uniform(-0.02, 0.02, k)])
        feet = flat @ r.T
        com = r @ np.r_[rng.uniform(-0.1, 0.1, 2), 0.15]
        p = force_problem(feet, com, 2.5, GRAVITY, r[:, 2], rng.uniform(0.2, 1.0), 8, rng.uniform(0, 2))
        upper, lower = p["u"] < 1e19, p["l"] > -1e19
        lp = linprog(np.zeros(3 * k), A_ub=np.vstack([p["C"][upper], -p["C"][lower]]),
                     b_ub=np.r_[p["u"][upper], -p["l"][lower]], A_eq=p["A"], b_eq=p["b"],
                     bounds=[(None, None)] * (3 * k), method="highs")
        p["feasible"] = lp.status == 0
        out.append(p)
    return out


def proxqp(p: dict[str, Any]) -> tuple[np.ndarray, float, int, str]:
    import proxsuite  # type: ignore[import-untyped]

    qp = proxsuite.proxqp.dense.QP(len(p["H"]), 6, len(p["C"]))
    qp.settings.eps_abs, qp.settings.eps_rel, qp.settings.max_iter = 1e-12, 0.0, 100  # as statics.py
    qp.init(p["H"], np.zeros(len(p["H"])), p["A"], p["b"], p["C"], p["l"], p["u"])
    start = time.perf_counter()
    qp.solve()
    elapsed = time.perf_counter() - start
    return np.array(qp.results.x), elapsed, int(qp.results.info.iter), qp.results.info.status.name


def osqp_solver(**settings: Any) -> Callable[[dict[str, Any]], tuple[np.ndarray, float, int, str]]:
    def solve(p: dict[str, Any]) -> tuple[np.ndarray, float, int, str]:
        import osqp  # type: ignore[import-not-found]  # not a gagen dependency
        from scipy import sparse

        a = sparse.csc_matrix(np.vstack([p["A"], p["C"]]))
        lower = np.r_[p["b"], np.maximum(p["l"], -np.inf)]
        upper = np.r_[p["b"], p["u"]]
        solver = osqp.OSQP()
        solver.setup(sparse.csc_matrix(np.triu(p["H"])), np.zeros(len(p["H"])), a, lower, upper,
                     verbose=False, **settings)
        start = time.perf_counter()
        res = solver.solve()
        elapsed = time.perf_counter() - start
        return np.asarray(res.x), elapsed, int(res.info.iter), str(res.info.status)
    return solve


def table(qps: list[dict[str, Any]], rows: list[tuple[str, Callable[..., Any]]]) -> None:
    print("| solver | max balance residual | median balance residual | max cone violation | median "
          "iterations | median time per QP | not solved (feasible) | infeasible found (of infeasible) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, solve in rows:
        balance, violation, times, iters, failed, found = [], [], [], [], 0, 0
        for p in qps:
            x, elapsed, it, status = solve(p)
            if not p.get("feasible", True):
                found += "infeasible" in status.lower()
                continue
            times.append(elapsed)
            iters.append(it)
            if status.lower() not in ("proxqp_solved", "solved") or not np.all(np.isfinite(x)):
                failed += 1
                continue
            balance.append(float(np.abs(p["A"] @ x - p["b"]).max()))
            violation.append(float(np.maximum(np.maximum(p["C"] @ x - p["u"], p["l"] - p["C"] @ x), 0).max()))
        infeasible = sum(not p.get("feasible", True) for p in qps)
        print(f"| {name} | {max(balance):.1e} | {statistics.median(balance):.1e} | {max(violation):.1e} | "
              f"{statistics.median(iters):.0f} | {1e6 * statistics.median(times):.0f} µs | "
              f"{failed} ({len(qps) - infeasible}) | {found} ({infeasible}) |")


def main() -> None:
    rows = [("ProxQP 0.8, eps_abs 1e-12", proxqp),
            ("OSQP 1.x defaults (eps 1e-3)", osqp_solver()),
            ("OSQP eps_abs 1e-9, eps_rel 0", osqp_solver(eps_abs=1e-9, eps_rel=0.0, max_iter=100_000)),
            ("OSQP defaults + polish", osqp_solver(polishing=True))]
    walk = problems()
    print(f"The bundled walk's {len(walk)} QPs (flat and 10°; 9 forces, 6 balance rows, 27 inequalities):\n")
    table(walk, rows)
    hard = hard_problems()
    print(f"\n{len(hard)} random stances (3-6 feet, slopes to 30°, mu 0.2-1, f_min 0-2 N; feasibility by "
          "HiGHS):\n")
    table(hard, rows)


if __name__ == "__main__":
    main()
