"""Algebraic identities and closed forms on the reference interpreter (no outside library).

Every check compares against a closed form with a tight tolerance (1e-12 relative to the natural
scale of the quantity), so that a wrong sign, metric or basis change fails.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import tiered
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from gagen.algebra.signature import Algebra, cga2d, cga3d, from_signature, ga3d, pga3d
from gagen.interp import MultiVector, conformal_point

RTOL = 1e-12
ALGEBRAS = {a.name: a for a in (cga3d(), cga2d(), pga3d(), ga3d(), from_signature(2, 1, 1))}
CGA = ["cga3d", "cga2d"]

coord = st.floats(-5, 5, allow_nan=False)


def mv(algebra: Algebra, values) -> MultiVector:
    return MultiVector(algebra, np.asarray(values, dtype=float))


def multivectors(algebra: Algebra, grades: tuple[int, ...] | None = None) -> st.SearchStrategy[MultiVector]:
    """Random multivectors, optionally restricted to some grades."""
    keep = np.array([grades is None or algebra.grade(m) in grades for m in range(algebra.size)])
    value = st.floats(-3, 3, allow_nan=False).map(lambda v: 0.0 if abs(v) < 1e-6 else v)  # no subnormals
    values = st.lists(value, min_size=algebra.size, max_size=algebra.size)
    return values.map(lambda v: mv(algebra, np.where(keep, v, 0.0)))


def points(dim: int) -> st.SearchStrategy[np.ndarray]:
    return st.lists(coord, min_size=dim, max_size=dim).map(np.array)


def scalar_mv(algebra: Algebra, s: float) -> MultiVector:
    return MultiVector.from_blades(algebra, {0: s})


def close(x: MultiVector, y: MultiVector, scale: float = 1.0) -> bool:
    """Coefficient-wise |x − y| ≤ RTOL × scale (scale = the natural magnitude of the quantities)."""
    return float(np.max(np.abs(x.coeffs - y.coeffs))) <= RTOL * scale


def mag(x: MultiVector) -> float:
    return float(np.max(np.abs(x.coeffs)))


# -- the null basis ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", CGA)
def test_null_basis_closed_forms(name):
    alg = ALGEBRAS[name]
    e0, einf = MultiVector.from_blades(alg, {"e0": 1}), MultiVector.from_blades(alg, {"einf": 1})
    assert (e0 | einf).coeffs.tolist() == scalar_mv(alg, -1).coeffs.tolist()
    assert e0.sp(einf) == -1.0 and einf.sp(e0) == -1.0
    assert not (e0 * e0).coeffs.any() and not (einf * einf).coeffs.any()
    # e0 e∞ = e0·e∞ + e0∧e∞ = −1 + e0∞ exactly
    assert (e0 * einf).coeffs.tolist() == MultiVector.from_blades(alg, {"1": -1, "e0inf": 1}).coeffs.tolist()
    # and (e0∧e∞)² = 1 (a Minkowski plane)
    assert ((e0 ^ einf) * (e0 ^ einf)).coeffs.tolist() == scalar_mv(alg, 1).coeffs.tolist()


@pytest.mark.parametrize(("name", "square"), [("cga3d", -1), ("cga2d", -1), ("ga3d", -1), ("pga3d", 0),
                                              ("g211", 0)])
def test_pseudoscalar_square(name, square):
    alg = ALGEBRAS[name]
    pss = MultiVector.from_blades(alg, {alg.pseudoscalar: 1})
    assert (pss * pss).coeffs.tolist() == scalar_mv(alg, square).coeffs.tolist()


# -- conformal points -------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", CGA)
@settings(max_examples=60)
@given(data=st.data())
def test_conformal_point_inner_product_is_minus_half_squared_distance(name, data):
    alg = ALGEBRAS[name]
    x, y = data.draw(points(alg.dimension - 2)), data.draw(points(alg.dimension - 2))
    px, py = conformal_point(alg, x), conformal_point(alg, y)
    scale = 1 + x @ x + y @ y
    expected = scalar_mv(alg, -0.5 * float((x - y) @ (x - y)))
    assert close(px | py, expected, scale)
    assert close(py | px, expected, scale)
    assert abs(px.sp(py) - expected.scalar()) <= RTOL * scale
    assert close(px * px, MultiVector.zero(alg), scale * scale)  # null vector, and P∧P = 0
    assert close(px | MultiVector.from_blades(alg, {"einf": 1}), scalar_mv(alg, -1.0))


@pytest.mark.parametrize("name", CGA)
@settings(max_examples=60)
@given(data=st.data())
def test_translator_moves_points(name, data):
    """T = 1 − ½ t∧e∞ maps P(x) to P(x + t)."""
    alg = ALGEBRAS[name]
    x, t = data.draw(points(alg.dimension - 2)), data.draw(points(alg.dimension - 2))
    t_inf = MultiVector.from_blades(alg, {1 << (i + 1): v for i, v in enumerate(t)}) ^ \
        MultiVector.from_blades(alg, {"einf": 1})
    translator = 1 - 0.5 * t_inf
    moved = translator.sandwich(conformal_point(alg, x))
    assert close(moved, conformal_point(alg, x + t), (1 + x @ x + t @ t) ** 2)
    assert close(translator * ~translator, scalar_mv(alg, 1.0), 1 + t @ t)


# -- products ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", tiered(sorted(ALGEBRAS), {"cga3d"}))
@settings(max_examples=40)
@given(data=st.data())
def test_geometric_product_is_associative(name, data):
    alg = ALGEBRAS[name]
    a, b, c = (data.draw(multivectors(alg)) for _ in range(3))
    scale = mag(a) * mag(b) * mag(c) * alg.size
    assert close((a * b) * c, a * (b * c), scale)


@pytest.mark.parametrize("name", tiered(sorted(ALGEBRAS), {"cga3d"}))
@settings(max_examples=40)
@given(data=st.data())
def test_vector_products_split_the_geometric_product(name, data):
    """For vectors: a·b = ½(ab + ba), a∧b = ½(ab − ba) = commutator, a⌋(b∧c) = (a·b)c − (a·c)b,
    (b∧c)⌊a = −a⌋(b∧c), and ∧ is antisymmetric and associative."""
    alg = ALGEBRAS[name]
    a, b, c = (data.draw(multivectors(alg, (1,))) for _ in range(3))
    scale = mag(a) * mag(b) * mag(c) * alg.size
    pair_scale = mag(a) * mag(b) * alg.size  # the two-vector identities must not shrink with |c|
    assert close(a | b, (a * b + b * a) / 2, pair_scale)
    assert close(a ^ b, (a * b - b * a) / 2, pair_scale)
    assert close(a.commutator(b), a ^ b, pair_scale)
    ab, ac = (a | b).scalar(), (a | c).scalar()
    assert close(a | (b ^ c), ab * c - ac * b, scale)
    assert close((b ^ c).rc(a), -(a | (b ^ c)), scale)
    assert close((a ^ b) ^ c, -((b ^ a) ^ c), scale)
    assert close((a ^ b) ^ c, a ^ (b ^ c), scale)


# -- duality ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", tiered(sorted(ALGEBRAS), {"cga3d"}))
@settings(max_examples=40)
@given(data=st.data())
def test_dual_undual_round_trip(name, data):
    alg = ALGEBRAS[name]
    x = data.draw(multivectors(alg))
    assert close(x.dual().undual(), x, mag(x))
    assert close(x.undual().dual(), x, mag(x))


@pytest.mark.parametrize("name", sorted(ALGEBRAS))
def test_dual_definition_on_blades(name):
    """X* = X I⁻¹ where I is invertible; otherwise e_A ∧ dual(e_A) = I for every blade."""
    alg = ALGEBRAS[name]
    pss = MultiVector.from_blades(alg, {alg.pseudoscalar: 1})
    for m in range(alg.size):
        blade = MultiVector.from_blades(alg, {m: 1})
        if alg.is_degenerate:
            assert (blade ^ blade.dual()).coeffs.tolist() == pss.coeffs.tolist()
            assert close(blade.dual().undual(), blade)
        else:
            assert close(blade.dual() * pss, blade)
            assert close(blade.dual(), blade * pss.inverse())


# -- versors ----------------------------------------------------------------------------------------------
def _non_null_vectors(alg: Algebra, data: st.DataObject, count: int) -> list[MultiVector]:
    vs = [data.draw(multivectors(alg, (1,))) for _ in range(count)]
    for v in vs:
        assume(mag(v) >= 0.5 and abs((v * v).scalar()) >= 0.25 * mag(v) ** 2)
    return vs


@pytest.mark.parametrize("name", tiered(["cga3d", "cga2d", "ga3d", "g211"], {"cga3d"}))
@settings(max_examples=40)
@given(data=st.data(), count=st.integers(1, 3))
def test_versor_inverse(name, data, count):
    """X X⁻¹ = X⁻¹ X = 1 for a product of non-null vectors; normalised, X X~ = ±1."""
    alg = ALGEBRAS[name]
    versor = scalar_mv(alg, 1.0)
    for v in _non_null_vectors(alg, data, count):
        versor = versor * v
    one = scalar_mv(alg, 1.0)
    assert close(versor * versor.inverse(), one, 10.0**count)
    assert close(versor.inverse() * versor, one, 10.0**count)
    unit = versor.normalized()
    assert close(unit * ~unit, scalar_mv(alg, math.copysign(1.0, versor.norm_squared())), 10.0**count)


@pytest.mark.parametrize("name", tiered(sorted(ALGEBRAS), {"cga3d"}))
@settings(max_examples=40)
@given(data=st.data())
def test_rotor_from_simple_bivector(name, data):
    """R = normalized(1 + a∧b) is a versor: R R~ = ±1, R R⁻¹ = 1, and R x R~ keeps grade 1 and x²."""
    alg = ALGEBRAS[name]
    a, b, x = (data.draw(multivectors(alg, (1,))) for _ in range(3))
    bivector = a ^ b
    assume(abs(1 - (bivector * bivector).scalar()) >= 0.1)
    rotor = (1 + bivector).normalized()
    one = scalar_mv(alg, 1.0)
    assert close(rotor * rotor.inverse(), one, 10.0)
    assert close(rotor * ~rotor, scalar_mv(alg, math.copysign(1.0, rotor.norm_squared())), 10.0)
    moved = rotor * x * ~rotor
    scale = mag(x) * 10.0
    assert close(moved, moved.grade(1), scale)
    assert close(rotor.sandwich(x), moved, scale)
    assert abs((moved * moved).scalar() - (x * x).scalar() * rotor.norm_squared() ** 2) <= RTOL * scale**2


def test_rotor_rotates_by_closed_form():
    """In ga3d, R = cos(θ/2) − sin(θ/2) e12 rotates e1 by θ towards e2."""
    alg = ALGEBRAS["ga3d"]
    for theta in np.linspace(-3.0, 3.0, 13):
        rotor = MultiVector.from_blades(alg, {"1": math.cos(theta / 2), "e12": -math.sin(theta / 2)})
        moved = rotor.sandwich(MultiVector.from_blades(alg, {"e1": 1}))
        expected = MultiVector.from_blades(alg, {"e1": math.cos(theta), "e2": math.sin(theta)})
        assert close(moved, expected)


# -- meet -------------------------------------------------------------------------------------------------
def _plane(alg: Algebra, p1, p2, p3) -> MultiVector:
    einf = MultiVector.from_blades(alg, {"einf": 1})
    return conformal_point(alg, p1) ^ conformal_point(alg, p2) ^ conformal_point(alg, p3) ^ einf


@settings(max_examples=80)
@given(st.lists(points(3), min_size=6, max_size=6))
def test_meet_of_two_planes_is_their_line(pts):
    """(Π1* ∧ Π2*) undualised ∝ Q1∧Q2∧e∞, Q1, Q2 two points of the intersection line of the planes."""
    alg = ALGEBRAS["cga3d"]
    p = [np.asarray(q) for q in pts]
    n1, n2 = np.cross(p[1] - p[0], p[2] - p[0]), np.cross(p[4] - p[3], p[5] - p[3])
    u = np.cross(n1, n2)
    assume(np.linalg.norm(n1) > 1 and np.linalg.norm(n2) > 1)
    assume(np.linalg.norm(u) > 0.3 * np.linalg.norm(n1) * np.linalg.norm(n2))
    d1, d2 = n1 @ p[0], n2 @ p[3]
    x0 = np.cross(d1 * n2 - d2 * n1, u) / (u @ u)  # on both planes: n1·x0 = d1, n2·x0 = d2
    assert abs(n1 @ x0 - d1) < 1e-9 * (1 + abs(d1)) and abs(n2 @ x0 - d2) < 1e-9 * (1 + abs(d2))
    plane1, plane2 = _plane(alg, *p[:3]), _plane(alg, *p[3:])
    meet = plane1 & plane2
    einf = MultiVector.from_blades(alg, {"einf": 1})
    line = conformal_point(alg, x0) ^ conformal_point(alg, x0 + u / np.linalg.norm(u)) ^ einf
    assert meet.grades <= {3} and line.grades <= {3}
    ratio = float(meet.coeffs @ line.coeffs / (line.coeffs @ line.coeffs))
    assert abs(ratio) > 1e-6 * mag(meet) / mag(line)
    assert close(meet, ratio * line, mag(meet) * 10)
    # the line lies in both planes: every point of it is on both (P ∧ Π = 0)
    for s in (-1.0, 2.5):
        q = conformal_point(alg, x0 + s * u)
        assert close(q ^ plane1, MultiVector.zero(alg), mag(plane1) * (1 + x0 @ x0 + s * s * (u @ u)) * 10)


def test_meet_sign_in_ga3d():
    """The regressive product of the planes e12 and e23 is their common line, −e2 with the convention
    undual(dual(A) ∧ dual(B)) and dual = X I⁻¹ (worked by hand below)."""
    alg = ALGEBRAS["ga3d"]
    e12, e23 = MultiVector.from_blades(alg, {"e12": 1}), MultiVector.from_blades(alg, {"e23": 1})
    # dual(e12) = e12 I⁻¹ = e12 (−e123) = e3, dual(e23) = e23 (−e123) = e1; e3 ∧ e1 = −e13;
    # undual(−e13) = −e13 e123 = −e1e3e1e2e3 = −e2
    assert (e12 & e23).coeffs.tolist() == MultiVector.from_blades(alg, {"e2": -1}).coeffs.tolist()
