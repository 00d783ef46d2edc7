"""Serial-chain FK as motors against an independent 4×4 homogeneous-matrix chain (numpy)."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import sympy
from conftest import tiered
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from gagen.algebra.signature import cga3d
from gagen.crosscheck import Formula, flatten_formula, relative_error
from gagen.interp import MultiVector
from gagen.model import kinematics as K
from gagen.model.conformal import EUCLID, location, point, vector
from gagen.model.kinematics import Joint, end_point, exact_angle, forward_kinematics

HALF_PI = math.pi / 2
# Franka Emika Panda, joint origins of franka_description's panda_arm.xacro, plus the flange
PANDA = (
    Joint("joint1", "revolute", (0, 0, 0.333), (0, 0, 0)),
    Joint("joint2", "revolute", (0, 0, 0), (-HALF_PI, 0, 0)),
    Joint("joint3", "revolute", (0, -0.316, 0), (HALF_PI, 0, 0)),
    Joint("joint4", "revolute", (0.0825, 0, 0), (HALF_PI, 0, 0)),
    Joint("joint5", "revolute", (-0.0825, 0.384, 0), (-HALF_PI, 0, 0)),
    Joint("joint6", "revolute", (0, 0, 0), (HALF_PI, 0, 0)),
    Joint("joint7", "revolute", (0.088, 0, 0), (HALF_PI, 0, 0)),
    Joint("flange", "fixed", (0, 0, 0.107)),
)
# a chain with every kind of joint and general (non-snapped) angles and axes
MIXED = (
    Joint("a", "revolute", (0.1, -0.2, 0.3), (0.3, -0.7, 1.1), (0.6, 0.0, 0.8)),
    Joint("b", "prismatic", (0.0, 0.5, 0.0), (0.0, HALF_PI, 0.0), (0.0, 0.0, 1.0)),
    Joint("c", "fixed", (0.2, 0.0, 0.0), (math.pi, 0.0, -HALF_PI)),
    Joint("d", "continuous", (0.0, 0.0, 0.4), (0.1, 0.2, 0.3), (0.0, 1.0, 0.0)),
)
CHAINS = {"panda": PANDA, "mixed": MIXED}
PINNED_FK = (156, 116, 1, 7, 7)
PINNED_FK_JACOBIAN = (203, 147, 16, {"cos": 7, "sin": 7})


def _rot(axis, angle):
    """Rodrigues rotation matrix."""
    k = np.asarray(axis, float)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx


def _homogeneous_fk(joints, q):
    h = np.eye(4)
    values = iter(q)
    for j in joints:
        r, p, y = j.rpy
        fixed = np.eye(4)
        fixed[:3, :3] = _rot((0, 0, 1), y) @ _rot((0, 1, 0), p) @ _rot((1, 0, 0), r)
        fixed[:3, 3] = j.xyz
        h = h @ fixed
        if j.moves:
            move = np.eye(4)
            if j.kind == "prismatic":
                move[:3, 3] = np.asarray(j.axis) * next(values)
            else:
                move[:3, :3] = _rot(j.axis, next(values))
            h = h @ move
    return h


def _dof(joints):
    return sum(j.moves for j in joints)


@pytest.mark.parametrize("chain", tiered(sorted(CHAINS), {"mixed"}))
@settings(max_examples=100)
@given(data=st.data())
def test_motor_fk_equals_homogeneous_matrix_chain(chain, data):
    joints = CHAINS[chain]
    q = data.draw(arrays(np.float64, _dof(joints), elements=st.floats(-3.1, 3.1)))
    like = MultiVector.zero(cga3d())
    motor = forward_kinematics(like, joints, list(q))
    h = _homogeneous_fk(joints, q)
    np.testing.assert_allclose([location(end_point(motor))[k] for k in EUCLID], h[:3, 3], atol=1e-12)
    for i in range(3):  # rotation: images of the basis vectors
        image = motor.sandwich(vector(like, np.eye(3)[i]))
        np.testing.assert_allclose([image[k] for k in EUCLID], h[:3, i], atol=1e-12)


@cache
def _fk_kernel(chain):
    joints = CHAINS[chain]
    formula = Formula(f"fk_{chain}", cga3d(), (("q", _dof(joints)),),
                      lambda zero, q: (forward_kinematics(zero, joints, q), end_point(
                          forward_kinematics(zero, joints, q))), pass_zero=True)
    return formula, flatten_formula(formula)


@pytest.mark.parametrize("chain", tiered(sorted(CHAINS), {"mixed"}))
def test_fk_kernel_equals_interpreter(chain):
    formula, kernel = _fk_kernel(chain)
    rng = np.random.default_rng(0)
    for _ in range(50):
        assert relative_error(kernel, formula, [rng.uniform(-3, 3, _dof(CHAINS[chain]))]) < 1e-12


def test_quarter_turns_snap_to_exact_constants():
    assert exact_angle(1.5707963267948966) == sympy.pi / 2
    assert exact_angle(-math.pi) == -sympy.pi
    assert exact_angle(1.5708) != sympy.pi / 2  # 3.7e-6 away: kept as given


def _pose_kernel(with_jacobian: bool):
    """The production path (``chain_pose``): motor, P(t) from the carried position, spatial J."""

    def pose(zero, q):
        motor, lines, position = K.chain_pose(zero, PANDA, q)
        return (motor, point(position), *(K.spatial_jacobian(lines) if with_jacobian else ()))

    return flatten_formula(Formula("panda_pose", cga3d(), (("q", 7),), pose, pass_zero=True))


def test_panda_fk_op_count_is_pinned():
    """Panda FK motor + end point on the production path: 273 flops + 7 sin/cos (the motor product
    chain was 340, the frame-carried chain 282 before sums equal up to a constant shared one node;
    the 4×4-matrix chain is 129)."""
    ops = _pose_kernel(False).op_count
    assert (ops.mul, ops.add, ops.neg, ops.calls.get("sin"), ops.calls.get("cos")) == PINNED_FK


def _fd(fn, q, h=1e-6):
    """Central differences of a multivector-valued function of q: one dense column per joint."""
    cols = []
    for i in range(len(q)):
        step = np.zeros(len(q))
        step[i] = h
        cols.append((fn(q + step).coeffs - fn(q - step).coeffs) / (2 * h))
    return cols


@pytest.mark.parametrize("chain", tiered(sorted(CHAINS), {"mixed"}))
@settings(max_examples=20)
@given(data=st.data())
def test_jacobians_from_joint_lines_equal_finite_differences(chain, data):
    """Spatial (−2 J_A V~), body (−2 V~ J_A), analytic (∂V/∂q) and point (∂P/∂q) Jacobians from the
    joint lines, against central differences of the interpreter's FK."""
    joints = CHAINS[chain]
    q = data.draw(arrays(np.float64, _dof(joints), elements=st.floats(-3, 3)))
    like = MultiVector.zero(cga3d())
    motor, lines = K.chain_kinematics(like, joints, list(q))
    fk = lambda x: forward_kinematics(like, joints, list(x))  # noqa: E731
    d_motor = _fd(fk, q)
    d_point = _fd(lambda x: end_point(fk(x)), q)
    for i, dv in enumerate(d_motor):
        dv = MultiVector(cga3d(), dv)
        np.testing.assert_allclose(K.analytic_jacobian(motor, lines)[i].coeffs, dv.coeffs, atol=1e-8)
        np.testing.assert_allclose(K.spatial_jacobian(lines)[i].coeffs, (dv * ~motor * -2).coeffs, atol=1e-8)
        np.testing.assert_allclose(K.body_jacobian(motor, lines)[i].coeffs, (~motor * dv * -2).coeffs,
                                   atol=1e-8)
        np.testing.assert_allclose(K.point_jacobian(motor, lines)[i].coeffs, d_point[i], atol=1e-8)


@pytest.mark.parametrize("chain", sorted(CHAINS))
def test_spatial_jacobian_columns_are_the_world_screw_axes(chain):
    """Against the matrix chain: a revolute column is (ω, p × ω) with ω the world axis and p a
    point on it; the tip moves at ω × (x_tip − p)."""
    joints = CHAINS[chain]
    rng = np.random.default_rng(4)
    q = rng.uniform(-2, 2, _dof(joints))
    like = MultiVector.zero(cga3d())
    _, lines = K.chain_kinematics(like, joints, list(q))
    tip = _homogeneous_fk(joints, q)[:3, 3]
    moving = [j for j in joints if j.moves]
    for k, (joint, line) in enumerate(zip(moving, lines, strict=True)):
        # frame of joint k before its motion: the chain up to it, with its own value set to 0
        head = joints[: joints.index(joint) + 1]
        frame = _homogeneous_fk(head, np.concatenate([q[:k], [0.0]]))
        axis = frame[:3, :3] @ np.asarray(joint.axis)
        omega = np.array([line["e23"], -line["e13"], line["e12"]])
        v = np.array([line[f"e{i}inf"] for i in (1, 2, 3)])
        if joint.kind == "prismatic":
            np.testing.assert_allclose(omega, 0, atol=1e-12)
            np.testing.assert_allclose(v, axis, atol=1e-12)
        else:
            np.testing.assert_allclose(omega, axis, atol=1e-12)
            np.testing.assert_allclose(v, np.cross(frame[:3, 3], omega), atol=1e-12)
            tip_velocity = np.cross(omega, tip - frame[:3, 3])
            np.testing.assert_allclose(tip_velocity, v + np.cross(omega, tip), atol=1e-12)


def test_panda_fk_and_spatial_jacobian_op_count_is_pinned():
    """Motor + end point + 6×7 spatial Jacobian from the joint lines: 366 flops + 7 sin/cos (the motor
    product chain was 744, rotor + position 602, the frame-carried chain 432 before sums equal up to a
    constant shared one node; the 4×4-matrix chain with its spatial Jacobian is 186)."""
    ops = _pose_kernel(True).op_count
    assert (ops.mul, ops.add, ops.neg, ops.calls) == PINNED_FK_JACOBIAN


def test_pose_kernel_values_equal_the_motor_sandwich_end_point():
    """P(t) from the carried position equals V_M e0 V_M~ of the interpreter's motor (1e-12)."""
    kernel, like = _pose_kernel(True), MultiVector.zero(cga3d())
    rng = np.random.default_rng(12)
    for _ in range(20):
        q = rng.uniform(-3, 3, 7)
        motor = forward_kinematics(like, PANDA, list(q))
        outputs = kernel(q)
        np.testing.assert_allclose(outputs[0], [motor[b] for b in kernel.outputs[0].rows], atol=1e-12)
        np.testing.assert_allclose(outputs[1], [end_point(motor)[b] for b in kernel.outputs[1].rows],
                                   atol=1e-12)


@pytest.mark.parametrize("chain", tiered(sorted(CHAINS), {"mixed"}))
def test_line_jacobian_equals_finite_differences(chain):
    """[SMC Eq. 20] for the tool's z axis (the bivector e12, rotation about it) and a line offset
    from the tool origin, against central differences of V_M L V_M~."""
    joints = CHAINS[chain]
    like = MultiVector.zero(cga3d())
    rng = np.random.default_rng(8)
    tool_lines = [like.make({"e12": 1.0}), like.make({"e23": 0.6, "e13": -0.8, "e2inf": 0.3})]
    for _ in range(5):
        q = rng.uniform(-2.5, 2.5, _dof(joints))
        motor, lines = K.chain_kinematics(like, joints, list(q))
        for tool_line in tool_lines:
            fd = _fd(lambda x, t=tool_line: forward_kinematics(like, joints, list(x)).sandwich(t), q)
            for ours, numeric in zip(K.line_jacobian(motor, lines, tool_line), fd, strict=True):
                np.testing.assert_allclose(ours.coeffs, numeric, atol=1e-8)


@pytest.mark.parametrize("chain", tiered(sorted(CHAINS), {"mixed"}))
def test_frame_turned_by_full_angles_gives_the_same_positions_and_lines(chain):
    """Without the motor the frame turns by cos q, sin q (Rodrigues) instead of by the joint rotor's
    half angles: the same end position and joint lines to 1e-14 (MIXED has a general, non-axis
    joint axis), and exactly what the system kernels use."""
    joints = CHAINS[chain]
    like = MultiVector.zero(cga3d())
    rng = np.random.default_rng(11)
    for _ in range(50):
        q = list(rng.uniform(-3.2, 3.2, _dof(joints)))
        _, lines, position = K.chain_pose(like, joints, q)
        none, free_lines, free_position = K.chain_pose(like, joints, q, with_motor=False)
        assert none is None
        np.testing.assert_allclose(free_position.coeffs, position.coeffs, rtol=0, atol=1e-14)
        for a, b in zip(free_lines, lines, strict=True):
            np.testing.assert_allclose(a.coeffs, b.coeffs, rtol=0, atol=1e-14)
