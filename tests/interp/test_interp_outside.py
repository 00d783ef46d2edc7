"""The reference interpreter against an outside library, kingdon, on random multivectors.

kingdon works in an orthonormal basis. Each gagen basis vector is written here by hand as a kingdon
vector (CGA: e0 = ½(e− − e+), e∞ = e+ + e−), each gagen blade is the kingdon outer product of its
vectors, and a gagen coefficient array maps to the kingdon multivector Σ c_A image(A). A kingdon
result maps back by solving the linear system of blade images. Nothing of gagen's own change of
basis is used on this side.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np
import pytest
from conftest import tiered
from hypothesis import given, settings
from hypothesis import strategies as st
from kingdon import Algebra as KingdonAlgebra

from gagen.algebra.signature import Algebra, cga2d, cga3d, from_signature, ga3d, pga3d
from gagen.interp import MultiVector

RTOL = 1e-12


def _kingdon_vectors(k: KingdonAlgebra) -> list:
    """kingdon's orthonormal basis vectors in key order."""
    return [k.multivector(values=[1.0], keys=(1 << j,)) for j in range(k.d)]


def _square(v) -> float:
    return float(sum((v * v).values()))


def _cga_vectors(k: KingdonAlgebra) -> list:
    """Euclidean vectors, then e0 = ½(e− − e+), e∞ = e+ + e− in gagen's order (e0, e1, ..., einf)."""
    *euclid, e_plus, e_minus = _kingdon_vectors(k)
    assert [_square(v) for v in euclid] == [1.0] * len(euclid)
    assert (_square(e_plus), _square(e_minus)) == (1.0, -1.0)  # kingdon's last vector is e−
    return [0.5 * (e_minus - e_plus), *euclid, e_plus + e_minus]


Case = tuple[Callable[[], Algebra], Callable[[], KingdonAlgebra], Callable[[KingdonAlgebra], list]]
CASES: dict[str, Case] = {
    "cga3d": (cga3d, lambda: KingdonAlgebra(4, 1), _cga_vectors),
    "cga2d": (cga2d, lambda: KingdonAlgebra(3, 1), _cga_vectors),
    "pga3d": (pga3d, lambda: KingdonAlgebra(3, 0, 1), _kingdon_vectors),  # e0 (null), e1, e2, e3
    "ga3d": (ga3d, lambda: KingdonAlgebra(3, 0), _kingdon_vectors),
    "g211": (lambda: from_signature(2, 1, 1), lambda: KingdonAlgebra(2, 1, 1), _kingdon_vectors),
}


@dataclass
class Bridge:
    """Coefficient arrays of one gagen algebra <-> kingdon multivectors."""

    algebra: Algebra
    kingdon: KingdonAlgebra
    images: np.ndarray  # column A = kingdon coefficients (by key) of gagen blade A
    pseudoscalar: object = None  # kingdon image of gagen's I (sparse, as built)

    def dense(self, x) -> np.ndarray:
        out = np.zeros(self.algebra.size)
        for key, value in zip(x.keys(), x.values(), strict=True):
            out[key] = float(value)
        return out

    def to_kingdon(self, coeffs: np.ndarray):
        keys = tuple(range(self.algebra.size))
        return self.kingdon.multivector(values=list(self.images @ coeffs), keys=keys)

    def from_kingdon(self, x) -> np.ndarray:
        return np.linalg.solve(self.images, self.dense(x))


@cache
def bridge(name: str) -> Bridge:
    make_algebra, make_kingdon, make_vectors = CASES[name]
    algebra, k = make_algebra(), make_kingdon()
    vectors = make_vectors(k)
    assert len(vectors) == algebra.dimension
    b = Bridge(algebra, k, np.zeros((algebra.size, algebra.size)))
    for mask in range(algebra.size):
        blade = k.multivector(values=[1.0], keys=(0,))
        for i in range(algebra.dimension):
            if mask >> i & 1:
                blade = blade ^ vectors[i]
        b.images[:, mask] = b.dense(blade)
    b.pseudoscalar = blade  # the last mask is the pseudoscalar
    return b


def coefficients(size: int) -> st.SearchStrategy[np.ndarray]:
    """Dense or sparse random coefficient arrays."""
    nonzero = st.floats(-10, 10, allow_nan=False).map(lambda v: 0.0 if abs(v) < 1e-6 else v)  # no subnormals
    value = st.one_of(st.just(0.0), nonzero)
    return st.lists(value, min_size=size, max_size=size).map(np.array)


def assert_close(ours: np.ndarray, theirs: np.ndarray, scale: float, what: str) -> None:
    """|ours − theirs| ≤ RTOL × the natural scale of the result (largest input product or output)."""
    scale = max(scale, float(np.max(np.abs(theirs))), 1e-300)
    err = float(np.max(np.abs(ours - theirs)))
    assert err <= RTOL * scale, f"{what}: error {err:.3g} at scale {scale:.3g}"


def check_all(name: str, a: np.ndarray, b: np.ndarray) -> None:
    """Every binary and unary operation of the interpreter against kingdon, for one pair."""
    br = bridge(name)
    alg = br.algebra
    A, B = MultiVector(alg, a), MultiVector(alg, b)
    ka, kb = br.to_kingdon(a), br.to_kingdon(b)
    scale = float(np.max(np.abs(a)) * np.max(np.abs(b)))
    unary_scale = float(np.max(np.abs(a)))

    binary = {
        "gp": (A * B, ka * kb),
        "op": (A ^ B, ka ^ kb),
        "lc": (A | B, ka.lc(kb)),
        "rc": (A.rc(B), ka.rc(kb)),
        "commutator": (A.commutator(B), ka.cp(kb)),
    }
    for what, (ours, theirs) in binary.items():
        assert_close(ours.coeffs, br.from_kingdon(theirs), scale, what)
    assert_close(np.array([A.sp(B)]), br.from_kingdon(ka.sp(kb))[:1], scale, "sp")

    unary = {"reverse": (~A, ~ka), "involute": (A.involute(), ka.involute()),
             "conjugate": (A.conjugate(), ka.conjugate())}
    for what, (ours, theirs) in unary.items():
        assert_close(ours.coeffs, br.from_kingdon(theirs), unary_scale, what)

    # duality: kingdon's own Hodge dual is gagen's right complement (PGA); elsewhere gagen's X I⁻¹ is
    # computed in kingdon from the image of gagen's pseudoscalar (the outer product of its vectors)
    if alg.is_degenerate:
        dual_k, undual_k, meet_k = ka.hodge(), ka.unhodge(), ka & kb
    else:
        pss = br.pseudoscalar
        pss_inv = pss.reverse() / (pss * pss.reverse()).e
        dual_k, undual_k = ka * pss_inv, ka * pss
        meet_k = ((ka * pss_inv) ^ (kb * pss_inv)) * pss
    assert_close(A.dual().coeffs, br.from_kingdon(dual_k), unary_scale, "dual")
    assert_close(A.undual().coeffs, br.from_kingdon(undual_k), unary_scale, "undual")
    assert_close((A & B).coeffs, br.from_kingdon(meet_k), scale, "regressive")


@pytest.mark.slow
@settings(max_examples=250)
@given(data=st.data())
def test_cga3d_agrees_with_kingdon(data):
    size = cga3d().size
    check_all("cga3d", data.draw(coefficients(size)), data.draw(coefficients(size)))


@pytest.mark.parametrize("name", tiered(["cga2d", "pga3d", "ga3d", "g211"], {"cga2d"}))
@settings(max_examples=100)
@given(data=st.data())
def test_other_algebras_agree_with_kingdon(name, data):
    size = bridge(name).algebra.size
    check_all(name, data.draw(coefficients(size)), data.draw(coefficients(size)))


@pytest.mark.parametrize("name", sorted(CASES))
def test_every_blade_pair_agrees_with_kingdon(name):
    """All basis-blade pairs of the geometric product, exactly (entries are small dyadic rationals)."""
    br = bridge(name)
    eye = np.eye(br.algebra.size)
    for i in range(br.algebra.size):
        for j in range(br.algebra.size):
            ours = (MultiVector(br.algebra, eye[i]) * MultiVector(br.algebra, eye[j])).coeffs
            theirs = br.from_kingdon(br.to_kingdon(eye[i]) * br.to_kingdon(eye[j]))
            assert np.array_equal(ours, theirs), (br.algebra.blade_name(i), br.algebra.blade_name(j))


def test_cga_pseudoscalar_orientation_against_kingdon_polarity():
    """For cga3d I = e0∧e1∧e2∧e3∧e∞ equals kingdon's e12345, so dual is kingdon's polarity itself;
    for cga2d I = −e1234 and dual = −polarity."""
    for name, sign in (("cga3d", 1.0), ("cga2d", -1.0)):
        br = bridge(name)
        x = np.arange(1.0, br.algebra.size + 1)
        theirs = sign * br.from_kingdon(br.to_kingdon(x).polarity())
        assert_close(MultiVector(br.algebra, x).dual().coeffs, theirs, float(np.max(x)), name)
