"""Torque-level cooperative optimal control with Crocoddyl (issue 30): gagen's task kernel as a
Crocoddyl residual against central differences and against Crocoddyl's own frame-translation residual,
and the torque OCP's solution re-simulated by an integration of our own through Pinocchio's ABA, with
its torque and joint limits."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import bundled_module

crocoddyl = pytest.importorskip("crocoddyl")
pinocchio = pytest.importorskip("pinocchio")

from gagen.apps.cooperative.scenarios import SCENARIOS, joint_limits, ready, spec_of  # noqa: E402
from gagen.control.goals import desired  # noqa: E402
from gagen.control.ocp import target_from  # noqa: E402
from gagen.control.torque import TorqueOCP, resimulate, task_residual  # noqa: E402
from gagen.dynamics.rigid_body import SystemDynamics  # noqa: E402


def _residual_data(dynamics, residual):
    collector = crocoddyl.DataCollectorMultibody(dynamics.model.createData())
    return residual.createData(collector), collector


def _differences(residual, data, x, u, count, h=1e-6):
    """Central differences of the residual's r along the first ``count`` entries of the state x."""
    columns = []
    for i in range(count):
        plus, minus = x.copy(), x.copy()
        plus[i] += h
        minus[i] -= h
        residual.calc(data, plus, u)
        r_plus = np.array(data.r)
        residual.calc(data, minus, u)
        columns.append((r_plus - np.array(data.r)) / (2 * h))
    return np.array(columns).T


def _target(module, q):
    return np.array(module.c.similarity(q)[0])


@pytest.mark.parametrize("native", [False, True], ids=["python", "c++"])
def test_the_task_residual_equals_central_differences(native):
    m = bundled_module("three_pandas_circle")
    dynamics = SystemDynamics(spec_of("three_pandas_circle"))
    state = crocoddyl.StateMultibody(dynamics.model)
    rng = np.random.default_rng(7)
    q0 = ready("three_pandas_circle")
    V_Sd = _target(m, q0 + rng.normal(0, 0.2, q0.size))
    residual = task_residual(state, dynamics, m.c.task, V_Sd, native=native)
    data, _ = _residual_data(dynamics, residual)
    for _ in range(3):
        q = q0 + rng.normal(0, 0.3, q0.size)
        x, u = np.concatenate([q, rng.normal(0, 1, q.size)]), np.zeros(q.size)
        residual.calc(data, x, u)
        residual.calcDiff(data, x, u)
        r, Rx = np.array(data.r), np.array(data.Rx)
        np.testing.assert_array_equal(r, m.c.task(q, V_Sd)[0])  # q read from the state as the kernel's
        differences = _differences(residual, data, x, u, x.size)
        assert np.abs(Rx - differences).max() <= 1e-6 * max(1.0, np.abs(differences).max())
        assert np.all(Rx[:, q.size:] == 0)  # no velocity dependence


@pytest.mark.parametrize("native", [False, True], ids=["python", "c++"])
def test_on_a_point_the_task_residual_is_crocoddyls_frame_translation(native):
    """A point primitive on one chain: e's translation part is −(p(q) − p_d), the frame-translation
    residual of the flange with its sign turned, and its Jacobian rows −R_x (LOCAL_WORLD_ALIGNED)."""
    m = bundled_module("panda_point")
    dynamics = SystemDynamics(spec_of("panda_point"))
    state = crocoddyl.StateMultibody(dynamics.model)
    rng = np.random.default_rng(3)
    q_target = ready("panda_point") + rng.normal(0, 0.3, 7)
    frame = dynamics.model.getFrameId("arm0/panda_link8")
    data = dynamics.model.createData()
    pinocchio.framesForwardKinematics(dynamics.model, data, q_target)
    ours = task_residual(state, dynamics, m.c.task, _target(m, q_target), native=native)
    theirs = crocoddyl.ResidualModelFrameTranslation(state, frame, data.oMf[frame].translation.copy(), 7)
    for _ in range(5):
        q = ready("panda_point") + rng.normal(0, 0.4, 7)
        x, u = np.concatenate([q, np.zeros(7)]), np.zeros(7)
        our_data, _ = _residual_data(dynamics, ours)
        their_data, collector = _residual_data(dynamics, theirs)
        pinocchio.forwardKinematics(dynamics.model, collector.pinocchio, q)
        pinocchio.updateFramePlacements(dynamics.model, collector.pinocchio)
        pinocchio.computeJointJacobians(dynamics.model, collector.pinocchio, q)
        for model, d in ((ours, our_data), (theirs, their_data)):
            model.calc(d, x, u)
            model.calcDiff(d, x, u)
        translation = slice(4, 7)  # e1∞, e2∞, e3∞ of e's rows (e12, e13, e23, e0∞, e1∞, e2∞, e3∞)
        np.testing.assert_allclose(np.array(our_data.r)[translation], -np.array(their_data.r), atol=1e-12)
        np.testing.assert_allclose(np.array(our_data.Rx)[translation], -np.array(their_data.Rx), atol=1e-12)
        assert np.abs(np.array(our_data.r)[:4]).max() <= 1e-12  # no rotation or dilation error for a point


def test_the_cpp_residual_is_the_python_one_bit_for_bit():
    """The C++ residual (crocoddyl_residual.cpp, the kernel called from Crocoddyl's loop) and the Python
    one give the same r and R_x, bit for bit, and so the same solution."""
    m = bundled_module("three_pandas_circle")
    dynamics = SystemDynamics(spec_of("three_pandas_circle"))
    state = crocoddyl.StateMultibody(dynamics.model)
    q0 = ready("three_pandas_circle")
    V_Sd = desired(SCENARIOS["circle"].goal, _target(m, q0), "circle")
    python, native = (task_residual(state, dynamics, m.c.task, V_Sd, native=n) for n in (False, True))
    rng = np.random.default_rng(11)
    for _ in range(20):
        x, u = np.concatenate([q0 + rng.normal(0, 0.5, 21), rng.normal(0, 1, 21)]), np.zeros(21)
        datas = [_residual_data(dynamics, r)[0] for r in (python, native)]
        for model, d in zip((python, native), datas, strict=True):
            model.calc(d, x, u)
            model.calcDiff(d, x, u)
        np.testing.assert_array_equal(np.array(datas[0].r), np.array(datas[1].r))
        np.testing.assert_array_equal(np.array(datas[0].Rx), np.array(datas[1].Rx))
    spec = spec_of("three_pandas_circle")
    ocps = [TorqueOCP(spec, m.c.task, N=20, dt=0.05, native=n) for n in (False, True)]
    first, second = (ocp.solve(q0, V_Sd, max_iterations=30) for ocp in ocps)
    assert first.iterations == second.iterations
    np.testing.assert_allclose(first.q, second.q, atol=1e-12)
    np.testing.assert_allclose(first.tau, second.tau, atol=1e-9)


def test_the_cpp_residual_needs_a_compiled_kernel():
    m = bundled_module("three_pandas_circle")
    dynamics = SystemDynamics(spec_of("three_pandas_circle"))
    state = crocoddyl.StateMultibody(dynamics.model)

    def python_task(q, V_Sd):
        return m.c.task(q, V_Sd)

    with pytest.raises(ValueError, match="needs a compiled kernel"):
        task_residual(state, dynamics, python_task, np.zeros(12), native=True)
    assert not TorqueOCP(spec_of("three_pandas_circle"), python_task).native  # (the Python residual then)


@pytest.fixture(scope="module")
def circle():
    m = bundled_module("three_pandas_circle")
    q0 = ready("three_pandas_circle")
    V_Sd = desired(SCENARIOS["circle"].goal, _target(m, q0), "circle")
    ocp = TorqueOCP(spec_of("three_pandas_circle"), m.c.task, N=50, dt=0.02)
    return m, q0, V_Sd, ocp, ocp.solve(q0, V_Sd, max_iterations=100)


def test_the_torque_ocp_reaches_the_circle(circle):
    m, _, V_Sd, _, result = circle
    assert result.converged and result.error_norm < 1e-4, (result.iterations, result.errors[-1])
    assert result.errors[0] > 0.3  # (the goal is far from the start)
    # the task error is the kernel's at the final state, recomputed here
    assert abs(np.linalg.norm(m.c.task(result.q[-1], V_Sd)[0]) - result.error_norm) <= 1e-15


def test_the_solution_is_what_the_torques_do_under_pinocchios_dynamics(circle):
    """Re-simulated by our own symplectic Euler over ABA: the solver's states, to 1e-9."""
    _, q0, _, ocp, result = circle
    q, qdot = resimulate(ocp.dynamics, q0, np.zeros(q0.size), result.tau, ocp.dt)
    np.testing.assert_allclose(q, result.q, atol=1e-9)
    np.testing.assert_allclose(qdot, result.qdot, atol=1e-9)


def test_torque_and_joint_limits_hold(circle):
    *_, result = circle
    effort = result.torque_limit
    assert np.all(np.abs(result.tau) <= effort + 1e-9)
    assert np.abs(result.tau).max() >= 0.5 * effort.max()  # (the box is met, so it is checked)
    lower, upper = joint_limits("three_pandas_circle")  # the URDFs' limits, read independently
    np.testing.assert_allclose((lower, upper), result.position_limits)
    assert np.all(result.q >= lower - 1e-3) and np.all(result.q <= upper + 1e-3)  # (a barrier: soft)


def test_a_moving_target_is_tracked():
    """The circle translates at 0.1 m/s and grows by 20 % over 1 s: the running cost tracks it."""
    m = bundled_module("three_pandas_circle")
    q0 = ready("three_pandas_circle")
    V_Sc0 = _target(m, q0)

    def moving(t):
        return target_from(V_Sc0, (0.1 * t, 0.0, 0.0), None, 1.0 + 0.2 * t, kind="circle")

    ocp = TorqueOCP(spec_of("three_pandas_circle"), m.c.task, N=50, dt=0.02)
    result = ocp.solve(q0, moving, max_iterations=100)
    assert result.errors[0] <= 1e-12  # (the target starts at the ready circle)
    assert result.errors.max() <= 0.02 and result.error_norm <= 1e-3, result.errors


def test_gagen_reach_dynamics_reports_and_plots(tmp_path, capsys):
    from gagen.cli import main

    argv = ["reach", "circle", "--dynamics", "--N", "50", "--horizon", "1.0", "--out", str(tmp_path)]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "circle (three_pandas_circle, 21 DOF, N = 50): box-FDDP, torque level" in out and "reached" in out
    assert "joints within limits: True" in out
    assert (tmp_path / "circle_torques.png").stat().st_size > 10_000


def test_the_conventional_formulation_reaches_the_same_circle(circle):
    """The end points pinned by Crocoddyl's frame-translation residuals, at the points of gagen's solution:
    the same circle, so the task error (gagen's kernel, evaluated after the solve) is as small."""
    _, q0, V_Sd, ocp, result = circle
    points = ocp.end_points(result.q[-1])
    assert [frame for frame, _ in points] == ["arm0/panda_link8", "arm1/panda_link8", "arm2/panda_link8"]
    conventional = ocp.solve(q0, V_Sd, points=points, max_iterations=100)
    assert conventional.converged
    assert conventional.error_norm <= 1e-4 and result.error_norm <= 1e-4, (conventional.errors[-1],
                                                                           result.errors[-1])
    reached = ocp.end_points(conventional.q[-1])
    assert max(np.abs(p - r).max() for (_, p), (_, r) in zip(points, reached, strict=True)) <= 1e-4


def test_the_conventional_circle_residual_equals_differences_and_reaches_the_circle(circle):
    """The circle error by 3-vector algebra of the three flanges (centre, normal, radius against the target
    circle's): its R_x equals central differences, and solved in place of gagen's task error it reaches
    the same circle (gagen's task error, evaluated after the solve, below 1e-4)."""
    from gagen.control.torque import CircleResidual, circle_through

    _, q0, V_Sd, ocp, result = circle
    points = ocp.end_points(result.q[-1])
    frames = [ocp.dynamics.model.getFrameId(frame) for frame, _ in points]
    residual = CircleResidual(ocp.state, 21, frames, *circle_through(points))
    data, _ = _residual_data(ocp.dynamics, residual)
    x, u = np.concatenate([q0 + 0.1, np.zeros(21)]), np.zeros(21)
    residual.calcDiff(data, x, u)
    Rx = np.array(data.Rx)
    differences = _differences(residual, data, x, u, 21)
    np.testing.assert_allclose(Rx[:, :21], differences, atol=1e-6 * np.abs(Rx).max())
    solved = ocp.solve(q0, V_Sd, points=points, circle=True, max_iterations=100)
    assert solved.converged and solved.error_norm <= 1e-4, solved.errors[-1]


@pytest.mark.parametrize("native", [False, True], ids=["python", "c++"])
def test_a_target_or_kernel_of_the_wrong_shape_is_refused_before_the_c_is_called(native):
    """The C++ residual calls a raw C address: a V_Sd of 10 values, a non-finite one, or a kernel of
    another signature would make it read or write out of bounds, so each is refused in one line first."""
    m = bundled_module("three_pandas_circle")
    dynamics = SystemDynamics(spec_of("three_pandas_circle"))
    state = crocoddyl.StateMultibody(dynamics.model)
    with pytest.raises(ValueError, match=r"V_Sd: expected 12 values \(a similarity versor\), got 10"):
        task_residual(state, dynamics, m.c.task, np.zeros(10), native=native)
    with pytest.raises(ValueError, match=r"V_Sd: expected finite values"):
        task_residual(state, dynamics, m.c.task, np.full(12, np.nan), native=native)
    with pytest.raises(ValueError, match=r"the kernel similarity takes \(q\[21\]\) and gives"):
        task_residual(state, dynamics, m.c.similarity, np.zeros(12), native=native)
    other = bundled_module("panda_point")  # a task kernel of 7 joints for a model of 21
    with pytest.raises(ValueError, match=r"the kernel task takes \(q\[7\], V_Sd\[12\]\)"):
        task_residual(state, dynamics, other.c.task, np.zeros(12), native=native)


@pytest.mark.compiling
def test_gagen_reach_dynamics_takes_a_users_own_spec(tmp_path, capsys):
    """A spec file of the user's (the three Pandas copied, renamed, with a goal stated on the command line)
    works as the bundled name does: its module is built from the file, then the torque-level OCP."""
    import shutil

    from gagen.cli import main

    robots = tmp_path / "robots"
    shutil.copytree(spec_of("three_pandas_circle").parent / "panda", robots / "panda")
    text = spec_of("three_pandas_circle").read_text().replace("name: three_pandas_circle", "name: my_cell")
    (robots / "my_cell.yaml").write_text(text)
    argv = [ "reach", str(robots / "my_cell.yaml"), "--translation", "0,0,0.05", "--dynamics", "--N", "40",
            "--horizon", "1.0", "--out", str(tmp_path / "out")]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "(my_cell.yaml" in out or "my_cell" in out
    assert "reached" in out and (tmp_path / "out" / "command_line_torques.png").is_file()
