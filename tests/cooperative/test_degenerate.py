"""Degenerate inputs of the similarity transformations give a reported condition, never a silent NaN.

``similarity(kind, X1, X2)`` and ``cooperative_similarity(kind, Xc)`` return ``(versor,
conditioning)``; the conditioning is documented to be 0 exactly at degenerate configurations
(coincident, collinear or coplanar spanning points; opposite orientations) and positive otherwise,
with finite versors throughout. Checked here on the reference interpreter:

* families of configurations that approach degeneracy as ε → 0: the versor stays finite and the
  conditioning decreases monotonically (quadratically) to ~0;
* exactly degenerate inputs (exact float arithmetic): finite versor, conditioning ~0;
* opposite orientations (the same primitive spanned in reverse order): a guarded half turn, and
  whether V X1 V~ ∝ +X2 still holds;
* identical primitives: V = 1 with a healthy conditioning.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from conftest import tiered
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from gagen.interp import MultiVector, cga3d
from gagen.model import primitives as pr
from gagen.model.conformal import point, vector
from gagen.model.similarity import cooperative_similarity, similarity

LIKE = MultiVector.zero(cga3d())
EPSILONS = (1e-1, 1e-3, 1e-6, 1e-9)
DEGENERATE = 1e-12  # conditioning at (or within rounding of) a degenerate configuration


def P(x) -> MultiVector:
    return point(vector(LIKE, [float(v) for v in x]))


def spanned(kind: str, xs) -> MultiVector:
    return pr.through(kind, [P(x) for x in xs])


def unit(v):
    return v / np.linalg.norm(v)


def perpendicular(d, hint):
    """Unit vector ⟂ d in the plane of d and hint."""
    w = hint - (hint @ unit(d)) * unit(d)
    return unit(w)


def rotated(v, axis, angle):
    """Rodrigues: v turned by angle about the unit axis."""
    return (v * math.cos(angle) + np.cross(axis, v) * math.sin(angle)
            + axis * (axis @ v) * (1 - math.cos(angle)))


def well_spread(xs) -> bool:
    d = [np.linalg.norm(xs[i] - xs[j]) for i in range(4) for j in range(i)]
    return min(d) > 0.5 and abs(np.linalg.det(xs[1:] - xs[0])) > 1.0


def finite(v: MultiVector) -> bool:
    return bool(np.all(np.isfinite(v.coeffs)))


def maps_onto(v: MultiVector, x1: MultiVector, x2: MultiVector, rtol=1e-9) -> float:
    """The positive-or-negative scale s with V X1 V~ = s X2 (asserting proportionality)."""
    moved = v.sandwich(x1).coeffs
    s = float(moved @ x2.coeffs / (x2.coeffs @ x2.coeffs))
    np.testing.assert_allclose(moved, s * x2.coeffs, atol=rtol * np.max(np.abs(moved)))
    return s


# -- families approaching degeneracy: base points b (4 × 3) and ε -> (kind, points) -------------
def _collinear_circle(b, eps):
    return "circle", [b[0], b[1], (b[0] + b[1]) / 2 + eps * perpendicular(b[1] - b[0], b[2] - b[0])]


def _coincident_circle(b, eps):
    return "circle", [b[0], b[0] + eps * unit(b[1] - b[0]), b[2]]


def _coplanar_sphere(b, eps):
    n = unit(np.cross(b[1] - b[0], b[2] - b[0]))
    return "sphere", [b[0], b[1], b[2], b[0] + 0.25 * (b[1] - b[0]) + 0.5 * (b[2] - b[0]) + eps * n]


def _concyclic_sphere(b, eps):
    """The fourth point on the circle of the first three (so the 4-blade itself → 0), lifted by ε."""
    a, c = b[1] - b[0], b[2] - b[0]
    axc = np.cross(a, c)
    centre = b[0] + np.cross(a @ a * c - c @ c * a, axc) / (2 * axc @ axc)
    return "sphere", [b[0], b[1], b[2], 2 * centre - b[0] + eps * unit(axc)]


def _coincident_pair(b, eps):
    return "point_pair", [b[0], b[0] + eps * unit(b[1] - b[0])]


def _coincident_line(b, eps):
    return "line", [b[0], b[0] + eps * unit(b[1] - b[0])]


def _collinear_plane(b, eps):
    return "plane", [b[0], b[1], (b[0] + b[1]) / 2 + eps * perpendicular(b[1] - b[0], b[2] - b[0])]


DEGENERATING = {
    "circle from collinear points": _collinear_circle,
    "circle with coincident points": _coincident_circle,
    "sphere from coplanar points": _coplanar_sphere,
    "sphere from concyclic points": _concyclic_sphere,
    "point pair with coincident points": _coincident_pair,
    "line with coincident points": _coincident_line,
    "plane from collinear points": _collinear_plane,
}


SHIFT = np.array([0.5, -0.25, 1.0])


def _healthy(family: str, b) -> MultiVector:
    """The family's well-conditioned member (ε = 1), translated: same kind and same orientation
    (normal or direction), so the conditioning of a map between it and a family member is
    governed by the degeneracy alone."""
    kind, xs = DEGENERATING[family](b, 1.0)
    return spanned(kind, [x + SHIFT for x in xs])


def _orientation_health(kind: str, xs) -> float:
    """(1 + a·b)/2 between the orientation of the points' primitive and of the unit primitive
    (+e3 normal for circles and planes, +e1 direction for pairs and lines); 1 for spheres."""
    if kind in ("circle", "plane"):
        return (1 + unit(np.cross(xs[1] - xs[0], xs[2] - xs[0]))[2]) / 2
    if kind in ("point_pair", "line"):
        return (1 + unit(xs[1] - xs[0])[0]) / 2
    return 1.0


def _call(direction: str, family: str, x: MultiVector, b):
    kind = DEGENERATING[family](b, 1.0)[0]
    if direction == "cooperative":
        return cooperative_similarity(kind, x)
    if direction == "onto it":
        return similarity(kind, _healthy(family, b), x)
    return similarity(kind, x, _healthy(family, b))


DIRECTIONS = ("cooperative", "onto it", "from it")
bases = arrays(np.float64, (4, 3), elements=st.floats(-3, 3, allow_nan=False, allow_subnormal=False))


def _assert_vanishes_continuously(conds):
    """conditioning(ε) for ε in EPSILONS: finite, decreasing, quadratic in ε, ~0 at the end."""
    assert all(math.isfinite(c) for c in conds)
    assert all(a > b for a, b in itertools.pairwise(conds)), conds
    assert 0 <= conds[-1] <= DEGENERATE, conds
    # ∝ ε²: squared area, squared volume, |x2 − x1|², or (1 − cos)/2 of an angle ε
    ratio = conds[2] / conds[1] / (EPSILONS[2] / EPSILONS[1]) ** 2
    assert 0.1 < ratio < 10, conds


SHRINKING_PAIR = "point pair with coincident points"
@pytest.mark.parametrize("direction", DIRECTIONS)
@pytest.mark.parametrize("family", sorted(set(DEGENERATING) - {SHRINKING_PAIR}))
@settings(max_examples=15)
@given(b=bases)
def test_conditioning_vanishes_continuously_as_points_degenerate(family, direction, b):
    _check_family(family, direction, b)


@pytest.mark.parametrize("direction", DIRECTIONS)
@settings(max_examples=15)
@given(b=bases)
@example(b=np.array([[1.0, 2, 1], [0, 1, 0.5], [2, -3, -0.5], [1, -1, -2]]))  # r²(ε = 1e-9) rounds to 0
def test_conditioning_vanishes_continuously_as_point_pair_shrinks(direction, b):
    """(Was a strict xfail in the "from it" direction: r² of a ~1e-9 pair rounded to 0, the radius
    ratio hit its old floor k = 1e-30 and the moved centre overflowed to NaN; the dilator's ratio is
    now bounded to k within 1e±6, see ``similarity._dilator_between``.)"""
    _check_family(SHRINKING_PAIR, direction, b)


def _check_family(family, direction, b):
    assume(well_spread(b))
    if direction == "cooperative":  # the unit primitive's orientation must not be nearly opposite
        assume(_orientation_health(*DEGENERATING[family](b, 1.0)) > 0.05)
    conds = []
    for eps in (1.0, *EPSILONS):
        kind, xs = DEGENERATING[family](b, eps)
        v, cond = _call(direction, family, spanned(kind, xs), b)
        assert finite(v), (eps, v)
        assert math.isfinite(cond)
        conds.append(cond)
    assert conds[0] > 1e-3  # the healthy neighbour (ε = 1) is clearly conditioned
    _assert_vanishes_continuously(conds[1:])


NEARLY_COINCIDENT_PAIRS = {
    # r² comes out −9.6e-11 instead of 2.5e-13 (was: sqrt of a negative ratio, math domain error)
    "negative r2": ([1.5, 0.0, 2.0], [0.5, 2.0, -2.0], 1e-6, "cooperative"),
    # r² of the first pair comes out exactly −0.0: k = 0, then 1/k (was ZeroDivisionError, now NaN)
    "zero r2": ([2.0, 0.0, 0.0], [-1.0, 1.0, 0.0], 1e-9, "from it"),
}


@pytest.mark.parametrize("case", sorted(NEARLY_COINCIDENT_PAIRS))
def test_nearly_coincident_point_pair_is_reported_not_crashed(case):
    """Reproductions. The numerator −⟨XX~⟩ of r² cancels catastrophically for a short pair (absolute
    error ~ eps·|x|⁴ against a true value ~ ε⁴), so r² can come out 0 or negative."""
    x, towards, eps, direction = NEARLY_COINCIDENT_PAIRS[case]
    x1 = np.array(x)
    pair = spanned("point_pair", [x1, x1 + eps * unit(np.array(towards))])
    unit_pair = pr.unit_primitive("point_pair", LIKE)
    if direction == "cooperative":
        v, cond = cooperative_similarity("point_pair", pair)
    else:
        v, cond = similarity("point_pair", pair, unit_pair)
    assert finite(v)
    assert 0 <= cond <= DEGENERATE


# -- the same families exactly at ε = 0 (exact in floating point: small integer coordinates) -------
EXACT_BASE = np.array([[1.0, 2, 3], [3, 2, -1], [-1, 1, 1], [0, -2, 2]])


def _exact_case(family, direction):
    return pytest.param(family, direction)


@pytest.mark.parametrize(("family", "direction"),
                         [_exact_case(f, d) for f in sorted(DEGENERATING) for d in DIRECTIONS])
def test_exactly_degenerate_points_give_finite_versor_and_zero_conditioning(family, direction):
    kind, xs = DEGENERATING[family](EXACT_BASE, 0.0)
    if family == "sphere from concyclic points":  # exact concyclic points: a square on the unit circle
        xs = [np.array(p, dtype=float) for p in ((1, 0, 0), (0, 1, 0), (-1, 0, 0), (0, -1, 0))]
    x = spanned(kind, xs)
    v, cond = _call(direction, family, x, EXACT_BASE)
    assert finite(v)
    assert math.isfinite(cond)
    assert 0 <= cond <= DEGENERATE


def test_exact_degenerate_configurations_are_exact():
    """The configurations above really are degenerate in floating point (so a failure there is not
    rounding): collinear/coplanar spans are flats, coincident or concyclic ones vanish."""
    for family, flat in [("circle from collinear points", "line"), ("sphere from coplanar points", "plane"),
                         ("plane from collinear points", None)]:
        kind, xs = DEGENERATING[family](EXACT_BASE, 0.0)
        x = spanned(kind, xs)
        if flat is None:
            assert not np.any(x.coeffs)
        else:
            assert pr.radius_squared_parts(x)[1] == 0
    for family in ("circle with coincident points", "point pair with coincident points",
                   "line with coincident points"):
        kind, xs = DEGENERATING[family](EXACT_BASE, 0.0)
        assert not np.any(spanned(kind, xs).coeffs)
    square = [(1, 0, 0), (0, 1, 0), (-1, 0, 0), (0, -1, 0)]
    assert not np.any(spanned("sphere", square).coeffs)


# -- opposite orientations -------------------------------------------------------------------------
def _turned(kind: str, b, angle: float):
    """(X1, X2): X2 is X1 turned by ``angle`` about an axis that, at angle π, reverses its orientation
    (⟂ the line through its first point; the line x1x2 for a plane; a diameter for a circle; ⟂ the
    pair about its centre)."""
    xs = list(b[: pr.points_needed(kind)])
    if kind == "plane":
        axis, pivot = unit(xs[1] - xs[0]), xs[0]
    elif kind == "circle":
        a, c = xs[1] - xs[0], xs[2] - xs[0]
        axc = np.cross(a, c)
        pivot = xs[0] + np.cross(a @ a * c - c @ c * a, axc) / (2 * axc @ axc)
        axis = unit(xs[0] - pivot)
    else:  # line, point pair: an axis ⟂ x2 − x1
        axis = unit(np.cross(xs[1] - xs[0], b[2] - b[0]))
        pivot = xs[0] if kind == "line" else (xs[0] + xs[1]) / 2
    moved = [pivot + rotated(x - pivot, axis, angle) for x in xs]
    return spanned(kind, xs), spanned(kind, moved)


ORIENTED = ("point_pair", "line", "circle", "plane")


@pytest.mark.parametrize("kind", tiered(ORIENTED, {"circle"}))
@settings(max_examples=25)
@given(b=bases)
def test_conditioning_vanishes_continuously_towards_opposite_orientation(kind, b):
    assume(well_spread(b))
    conds = []
    for eps in (math.pi / 2, *EPSILONS):
        x1, x2 = _turned(kind, b, math.pi - eps)
        v, cond = similarity(kind, x1, x2)
        assert finite(v)
        if eps >= 1e-3:  # still mapped onto X2 (with the accuracy the conditioning allows)
            assert maps_onto(v, x1, x2, rtol=1e-8) > 0
        conds.append(cond)
    assert conds[0] > 1e-3
    _assert_vanishes_continuously(conds[1:])


@pytest.mark.parametrize("kind", tiered(ORIENTED, {"line"}))
@settings(max_examples=50)
@given(b=bases)
def test_reversed_point_order_is_a_guarded_half_turn_that_still_maps_x1_onto_x2(kind, b):
    """X2 = the same points in reverse order (X2 = −X1 up to rounding). Finding: the guarded half
    turn still gives V X1 V~ = +X2 (exactly what is asked), with conditioning ~0 to say that the
    map is arbitrary (any perpendicular axis would do) and discontinuous there."""
    assume(well_spread(b))
    xs = list(b[: pr.points_needed(kind)])
    x1, x2 = spanned(kind, xs), spanned(kind, xs[::-1])
    np.testing.assert_allclose(x2.coeffs, -x1.coeffs, atol=1e-12 * np.max(np.abs(x1.coeffs)))
    for target in (x2, -x1):
        v, cond = similarity(kind, x1, target)
        assert finite(v)
        assert abs(cond) <= DEGENERATE  # (a plane's K0/4 can come out as −0.0)
        assert (v * ~v).allclose(LIKE + 1, rtol=1e-12)
        assert maps_onto(v, x1, target) == pytest.approx(1, rel=1e-9)


@settings(max_examples=50)
@given(b=bases)
def test_sphere_of_opposite_orientation_is_mapped_onto_minus_x2_and_not_reported(b):
    """Finding (a limitation, not reported by the conditioning): a sphere spanned by an odd
    permutation of its points is −X1; no similarity (V_R = 1, positive dilation) can flip a sphere's
    orientation, so V = 1, V X1 V~ = −X2, and the conditioning stays healthy."""
    assume(well_spread(b))
    x1 = spanned("sphere", b)
    x2 = spanned("sphere", b[[1, 0, 2, 3]])
    v, cond = similarity("sphere", x1, x2)
    assert finite(v)
    assert v.allclose(LIKE + 1, rtol=1e-12, atol=1e-12)
    assert maps_onto(v, x1, x2) == pytest.approx(-1, rel=1e-9)
    assert cond > 1e-3


# -- identical primitives ----------------------------------------------------------------------------
@pytest.mark.parametrize("kind", pr.KINDS)
@settings(max_examples=25)
@given(b=bases)
def test_identical_primitives_give_the_identity_versor(kind, b):
    assume(well_spread(b))
    x = spanned(kind, b[: pr.points_needed(kind)])
    v, cond = similarity(kind, x, x)
    assert finite(v)
    assert v.allclose(LIKE + 1, rtol=1e-12, atol=1e-12)
    assert cond > 1e-3
    v, cond = cooperative_similarity(kind, pr.unit_primitive(kind, LIKE))
    assert v.allclose(LIKE + 1, rtol=0, atol=1e-15)
    assert cond > 0.1


# -- direct queries: undefined on degenerate inputs, but never a silent NaN ---------------------------
EXACT = {
    "circle from collinear points": ("circle", [(1, 2, 3), (2, 3, 4), (3, 4, 5)]),
    "circle with coincident points": ("circle", [(1, 2, 3), (1, 2, 3), (0, 1, -1)]),
    "sphere from coplanar points": ("sphere", [(1, 2, 0), (0, 1, 0), (-1, 0, 0), (3, -1, 0)]),
    "sphere from concyclic points": ("sphere", [(1, 0, 0), (0, 1, 0), (-1, 0, 0), (0, -1, 0)]),
    "point pair with coincident points": ("point_pair", [(1, 2, 3), (1, 2, 3)]),
    "line with coincident points": ("line", [(1, 2, 3), (1, 2, 3)]),
    "plane from collinear points": ("plane", [(1, 2, 3), (2, 3, 4), (3, 4, 5)]),
}
QUERIES = {
    "centre": (pr.ROUNDS, pr.centre),
    "radius_squared": (pr.ROUNDS, pr.radius_squared),
    "radius": (pr.ROUNDS, pr.radius),
    "unit_normal": (("circle",), pr.unit_normal),
    "direction": (("line",), pr.direction),
    "direction of carrier": (("point_pair",), lambda x: pr.direction(pr.carrier_plane(x))),
    "split_point_pair": (("point_pair",), pr.split_point_pair),
    "project_point": (pr.KINDS, lambda x: pr.project_point(P((0.3, -0.2, 0.5)), x)),
    "contains_cost": (pr.KINDS, lambda x: pr.contains_cost(x, P((0.3, -0.2, 0.5)))),
    "meet with unit plane": (pr.KINDS, lambda x: pr.meet(x, pr.unit_primitive("plane", LIKE))),
}


@pytest.mark.parametrize("case", sorted(EXACT))
def test_direct_queries_on_exactly_degenerate_inputs_raise_or_are_finite(case):
    """On the interpreter a degenerate query raises (ZeroDivisionError) instead of returning NaN;
    those that return must return finite values."""
    kind, xs = EXACT[case]
    x = spanned(kind, xs)
    for name, (kinds, query) in QUERIES.items():
        if kind not in kinds:
            continue
        with np.errstate(all="raise"):
            try:
                result = query(x)
            except (ZeroDivisionError, ValueError, FloatingPointError):
                continue
        values = result if isinstance(result, tuple) else (result,)
        for value in values:
            coeffs = np.atleast_1d(getattr(value, "coeffs", value))
            assert np.all(np.isfinite(coeffs)), (case, name, value)
