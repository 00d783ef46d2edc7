"""Ground contact in PGA and CGA (issue 14, item 4): the plane Π, a point's signed distance, its foot on
the plane and the incidence Π ∧ P, on flat and sloped ground, against the Euclidean closed forms
(n·x − d, x − (n·x − d) n) for scaled planes and points; and the generated kernels against both."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gagen.algebra.kinds import kind_blades
from gagen.apps.hexapod.kernels import hexapod_kernels, random_pose, random_q, toe_position
from gagen.check import DIFFERENCES, INTERPRETER, check_kernels, failures
from gagen.interp import MultiVector, preset
from gagen.model.euclidean import GEOMETRIES

ALGEBRAS = sorted(GEOMETRIES)
finite = st.floats(-2.0, 2.0, allow_nan=False)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _sloped(slope_deg: float, about=(1.0, 0.0, 0.0)) -> np.ndarray:
    """The unit normal of ground tilted by ``slope_deg`` about a horizontal axis (Rodrigues)."""
    k, z, a = _unit(about), np.array([0.0, 0.0, 1.0]), np.radians(slope_deg)
    return z * np.cos(a) + np.cross(k, z) * np.sin(a) + k * (k @ z) * (1 - np.cos(a))


@pytest.mark.parametrize("algebra", ALGEBRAS)
@settings(max_examples=60, deadline=None, derandomize=True)
@given(x=st.lists(finite, min_size=3, max_size=3), normal=st.lists(finite, min_size=3, max_size=3),
       offset=finite, plane_weight=st.floats(0.2, 5.0), point_weight=st.floats(0.2, 5.0))
def test_distance_foot_and_incidence_match_the_closed_form(algebra, x, normal, offset, plane_weight,
                                                            point_weight):
    if np.linalg.norm(normal) < 1e-3:
        return
    geo, zero = GEOMETRIES[algebra], MultiVector.zero(preset(algebra))
    n, x = _unit(normal), np.array(x)
    plane = geo.plane(zero, list(n), offset) * plane_weight
    p = geo.point(zero, list(x)) * point_weight
    height = n @ x - offset
    assert geo.signed_distance(plane, p) == pytest.approx(height, abs=1e-12)
    foot = geo.project(plane, p)
    np.testing.assert_allclose(geo.location(foot), x - height * n, atol=1e-12)
    assert abs(geo.signed_distance(plane, foot)) < 1e-12  # the foot lies on the plane
    # Π ∧ P: the pseudoscalar times the height, scaled by both weights
    assert geo.incidence(plane, p) == pytest.approx(height * plane_weight * point_weight, abs=1e-11)


@pytest.mark.parametrize("algebra", ALGEBRAS)
@pytest.mark.parametrize("slope", [0.0, 10.0, 25.0])
def test_contact_test_on_sloped_ground(algebra, slope):
    """A toe placed on the sloped ground has Π ∧ P = 0 (to rounding); one lifted by h along the
    normal has Π ∧ P = h; the foot of the lifted toe is the placed one."""
    geo, zero = GEOMETRIES[algebra], MultiVector.zero(preset(algebra))
    n = _sloped(slope, about=(0.3, 1.0, 0.0))
    offset = -0.02
    plane = geo.plane(zero, list(n), offset)
    rng = np.random.default_rng(3)
    for _ in range(20):
        on = rng.uniform(-1, 1, 3)
        on -= (n @ on - offset) * n
        lifted = on + 0.037 * n
        assert abs(geo.incidence(plane, geo.point(zero, list(on)))) < 1e-15 + 1e-15 * abs(on).max()
        assert geo.incidence(plane, geo.point(zero, list(lifted))) == pytest.approx(0.037, abs=1e-14)
        np.testing.assert_allclose(geo.location(geo.project(plane, geo.point(zero, list(lifted)))), on,
                                   atol=1e-15)


def test_pga_and_cga_planes_agree_with_each_other():
    """The same plane and point in both algebras: equal distances and feet."""
    rng = np.random.default_rng(7)
    for _ in range(50):
        n, d, x = _unit(rng.normal(size=3)), rng.normal(), rng.normal(size=3)
        values = []
        for algebra in ALGEBRAS:
            geo, zero = GEOMETRIES[algebra], MultiVector.zero(preset(algebra))
            plane, p = geo.plane(zero, list(n), d), geo.point(zero, list(x))
            values.append([geo.signed_distance(plane, p), *geo.location(geo.project(plane, p))])
        np.testing.assert_allclose(values[0], values[1], atol=1e-14)


def _motor(algebra: str, coefficients: np.ndarray) -> MultiVector:
    a = preset(algebra)
    return MultiVector.from_blades(a, dict(zip(kind_blades(a, "motor"), coefficients, strict=True)))


def _pose_matrix(algebra: str, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R, t of a pose motor, read from its action on the origin and the unit points (the test's own
    route: points, not the motor's coefficients)."""
    geo, motor = GEOMETRIES[algebra], _motor(algebra, pose)
    zero = MultiVector.zero(preset(algebra))

    def image(x):
        return np.array(geo.location(motor.sandwich(geo.point(zero, list(x)))))

    t = image([0.0, 0.0, 0.0])
    return np.array([image(e) - t for e in np.eye(3)]).T, t


@pytest.mark.compiling
@pytest.mark.parametrize("algebra", ALGEBRAS)
def test_body_contact_kernel_against_the_closed_form(hexapod, hexapod_module, algebra):
    """body_contact_<alg>: each toe's signed distance from sloped ground and its foot, compiled, against
    the toe's body-frame FK moved by the pose (R p + t) and the Euclidean closed form."""
    suffix = algebra[:3]
    kernel = getattr(hexapod_module.c, f"body_contact_{suffix}")
    geo, zero = GEOMETRIES[algebra], MultiVector.zero(preset(algebra))
    rng = np.random.default_rng(11)
    n, d = _sloped(12.0, about=(1.0, 1.0, 0.0)), -0.1
    plane = geo.plane(zero, list(n), d)
    plane_coefficients = np.array([plane[b] for b in kind_blades(preset(algebra), "plane")])
    for _ in range(10):
        pose, q = random_pose(rng, algebra), random_q(hexapod, rng)
        R, t = _pose_matrix(algebra, pose)
        distance, feet = kernel(pose, q, plane_coefficients)
        for i, leg in enumerate(hexapod.legs):
            x = R @ toe_position(leg, q[3 * i:3 * i + 3]) + t
            assert distance[i] == pytest.approx(n @ x - d, abs=1e-12)
            np.testing.assert_allclose(feet[3 * i:3 * i + 3], x - (n @ x - d) * n, atol=1e-12)


@pytest.mark.compiling
def test_every_kernel_against_the_interpreter(hexapod, hexapod_module):
    """Every generated kernel (C single, C batch, CasADi) against its function on the reference
    interpreter at random inputs from its sampler (reachable and unreachable IK targets included),
    and every J = ∂p/∂q the leg formulas give against central differences."""
    functions = {k.name: k for k in hexapod_kernels(hexapod)}
    report = check_kernels(hexapod_module, functions, count=4, seed=5)
    assert {d.kernel for d in report} == set(functions)
    assert not failures(report), [d.message() for d in failures(report)]
    assert max(d.worst for d in report if d.reference == INTERPRETER) < 1e-12
    # each leg's own J (fk and body_fk kernels) also against central differences of its p
    by_differences = [d for d in report if d.reference == DIFFERENCES]
    assert {d.kernel for d in by_differences} == {f for f in functions if "fk_" in f}
    assert max(d.worst for d in by_differences) < 1e-9
