"""FATROP and the Gauss-Newton Hessian for the reaching OCP (gagen.control.ocp, ``solver`` / ``hessian``).

FATROP solves every ``gagen reach`` scenario (N = 15) and is held to the same solver-free checks as
IPOPT (``check_reached``, ``check_dynamics_and_bounds`` from test_ocp.py: the C kernel's e at q_N, the
target primitive built on the interpreter, the double-integrator recursion written out, the URDF
limits), and to IPOPT's optimum on the same NLP. The Gauss-Newton Hessian handed to IPOPT is checked
against 2R and 2 J_Beᵀ Q J_Be with J_Be from central differences of the C kernel's e, and against
CasADi's exact Hessian where the terminal residual vanishes (there the two coincide).
"""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from test_ocp import check_dynamics_and_bounds, check_reached, circle_problem

from gagen.apps.cooperative import scenarios
from gagen.cli import main as gagen_main
from gagen.control.ocp import BLADES, ReachingOCP, reach, target_from

N = 15


@pytest.fixture(scope="module")
def solved() -> dict[str, tuple[scenarios.ScenarioResult, scenarios.ScenarioResult]]:
    """(FATROP, IPOPT) on every scenario."""
    return {name: (scenarios.run(name, N=N, solver="fatrop"), scenarios.run(name, N=N))
            for name in scenarios.SCENARIOS}


@pytest.mark.compiling
@pytest.mark.slow
@pytest.mark.parametrize("name", list(scenarios.SCENARIOS))
def test_fatrop_reaches_every_scenario(solved, name):
    fatrop, ipopt = solved[name]
    assert fatrop.result.solver == "fatrop" and ipopt.result.solver == "ipopt"
    check_reached(fatrop)
    check_dynamics_and_bounds(fatrop, N)
    # the same NLP, solved to the same optimum from the same start
    assert fatrop.result.objective == pytest.approx(ipopt.result.objective, rel=1e-5), name
    assert np.abs(fatrop.result.q - ipopt.result.q).max() < 1e-3, name


def test_fatrop_with_binding_limits():
    """A ±0.25 rad box around q0 binds (test_ocp.test_joint_limits_bind): FATROP stays inside it (stage
    bounds), reaches the circle exactly and agrees with IPOPT."""
    m, q0, V_Sd = circle_problem()
    box = (q0 - 0.25, q0 + 0.25)
    fatrop = reach(m, q0, V_Sd, N=10, limits=box, solver="fatrop")
    ipopt = reach(m, q0, V_Sd, N=10, limits=box)
    assert fatrop.success and fatrop.error_norm < 1e-9 and fatrop.updates >= 1, fatrop.message
    assert np.linalg.norm(m.c.task(fatrop.q[-1], V_Sd)[0]) < 1e-9
    assert np.all(fatrop.q >= box[0] - 1e-7) and np.all(fatrop.q <= box[1] + 1e-7)
    assert np.abs(fatrop.q - q0).max() > 0.249
    assert np.abs(fatrop.qdot[-1]).max() < 1e-9 and fatrop.dynamics_residual() < 1e-10
    assert fatrop.objective == pytest.approx(ipopt.objective, rel=1e-5)
    # a warm start from its own solution: the primal point only (FATROP takes no multipliers), so not
    # IPOPT's one or two iterations, but under half of the cold solve's (43 → 18 when written)
    again = reach(m, q0, V_Sd, N=10, limits=box, solver="fatrop", warm_start=fatrop)
    assert again.success and again.iterations <= fatrop.iterations // 2
    assert np.abs(again.q - fatrop.q).max() < 1e-8


def test_invalid_solver_and_hessian():
    m, q0, _ = circle_problem()
    with pytest.raises(ValueError, match="solver"):
        ReachingOCP(m.casadi.task, q0.size, N=5, solver="snopt")
    with pytest.raises(ValueError, match="hessian"):
        ReachingOCP(m.casadi.task, q0.size, N=5, hessian="bfgs")
    with pytest.raises(ValueError, match="Gauss-Newton"):
        ReachingOCP(m.casadi.task, q0.size, N=5, solver="fatrop", hessian="gauss-newton")


# -- the Gauss-Newton Hessian ---------------------------------------------------------------------------
def jacobian_fd(m, q, V_Sd, h: float = 1e-6) -> np.ndarray:
    """∂e/∂q by central differences of the C kernel's e."""
    columns = []
    for j in range(q.size):
        step = np.zeros(q.size)
        step[j] = h
        plus, minus = np.array(m.c.task(q + step, V_Sd)[0]), np.array(m.c.task(q - step, V_Sd)[0])
        columns.append((plus - minus) / (2 * h))
    return np.array(columns).T


def test_gauss_newton_hessian_blocks():
    """hess_lag(w, p, σ, λ) = σ blockdiag(2R, 0, …, 2R, [2 JᵀQJ, 0; 0, 0]) (upper triangle), J by finite
    differences; λ (the dynamics' multipliers) does not enter."""
    m, q0, V_Sd = circle_problem()
    dof, steps = q0.size, 4
    R = np.diag(np.linspace(1e-6, 3e-6, dof))
    Q = np.diag(np.linspace(1.0, 2.0, len(BLADES)))
    ocp = ReachingOCP(m.casadi.task, dof, N=steps, R=R, Q=Q, hessian="gauss-newton")
    hess = ocp._options["hess_lag"]
    rng = np.random.default_rng(3)
    w = rng.normal(scale=0.1, size=steps * 3 * dof)
    w[-2 * dof: -dof] += q0  # q_N
    p = np.concatenate([q0, np.zeros(dof), V_Sd, rng.normal(scale=0.01, size=len(BLADES))])
    sigma = 0.7
    H = np.array(ca.densify(hess(w, p, sigma, rng.normal(size=2 * dof * steps))))
    assert np.allclose(H, np.triu(H))  # the upper triangle, as IPOPT's hess_lag
    J = jacobian_fd(m, w[-2 * dof: -dof], V_Sd)
    expected = np.zeros_like(H)
    for k in range(steps):
        expected[3 * dof * k: 3 * dof * k + dof, 3 * dof * k: 3 * dof * k + dof] = 2 * sigma * R
    end = 3 * dof * steps - 2 * dof
    expected[end: end + dof, end: end + dof] = np.triu(2 * sigma * J.T @ Q @ J)
    assert np.abs(H - expected).max() < 1e-7 * np.abs(expected).max()


def test_gauss_newton_is_exact_at_zero_residual():
    """Where e(q_N) = s (zero terminal residual) the dropped term Σ (Q(e − s))ᵢ ∇²eᵢ vanishes: the
    Gauss-Newton Hessian equals CasADi's exact Hessian of the Lagrangian of the same NLP."""
    m, q0, V_Sd = circle_problem()
    dof, steps = q0.size, 3
    ocp = ReachingOCP(m.casadi.task, dof, N=steps, hessian="gauss-newton")
    nlp = ocp._nlp
    w_sym, p_sym, lam_g = nlp["x"], nlp["p"], ca.MX.sym("lam_g", nlp["g"].numel())
    exact = ca.Function("exact", [w_sym, p_sym, lam_g],
                        [ca.triu(ca.hessian(nlp["f"] + ca.dot(lam_g, nlp["g"]), w_sym)[0])])
    rng = np.random.default_rng(5)
    w = rng.normal(scale=0.1, size=steps * 3 * dof)
    w[-2 * dof: -dof] += q0
    shift = np.array(m.c.task(w[-2 * dof: -dof], V_Sd)[0])
    p = np.concatenate([q0, np.zeros(dof), V_Sd, shift])
    lam = rng.normal(size=2 * dof * steps)
    H_exact = np.array(ca.densify(exact(w, p, lam)))
    H_gn = np.array(ca.densify(ocp._options["hess_lag"](w, p, 1.0, lam)))
    assert np.abs(H_gn - H_exact).max() < 1e-12 * np.abs(H_exact).max()
    # elsewhere the two differ (the kernel's second derivatives are not zero)
    p[-len(BLADES):] = 0.0
    H_exact = np.array(ca.densify(exact(w, p, lam)))
    H_gn = np.array(ca.densify(ocp._options["hess_lag"](w, p, 1.0, lam)))
    assert np.abs(H_gn - H_exact).max() > 1e-3 * np.abs(H_exact).max()


def test_gauss_newton_reaches_a_solution_of_the_same_nlp():
    """Only the Hessian changes, not the problem: Gauss-Newton reaches the target exactly at a KKT point
    of the same NLP, which IPOPT with the exact Hessian, started there, accepts (it moves nowhere). On
    the circle at N = 10 that is another local optimum than the exact Hessian's path finds (a PSD model
    never sees the negative curvature that steers it; 1.89e-6 vs 1.86e-6), on the line the same one."""
    m, q0, V_Sd = circle_problem()
    limits = scenarios.joint_limits("three_pandas_circle")
    gn = reach(m, q0, V_Sd, N=10, limits=limits, hessian="gauss-newton")
    assert gn.success and gn.error_norm < 1e-9 and gn.status == "Solve_Succeeded", gn.message
    assert np.linalg.norm(m.c.task(gn.q[-1], V_Sd)[0]) < 1e-9
    assert gn.dynamics_residual() < 1e-10 and np.abs(gn.qdot[-1]).max() < 1e-12
    exact = ReachingOCP(m.casadi.task, q0.size, N=10).solve(q0, V_Sd, limits=limits, warm_start=gn)
    assert exact.success and exact.iterations <= 2
    assert np.abs(exact.q - gn.q).max() < 1e-4 and exact.objective == pytest.approx(gn.objective, rel=1e-6)
    s = scenarios.SCENARIOS["line"]
    m, q0 = scenarios.module(s.system), scenarios.ready(s.system)
    V_Sd = target_from(np.array(m.c.similarity(q0)[0]), s.translation, s.rotation, kind="line")
    limits = scenarios.joint_limits(s.system)
    exact, gn = (reach(m, q0, V_Sd, N=10, limits=limits, hessian=h) for h in ("exact", "gauss-newton"))
    assert gn.success and gn.error_norm < 1e-9
    assert gn.objective == pytest.approx(exact.objective, rel=1e-6) and np.abs(gn.q - exact.q).max() < 1e-4


@pytest.mark.compiling
def test_command_line_solver_options(tmp_path: Path, capsys):
    assert gagen_main(["reach", "plane", "--out", str(tmp_path), "--N", "10", "--solver", "fatrop"]) == 0
    out = capsys.readouterr().out
    assert "plane (leap_three_fingers_plane, 12 DOF, N = 10): fatrop, exact Hessian:" in out
    assert "reached" in out
    assert gagen_main(["reach", "line", "--out", str(tmp_path), "--N", "10",
                       "--hessian", "gauss-newton"]) == 0
    assert "N = 10): ipopt, gauss-newton Hessian:" in capsys.readouterr().out
