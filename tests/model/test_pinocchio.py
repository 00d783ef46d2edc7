"""FK and 6×n Jacobians of URDF chains against Pinocchio (an independent rigid-body library), on the
same URDF file: the interpreter's model and the flattened CasADi kernel, at 50 random configurations.

Pinocchio models the whole URDF tree (a humanoid's two arms, a hand's four fingers); a chain's joints
are found in it by name: its values are picked from Pinocchio's q and its columns from the Jacobian,
whose other columns (joints not between base and tip) must be zero."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import tiered

from gagen.algebra.signature import cga3d
from gagen.crosscheck import Formula, dense_outputs, flatten_formula
from gagen.interp import MultiVector
from gagen.model import kinematics as K
from gagen.model.conformal import EUCLID, location, vector
from gagen.robots.urdf import load_chain

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
G1 = ROBOTS / "g1" / "g1_upper_body.urdf"
LEAP = ROBOTS / "leap_hand" / "leap_hand.urdf"
CHAINS = {"panda": (ROBOTS / "panda" / "panda.urdf", "panda_link0", "panda_link8"),
          "iiwa14": (ROBOTS / "iiwa14" / "iiwa14.urdf", "iiwa_link_0", "iiwa_link_ee"),
          "g1_left_arm": (G1, "pelvis", "left_rubber_hand"),
          "g1_right_arm": (G1, "pelvis", "right_rubber_hand"),
          "g1_torso_point": (G1, "pelvis", "torso_point"),
          "leap_index": (LEAP, "palm_lower", "index_tip"),
          "leap_middle": (LEAP, "palm_lower", "middle_tip"),
          "leap_ring": (LEAP, "palm_lower", "ring_tip"),
          "leap_thumb": (LEAP, "palm_lower", "thumb_tip")}
ALG = cga3d()


def _twist(line) -> np.ndarray:
    """A spatial Jacobian column [e12, e13, e23, e1∞, e2∞, e3∞] as Pinocchio's [v; ω]."""
    return np.array([line["e1inf"], line["e2inf"], line["e3inf"], line["e23"], -line["e13"], line["e12"]])


@cache
def _model(urdf: Path):
    return pin.buildModelFromUrdf(str(urdf))


@cache
def _setup(name: str):
    urdf, base, tip = CHAINS[name]
    model = _model(urdf)
    assert model.frames[model.getFrameId(base)].parentJoint == 0, f"{base} is not Pinocchio's root body"
    joints = load_chain(urdf, base, tip)
    dof = sum(j.moves for j in joints)
    ids = [model.getJointId(j.name) for j in joints if j.moves]
    assert all(0 < i < model.njoints and model.joints[i].nq == 1 for i in ids), f"{name}: joints by name"
    idx_q = [model.joints[i].idx_q for i in ids]
    idx_v = [model.joints[i].idx_v for i in ids]

    def fk_and_jacobian(zero, q):
        motor, lines = K.chain_kinematics(zero, joints, q)
        return (motor, K.end_point(motor), *K.spatial_jacobian(lines))

    kernel = flatten_formula(Formula(f"{name}_fk_jacobian", ALG, (("q", dof),), fk_and_jacobian,
                                     pass_zero=True))
    return model, model.getFrameId(tip), joints, kernel, idx_q, idx_v


def _pinocchio(model, frame, q):
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    placement = data.oMf[frame]
    jacobian = pin.computeFrameJacobian(model, data, q, frame, pin.ReferenceFrame.WORLD)
    return placement.translation.copy(), placement.rotation.copy(), jacobian


@pytest.mark.parametrize("name", tiered(sorted(CHAINS), {"panda", "g1_torso_point"}))
def test_fk_and_jacobian_agree_with_pinocchio(name):
    model, frame, joints, kernel, idx_q, idx_v = _setup(name)
    rng = np.random.default_rng(2024)
    like = MultiVector.zero(ALG)
    others = np.setdiff1d(np.arange(model.nv), idx_v)
    for _ in range(50):
        full = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
        position, rotation, full_jacobian = _pinocchio(model, frame, full)
        np.testing.assert_array_equal(full_jacobian[:, others], 0.0)  # no other joint moves the tip
        q, jacobian = full[idx_q], full_jacobian[:, idx_v]
        # the interpreter's model
        motor, lines = K.chain_kinematics(like, joints, list(q))
        np.testing.assert_allclose([location(K.end_point(motor))[k] for k in EUCLID], position, atol=1e-10)
        for i in range(3):
            image = motor.sandwich(vector(like, np.eye(3)[i]))
            np.testing.assert_allclose([image[k] for k in EUCLID], rotation[:, i], atol=1e-10)
        np.testing.assert_allclose(np.array([_twist(line) for line in lines]).T, jacobian, atol=1e-10)
        # the flattened kernel
        outputs = dense_outputs(kernel, ALG, kernel(q))
        point = MultiVector(ALG, outputs[1])
        np.testing.assert_allclose([location(point)[k] for k in EUCLID], position, atol=1e-10)
        columns = [_twist(MultiVector(ALG, c)) for c in outputs[2:]]
        np.testing.assert_allclose(np.array(columns).T, jacobian, atol=1e-10)


def _as_written(q, joints, model, frame, idx_q, idx_v, kernel=None) -> tuple[float, float]:
    """The largest FK (position, rotation) and Jacobian differences to Pinocchio at q: the interpreter's,
    and the flattened kernel's when given."""
    position, rotation, full_jacobian = _pinocchio(model, frame, q)
    jacobian = full_jacobian[:, idx_v]
    like = MultiVector.zero(ALG)
    motor, lines = K.chain_kinematics(like, joints, list(q[idx_q]))
    fk = max(np.abs([location(K.end_point(motor))[k] for k in EUCLID] - position).max(),
             *(np.abs([motor.sandwich(vector(like, np.eye(3)[i]))[k] for k in EUCLID] - rotation[:, i]).max()
               for i in range(3)))
    jac = np.abs(np.array([_twist(line) for line in lines]).T - jacobian).max()
    if kernel is not None:
        outputs = dense_outputs(kernel, ALG, kernel(q[idx_q]))
        fk = max(fk, np.abs([location(MultiVector(ALG, outputs[1]))[k] for k in EUCLID] - position).max())
        columns = [_twist(MultiVector(ALG, c)) for c in outputs[2:]]
        jac = max(jac, np.abs(np.array(columns).T - jacobian).max())
    return float(fk), float(jac)


def test_unsnapped_constants_agree_with_pinocchio_to_1e_12(tmp_path):
    """URDFs write π/2 as ``1.57079632679`` (UR, Kinova, …): snapped to an exact π/2 (the default) the
    chain is off the file's by ≈ 5e-12 rad per turn; with ``snap=False`` it keeps the numbers as written
    and FK and Jacobians agree with Pinocchio on the same file to 1e-12, interpreter and kernel."""
    urdf = tmp_path / "panda_rounded.urdf"
    text = (ROBOTS / "panda" / "panda.urdf").read_text()
    urdf.write_text(text.replace("1.5707963267948966", "1.57079632679"))
    model = pin.buildModelFromUrdf(str(urdf))
    frame = model.getFrameId("panda_link8")
    snapped, as_written = (load_chain(urdf, "panda_link0", "panda_link8", snap=s) for s in (True, False))
    assert all(j.snap is False for j in as_written) and "snap=False" in repr(as_written[1])
    assert "snap" not in repr(snapped[1])  # snapped reprs (build keys) are those of before the switch
    turns = [j.rpy for j in as_written if j.rpy[0]][:2]
    assert turns == [(-1.57079632679, 0.0, 0.0), (1.57079632679, 0.0, 0.0)]
    ids = [model.getJointId(j.name) for j in as_written if j.moves]
    idx_q, idx_v = [model.joints[i].idx_q for i in ids], [model.joints[i].idx_v for i in ids]

    def fk_and_jacobian(zero, q):
        motor, lines = K.chain_kinematics(zero, as_written, q)
        return (motor, K.end_point(motor), *K.spatial_jacobian(lines))

    kernel = flatten_formula(Formula("panda_rounded_fk_jacobian", ALG, (("q", 7),), fk_and_jacobian,
                                     pass_zero=True))
    rng = np.random.default_rng(7)
    worst_snapped = 0.0
    for _ in range(20):
        q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
        fk, jac = _as_written(q, as_written, model, frame, idx_q, idx_v, kernel)
        assert fk <= 1e-12 and jac <= 1e-12
        worst_snapped = max(worst_snapped, *_as_written(q, snapped, model, frame, idx_q, idx_v))
    assert 1e-12 < worst_snapped < 1e-10  # the snapped chain differs, by the rounding of π/2 only
