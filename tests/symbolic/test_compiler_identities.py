"""Identities of the algebra, on the compiler's path: exactly (sympy backend) or on random inputs."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
import sympy
from conftest import ALGEBRAS, far_from_null_vectors, versor_from_vectors
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from gagen.algebra import SparseMultivector, cga2d, cga3d
from gagen.crosscheck import Formula, flatten_formula
from gagen.model.conformal import point as conformal_point
from gagen.symbolic import CasadiBackend, SympyBackend


@cache
def _compiled(formula: Formula):
    return flatten_formula(formula)


points = arrays(np.float64, 3, elements=st.floats(-2, 2, allow_subnormal=False))


def _exactly_equal(x: SparseMultivector, y: SparseMultivector) -> bool:
    diff = x - y
    return all(sympy.expand(diff.backend.native(c)) == 0 for c in diff.coeffs.values())


@pytest.mark.parametrize("name", ["ga3d", "cga2d", "pga3d"])
def test_geometric_product_is_associative_exactly(name):
    algebra = ALGEBRAS[name]
    b = SympyBackend()
    x, y, z = (SparseMultivector.symbolic(algebra, b, n) for n in "xyz")
    assert _exactly_equal((x * y) * z, x * (y * z))


@pytest.mark.parametrize("algebra", [cga3d(), cga2d()], ids=lambda a: a.name)
@pytest.mark.parametrize("backend", [CasadiBackend(), SympyBackend()], ids=lambda b: b.name)
def test_conformal_points_are_null_exactly(algebra, backend):
    """P·P = 0 for symbolic x: the compiler proves it, no coefficient is left."""
    euclid = [m for m in algebra.blades_of_grade(1) if algebra.blade_name(m) not in ("e0", "einf")]
    x = SparseMultivector.symbolic(algebra, backend, "x", euclid)
    p = conformal_point(x)
    assert p.sp(p) == 0
    assert (p | p).support == ()


def test_inner_product_of_points_is_minus_half_squared_distance_exactly():
    algebra, b = cga3d(), SympyBackend()
    x = SparseMultivector.symbolic(algebra, b, "x", ["e1", "e2", "e3"])
    y = SparseMultivector.symbolic(algebra, b, "y", ["e1", "e2", "e3"])
    got = b.native(conformal_point(x).sp(conformal_point(y)))
    xs, ys = [b.native(x[k]) for k in ("e1", "e2", "e3")], [b.native(y[k]) for k in ("e1", "e2", "e3")]
    expected = -sympy.Rational(1, 2) * sum((u - v) ** 2 for u, v in zip(xs, ys, strict=True))
    assert sympy.expand(got - expected) == 0


def test_pseudoscalar_squares_to_minus_one():
    algebra = cga3d()
    i = SparseMultivector(algebra, CasadiBackend(), {algebra.pseudoscalar: 1})
    assert (i * i).coeffs == {0: -1}


@pytest.mark.parametrize("name", sorted(ALGEBRAS))
def test_dual_undual_round_trip_exactly(name):
    algebra = ALGEBRAS[name]
    x = SparseMultivector.symbolic(algebra, SympyBackend(), "x")
    assert _exactly_equal(x.dual().undual(), x)
    assert _exactly_equal(x.undual().dual(), x)


_VERSOR = Formula("v v^-1", cga3d(), (("v", tuple(m for m in range(32) if m.bit_count() % 2 == 0)),),
                  lambda v: v * v.inverse())


@settings(max_examples=200)
@given(far_from_null_vectors(cga3d()))
def test_versor_times_its_inverse_is_one(vectors):
    v = versor_from_vectors(cga3d(), vectors)
    kernel = _compiled(_VERSOR)
    (out,) = kernel([v.coeffs[m] for m in _VERSOR.inputs[0][1]])
    dense = dict(zip(kernel.outputs[0].rows, out, strict=True))
    assert abs(dense.pop("1") - 1) < 1e-12
    assert all(abs(c) < 1e-12 for c in dense.values())


def _plane_meet(a, b, c, d):
    einf = a.make({"einf": 1})
    pa, pb = conformal_point(a), conformal_point(b)
    first = pa ^ pb ^ conformal_point(c) ^ einf
    second = pa ^ pb ^ conformal_point(d) ^ einf
    return first & second


_MEET = Formula("meet", cga3d(), tuple((n, ("e1", "e2", "e3")) for n in "abcd"), _plane_meet)
_LINE = Formula("line", cga3d(), tuple((n, ("e1", "e2", "e3")) for n in "ab"),
                lambda a, b: conformal_point(a) ^ conformal_point(b) ^ a.make({"einf": 1}))


@settings(max_examples=200)
@given(points, points, points, points)
def test_meet_of_two_planes_is_their_common_line(a, b, c, d):
    """Planes through (a, b, c) and (a, b, d) meet in the line through a and b (up to scale)."""
    assume(np.linalg.norm(b - a) > 0.3)
    n1, n2 = np.cross(b - a, c - a), np.cross(b - a, d - a)
    assume(np.linalg.norm(n1) > 0.3 and np.linalg.norm(n2) > 0.3)
    assume(np.linalg.norm(np.cross(n1 / np.linalg.norm(n1), n2 / np.linalg.norm(n2))) > 0.3)
    meet_k, line_k = _compiled(_MEET), _compiled(_LINE)
    (meet,) = meet_k(a, b, c, d)
    (line,) = line_k(a, b)
    m = dict(zip(meet_k.outputs[0].rows, meet, strict=True))
    l_ = dict(zip(line_k.outputs[0].rows, line, strict=True))
    keys = sorted(set(m) | set(l_))
    mv, lv = np.array([m.get(k, 0.0) for k in keys]), np.array([l_.get(k, 0.0) for k in keys])
    scale = mv @ lv / (lv @ lv)
    assert abs(scale) > 1e-6
    np.testing.assert_allclose(mv, scale * lv, atol=1e-10 * np.max(np.abs(mv)))
