"""A ring held by the three iiwas in MuJoCo (issue 30): the grasp forces read from MuJoCo's equality rows
against the ring's own Newton-Euler equations and its statics, their internal part against the grasp
map's nullspace and the edge tensions, the load feed-forward against virtual work, and the ring carried
along a commanded lift and tilt by the impedance law, which without torques it is not."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import bundled_module

pytest.importorskip("mujoco")
pytest.importorskip("pinocchio")

import mujoco

from gagen.apps.cooperative.impedance_demo import start
from gagen.apps.cooperative.scenarios import spec_of
from gagen.dynamics.held_object import HeldRing, grasp_map, internal_forces, ring_frame
from gagen.dynamics.rigid_body import GRAVITY, DynamicsError

SYSTEM = "three_iiwas_circle"


@pytest.fixture(scope="module")
def ring():
    return HeldRing(spec_of(SYSTEM), start(SYSTEM))


def cross(r):
    return np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])


def test_the_ring_is_a_hoop_through_the_end_points_of_the_generated_kinematics(ring):
    """The end sites are the generated kernels' end points (any q); at q0 the grasp points sit on them,
    on a circle of the ring's radius about its centre, and the ring's inertia is the hoop's."""
    m = bundled_module(SYSTEM)
    rng = np.random.default_rng(1)
    for q in (ring.q0, *rng.uniform(-2, 2, (3, 21))):
        ring.set_state(q, np.zeros(21))
        kernels = np.array([np.asarray(getattr(m.c, f"arm{a}_fk")(q[7 * a:7 * a + 7])[1]).ravel()[1:4]
                            for a in range(3)])
        np.testing.assert_allclose(ring.end_points(), kernels, atol=1e-12)
    ring.set_state(ring.q0, np.zeros(21))
    centre, rotation = ring.ring_pose()
    np.testing.assert_allclose(ring.grasp_points(), ring.end_points(), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(ring.grasp_points() - centre, axis=1), ring.radius, rtol=1e-12)
    np.testing.assert_allclose(ring.grasp_points() @ rotation[:, 2], centre @ rotation[:, 2], atol=1e-12)
    assert ring.radius == pytest.approx(1.5507, abs=1e-4)  # the iiwa circle's
    body = ring.ring_body
    assert ring.model.body_mass[body] == 1.5
    np.testing.assert_allclose(ring.model.body_inertia[body], 1.5 * ring.radius**2 * np.array([0.5, 0.5, 1]))
    np.testing.assert_allclose(ring.model.body_ipos[body], 0, atol=1e-15)


def test_the_circle_through_three_points_and_a_line_refused():
    p = np.array([[1.0, 0, 0], [0, 2, 0], [0, 0, 3]])
    centre, radius, rotation = ring_frame(p)
    np.testing.assert_allclose(np.linalg.norm(p - centre, axis=1), radius, rtol=1e-14)
    np.testing.assert_allclose(rotation.T @ rotation, np.eye(3), atol=1e-15)
    np.testing.assert_allclose((p - centre) @ rotation[:, 2], 0, atol=1e-15)
    with pytest.raises(DynamicsError, match="on a line"):
        ring_frame([[0, 0, 0], [1, 1, 1], [2, 2, 2]])


def hold(ring, offset, steps):
    """τ = MuJoCo's bias + the ring's weight fed forward + M (K_p (q0 + offset − q) − K_d q̇), stepped from
    rest at q0; yields before each step, with the state's forces and q̈ under that τ computed."""
    target = ring.q0 + offset
    ring.set_state(ring.q0, np.zeros(21))
    model, data = ring.model, ring.data
    for _ in range(steps):
        q, qd = ring.state()
        mujoco.mj_forward(model, data)
        data.ctrl[:] = ring.bias_now() + ring.hold_torque() + ring.current_mass_matrix() @ (
            400 * (target - q) - 40 * qd)
        mujoco.mj_forward(model, data)
        yield
        mujoco.mj_step(model, data)


def test_grasp_forces_obey_the_rings_newton_euler_equations_and_at_rest_carry_its_weight(ring):
    """The three forces read from MuJoCo's equality rows, with gravity, give the ring's acceleration
    (m a = Σ f + m g, I ω̇ + ω × I ω = Σ r × f in its body frame, to 1e-13 with the solver's tolerance
    at 1e-12) at every step, while one arm's elbow
    squeezes the ring (its PD target 0.02 rad off). After 1 s, at rest: Σ f = m g up to 1e-6 of it, no net
    torque, and what is left is internal: in the grasp map's nullspace, equal to f − G⁺ (m g ẑ, 0), and
    made of tensions along the triangle's edges, of a few newtons."""
    offset = np.zeros(21)
    offset[3] = 0.02
    m, weight = ring.mass, ring.mass * GRAVITY
    inertia = np.diag(ring.model.body_inertia[ring.ring_body])
    lin = slice(ring.ring_qvel, ring.ring_qvel + 3)
    ang = slice(ring.ring_qvel + 3, ring.ring_qvel + 6)
    worst = 0.0
    ring.model.opt.tolerance = 1e-12  # MuJoCo's Newton solver stops at 1e-8 by default: q̈ to about that
    try:
        for _ in hold(ring, offset, 1000):
            f, d = ring.grasp_forces(), ring.data
            centre, rotation = ring.ring_pose()
            r = ring.grasp_points() - centre
            newton = m * d.qacc[lin] - f.sum(0) - np.array([0, 0, -weight])
            omega = d.qvel[ang]  # the free joint's angular velocity and acceleration: in the body frame
            torque = rotation.T @ sum(np.cross(ri, fi) for ri, fi in zip(r, f, strict=True))
            euler = inertia @ d.qacc[ang] + np.cross(omega, inertia @ omega) - torque
            worst = max(worst, np.abs(newton).max() / weight, np.abs(euler).max() / (weight * ring.radius))
    finally:
        ring.model.opt.tolerance = 1e-8
    assert worst < 1e-13, worst
    f = ring.grasp_forces()
    centre, _ = ring.ring_pose()
    points = ring.grasp_points()
    np.testing.assert_allclose(f.sum(0), [0, 0, weight], atol=1e-6 * weight)
    net_torque = sum(np.cross(p - centre, fi) for p, fi in zip(points, f, strict=True))
    np.testing.assert_allclose(net_torque, 0, atol=1e-6 * weight * ring.radius)
    split = ring.internal()
    G = grasp_map(points, centre)
    np.testing.assert_allclose(G @ split.internal.reshape(-1), 0, atol=1e-12 * np.abs(f).max())
    carrying = np.linalg.lstsq(G, [0, 0, weight, 0, 0, 0], rcond=None)[0]  # the least-norm G⁺ w
    np.testing.assert_allclose(split.internal.reshape(-1), f.reshape(-1) - carrying, atol=1e-5 * weight)
    edges = np.zeros((3, 3))
    for k, (i, j) in enumerate(((0, 1), (1, 2), (2, 0))):
        u = (points[j] - points[i]) / np.linalg.norm(points[j] - points[i])
        edges[i] -= split.tensions[k] * u
        edges[j] += split.tensions[k] * u
    np.testing.assert_allclose(edges, split.internal, atol=1e-12 * np.abs(f).max())
    assert 0.5 < np.abs(split.tensions).max() < 50, split.tensions
    assert ring.grasp_gaps().max() < 1e-3  # the soft constraints' give under a 15 N load


def test_internal_forces_of_a_pure_squeeze_and_of_a_pure_lift():
    """Equal and opposite forces along an edge are all internal (their tension read back); forces with
    no nullspace part (G⁺ of a wrench) have none."""
    p = np.array([[1.0, 0, 0], [-0.5, 0.8, 0.1], [-0.4, -0.9, -0.1]])
    u = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0])
    squeeze = internal_forces(np.array([-3 * u, 3 * u, np.zeros(3)]), p, p.mean(0))
    np.testing.assert_allclose(squeeze.tensions, [3, 0, 0], atol=1e-12)
    assert squeeze.magnitude == pytest.approx(3 * np.sqrt(2))
    lift = np.linalg.pinv(grasp_map(p, p.mean(0))) @ np.array([0, 0, 10, 0.5, -0.2, 0.1])
    assert internal_forces(lift.reshape(3, 3), p, p.mean(0)).magnitude < 1e-12


def test_the_load_feed_forward_does_the_virtual_work_of_the_least_norm_grasp_forces(ring):
    """τ of ``hold_torque`` against τ·δq = Σ f_i·δp_i with δp_i by central differences of the end points,
    f = G⁺ w: forces that carry the wrench w (checked on the net force and torque) with no internal part."""
    rng = np.random.default_rng(3)
    q = ring.q0 + rng.uniform(-0.1, 0.1, 21)
    w = np.array([1.0, -2.0, 15.0, 0.3, -0.2, 0.5])
    ring.set_state(q, np.zeros(21))
    tau = ring.hold_torque(w)
    centre, _ = ring.ring_pose()
    points = ring.end_points()
    f = (np.linalg.pinv(grasp_map(points, centre)) @ w).reshape(3, 3)
    np.testing.assert_allclose(f.sum(0), w[:3], atol=1e-12)
    np.testing.assert_allclose(sum(np.cross(p - centre, fi) for p, fi in zip(points, f, strict=True)), w[3:],
                               atol=1e-12)
    assert internal_forces(f, points, centre).magnitude < 1e-12
    for _ in range(3):
        dq, h = rng.normal(size=21), 1e-6
        ring.set_state(q + h * dq, np.zeros(21))
        ahead = ring.end_points()
        ring.set_state(q - h * dq, np.zeros(21))
        dp = (ahead - ring.end_points()) / (2 * h)
        assert tau @ dq == pytest.approx(np.sum(f * dp), rel=1e-7, abs=1e-9)


def test_the_impedance_law_carries_the_ring_and_without_torques_it_falls(ring):
    """Lift 1 cm and tilt 0.02 rad over 0.2 s (minimum jerk), 0.4 s in all, under the impedance law
    (K = 100, D = 20, the ring's weight fed forward): the ring's centre stays within 1.5 cm of the
    commanded one and ends within 4 mm, its tilt within 25 mrad and ends within 7 mrad (the law follows a
    moving set-point with a lag D/K v), the internal forces stay below 1 N and the grasps within 0.5 mm.
    With no torque the ring falls more than 0.3 m."""
    from gagen.apps.cooperative.held_object_demo import GAINS, Command, carry, impedance_policy, zero_policy
    from gagen.control.impedance import ImpedanceController
    from gagen.dynamics.rigid_body import SystemDynamics

    m = bundled_module(SYSTEM)
    V_Sc0 = np.asarray(m.c.similarity(ring.q0)[0])
    command = Command(lift=(0.0, 0.0, 0.01), tilt=0.02, motion=0.2)
    V_Sd = command.target(V_Sc0)
    controller = ImpedanceController(m, SystemDynamics(spec_of(SYSTEM)), V_Sc0, GAINS, ring.q0, 6)
    run = carry(ring, impedance_policy(ring, controller, V_Sd), command, m.c.task, V_Sd, 0.4)
    assert len(run.t) == 400 and run.t[-1] == pytest.approx(0.399)
    # the record's commanded pose is the command's: 1 cm up, tilted 0.02 rad about x at the end
    np.testing.assert_allclose(run.centre_d[-1] - run.centre_d[0], [0, 0, 0.01], atol=1e-15)
    assert np.arccos(run.rotation_d[-1][:, 2] @ run.rotation_d[0][:, 2]) == pytest.approx(0.02, abs=1e-9)
    assert run.position_error.max() < 0.015 and run.position_error[-1] < 0.004, run.position_error[[-1]]
    assert run.tilt_error.max() < 0.025 and run.tilt_error[-1] < 0.007, run.tilt_error[[-1]]
    assert run.internal.max() < 1.0 and run.gaps.max() < 5e-4
    assert run.task_error[-1] < 0.006
    fallen = carry(ring, zero_policy, command, m.c.task, V_Sd, 0.4)
    assert fallen.position_error[-1] > 0.3 and fallen.task_error[-1] > 0.3


def test_the_commanded_pose_is_the_commanded_similaritys_circle(ring):
    """The start grasp points moved by ``Command.pose`` (c0 + s lift, R_x(s tilt) R0) span the circle
    X_d = V_Sd(t) X_u V_Sd(t)~ of the task's target (``target_from``), at the start, midway and the end."""
    from gagen.apps.cooperative.held_object_demo import Command
    from gagen.control.ocp import multivector, target_primitive
    from gagen.model.primitives import through

    m = bundled_module(SYSTEM)
    rows = next(p["rows"] for k in m.manifest["kernels"] if k["name"] == "primitive" for p in k["outputs"]
                if p["name"] == "X_c")
    command = Command()
    V_Sd = command.target(np.asarray(m.c.similarity(ring.q0)[0]))
    ring.set_state(ring.q0, np.zeros(21))
    centre0, rotation0 = ring.ring_pose()
    points0 = ring.grasp_points()
    for t in (0.0, 1.0, 2.5):
        centre, rotation = command.pose(t, centre0, rotation0)
        points = centre + (points0 - centre0) @ rotation0 @ rotation.T
        circle = through("circle", [multivector(["e0", "e1", "e2", "e3", "einf"], [1, *p, 0.5 * p @ p])
                                    for p in points])
        x = np.array([circle[r] for r in rows])
        x_d = target_primitive(m, V_Sd(t))
        assert x @ x_d / np.linalg.norm(x) / np.linalg.norm(x_d) > 1 - 1e-12, t
    assert np.linalg.norm(m.c.task(ring.q0, V_Sd(2.5))[0]) > 0.1  # the end is far from the start


@pytest.mark.compiling  # builds three_iiwas_plane's module
def test_gagen_carry_runs_on_a_users_own_spec_and_refuses_a_plane(tmp_path, capsys):
    """A copied, renamed three-iiwa circle spec (its URDF next to it) carries the ring through the CLI;
    a system spanning a plane is refused in one line."""
    import shutil

    from gagen.cli import main

    source = spec_of("three_iiwas_circle")
    mine = tmp_path / "my_ring_cell.yaml"
    mine.write_text(source.read_text())
    shutil.copytree(source.parent / "iiwa14", tmp_path / "iiwa14")
    out = tmp_path / "out"
    argv = ["carry", str(mine), "--no-mpc", "--no-animation", "--duration", "0.2", "--out", str(out)]
    assert main(argv) == 0
    assert "impedance" in capsys.readouterr().out and (out / "held_object.png").stat().st_size > 1000
    assert main(["carry", "three_iiwas_plane", "--no-mpc", "--duration", "0.1", "--out", str(out)]) == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]  # (after the module's build progress line)
    assert error.startswith("error: three_iiwas_plane") and "spans a plane" in error
