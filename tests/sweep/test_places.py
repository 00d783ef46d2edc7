"""The sweeps' batched geometry for systems with more chains than their primitive needs: the fitted
centre and radius of each row (``places.fitted_rounds``) against the model's best fit on the reference
interpreter (``gagen.model.fitting.best_fit``: its centre and radius read from the conformal blade), and
a system with a measured chain refused in one line."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gagen.interp import MultiVector, preset
from gagen.model.conformal import location, point, vector
from gagen.model.fitting import best_fit
from gagen.model.primitives import centre, radius
from gagen.sweep.places import fitted_rounds, locate
from gagen.sweep.problems import Manipulability
from gagen.sweep.store import SweepError

LIKE = MultiVector.zero(preset("cga3d"))


def _reference(kind: str, cloud: np.ndarray) -> tuple[np.ndarray, float]:
    x = best_fit(kind, [point(vector(LIKE, [float(c) for c in p])) for p in cloud]).primitive
    return np.array([float(location(centre(x))[b]) for b in ("e1", "e2", "e3")]), float(radius(x))


@settings(max_examples=20, deadline=None)
@given(kind=st.sampled_from(["circle", "sphere"]), extra=st.integers(1, 3), seed=st.integers(0, 2**31))
def test_fitted_centres_and_radii_are_the_models_best_fit(kind, extra, seed):
    rng = np.random.default_rng(seed)
    count = (3 if kind == "circle" else 4) + extra
    direction = rng.normal(size=(3, count, 3))
    direction /= np.linalg.norm(direction, axis=2, keepdims=True)
    if kind == "circle":
        direction[..., 2] = 0.0
        direction /= np.linalg.norm(direction, axis=2, keepdims=True)
    clouds = rng.normal(size=(3, 1, 3)) + rng.uniform(0.2, 2.0, size=(3, 1, 1)) * direction \
        + 0.02 * rng.normal(size=(3, count, 3))
    centres, radii = fitted_rounds(kind, clouds)
    for cloud, c, r in zip(clouds, centres, radii, strict=True):
        expected_centre, expected_radius = _reference(kind, cloud)
        np.testing.assert_allclose(c, expected_centre, atol=1e-9)
        assert r == pytest.approx(expected_radius, rel=1e-9)


def test_points_exactly_on_a_sphere_give_the_sphere():
    rng = np.random.default_rng(3)
    d = rng.normal(size=(1, 6, 3))
    d /= np.linalg.norm(d, axis=2, keepdims=True)
    centres, radii = locate("sphere", np.array([0.1, -0.2, 0.3]) + 0.7 * d)
    np.testing.assert_allclose(centres[0], [0.1, -0.2, 0.3], atol=1e-12)
    assert radii[0] == pytest.approx(0.7, rel=1e-12)


def test_a_system_with_a_measured_chain_is_refused_in_one_line():
    with pytest.raises(SweepError, match=r"^system: .*hand_circle.yaml has measured chains \(hand\)"):
        Manipulability(samples=10, system="robots/leader/two_pandas_hand_circle.yaml")
