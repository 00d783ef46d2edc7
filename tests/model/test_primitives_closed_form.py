"""Primitive queries of ``gagen.model`` on the reference interpreter against Euclidean closed forms.

Every expected value here is computed with numpy from the Euclidean points alone (circumcentres,
circumspheres, feet of perpendiculars, Rodrigues' formula, Gram determinants), independently of
gagen's algebra. Random points come from the box [-3, 3]^3; ``assume`` keeps the configurations
well-conditioned (the degenerate ones are in ``test_degenerate.py``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import tiered
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from gagen.interp import MultiVector, cga3d
from gagen.model import primitives as pr
from gagen.model.conformal import EUCLID, einf, location, normalized_point, point, vector
from gagen.model.versors import dilator, rotor, translator

LIKE = MultiVector.zero(cga3d())
RTOL = 1e-9
MAIN = settings(max_examples=200)  # the main closed forms
MORE = settings(max_examples=100)
coords = st.floats(-3, 3, allow_nan=False, allow_subnormal=False)


def points(n: int):
    return arrays(np.float64, (n, 3), elements=coords)


def P(x) -> MultiVector:
    return point(vector(LIKE, [float(v) for v in x]))


def vec(x) -> MultiVector:
    return vector(LIKE, [float(v) for v in x])


def euclid(x: MultiVector) -> np.ndarray:
    return np.array([x[k] for k in EUCLID])


def where(x: MultiVector) -> np.ndarray:
    """Euclidean location of a (possibly scaled) conformal point."""
    return euclid(location(x))


def spanned(kind: str, xs) -> MultiVector:
    return pr.through(kind, [P(x) for x in xs])


def assert_close(actual, expected, scale=1.0, rtol=RTOL):
    actual, expected = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    err = float(np.max(np.abs(actual - expected)))
    assert err <= rtol * max(scale, 1.0), f"{actual} != {expected} (err {err:.3g}, scale {scale:.3g})"


# -- Euclidean closed forms (numpy only) -------------------------------------------------------------
def circumcentre(x1, x2, x3):
    a, b = x2 - x1, x3 - x1
    axb = np.cross(a, b)
    return x1 + np.cross(a @ a * b - b @ b * a, axb) / (2 * axb @ axb)


def circumsphere(xs):
    """Centre and radius of the sphere through four points: 2(xi − x1)·c = |xi|² − |x1|²."""
    a = 2 * (xs[1:] - xs[0])
    b = np.sum(xs[1:] ** 2, axis=1) - xs[0] @ xs[0]
    c = np.linalg.solve(a, b)
    return c, float(np.linalg.norm(xs[0] - c))


def unit(v):
    return v / np.linalg.norm(v)


def triangle_normal(xs):
    return np.cross(xs[1] - xs[0], xs[2] - xs[0])


def tetra_volume6(xs):
    return float(np.linalg.det(xs[1:] - xs[0]))


def null_row(x):
    """Coordinates of P(x) on (e0, e1, e2, e3, e∞)."""
    return np.array([1.0, *x, 0.5 * x @ x])


EINF_ROW = np.array([0.0, 0, 0, 0, 1])


def rows_of(kind: str, xs) -> list[np.ndarray]:
    rows = [null_row(x) for x in xs]
    return [*rows, EINF_ROW] if kind in pr.FLATS else rows


def well_spread(kind: str, xs) -> bool:
    n = len(xs)
    if n >= 2 and min(np.linalg.norm(xs[i] - xs[j]) for i in range(n) for j in range(i)) < 0.3:
        return False
    if n >= 3 and np.linalg.norm(triangle_normal(xs)) < 1.0:  # twice the triangle area
        return False
    return not (n == 4 and abs(tetra_volume6(xs)) < 1.0)  # six times the tetrahedron volume


# -- circle, sphere, point pair, line ---------------------------------------------------------------
@MAIN
@given(points(3))
def test_circle_through_three_points_has_their_circumcircle(xs):
    assume(well_spread("circle", xs))
    c = circumcentre(*xs)
    r2 = float((xs[0] - c) @ (xs[0] - c))
    assume(r2 < 100)
    x = spanned("circle", xs)
    assert_close(where(pr.centre(x)), c, scale=math.sqrt(r2))
    assert pr.centre(x).allclose(P(c), rtol=RTOL)  # a normalised conformal point
    assert pr.radius_squared(x) == pytest.approx(r2, rel=RTOL)
    assert pr.radius(x) == pytest.approx(math.sqrt(r2), rel=RTOL)
    # exact orientation, not just up to sign: (x2 − x1) × (x3 − x1)
    assert_close(euclid(pr.unit_normal(x)), unit(triangle_normal(xs)))


@pytest.mark.slow
@MAIN
@given(points(4))
def test_sphere_through_four_points_has_their_circumsphere(xs):
    assume(well_spread("sphere", xs))
    c, r = circumsphere(xs)
    assume(r < 10)
    x = spanned("sphere", xs)
    assert_close(where(pr.centre(x)), c, scale=r)
    assert pr.centre(x).allclose(P(c), rtol=RTOL)  # a normalised conformal point
    assert pr.radius(x) == pytest.approx(r, rel=RTOL)
    assert pr.radius_squared(x) == pytest.approx(r * r, rel=RTOL)


@pytest.mark.slow
@MAIN
@given(points(2))
def test_point_pair_centre_radius_and_split_order(xs):
    assume(well_spread("point_pair", xs))
    x1, x2 = xs
    pp = spanned("point_pair", xs)
    assert_close(where(pr.centre(pp)), (x1 + x2) / 2)
    assert pr.centre(pp).allclose(P((x1 + x2) / 2), rtol=RTOL)
    assert pr.radius(pp) == pytest.approx(np.linalg.norm(x1 - x2) / 2, rel=RTOL)
    p1, p2 = pr.split_point_pair(pp)
    scale = max(np.linalg.norm(x1), np.linalg.norm(x2))
    assert_close(where(p1), x1, scale)  # in the order they were given
    assert_close(where(p2), x2, scale)
    for p, x in ((p1, x1), (p2, x2)):  # normalised conformal points, all five coefficients
        assert p.allclose(P(x), rtol=RTOL)
    # the carrier line of the pair runs from x1 to x2
    assert_close(euclid(pr.direction(pr.carrier_plane(pp))), unit(x2 - x1))


@pytest.mark.slow
@MAIN
@given(points(2))
def test_line_direction_runs_from_first_to_second_point(xs):
    assume(well_spread("line", xs))
    assert_close(euclid(pr.direction(spanned("line", xs))), unit(xs[1] - xs[0]))


# -- contains: ‖X ∧ P‖² ------------------------------------------------------------------------------
KINDS_WITH_POINTS = [k for k in pr.KINDS if k != "point"]


@pytest.mark.parametrize("kind", tiered(KINDS_WITH_POINTS, {"circle"}))
@settings(max_examples=60)
@given(data=st.data())
def test_contains_cost_is_squared_coefficient_norm_and_gram_determinant(kind, data):
    """‖X ∧ P‖² is the sum of squared coefficients of X ∧ P, and (Cauchy-Binet) the Gram determinant
    det(A Aᵀ) of the rows of the spanning vectors and P on (e0, e1, e2, e3, e∞)."""
    xs = data.draw(points(pr.points_needed(kind)), label="xs")
    x = data.draw(points(1), label="x")[0]
    assume(well_spread(kind, xs))
    X, p = spanned(kind, xs), P(x)
    cost = pr.contains_cost(X, p)
    wedge = (X ^ p).coeffs
    assert cost == pytest.approx(float(wedge @ wedge), rel=1e-12, abs=1e-300)
    a = np.array([*rows_of(kind, xs), null_row(x)])
    gram = float(np.linalg.det(a @ a.T))
    hadamard = float(np.prod(np.sum(a * a, axis=1)))  # det(A Aᵀ) <= Π |rows|²
    assert abs(cost - gram) <= 1e-10 * hadamard


def _frame(n):
    """Two unit vectors completing the unit n to an orthonormal frame."""
    helper = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0.0, 1, 0])
    u = unit(np.cross(n, helper))
    return u, np.cross(n, u)


@pytest.mark.slow
@MAIN
@given(points(3), st.floats(0, 2 * math.pi), st.floats(-0.9, 2), st.floats(0.1, 1))
def test_contains_cost_of_circle_vanishes_on_it_only(xs, phi, stretch, height):
    """For x in the carrier plane, C ∧ P(x) = ½ (|x − c|² − r²) E with E = P1∧P2∧P3∧e∞, whose
    squared coefficient norm is |n|² + (x1·(x2 × x3))²; off the plane, its e0123 coefficient is
    (x − x1)·n. So the cost is zero exactly on the circumcircle."""
    assume(well_spread("circle", xs))
    c = circumcentre(*xs)
    r = float(np.linalg.norm(xs[0] - c))
    assume(r < 5)
    n = triangle_normal(xs)
    u, v = _frame(unit(n))
    radial = math.cos(phi) * u + math.sin(phi) * v
    norm2_e = float(n @ n + (xs[0] @ np.cross(xs[1], xs[2])) ** 2)
    X, E = spanned("circle", xs), spanned("plane", xs)

    on = c + r * radial  # a fourth point of the circle
    assert pr.contains_cost(X, P(on)) <= 1e-24 * norm2_e * (r * r + on @ on) ** 2

    x = c + (1 + stretch) * r * radial  # in the carrier plane, off the circle unless stretch = 0
    half_power = 0.5 * float((x - c) @ (x - c) - r * r)
    assert (X ^ P(x)).allclose(E * half_power, rtol=1e-9, atol=1e-12 * (1 + x @ x) * math.sqrt(norm2_e))
    expected = half_power**2 * norm2_e
    tol = 1e-20 * norm2_e * (1 + x @ x) ** 2
    assert pr.contains_cost(X, P(x)) == pytest.approx(expected, rel=1e-9, abs=tol)

    lifted = on + height * unit(n)  # above the circle
    h = float((lifted - xs[0]) @ n)
    assert (X ^ P(lifted))["e0123"] == pytest.approx(h, rel=1e-9)
    assert pr.contains_cost(X, P(lifted)) >= h * h * (1 - 1e-9) > 0


@MORE
@given(points(3), st.floats(-2, 2), st.floats(-2, 2), st.floats(-1, 1))
def test_contains_cost_of_plane_is_squared_signed_distance_times_normal(xs, s, t, h):
    """E ∧ P(x) = −((x − x1)·n) e0123∞ with n = (x2 − x1) × (x3 − x1): zero exactly on the plane."""
    assume(well_spread("plane", xs))
    n = triangle_normal(xs)
    x = xs[0] + s * (xs[1] - xs[0]) + t * (xs[2] - xs[0]) + h * unit(n)
    E = spanned("plane", xs)
    d = float((x - xs[0]) @ n)
    tol = 1e-12 * float(np.linalg.norm(n)) * (1 + x @ x)
    assert (E ^ P(x))["e0123inf"] == pytest.approx(-d, rel=1e-9, abs=tol)
    assert math.sqrt(pr.contains_cost(E, P(x))) == pytest.approx(abs(d), rel=1e-9, abs=tol)


@MORE
@given(points(2), st.floats(-2, 2), points(1))
def test_contains_cost_of_line_matches_its_closed_form(xs, t, w):
    """L ∧ P(x) = e0∧(d∧w)∧e∞ + (x1∧d∧w)∧e∞ with d = x2 − x1, w = x − x1: zero on the line only."""
    assume(well_spread("line", xs))
    x1, d = xs[0], xs[1] - xs[0]
    L = spanned("line", xs)
    on = x1 + t * d
    assert pr.contains_cost(L, P(on)) <= 1e-24 * (d @ d) * (1 + on @ on) ** 2
    x = w[0]
    m = np.cross(d, x - x1)
    expected = float(m @ m + (x1 @ m) ** 2)
    # compared as norms: the coefficients of L ∧ P carry rounding ≈ eps |d| (1 + |x|²), which a squared
    # cost near 0 (x near the line) cannot be held to relatively
    tol = 1e-12 * float(np.linalg.norm(d)) * (1 + x @ x)
    assert math.sqrt(pr.contains_cost(L, P(x))) == pytest.approx(math.sqrt(expected), rel=1e-9, abs=tol)
    dist = np.linalg.norm(m) / np.linalg.norm(d)
    assume(dist > 0.1)
    assert pr.contains_cost(L, P(x)) >= (dist * dist) * (d @ d) * (1 - 1e-9)


@pytest.mark.slow
@MORE
@given(points(4), points(1))
def test_contains_cost_of_sphere_is_its_power_times_volume(xs, w):
    """S ∧ P(x) = det[rows (1, xi, ½|xi|²), (1, x, ½|x|²)] e0123∞ = ½ D (|x − c|² − r²) e0123∞ up to sign,
    D = det[(1, xi)] = 6 · signed volume: zero exactly on the circumsphere."""
    assume(well_spread("sphere", xs))
    c, r = circumsphere(xs)
    assume(r < 10)
    S = spanned("sphere", xs)
    D = tetra_volume6(xs)
    x = w[0]
    power = float((x - c) @ (x - c) - r * r)
    scale = D * D * (r * r + (x - c) @ (x - c)) ** 2
    expected = 0.25 * D * D * power * power
    assert pr.contains_cost(S, P(x)) == pytest.approx(expected, rel=1e-9, abs=1e-20 * scale)
    direction = w[0] - c
    assume(np.linalg.norm(direction) > 0.1)
    on = c + r * unit(direction)
    assert pr.contains_cost(S, P(on)) <= 1e-24 * D * D * (r * r + on @ on) ** 2


# -- projection and meet ----------------------------------------------------------------------------
@pytest.mark.slow
@MORE
@given(points(3), points(1))
def test_project_point_onto_plane_is_the_orthogonal_projection(xs, w):
    assume(well_spread("plane", xs))
    x = w[0]
    n = unit(triangle_normal(xs))
    expected = x - ((x - xs[0]) @ n) * n
    projected = pr.project_point(P(x), spanned("plane", xs))
    scale = float(np.linalg.norm(x) + np.linalg.norm(xs[0]))
    assert_close(where(projected), expected, scale)
    assert_close(euclid(normalized_point(projected)), expected, scale)
    assert projected.grade(1).allclose(normalized_point(projected) * -projected.sp(einf(LIKE)), rtol=1e-9)


@MORE
@given(points(2), points(1))
def test_project_point_onto_line_is_the_foot_of_the_perpendicular(xs, w):
    assume(well_spread("line", xs))
    x = w[0]
    d = unit(xs[1] - xs[0])
    expected = xs[0] + ((x - xs[0]) @ d) * d
    projected = pr.project_point(P(x), spanned("line", xs))
    scale = float(np.linalg.norm(x) + np.linalg.norm(xs[0]))
    assert_close(where(projected), expected, scale)
    assert_close(euclid(normalized_point(projected)), expected, scale)


@pytest.mark.slow
@MORE
@given(points(2), points(3))
def test_meet_of_line_and_transversal_plane_is_the_flat_point_of_intersection(ls, ps):
    assume(well_spread("line", ls) and well_spread("plane", ps))
    d, n = unit(ls[1] - ls[0]), unit(triangle_normal(ps))
    assume(abs(d @ n) > 0.2)  # transversal, not grazing
    t = ((ps[0] - ls[0]) @ n) / (d @ n)
    expected = ls[0] + t * d
    assume(np.linalg.norm(expected) < 20)
    f = pr.meet(spanned("line", ls), spanned("plane", ps))
    assert f.grade(2).allclose(f, rtol=1e-12)  # a flat point: grade 2, = w (P(x) ∧ e∞)
    w = f["e0inf"]
    # weight and sign: w = (x2 − x1)·((p2 − p1) × (p3 − p1)) (zero for a parallel line)
    assert w == pytest.approx((ls[1] - ls[0]) @ triangle_normal(ps), rel=1e-9)
    located = np.array([f[f"e{k}inf"] for k in "123"]) / w
    assert_close(located, expected, scale=float(np.linalg.norm(expected)))
    assert f.allclose((P(expected) ^ einf(LIKE)) * w, rtol=1e-9)


TETRA = np.array([[1.0, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]) / math.sqrt(3)


def sphere_at(c, r) -> MultiVector:
    return spanned("sphere", [c + r * u for u in TETRA])


@MORE
@given(points(1), st.floats(0.5, 3), st.floats(0.5, 3), points(1), st.floats(0.05, 0.95))
def test_meet_of_two_spheres_is_their_intersection_circle(c1, r1, r2, u, f):
    c1, u = c1[0], u[0]
    assume(np.linalg.norm(u) > 0.3)
    u = unit(u)
    lo, hi = abs(r1 - r2), r1 + r2
    d = lo + f * (hi - lo)  # strictly between internal and external tangency
    c2 = c1 + d * u
    a = (d * d + r1 * r1 - r2 * r2) / (2 * d)
    centre, rho2 = c1 + a * u, r1 * r1 - a * a
    assume(rho2 > 1e-2)
    c = pr.meet(sphere_at(c1, r1), sphere_at(c2, r2))
    assert c.grade(3).allclose(c, rtol=1e-12)
    assert_close(where(pr.centre(c)), centre, scale=float(np.linalg.norm(c1)) + r1 + r2, rtol=1e-8)
    assert pr.radius_squared(c) == pytest.approx(rho2, rel=1e-8, abs=1e-9 * (r1 + r2) ** 2)
    # carrier plane ⟂ c2 − c1; for two spheres spanned alike (by TETRA, so of the same orientation)
    # the meet's normal points from c2 to c1
    assert_close(euclid(pr.unit_normal(c)), -u)


# -- unit primitives ----------------------------------------------------------------------------------
def test_unit_primitives_have_the_documented_properties():
    o, e1, e2, e3 = np.zeros(3), np.eye(3)[0], np.eye(3)[1], np.eye(3)[2]
    u = {k: pr.unit_primitive(k, LIKE) for k in pr.KINDS}

    assert u["point"].allclose(LIKE.make({"e0": 1}), rtol=0)

    pp = u["point_pair"]
    assert_close(where(pr.centre(pp)), o, rtol=1e-15)
    assert pr.radius_squared(pp) == 1
    p1, p2 = pr.split_point_pair(pp)
    assert_close(where(p1), -e1, rtol=1e-15)
    assert_close(where(p2), e1, rtol=1e-15)

    line = u["line"]
    assert_close(euclid(pr.direction(line)), e1, rtol=0)
    for x in (o, e1, -2.5 * e1):
        assert pr.contains_cost(line, P(x)) == 0
    assert pr.contains_cost(line, P(e2)) > 0.5

    circle = u["circle"]
    assert_close(where(pr.centre(circle)), o, rtol=0)
    assert pr.radius_squared(circle) == 1
    assert_close(euclid(pr.unit_normal(circle)), e3, rtol=0)
    for phi in np.linspace(0, 2 * math.pi, 7):
        assert pr.contains_cost(circle, P([math.cos(phi), math.sin(phi), 0])) < 1e-30
    assert pr.contains_cost(circle, P(e3)) > 0.5

    plane = u["plane"]
    for x in (o, e1, e2, [1.5, -2, 0]):
        assert pr.contains_cost(plane, P(x)) == 0
    # oriented with normal +e3: E ∧ P(x) = −((x − x1)·n) I, and E is a positive multiple of the
    # unit circle's carrier plane
    assert (plane ^ P(e3))["e0123inf"] == -1
    carrier = pr.carrier_plane(circle)
    assert carrier.allclose(plane * (carrier.sp(plane) / plane.sp(plane)), rtol=0)
    assert carrier.sp(plane) / plane.sp(plane) > 0

    sphere = u["sphere"]
    assert_close(where(pr.centre(sphere)), o, rtol=0)
    assert pr.radius_squared(sphere) == 1
    for x in (e1, -e2, e3, unit(np.array([1.0, 2, -2]))):
        assert pr.contains_cost(sphere, P(x)) < 1e-30
    assert pr.contains_cost(sphere, P(o)) > 0.5


# -- versors ------------------------------------------------------------------------------------------
@MORE
@given(points(4), st.floats(-3, 3))
def test_dilator_scales_a_sphere_about_the_origin(xs, log_d):
    assume(well_spread("sphere", xs))
    c, r = circumsphere(xs)
    assume(r < 10)
    d = math.exp(log_d)
    s = dilator(LIKE, d).sandwich(spanned("sphere", xs))
    assert_close(where(pr.centre(s)), d * c, scale=d * (r + np.linalg.norm(c)))
    assert pr.radius(s) == pytest.approx(d * r, rel=RTOL)


@MORE
@given(points(1), st.floats(-3, 3))
def test_dilator_scales_a_point_about_the_origin(x, log_d):
    d = math.exp(log_d)
    p = dilator(LIKE, d).sandwich(P(x[0]))
    assert_close(where(p), d * x[0], scale=d * np.linalg.norm(x[0]))


@MORE
@given(points(1), st.floats(-math.pi, math.pi), points(1))
def test_rotor_rotates_by_rodrigues_formula(axis, angle, v):
    axis, v = axis[0], v[0]
    assume(np.linalg.norm(axis) > 0.3)
    n = unit(axis)
    expected = (v * math.cos(angle) + np.cross(n, v) * math.sin(angle)
                + n * (n @ v) * (1 - math.cos(angle)))
    r = rotor(vec(n), angle)
    assert_close(euclid(r.sandwich(vec(v))), expected, scale=float(np.linalg.norm(v)))
    assert r.sandwich(P(v)).allclose(P(expected), rtol=RTOL)  # and it fixes the origin
    assert (r * ~r).allclose(LIKE + 1, rtol=1e-14)


def test_rotor_is_right_handed():
    e1, e2, e3 = (vec(row) for row in np.eye(3))
    assert rotor(e3, math.pi / 2).sandwich(e1).allclose(e2, rtol=1e-15, atol=1e-15)
    assert rotor(e1, math.pi / 2).sandwich(e2).allclose(e3, rtol=1e-15, atol=1e-15)
    assert rotor(e2, math.pi / 2).sandwich(e3).allclose(e1, rtol=1e-15, atol=1e-15)


@MORE
@given(points(1), points(1))
def test_translator_moves_points_by_t(x, t):
    x, t = x[0], t[0]
    moved = translator(vec(t)).sandwich(P(x))
    assert moved.allclose(P(x + t), rtol=1e-12)  # a normalised point, all five coefficients
