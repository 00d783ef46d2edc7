"""MuJoCo as the plant (issue 30): the system's MuJoCo model against Pinocchio's (two rigid-body engines on
the same URDF inertias), and a torque-level plan from Crocoddyl played in MuJoCo, closed by a PD through
the mass matrix, reaching the target circle within a stated bound."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import REPO, bundled_module

pytest.importorskip("crocoddyl")
pytest.importorskip("mujoco")

from gagen.apps.cooperative.scenarios import ready, spec_of
from gagen.control.mujoco_loop import track
from gagen.control.ocp import target_from
from gagen.control.torque import TorqueOCP
from gagen.dynamics.mujoco_model import MujocoSystem
from gagen.dynamics.rigid_body import DynamicsError, SystemDynamics

SYSTEM = "three_iiwas_circle"


@pytest.fixture(scope="module")
def sim():
    return MujocoSystem(spec_of(SYSTEM))


def test_mujoco_and_pinocchio_give_the_same_dynamics(sim):
    """M(q) by MuJoCo's CRB and Pinocchio's CRBA, C q̇ + g by MuJoCo's RNE and Pinocchio's RNEA."""
    pinocchio = SystemDynamics(spec_of(SYSTEM))
    rng = np.random.default_rng(5)
    for _ in range(5):
        q, qdot = rng.uniform(-2, 2, 21), rng.normal(0, 1, 21)
        M = pinocchio.mass_matrix(q)
        np.testing.assert_allclose(sim.mass_matrix(q), M, atol=1e-12 * np.abs(M).max())
        bias = pinocchio.bias(q, qdot)
        np.testing.assert_allclose(sim.bias(q, qdot), bias, atol=1e-12 * np.abs(bias).max())
    np.testing.assert_array_equal(sim.effort, np.full(21, 300.0))  # the URDF's <limit effort>


def test_a_urdf_with_an_impossible_inertia_is_named():
    """The published Panda's link 4 breaks the triangle inequality: MuJoCo refuses it, and so do we,
    naming the URDF, rather than balance (change) the robot's inertia."""
    with pytest.raises(DynamicsError, match=r"panda\.urdf: MuJoCo cannot load it .*inertia"):
        MujocoSystem(spec_of("three_pandas_circle"))


def test_the_plan_played_in_mujoco_reaches_the_circle(sim):
    """Crocoddyl's plan (50 nodes of 20 ms, lift 5 cm, tilt 0.1 rad, ×1.1) in MuJoCo at 1 kHz under
    τ*(t) + M (K_p e + K_d ė), then 0.2 s of holding: within 0.02 rad of the plan at every node and the
    task error at the end within 2 × the plan's own (its terminal cost leaves ≈ 7e-5)."""
    m = bundled_module(SYSTEM)
    q0 = ready(SYSTEM)
    V_Sd = target_from(m.c.similarity(q0)[0], (0.0, 0.0, 0.05), ((1.0, 0.0, 0.0), 0.1), 1.1, kind="circle")
    plan = TorqueOCP(spec_of(SYSTEM), m.c.task, N=50, dt=0.02).solve(q0, V_Sd)
    assert plan.converged and plan.error_norm < 1e-4
    run = track(sim, plan, duration=1.2)
    assert run.t[-1] == pytest.approx(1.2) and len(run.tau) == 1200
    steps = round(0.02 / 1e-3)
    deviation = max(np.abs(run.q[k * steps] - plan.q[k]).max() for k in range(len(plan.q)))
    assert deviation <= 0.02, deviation
    final = np.linalg.norm(m.c.task(run.q[-1], V_Sd)[0])
    assert final <= 2 * plan.error_norm, (final, plan.error_norm)
    assert np.all(np.abs(run.tau) <= sim.effort)
    # without the feedback the plan alone drifts: the loop is what carries it over
    open_loop = track(sim, plan, kp=0.0, kd=0.0, duration=1.0)
    assert np.linalg.norm(m.c.task(open_loop.q[-1], V_Sd)[0]) > 10 * final


def test_torque_mpc_in_mujoco_tracks_a_moving_growing_tilting_circle(sim):
    """Receding-horizon box-FDDP (N = 20 × 20 ms, 2 iterations a tick, warm-started) at 50 Hz closing the
    loop in MuJoCo at 1 kHz, the circle moving 5 cm/s forward and 3 cm/s up, tilting 0.1 rad/s and
    growing 10 %/s: over 1 s the task error stays below 0.02, while standing still would leave ≥ 0.1."""
    from gagen.control.torque_mpc import TorqueMPC, run

    m = bundled_module(SYSTEM)
    q0 = ready(SYSTEM)
    V_Sc0 = m.c.similarity(q0)[0]

    def target(t):
        return target_from(V_Sc0, (0.05 * t, 0.0, 0.03 * t), ((1.0, 0.0, 0.0), 0.1 * t), 1.0 + 0.1 * t,
                           kind="circle")

    mpc = TorqueMPC(TorqueOCP(spec_of(SYSTEM), m.c.task, N=20, dt=0.02), q0, target, iterations=2)
    loop = run(sim, mpc, duration=1.0, rate=50)
    assert len(loop.tick_t) == 50 and len(loop.t) == 1000 and np.all(loop.iterations >= 1)
    # the error the loop reports is the kernel's at the measured state, recomputed here at the last tick
    k = round(loop.tick_t[-1] / 1e-3)
    assert loop.errors[-1] == pytest.approx(np.linalg.norm(m.c.task(loop.q[k], target(loop.tick_t[-1]))[0]))
    standing = np.linalg.norm(m.c.task(q0, target(loop.tick_t[-1]))[0])
    assert loop.errors.max() <= 0.02 and standing >= 0.1, (loop.errors.max(), standing)
    assert np.all(np.abs(loop.tau) <= sim.effort)


def test_gagen_mpc_dynamics_reports_plots_and_animates(tmp_path, capsys):
    from gagen.cli import main

    assert main(["mpc", "--dynamics", "--duration", "0.3", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "# Torque-level MPC: three_iiwas_circle in MuJoCo" in out and "15 ticks at 50 Hz" in out
    for name in ("torque_mpc_report.md", "torque_mpc.png", "torque_mpc.gif"):
        assert (tmp_path / name).stat().st_size > 300, name


def test_gagen_mpc_dynamics_on_the_pandas_is_one_line(capsys):
    """MuJoCo refuses the published Panda's inertia: one line naming the URDF, exit status 2."""
    from gagen.cli import main

    assert main(["mpc", "three_pandas_circle", "--dynamics", "--duration", "0.1", "--no-animation"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "panda.urdf: MuJoCo cannot load it" in err[0], err


def test_impedance_control_in_mujoco_matches_the_pinocchio_rk4_plant(sim):
    """The similarity impedance law (tuned gains, a random start 0.2 rad around q0) on MuJoCo's plant and
    on Pinocchio's ABA integrated by RK4: both converge, and the two runs stay within 1e-3 rad."""
    from gagen.apps.cooperative.impedance_demo import GAINS, controller
    from gagen.control.impedance import simulate
    from gagen.control.mujoco_loop import impedance

    control, q0 = controller(SYSTEM, GAINS["tuned"])
    start = q0 + np.random.default_rng(0).uniform(-0.2, 0.2, q0.size)
    mujoco_run = impedance(sim, control, start, duration=2.0)
    rk4_run = simulate(control, start, duration=2.0)
    assert mujoco_run.error_norm[0] > 0.05 and mujoco_run.final_error < 1e-4
    assert np.abs(mujoco_run.q - rk4_run.q).max() < 1e-3
    assert abs(mujoco_run.final_error - rk4_run.final_error) < 1e-5


def test_gagen_impedance_mujoco_reports_the_plant(tmp_path, capsys):
    from gagen.cli import main

    argv = ["impedance", "three_iiwas_circle", "--mujoco", "--runs", "1", "--duration", "0.5", "--out",
            str(tmp_path)]
    main(argv)
    out = capsys.readouterr().out
    assert "forward dynamics (MuJoCo's own integrator" in out and "| three_iiwas_circle | tuned |" in out
    assert (tmp_path / "impedance.png").is_file()


def test_a_moving_target_that_turns_non_finite_stops_the_mpc_in_one_line(sim):
    from gagen.control.torque_mpc import TorqueMPC, run

    m = bundled_module(SYSTEM)
    q0 = ready(SYSTEM)
    V_Sc0 = np.asarray(m.c.similarity(q0)[0])

    def target(t):
        return V_Sc0 if t < 0.15 else np.full(12, np.nan)  # (the first horizon ends at 0.1 s)

    mpc = TorqueMPC(TorqueOCP(spec_of(SYSTEM), m.c.task, N=5, dt=0.02), q0, target, iterations=1)
    with pytest.raises(ValueError, match=r"the target at t = 0\.16 s is not 12 finite values"):
        run(sim, mpc, duration=0.2, rate=50)


def test_follow_tracks_a_smooth_joint_trajectory_by_computed_torque(sim):
    """A 0.5 Hz swing of every joint, sampled at 100 Hz, tracked to 2e-3 rad; without the computed
    torque's feedback (K_p = K_d = 0) the same run drifts further; bad trajectories are refused."""
    from gagen.control.mujoco_loop import follow

    t = np.arange(0.0, 1.0001, 0.01)
    q0 = ready("three_iiwas_circle")
    q = q0 + 0.2 * np.sin(np.pi * t)[:, None] * np.linspace(0.5, 1.0, sim.dof)
    loop = follow(sim, t, q)
    at = np.searchsorted(loop.t, t - 1e-9)
    tracked = np.abs(loop.q[at] - q).max()
    assert tracked < 2e-3, tracked
    loose = follow(sim, t, q, kp=0.0, kd=0.0)
    assert np.abs(loose.q[np.searchsorted(loose.t, t - 1e-9)] - q).max() > 2 * tracked
    with pytest.raises(ValueError, match="increasing times"):
        follow(sim, t[::-1], q)
    with pytest.raises(ValueError, match="finite"):
        follow(sim, t, np.where(t[:, None] > 0.5, np.nan, q))


def test_gagen_teleop_mujoco_reports_the_plant(tmp_path, capsys):
    from gagen.cli import main

    trace = REPO / "gagen/apps/cooperative/traces/circle_move_tilt_dilate.csv"
    main(["teleop", "three_iiwas_circle", "--trace", str(trace), "--mujoco", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert "In MuJoCo" in out and "primitive from the kinematic run" in out
