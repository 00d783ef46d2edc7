"""The mass model's centre of mass against closed forms on symmetric stances and an independent 4×4
matrix chain (tests/hexapod/matrix_chain.py) at random configurations and body poses; MuJoCo's
subtree_com is compared in test_mujoco_walk.py."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gagen.apps.hexapod.mass import MassModel, centre_of_mass, default_mass_model, total_mass

from . import matrix_chain


def _pose(rng: np.random.Generator) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = matrix_chain.rotation(rng.normal(size=3), np.array([rng.uniform(-math.pi, math.pi)]))[0]
    pose[:3, 3] = rng.uniform(-1, 1, size=3)
    return pose


def test_default_model_is_documented(hexapod):
    model = default_mass_model(hexapod)
    assert total_mass(model) == pytest.approx(2.5, abs=1e-12)
    assert model.body_size == pytest.approx((2 * 0.103923048454, 0.24, 0.05), abs=1e-12)


def test_symmetric_stance_closed_form(hexapod):
    """Every leg at (0, a, b): the six legs are 60° turns of each other, so the CoM is on the body's z
    axis at the femur's and tibia's mean height: z_f = −l2/2 sin a, z_t = −l2 sin a − l3/2 sin(a + b)."""
    model = default_mass_model(hexapod)
    _, m2, m3 = model.link_masses[0]
    _, l2, l3 = hexapod.legs[0].lengths
    for a, b in [(0.0, 0.0), (-0.25, 1.8), (0.7, -1.1)]:
        com = centre_of_mass(hexapod, model, np.eye(4), np.tile([0.0, a, b], 6))
        z = 6 * (m2 * -l2 / 2 * math.sin(a) + m3 * (-l2 * math.sin(a) - l3 / 2 * math.sin(a + b)))
        np.testing.assert_allclose(com, [0.0, 0.0, z / total_mass(model)], atol=1e-15)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_against_matrix_chain(hexapod, seed):
    rng = np.random.default_rng(seed)
    masses = rng.uniform(0.01, 1.0, size=(6, 3))
    model = MassModel(float(rng.uniform(0.1, 3)), (0.2, 0.2, 0.05), tuple(map(tuple, masses)),
                      body_centre=tuple(rng.uniform(-0.02, 0.02, 3)))
    q = np.concatenate([matrix_chain.random_configurations(leg, rng, 1)[0] for leg in hexapod.legs])
    pose = _pose(rng)
    weighted = model.body_mass * np.array(model.body_centre)
    for i, leg in enumerate(hexapod.legs):
        joints, tip = matrix_chain.frames(leg, q[3 * i:3 * i + 3])
        ends = [f[0, :3, 3] for f in joints] + [tip[0, :3, 3]]
        for j in range(3):
            weighted = weighted + masses[i, j] * (ends[j] + ends[j + 1]) / 2
    expected = pose[:3, :3] @ (weighted / total_mass(model)) + pose[:3, 3]
    np.testing.assert_allclose(centre_of_mass(hexapod, model, pose, q), expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("field,value", [("body_mass", 0.0), ("body_mass", math.nan), ("link_radius", -1.0)])
def test_bad_model(hexapod, field, value):
    import dataclasses

    with pytest.raises(ValueError, match=field):
        dataclasses.replace(default_mass_model(hexapod), **{field: value})


def test_bad_inputs(hexapod):
    model = default_mass_model(hexapod)
    with pytest.raises(ValueError, match="q: expected 18"):
        centre_of_mass(hexapod, model, np.eye(4), np.zeros(17))
    with pytest.raises(ValueError, match="pose_matrix"):
        centre_of_mass(hexapod, model, np.eye(3), np.zeros(18))
