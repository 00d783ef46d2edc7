"""FK and 6×n Jacobians of URDF chains against Pinocchio (an independent rigid-body library), on the
same URDF file: the interpreter's model and the flattened CasADi kernel, at 50 random configurations."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from gagen.algebra.signature import cga3d
from gagen.crosscheck import Formula, dense_outputs, flatten_formula
from gagen.interp import MultiVector
from gagen.model import kinematics as K
from gagen.model.conformal import EUCLID, location, vector
from gagen.robots.urdf import load_chain

ROBOTS = Path(__file__).resolve().parent.parent / "robots"
CHAINS = {"panda": (ROBOTS / "panda" / "panda.urdf", "panda_link0", "panda_link8"),
          "iiwa14": (ROBOTS / "iiwa14" / "iiwa14.urdf", "iiwa_link_0", "iiwa_link_ee")}
ALG = cga3d()


def _twist(line) -> np.ndarray:
    """A spatial Jacobian column [e12, e13, e23, e1∞, e2∞, e3∞] as Pinocchio's [v; ω]."""
    return np.array([line["e1inf"], line["e2inf"], line["e3inf"], line["e23"], -line["e13"], line["e12"]])


@cache
def _setup(name: str):
    urdf, base, tip = CHAINS[name]
    model = pin.buildModelFromUrdf(str(urdf))
    joints = load_chain(urdf, base, tip)
    dof = sum(j.moves for j in joints)

    def fk_and_jacobian(zero, q):
        motor, lines = K.chain_kinematics(zero, joints, q)
        return (motor, K.end_point(motor), *K.spatial_jacobian(lines))

    kernel = flatten_formula(Formula(f"{name}_fk_jacobian", ALG, (("q", dof),), fk_and_jacobian,
                                     pass_zero=True))
    return model, model.getFrameId(tip), joints, kernel


def _pinocchio(model, frame, q):
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    placement = data.oMf[frame]
    jacobian = pin.computeFrameJacobian(model, data, q, frame, pin.ReferenceFrame.WORLD)
    return placement.translation.copy(), placement.rotation.copy(), jacobian


@pytest.mark.parametrize("name", sorted(CHAINS))
def test_fk_and_jacobian_agree_with_pinocchio(name):
    model, frame, joints, kernel = _setup(name)
    rng = np.random.default_rng(2024)
    like = MultiVector.zero(ALG)
    for _ in range(50):
        q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
        position, rotation, jacobian = _pinocchio(model, frame, q)
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
