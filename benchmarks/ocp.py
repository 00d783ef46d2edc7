"""Reaching OCP benchmark: the three-Panda circle (21 DOF), N = 100, T = 2.5 s, solved by IPOPT.

    python benchmarks/ocp.py [--N 100] [--repeats 5] [--no-external] [--scenarios] [--solvers]

The same NLP (``gagen.control.ocp.ReachingOCP``: multiple shooting, exact Hessian, multiplier updates
until ‖e(q_N)‖ <= 1e-9) with the terminal error e(q_N) supplied six ways:

1. ``flat SX``: the generated ``task`` CasADi Function (an SX graph) called on the NLP's MX symbols
   and ``expand=True``: the whole NLP, kernel included, becomes one flat SX graph; CasADi's AD sees
   every scalar operation (this is what ``reach`` does by default);
2. ``SX call node``: the same call, ``expand=False``: the kernel stays one call node of an MX graph;
   its derivatives are the SX Function's own derivative Functions;
3. ``MX wrapper``: the kernel wrapped in an MX Function (``task_mx(q, V) = task(q, V)`` built on MX
   symbols), so the NLP calls an MX Function that calls the SX one; ``expand=False``: nothing is
   flattened, every derivative goes through the MX layer;
4. ``MX wrapper, expand``: the same wrapper with ``expand=True`` (flattened again);
5. ``GA formulas on MX``: the model's formulas run on the interpreter's operations over MX symbols
   (``benchmarks/mx_baseline.py``: dense product tables as DM matrices, no flattening, no CSE):
   the unflattened formulation the generated kernels are measured against;
6. ``C external``: gagen's compiled C kernel (``<system>_task``, the same doubles as the CasADi
   Function) through ``casadi.external``: a small C shim implements CasADi's external-function API
   for e and its Jacobian (J_Be from the kernel); the Hessian is taken by CasADi's finite differences
   of that exact Jacobian (``enable_fd``), as a compiled kernel has no second derivatives.

Reported: the time to build the NLP and IPOPT's derivative Functions, IPOPT iterations (summed over
the multiplier updates), the wall time of a cold solve (median of --repeats), the part of it spent in
the NLP's Functions (CasADi's t_wall_nlp_* statistics; the rest is IPOPT, mostly MUMPS on the KKT
system) and the final ‖e‖. All variants build the dynamics and running cost as the same flat SX
Function (one call node when not expanded); only the terminal error's form changes. The
target: the circle at N = 100 converges (‖e‖ < 1e-6) in <= 1 s wall.

``--solvers``: every scenario of ``gagen reach`` with the generated kernel (flat SX NLP) solved three
ways: IPOPT with the exact Hessian, IPOPT with the Gauss-Newton Hessian (``hess_lag``: 2R on u_k,
2 J_Beᵀ Q J_Be on q_N) and FATROP (CasADi's structure-exploiting plugin, exact Hessian, the same NLP with
its stage structure stated). Ratios are against IPOPT-gagen with the exact Hessian (the conventional
IPOPT baseline is benchmarks/ocp_conventional.py). ``--solvers-only`` skips the tables above.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.mx_baseline import task_mx  # noqa: E402
from gagen.apps.cooperative import scenarios  # noqa: E402
from gagen.apps.cooperative.bundled import bundled_systems  # noqa: E402
from gagen.codegen.compiler import FLAGS, find_compiler  # noqa: E402
from gagen.control.ocp import ReachingOCP, target_from  # noqa: E402

SOLVER_VARIANTS = (("IPOPT, exact Hessian", "ipopt", "exact"),
                   ("IPOPT, Gauss-Newton", "ipopt", "gauss-newton"),
                   ("FATROP, exact Hessian", "fatrop", "exact"))

SYSTEM = "three_pandas_circle"

SHIM = r"""
/* CasADi external-function API around gagen's {system}_task kernel: task_e(q, V_Sd) -> e and its
   Jacobian jac_task_e(q, V_Sd, e) -> (de/dq = J_Be, de/dV_Sd: not provided, structurally zero: V_Sd
   is an NLP parameter, never differentiated here). */
#include "{system}.h"
typedef long long int casadi_int;
typedef double casadi_real;

static const casadi_int s_q[3] = {{{m}, 1, 1}};
static const casadi_int s_v[3] = {{12, 1, 1}};
static const casadi_int s_e[3] = {{7, 1, 1}};
static const casadi_int s_jq[3] = {{7, {m}, 1}};
static const casadi_int s_jv[2 + 13] = {{7, 12, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}};
static double J_scratch[7 * {m}];

casadi_int task_e_n_in(void) {{ return 2; }}
casadi_int task_e_n_out(void) {{ return 1; }}
const casadi_int* task_e_sparsity_in(casadi_int i) {{ return i == 0 ? s_q : s_v; }}
const casadi_int* task_e_sparsity_out(casadi_int i) {{ (void)i; return s_e; }}
int task_e_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w) {{
  *sz_arg = 2; *sz_res = 1; *sz_iw = 0; *sz_w = 0; return 0;
}}
int task_e(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem) {{
  (void)iw; (void)w; (void)mem;
  if (res[0]) {system}_task(arg[0], arg[1], res[0], J_scratch);
  return 0;
}}

casadi_int jac_task_e_n_in(void) {{ return 3; }}
casadi_int jac_task_e_n_out(void) {{ return 2; }}
const casadi_int* jac_task_e_sparsity_in(casadi_int i) {{ return i == 0 ? s_q : i == 1 ? s_v : s_e; }}
const casadi_int* jac_task_e_sparsity_out(casadi_int i) {{ return i == 0 ? s_jq : s_jv; }}
int jac_task_e_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w) {{
  *sz_arg = 3; *sz_res = 2; *sz_iw = 0; *sz_w = 0; return 0;
}}
int jac_task_e(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem) {{
  double e[7];
  (void)iw; (void)w; (void)mem;
  if (res[0]) {system}_task(arg[0], arg[1], e, res[0]);  /* J_Be, column-major 7 x m */
  return 0;
}}
"""


def external_task(module, folder: Path) -> ca.Function:
    """gagen's C task kernel as a CasADi external Function (compiled here with gagen's own flags)."""
    m = int(module.manifest["dof"])
    shim = folder / "task_external.c"
    shim.write_text(SHIM.format(system=module.manifest["system"], m=m))
    library = folder / "libtask_external.so"
    source = module.folder / module.manifest["c_source"]
    subprocess.run([*find_compiler(), *FLAGS, "-I", str(module.folder), "-o", str(library), str(shim),
                    str(source), "-lm"], check=True)
    return ca.external("task_e", str(library), {"enable_fd": True, "der_options": {"enable_fd": True}})


def mx_wrapper(task: ca.Function, m: int) -> ca.Function:
    q, v = ca.MX.sym("q", m), ca.MX.sym("V_Sd", 12)
    return ca.Function("task_mx", [q, v], [task(q, v)[0]], ["q", "V_Sd"], ["e"])


def measure(label: str, task: ca.Function, expand: bool, q0, V_Sd, limits, N: int, repeats: int,
            options: dict | None = None, solver: str = "ipopt", hessian: str = "exact") -> dict:
    started = time.perf_counter()
    ocp = ReachingOCP(task, q0.size, N=N, expand=expand, options=options, solver=solver, hessian=hessian)
    build = time.perf_counter() - started
    runs = [ocp.solve(q0, V_Sd, limits=limits) for _ in range(repeats)]
    last = runs[-1]
    build += runs[0].build_time  # the warm-start solver, built during the first multiplier update
    return {"label": label, "expand": expand, "build": build, "iterations": last.iterations,
            "updates": last.updates, "wall": statistics.median(r.wall_time for r in runs),
            "functions": statistics.median(r.function_time for r in runs),
            "error": last.error_norm, "success": last.success, "objective": last.objective}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--N", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--no-external", action="store_true", help="skip the casadi.external variant")
    parser.add_argument("--scenarios", action="store_true",
                        help="also every paper scenario: generated kernels vs the GA formulas on MX")
    parser.add_argument("--solvers", action="store_true",
                        help="also every paper scenario: IPOPT (exact, Gauss-Newton Hessian) vs FATROP")
    parser.add_argument("--solvers-only", action="store_true", help="only the --solvers table")
    args = parser.parse_args(argv)
    if args.solvers_only:
        every_solver(args.N, args.repeats)
        return 0

    module = scenarios.module(SYSTEM)
    q0 = scenarios.ready(SYSTEM)
    limits = scenarios.joint_limits(SYSTEM)
    s = scenarios.SCENARIOS["circle"]
    V_Sd = target_from(np.array(module.c.similarity(q0)[0]), s.translation, s.rotation, s.dilation,
                       kind="circle")
    task = module.casadi.task
    m = q0.size
    variants = [
        ("generated SX Function, flat SX NLP", task, True),
        ("generated SX Function as an MX call node", task, False),
        ("MX wrapper around it (unflattened)", mx_wrapper(task, m), False),
        ("MX wrapper, expanded", mx_wrapper(task, m), True),
        ("GA formulas on MX (interpreter's operations, unflattened)", task_mx(bundled_systems()[SYSTEM]),
         False),
    ]
    rows = []
    for label, function, expand in variants:
        print(f"  {label} ...", file=sys.stderr, flush=True)
        rows.append(measure(label, function, expand, q0, V_Sd, limits, args.N, args.repeats))
    if not args.no_external:
        with tempfile.TemporaryDirectory() as tmp:
            try:
                external = external_task(module, Path(tmp))
            except (subprocess.CalledProcessError, RuntimeError, OSError) as e:
                print(f"  casadi.external skipped: {e}", file=sys.stderr)
            else:
                print("  gagen C kernel via casadi.external ...", file=sys.stderr, flush=True)
                rows.append(measure("gagen C kernel via casadi.external (FD Hessian)", external, False,
                                    q0, V_Sd, limits, args.N, args.repeats))

    print(f"\n### Reaching OCP: {SYSTEM} ({m} DOF), N = {args.N}, T = 2.5 s, IPOPT "
          f"({args.repeats} cold solves, median wall)\n")
    print("| terminal error e(q_N) from | expand | build (s) | IPOPT iterations | updates | wall (s) "
          "| of which NLP functions (s) | ms / iteration | final ‖e‖ | met (‖e‖ < 1e-6 in ≤ 1 s) |")
    print("| --- | --- | --: | --: | --: | --: | --: | --: | --: | --- |")
    for r in rows:
        met = r["success"] and r["error"] < 1e-6 and r["wall"] <= 1.0
        print(f"| {r['label']} | {r['expand']} | {r['build']:.2f} | {r['iterations']} | {r['updates']} "
              f"| {r['wall']:.3f} | {r['functions']:.3f} | {1e3 * r['wall'] / max(r['iterations'], 1):.1f} "
              f"| {r['error']:.1e} "
              f"| {'✓' if met else '✗'} |")
    if args.scenarios:
        every_scenario(args.N, args.repeats)
    if args.solvers:
        every_solver(args.N, args.repeats)
    return 0


def every_solver(N: int, repeats: int) -> None:
    """Each paper scenario, the generated task Function (flat NLP): IPOPT with the exact and the
    Gauss-Newton Hessian, FATROP; ratios against IPOPT with the exact Hessian."""
    rows = []
    for name, s in scenarios.SCENARIOS.items():
        module = scenarios.module(s.system)
        q0, limits = scenarios.ready(s.system), scenarios.joint_limits(s.system)
        V_Sd = target_from(np.array(module.c.similarity(q0)[0]), s.translation, s.rotation, s.dilation,
                           kind=module.manifest["primitive"])
        for label, solver, hessian in SOLVER_VARIANTS:
            print(f"  {name}: {label} ...", file=sys.stderr, flush=True)
            rows.append((name, q0.size, measure(label, module.casadi.task, True, q0, V_Sd, limits, N, repeats,
                                                solver=solver, hessian=hessian)))
    print(f"\n### Every scenario, N = {N}: IPOPT (exact / Gauss-Newton Hessian) vs FATROP, generated kernels "
          f"({repeats} cold solves, median wall; × = IPOPT-gagen exact wall / this wall)\n")
    print("| scenario | DOF | solver | build (s) | iterations | updates | wall (s) | ms / iteration "
          "| × vs IPOPT exact | objective | final ‖e‖ | reached |")
    print("| --- | --: | --- | --: | --: | --: | --: | --: | --: | --: | --: | --- |")
    reference: dict[str, float] = {}
    for name, dof, r in rows:
        reference.setdefault(name, r["wall"])
        print(f"| {name} | {dof} | {r['label']} | {r['build']:.2f} | {r['iterations']} | {r['updates']} "
              f"| {r['wall']:.3f} | {1e3 * r['wall'] / max(r['iterations'], 1):.1f} "
              f"| {reference[name] / r['wall']:.2f} | {r['objective']:.4e} | {r['error']:.1e} "
              f"| {'✓' if r['success'] and r['error'] < 1e-9 else '✗'} |")


def every_scenario(N: int, repeats: int) -> None:
    """Each paper scenario: the generated task Function (flat NLP) vs the GA formulas on MX."""
    rows = []
    for name, s in scenarios.SCENARIOS.items():
        module = scenarios.module(s.system)
        q0, limits = scenarios.ready(s.system), scenarios.joint_limits(s.system)
        V_Sd = target_from(np.array(module.c.similarity(q0)[0]), s.translation, s.rotation, s.dilation,
                           kind=module.manifest["primitive"])
        print(f"  {name}: generated, then GA formulas on MX ...", file=sys.stderr, flush=True)
        flat = measure("generated", module.casadi.task, True, q0, V_Sd, limits, N, repeats)
        mx = measure("MX", task_mx(bundled_systems()[s.system]), False, q0, V_Sd, limits, N, repeats)
        rows.append((name, s.system, q0.size, flat, mx))
    print(f"\n### Every scenario, N = {N}: generated kernels vs the GA formulas on MX (unflattened)\n")
    print("| scenario | system | DOF | iterations (generated / MX) | wall generated (s) | wall MX (s) "
          "| × faster | final ‖e‖ (generated / MX) |")
    print("| --- | --- | --: | --: | --: | --: | --: | --: |")
    for name, system, dof, flat, mx in rows:
        print(f"| {name} | {system} | {dof} | {flat['iterations']} / {mx['iterations']} | {flat['wall']:.3f} "
              f"| {mx['wall']:.3f} | {mx['wall'] / flat['wall']:.1f} "
              f"| {flat['error']:.1e} / {mx['error']:.1e} |")


if __name__ == "__main__":
    sys.exit(main())
