"""Structured iLQR for cooperative reaching (gagen.control.ilqr) against independent computations: the
textbook iLQR step (a full Riccati pass, no structure), finite differences of the terminal cost, the
double-integrator recursion written out, the URDF limits, the target primitive, and IPOPT's solution."""

from __future__ import annotations

import numpy as np
import pytest

from gagen.apps.cooperative import scenarios
from gagen.control.ilqr import ILQR, dense_ilqr_step, gramian
from gagen.control.ocp import BLADES, double_integrator, reach, target_from

N = 15


def _problem(name: str):
    s = scenarios.SCENARIOS[name]
    m = scenarios.module(s.system)
    q0 = scenarios.ready(s.system)
    V_Sd = target_from(np.array(m.c.similarity(q0)[0]), s.translation, s.rotation, s.dilation,
                       kind=m.manifest["primitive"])
    return m, q0, V_Sd, scenarios.joint_limits(s.system)


def test_gramian_controls_reach_the_state_with_least_effort():
    """The closed-form least-effort controls reach the asked terminal state (recursion written out) and
    any other controls that reach it cost more."""
    rng = np.random.default_rng(0)
    dt, steps, r = 0.05, 30, np.array([1e-3, 2.0])
    g = gramian(steps, dt, r)
    for j in range(2):
        start, goal = rng.normal(size=2), rng.normal(size=2)
        free = np.array([start[0] + steps * dt * start[1], start[1]])
        u = g.gamma @ (g.inverse[j] @ (goal - free)) / r[j]
        x = start.copy()
        for k in range(steps):
            x = np.array([x[0] + dt * x[1] + 0.5 * dt * dt * u[k], x[1] + dt * u[k]])
        assert np.abs(x - goal).max() <= 1e-12 * max(1.0, np.abs(goal).max())
        other = u + np.linalg.svd(g.gamma.T)[2][-1]  # the same end state: add a null direction of Γᵀ
        assert np.abs(g.gamma.T @ (other - u)).max() <= 1e-12
        assert r[j] * other @ other > r[j] * u @ u


@pytest.mark.parametrize("seed", range(3))
def test_structured_step_is_the_textbook_ilqr_step(seed):
    """From arbitrary controls, one iLQR step with the full Riccati recursion (2m × 2m matrices) and the
    Gauss-Newton model of the terminal cost lands on the same controls as the structured step: the
    least-effort controls to q_N + δ, δ from the m × m (Woodbury) Gauss-Newton system."""
    m, q0, V_Sd, _ = _problem("circle")
    rng = np.random.default_rng(seed)
    R = rng.uniform(0.5, 2.0, q0.size) * 1e-3
    solver = ILQR(m.c.task, q0.size, N=N, R=R, rest=False)
    qdot0 = rng.uniform(-0.2, 0.2, q0.size)
    u = rng.normal(scale=0.05, size=(N, q0.size))
    A, B = double_integrator(q0.size, solver.dt)
    x = np.concatenate([q0, qdot0])
    for k in range(N):
        x = A @ x + B @ u[k]
    shift = rng.normal(scale=1e-3, size=len(BLADES))
    e, J = (np.asarray(v, dtype=float) for v in m.c.task(x[: q0.size], V_Sd))
    Q = solver.Q
    gradient = np.concatenate([2 * J.T @ Q @ (e - shift), np.zeros(q0.size)])
    hessian = np.zeros((2 * q0.size, 2 * q0.size))
    hessian[: q0.size, : q0.size] = 2 * J.T @ Q @ J
    dense = dense_ilqr_step(A, B, np.diag(R), np.concatenate([q0, qdot0]), u, gradient, hessian)
    a, c = solver._terminal_quadratic(q0, qdot0)
    step = solver.gauss_newton_step(x[: q0.size], a, c, e, J, shift, np.zeros(q0.size, dtype=bool))
    _, _, structured = solver.trajectory(q0, qdot0, x[: q0.size] + step)
    assert np.abs(structured - dense).max() <= 1e-9 * np.abs(dense).max()


@pytest.mark.parametrize("seed", range(3))
def test_terminal_gradient_and_gauss_newton_hessian(seed):
    """The terminal cost ‖e(q) − s‖²_Q: its gradient 2 J_Beᵀ Q (e − s) against central differences of the
    C kernel's e; at e = s (zero residual) its Hessian equals the Gauss-Newton 2 J_Beᵀ Q J_Be, against
    differences of that gradient."""
    m, q0, V_Sd, _ = _problem("circle")
    rng = np.random.default_rng(seed)
    q = q0 + rng.uniform(-0.2, 0.2, q0.size)
    Q = np.diag(rng.uniform(0.5, 2.0, len(BLADES)))
    shift = rng.normal(scale=0.1, size=len(BLADES))

    def cost(x, s):
        e = np.asarray(m.c.task(x, V_Sd)[0])
        return float((e - s) @ Q @ (e - s))

    def gradient(x, s):
        e, J = (np.asarray(v) for v in m.c.task(x, V_Sd))
        return 2 * J.T @ Q @ (e - s)

    h = 1e-6
    steps = np.eye(q.size) * h
    fd = np.array([(cost(q + d, shift) - cost(q - d, shift)) / (2 * h) for d in steps])
    assert np.abs(gradient(q, shift) - fd).max() <= 1e-7 * np.abs(fd).max()
    at_target = np.asarray(m.c.task(q, V_Sd)[0])
    J = np.asarray(m.c.task(q, V_Sd)[1])
    h = 1e-5
    fd_hessian = np.array([(gradient(q + d, at_target) - gradient(q - d, at_target)) / (2 * h)
                           for d in np.eye(q.size) * h]).T
    assert np.abs(2 * J.T @ Q @ J - fd_hessian).max() <= 1e-6 * np.abs(fd_hessian).max()


@pytest.mark.compiling
@pytest.mark.slow
@pytest.mark.parametrize("name", list(scenarios.SCENARIOS))
def test_every_scenario_reaches_its_target(name):
    """iLQR reaches ‖e(q_N)‖ < 1e-9 on every `gagen reach` scenario, with the recursion, rest conditions
    and URDF limits checked here, and moves with no more effort than IPOPT's solution (1e-6)."""
    m, q0, V_Sd, limits = _problem(name)
    result = ILQR(m.c.task, q0.size, N=N).solve(q0, V_Sd, limits=limits)
    assert result.success, result.message
    e = np.asarray(m.c.task(result.q[-1], V_Sd)[0])
    assert np.linalg.norm(e) < 1e-9
    dt = result.dt
    predicted = result.q[:-1] + dt * result.qdot[:-1] + 0.5 * dt**2 * result.u
    assert np.abs(result.q[1:] - predicted).max() < 1e-10
    assert np.abs(result.qdot[1:] - (result.qdot[:-1] + dt * result.u)).max() < 1e-10
    assert np.array_equal(result.q[0], q0) and np.all(result.qdot[0] == 0)
    assert np.abs(result.qdot[-1]).max() < 1e-10
    lower, upper = limits
    assert np.all(result.q >= lower - 1e-9) and np.all(result.q <= upper + 1e-9)
    ipopt = reach(m, q0, V_Sd, N=N, limits=limits)
    effort = float(np.sum(result.u**2)) * 1e-6
    assert effort <= float(np.sum(ipopt.u**2)) * 1e-6 * (1 + 1e-6), (effort, name)


@pytest.mark.compiling
def test_joint_limits_bind_at_the_bound():
    """A box that the unconstrained solution leaves: iLQR stops the joint at its bound, still reaches the
    target, and every q_k stays inside."""
    m, q0, V_Sd, limits = _problem("circle")
    free = ILQR(m.c.task, q0.size, N=N).solve(q0, V_Sd, limits=limits)
    moved = int(np.argmax(np.abs(free.q[-1] - q0)))
    lower, upper = (np.array(b, dtype=float) for b in limits)
    if free.q[-1, moved] > q0[moved]:
        upper[moved] = q0[moved] + 0.5 * (free.q[-1, moved] - q0[moved])
    else:
        lower[moved] = q0[moved] + 0.5 * (free.q[-1, moved] - q0[moved])
    bound = ILQR(m.c.task, q0.size, N=N).solve(q0, V_Sd, limits=(lower, upper))
    assert bound.success, bound.message
    assert min(abs(bound.q[-1, moved] - upper[moved]), abs(bound.q[-1, moved] - lower[moved])) <= 1e-12
    assert np.all(bound.q >= lower - 1e-9) and np.all(bound.q <= upper + 1e-9)


def test_bad_weights_are_refused():
    with pytest.raises(ValueError, match="R must be diagonal and positive"):
        ILQR(lambda q, v: (q, q), 3, R=np.ones((3, 3)))
    with pytest.raises(ValueError, match="R must be diagonal and positive"):
        ILQR(lambda q, v: (q, q), 3, R=0.0)


@pytest.mark.compiling
@pytest.mark.parametrize("name", ["circle", "hand_sphere", "humanoids_sphere"])
def test_c_loop_equals_the_numpy_loop(name):
    """ilqr_loop.c (calling the kernel's C function) takes the same steps as the numpy loop: the same
    iterations and updates, q_N to 1e-12."""
    m, q0, V_Sd, limits = _problem(name)
    c, python = (ILQR(m.c.task, q0.size, N=N, backend=b).solve(q0, V_Sd, limits=limits)
                 for b in ("c", "python"))
    assert (c.iterations, c.updates, c.status) == (python.iterations, python.updates, python.status)
    assert np.abs(c.q[-1] - python.q[-1]).max() <= 1e-12
    with pytest.raises(ValueError, match="backend='c' needs a compiled kernel"):
        ILQR(lambda q, v: m.c.task(q, v), q0.size, backend="c")


@pytest.mark.compiling
def test_reach_dispatches_to_ilqr_and_refuses_what_it_cannot_do():
    """``reach(..., solver="ilqr")`` is the structured iLQR (its result labelled so); velocity limits, an
    inexact solve or another Hessian are refused with the reason."""
    m, q0, V_Sd, limits = _problem("torso_circle")
    result = reach(m, q0, V_Sd, N=N, limits=limits, solver="ilqr")
    assert result.solver == "ilqr" and result.success and result.error_norm < 1e-9
    direct = ILQR(m.c.task, q0.size, N=N).solve(q0, V_Sd, limits=limits)
    assert np.array_equal(result.q, direct.q)
    for bad in ({"velocity_limits": (-1.0, 1.0)}, {"exact": False}, {"hessian": "gauss-newton"}):
        with pytest.raises(ValueError, match="solver='ilqr' takes no velocity limits"):
            reach(m, q0, V_Sd, N=N, solver="ilqr", **bad)
