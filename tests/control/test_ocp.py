"""Reaching optimal control [COOP Eq. 53-57] on the bundled systems: gagen.control.ocp and .scenarios.

Every scenario is solved once (N = 15, module fixture) and held to checks that do not go through the
solver: the final primitive X_c(q_N) of the ``primitive`` kernel against X_d = V_Sd X_u V_Sd~ built
here on the interpreter, the task error re-evaluated by the C kernel, the double-integrator recursion
written out by hand, the joint limits read from the URDF files, and the target's geometry (centre,
radius, normal, direction) against the similarity it was made from.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gagen.algebra.signature import cga3d
from gagen.apps.cooperative import scenarios
from gagen.cli import main as gagen_main
from gagen.control.ocp import (
    BLADES,
    ReachingOCP,
    bivector_command,
    double_integrator,
    reach,
    target_from,
    target_primitive,
)
from gagen.interp import MultiVector
from gagen.model.conformal import SIMILARITY, e0, location
from gagen.model.primitives import centre, direction, radius, unit_normal, unit_primitive

N = 15
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def solved(tmp_path_factory) -> dict[str, scenarios.ScenarioResult]:
    out = tmp_path_factory.mktemp("ocp_plots")
    return {name: scenarios.run(name, out, N=N) for name in scenarios.SCENARIOS}


def mv(rows, values) -> MultiVector:
    return MultiVector.from_blades(cga3d(), dict(zip(rows, np.asarray(values, dtype=float), strict=True)))


def rows(module, kernel: str, port: str) -> list[str]:
    entry = next(k for k in module.manifest["kernels"] if k["name"] == kernel)
    return next(p["rows"] for p in entry["inputs"] + entry["outputs"] if p["name"] == port)


def desired_primitive(module, V_Sd) -> np.ndarray:
    """X_d = V_Sd X_u V_Sd~ on the interpreter, in the primitive kernel's row order."""
    v = mv(SIMILARITY, V_Sd)
    x_d = v * unit_primitive(module.manifest["primitive"], v) * ~v
    return np.array([x_d[r] for r in rows(module, "primitive", "X_c")])


def cosine(a, b) -> float:
    return float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)))


def xyz(v) -> np.ndarray:
    return np.array([v["e1"], v["e2"], v["e3"]])


def rotation_matrix(axis, angle) -> np.ndarray:
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


# -- every scenario reaches its target ----------------------------------------------------------------
@pytest.mark.compiling
@pytest.mark.slow
@pytest.mark.parametrize("name", list(scenarios.SCENARIOS))
def test_scenario_reaches_target_primitive(solved, name):
    r = solved[name]
    assert r.module.manifest["system"] == r.scenario.system
    check_reached(r)
    assert r.result.iterations < 100 and r.result.wall_time < 5.0


def check_reached(r: scenarios.ScenarioResult) -> None:
    """The solver succeeded and X_c(q_N) is the target primitive, checked without the solver (shared with
    the other solvers' tests)."""
    m, res, name = r.module, r.result, r.scenario.name
    assert res.success and res.status == "Solve_Succeeded", res.status
    # the error the solver reports, and the C kernel's own evaluation at q_N
    e = np.array(m.c.task(res.q[-1], r.V_Sd)[0])
    assert np.linalg.norm(e) < 1e-9 and res.error_norm < 1e-9, (name, res.error_norm)
    assert np.allclose(e, res.error, atol=1e-12)
    # the primitive itself: X_c(q_N) ∝ X_d (positive scale), and the start was elsewhere
    x_d = desired_primitive(m, r.V_Sd)
    assert np.allclose(target_primitive(m, r.V_Sd), x_d, atol=1e-12)
    assert cosine(np.array(m.c.primitive(res.q[-1])[0]), x_d) > 1 - 1e-12, name
    assert cosine(np.array(m.c.primitive(r.q0)[0]), x_d) < 1 - 1e-5
    assert np.linalg.norm(m.c.task(r.q0, r.V_Sd)[0]) > 0.1


@pytest.mark.compiling
@pytest.mark.slow
@pytest.mark.parametrize("name", list(scenarios.SCENARIOS))
def test_scenario_dynamics_and_bounds(solved, name):
    check_dynamics_and_bounds(solved[name], N)


def check_dynamics_and_bounds(r: scenarios.ScenarioResult, N: int) -> None:
    """The double-integrator recursion written out, rest to rest, inside the URDF limits (shared with the
    other solvers' tests)."""
    res = r.result
    m = r.q0.size
    assert res.q.shape == res.qdot.shape == (N + 1, m) and res.u.shape == (N, m)
    assert res.dt == pytest.approx(2.5 / N) and res.t[-1] == pytest.approx(2.5)
    dt = res.dt
    # the exact discretisation of q̈ = u with u constant over each step, written out
    assert np.abs(res.q[1:] - (res.q[:-1] + dt * res.qdot[:-1] + 0.5 * dt**2 * res.u)).max() < 1e-10
    assert np.abs(res.qdot[1:] - (res.qdot[:-1] + dt * res.u)).max() < 1e-10
    assert res.dynamics_residual() < 1e-10
    # from rest at the ready configuration, to rest
    assert np.array_equal(res.q[0], r.q0) and np.all(res.qdot[0] == 0)
    assert np.abs(res.qdot[-1]).max() < 1e-12
    lower, upper = r.limits
    assert np.all(res.q >= lower - 1e-7) and np.all(res.q <= upper + 1e-7)
    assert np.abs(res.u).max() > 1e-3  # it moved


@pytest.mark.compiling
@pytest.mark.slow
@pytest.mark.parametrize("name", list(scenarios.SCENARIOS))
def test_scenario_plots_are_written(solved, name):
    import matplotlib.image

    paths = solved[name].plots
    assert [p.name for p in paths] == [f"{name}_command.png", f"{name}_trajectory.png"]
    for path in paths:
        assert path.read_bytes()[:8] == PNG
        image = matplotlib.image.imread(path)
        assert image.shape[0] > 300 and image.shape[1] > 300 and image[..., :3].std() > 0.05


# -- the bivector command ------------------------------------------------------------------------------
@pytest.mark.compiling
@pytest.mark.slow
def test_command_is_the_similarity_twist(solved):
    """B_k = J_G,Sc(q_k) q̇_k equals −2 V_Sc~ dV_Sc/dt by central differences of the similarity kernel."""
    r = solved["circle"]
    m, res = r.module, r.result
    command = bivector_command(m, res)
    assert np.array_equal(command, r.command) and command.shape == (N + 1, len(BLADES))
    assert np.all(command[0] == 0) and np.abs(command[-1]).max() < 1e-12  # rest to rest
    k, h = N // 2, 1e-6
    v = mv(SIMILARITY, m.c.similarity(res.q[k])[0])
    plus = mv(SIMILARITY, m.c.similarity(res.q[k] + h * res.qdot[k])[0])
    minus = mv(SIMILARITY, m.c.similarity(res.q[k] - h * res.qdot[k])[0])
    twist = ~v * ((plus - minus) / (2 * h)) * -2.0
    assert np.allclose([twist[b] for b in BLADES], command[k], atol=1e-7)


def trapezoid(y: np.ndarray, dt: float) -> float:
    return float(dt * (y.sum() - 0.5 * (y[0] + y[-1])))


@pytest.mark.compiling
@pytest.mark.slow
def test_dilation_command(solved):
    """The e0∞ row of the command is the rate of λ = −ln(scale) [gagen's dilation convention]: zero for
    flats [COOP Fig. 11], negative while a circle grows (Fig. 8), positive while a sphere shrinks, and
    it integrates to −ln d."""
    row = BLADES.index("e0inf")
    for name in ("plane", "line"):
        command = solved[name].command
        assert np.abs(command[:, row]).max() < 1e-9 * np.abs(command).max(), name
    for name, d in (("circle", 1.3), ("hand_sphere", 0.85)):
        r = solved[name]
        b = r.command[:, row]
        sign = -1.0 if d > 1 else 1.0
        assert np.all(sign * b[1:-1] > 0), name
        assert trapezoid(b, r.result.dt) == pytest.approx(-math.log(d), rel=3e-2), name
    # and the remaining error's e0∞ row goes from ln-ratio to zero
    errors = solved["circle"].errors
    assert errors[0, row] == pytest.approx(math.log(1 / 1.3), rel=1e-9) and abs(errors[-1, row]) < 1e-9


# -- targets -----------------------------------------------------------------------------------------
def test_target_from_identity_is_the_current_similarity():
    m = scenarios.module("three_pandas_circle")
    V = np.array(m.c.similarity(scenarios.ready("three_pandas_circle"))[0])
    assert np.allclose(target_from(V, kind="circle"), V, atol=1e-14)
    assert np.allclose(target_from(V), V, atol=1e-14)


@pytest.mark.compiling
@pytest.mark.slow
def test_target_geometry_round(solved):
    """Circle: centre + t (the rotation is about the centre), radius × d, normal rotated."""
    r, s = solved["circle"], scenarios.SCENARIOS["circle"]
    prim = rows(r.module, "primitive", "X_c")
    x0 = mv(prim, r.module.c.primitive(r.q0)[0])
    xd = mv(prim, desired_primitive(r.module, r.V_Sd))
    assert np.allclose(xyz(location(centre(xd))), xyz(location(centre(x0))) + s.translation, atol=1e-12)
    assert radius(xd) == pytest.approx(s.dilation * radius(x0), rel=1e-12)
    turned = rotation_matrix(*s.rotation) @ xyz(unit_normal(x0))
    assert np.allclose(xyz(unit_normal(xd)), turned, atol=1e-12)
    # sphere: centre + t, radius × d
    r, s = solved["hand_sphere"], scenarios.SCENARIOS["hand_sphere"]
    prim = rows(r.module, "primitive", "X_c")
    x0, xd = mv(prim, r.module.c.primitive(r.q0)[0]), mv(prim, desired_primitive(r.module, r.V_Sd))
    assert np.allclose(xyz(location(centre(xd))), xyz(location(centre(x0))) + s.translation, atol=1e-12)
    assert radius(xd) == pytest.approx(s.dilation * radius(x0), rel=1e-12)


@pytest.mark.compiling
@pytest.mark.slow
def test_target_geometry_flat(solved):
    """Line: direction rotated, through the moved reference point c + t (c = V_Sc0 e0 V_Sc0~)."""
    r, s = solved["line"], scenarios.SCENARIOS["line"]
    m = r.module
    prim = rows(m, "primitive", "X_c")
    x0, xd = mv(prim, m.c.primitive(r.q0)[0]), mv(prim, desired_primitive(m, r.V_Sd))
    turned = rotation_matrix(*s.rotation) @ xyz(direction(x0))
    assert abs(float(np.dot(xyz(direction(xd)), turned))) == pytest.approx(1.0, abs=1e-12)
    v0 = mv(SIMILARITY, m.c.similarity(r.q0)[0])
    c = xyz(location(v0 * e0(v0) * ~v0)) + np.asarray(s.translation)
    p = mv(["e0", "e1", "e2", "e3", "einf"], [1.0, *c, 0.5 * c @ c])
    assert max(abs(k) for k in (xd ^ p).coeffs) < 1e-12  # P(c + t) lies on X_d
    # a dilation does not change a flat
    V = np.array(m.c.similarity(r.q0)[0])
    assert np.allclose(target_from(V, dilation=1.5, kind="line"), V, atol=1e-14)


# -- options of the solver -----------------------------------------------------------------------------
def circle_problem():
    m = scenarios.module("three_pandas_circle")
    q0 = scenarios.ready("three_pandas_circle")
    s = scenarios.SCENARIOS["circle"]
    V_Sd = target_from(np.array(m.c.similarity(q0)[0]), s.translation, s.rotation, s.dilation, kind="circle")
    return m, q0, V_Sd


def test_penalty_residual_scales_with_R():
    """exact=False is the paper's penalty problem: its residual ‖e(q_N)‖ is proportional to R/Q."""
    m, q0, V_Sd = circle_problem()
    coarse = reach(m, q0, V_Sd, N=10, R=1e-4, exact=False)
    fine = reach(m, q0, V_Sd, N=10, R=1e-6, exact=False)
    assert coarse.updates == fine.updates == 0 and coarse.success and fine.success
    assert 1e-4 < coarse.error_norm < 1e-2
    assert 30 < coarse.error_norm / fine.error_norm < 300
    exact = reach(m, q0, V_Sd, N=10, R=1e-4)
    assert exact.updates >= 1 and exact.error_norm < 1e-9
    # the final shift is, to first order, the penalty optimum's residual with the opposite sign
    assert np.linalg.norm(exact.shift + coarse.error) < 0.1 * coarse.error_norm


def test_warm_start_and_cache():
    m, q0, V_Sd = circle_problem()
    first = reach(m, q0, V_Sd, N=12)
    again = reach(m, q0, V_Sd, N=12, warm_start=first)
    assert again.build_time == 0.0 and again.iterations <= 2 and again.success
    assert np.allclose(again.q, first.q, atol=1e-8)
    with pytest.raises(ValueError, match="another size"):
        reach(m, q0, V_Sd, N=13, warm_start=first)


def test_joint_limits_bind():
    """A ±0.25 rad box around q0 cuts off the free solution (which moves a joint 0.32 rad); the
    redundant system still reaches the circle inside it."""
    m, q0, V_Sd = circle_problem()
    free = reach(m, q0, V_Sd, N=N)
    assert np.abs(free.q - q0).max() > 0.3
    box = (q0 - 0.25, q0 + 0.25)
    bound = reach(m, q0, V_Sd, N=N, limits=box)
    assert bound.success and bound.error_norm < 1e-9
    assert np.all(bound.q >= box[0] - 1e-7) and np.all(bound.q <= box[1] + 1e-7)
    assert np.abs(bound.q - q0).max() > 0.249
    assert cosine(np.array(m.c.primitive(bound.q[-1])[0]), desired_primitive(m, V_Sd)) > 1 - 1e-12


def test_velocity_limits_bind():
    m, q0, V_Sd = circle_problem()
    free = reach(m, q0, V_Sd, N=N)
    assert np.abs(free.qdot).max() > 0.18
    bound = reach(m, q0, V_Sd, N=N, velocity_limits=(-0.12, 0.12))
    assert bound.success and bound.error_norm < 1e-9
    assert np.abs(bound.qdot).max() <= 0.12 + 1e-7 and np.abs(bound.qdot).max() > 0.119


def test_invalid_input():
    m, q0, V_Sd = circle_problem()
    with pytest.raises(ValueError, match="outside the joint limits"):
        reach(m, q0, V_Sd, N=N, limits=(q0 + 0.1, q0 + 0.2))
    with pytest.raises(ValueError, match="Q"):
        ReachingOCP(m.casadi.task, q0.size, N=5, Q=np.ones(3))
    with pytest.raises(ValueError, match="horizon"):
        ReachingOCP(m.casadi.task, q0.size, N=5, horizon=0.0)


def test_double_integrator_is_exact():
    """(A, B) = the exact zero-order-hold discretisation: exp of the nilpotent augmented matrix."""
    m, dt = 3, 0.04
    z, eye = np.zeros((m, m)), np.eye(m)
    M = np.block([[z, eye, z], [z, z, eye], [z, z, z]]) * dt
    expm = np.eye(3 * m) + M + M @ M / 2  # M³ = 0
    A, B = double_integrator(m, dt)
    assert np.allclose(A, expm[: 2 * m, : 2 * m], atol=1e-15)
    assert np.allclose(B, expm[: 2 * m, 2 * m:], atol=1e-15)


def test_joint_limits_from_urdf():
    lower, upper = scenarios.joint_limits("three_pandas_circle")
    assert lower.size == 21 and (lower[3], upper[3]) == (-3.0718, -0.0698)  # panda_joint4
    lower, upper = scenarios.joint_limits("g1_arms_line")
    assert lower.size == 17 and (lower[0], upper[0]) == (-2.618, 2.618)  # the shared waist yaw, once
    for name in scenarios.SCENARIOS.values():
        lower, upper = scenarios.joint_limits(name.system)
        q = scenarios.ready(name.system)
        assert np.all(np.isfinite(lower)) and np.all(lower <= q) and np.all(q <= upper), name.system


@pytest.mark.compiling
def test_command_line(tmp_path: Path, capsys):
    assert gagen_main(["reach", "plane", "--out", str(tmp_path), "--N", "10"]) == 0
    out = capsys.readouterr().out
    assert "plane (leap_three_fingers_plane, 12 DOF, N = 10)" in out and "iterations" in out and "‖e‖" in out
    assert (tmp_path / "plane_command.png").read_bytes()[:8] == PNG
    assert (tmp_path / "plane_trajectory.png").read_bytes()[:8] == PNG
