"""Every operation, in every algebra: the flattened symbolic kernel equals the reference interpreter.

The compiler (exact blade rules by Chevalley recursion, sparse Poly coefficients, CasADi or sympy
flattening) and the interpreter (dense orthonormal-frame arithmetic) share only the algebra
description, so agreement on random inputs checks both.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache

import numpy as np
import pytest
from conftest import ALGEBRAS, far_from_null_vectors, tiered, versor_from_vectors
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from gagen.algebra.signature import Algebra
from gagen.crosscheck import Formula, flatten_formula, relative_error
from gagen.symbolic import CasadiBackend, SympyBackend

TOL = 1e-12

BINARY: dict[str, Callable] = {
    "gp": lambda a, b: a * b,
    "op": lambda a, b: a ^ b,
    "lc": lambda a, b: a.lc(b),
    "rc": lambda a, b: a.rc(b),
    "inner": lambda a, b: a | b,
    "sp": lambda a, b: a.sp(b),
    "commutator": lambda a, b: a.commutator(b),
    "regressive": lambda a, b: a & b,
    "add": lambda a, b: a + b,
    "sub": lambda a, b: a - b,
}
UNARY: dict[str, Callable] = {
    "reverse": lambda a: ~a,
    "involute": lambda a: a.involute(),
    "conjugate": lambda a: a.conjugate(),
    "dual": lambda a: a.dual(),
    "undual": lambda a: a.undual(),
    "grade 0": lambda a: a.grade(0),
    "grade 1": lambda a: a.grade(1),
    "grade 2": lambda a: a.grade(2),
    "grades 3,4": lambda a: a.grade((3, 4)),
    "scalar x mv": lambda a: a * (a.scalar() * 3 - 0.25),
    "divide": lambda a: a / 4,
}
VERSOR: dict[str, Callable] = {
    "inverse": lambda v: v.inverse(),
    "normalized": lambda v: v.normalized(),
    "norm_squared": lambda v: v.norm_squared(),
    "v * v^-1": lambda v: v * v.inverse(),
}


# the fast tier: a few operations in cga3d (and one per sympy test); the full tier: every one, everywhere
FAST = {"binary": {("cga3d", "gp"), ("cga3d", "op"), ("cga3d", "regressive")},
        "unary": {("cga3d", "reverse"), ("cga3d", "dual")},
        "versor": {("cga3d", "inverse")},
        "sympy binary": {("cga2d", "gp")}}


def _cases(kind: str, algebras, ops) -> list:
    """(algebra, op) for every op and algebra (ids ``algebra-op``), slow but for FAST[kind]."""
    return tiered([(a, op) for op in ops for a in algebras], FAST[kind])


def _blades(algebra: Algebra, parity: int | None = None) -> tuple[int, ...]:
    return tuple(m for m in range(algebra.size) if parity is None or m.bit_count() % 2 == parity)


@cache
def _kernel(algebra_name: str, kind: str, op: str, backend_name: str = "casadi"):
    algebra = ALGEBRAS[algebra_name]
    full, even = _blades(algebra), _blades(algebra, 0)
    if kind == "binary":
        formula = Formula(op, algebra, (("a", full), ("b", full)), BINARY[op])
    elif kind == "unary":
        formula = Formula(op, algebra, (("a", full),), UNARY[op])
    elif kind == "versor":
        formula = Formula(op, algebra, (("v", even),), VERSOR[op])
    else:  # sandwich of a general multivector by an even versor
        formula = Formula(op, algebra, (("v", even), ("x", full)), lambda v, x: v.sandwich(x))
    backend = CasadiBackend() if backend_name == "casadi" else SympyBackend()
    return formula, flatten_formula(formula, backend)


def _coefficients(algebra: Algebra):
    return arrays(np.float64, algebra.size, elements=st.floats(-1, 1, allow_subnormal=False))


def _versor(algebra: Algebra, vectors: np.ndarray) -> np.ndarray:
    """Coefficients, on the even blades, of the product of four vectors far from null."""
    v = versor_from_vectors(algebra, vectors)
    return np.array([v.coeffs[m] for m in _blades(algebra, 0)])


@pytest.mark.parametrize(("algebra_name", "op"), _cases("binary", sorted(ALGEBRAS), sorted(BINARY)))
@settings(max_examples=200)
@given(data=st.data())
def test_binary_operation(algebra_name, op, data):
    algebra = ALGEBRAS[algebra_name]
    formula, kernel = _kernel(algebra_name, "binary", op)
    a, b = data.draw(_coefficients(algebra)), data.draw(_coefficients(algebra))
    assert relative_error(kernel, formula, [a, b]) < TOL


@pytest.mark.parametrize(("algebra_name", "op"), _cases("unary", sorted(ALGEBRAS), sorted(UNARY)))
@settings(max_examples=200)
@given(data=st.data())
def test_unary_operation(algebra_name, op, data):
    algebra = ALGEBRAS[algebra_name]
    formula, kernel = _kernel(algebra_name, "unary", op)
    assert relative_error(kernel, formula, [data.draw(_coefficients(algebra))]) < TOL


@pytest.mark.parametrize(("algebra_name", "op"), _cases("versor", sorted(ALGEBRAS), sorted(VERSOR)))
@settings(max_examples=200)
@given(data=st.data())
def test_versor_operation(algebra_name, op, data):
    algebra = ALGEBRAS[algebra_name]
    formula, kernel = _kernel(algebra_name, "versor", op)
    v = _versor(algebra, data.draw(far_from_null_vectors(algebra)))
    assert relative_error(kernel, formula, [v]) < TOL


@pytest.mark.parametrize("algebra_name", tiered(sorted(ALGEBRAS), {"cga3d"}))
@settings(max_examples=200)
@given(data=st.data())
def test_sandwich(algebra_name, data):
    algebra = ALGEBRAS[algebra_name]
    formula, kernel = _kernel(algebra_name, "sandwich", "sandwich")
    v = _versor(algebra, data.draw(far_from_null_vectors(algebra)))
    x = data.draw(_coefficients(algebra))
    # pure-grade inputs, where "keep the grades of x" is what a versor guarantees
    grade = data.draw(st.integers(0, algebra.dimension))
    x = np.where([m.bit_count() == grade for m in range(algebra.size)], x, 0.0)
    assert relative_error(kernel, formula, [v, x]) < TOL


# -- the sympy backend: exact derivation, same answers ---------------------------------------------
@pytest.mark.parametrize(("algebra_name", "op"),
                         _cases("sympy binary", ["cga2d", "pga3d", "ga3d"], ["gp", "op", "lc", "regressive",
                                                                              "commutator"]))
@settings(max_examples=50)
@given(data=st.data())
def test_sympy_backend_binary(algebra_name, op, data):
    algebra = ALGEBRAS[algebra_name]
    formula, kernel = _kernel(algebra_name, "binary", op, "sympy")
    a, b = data.draw(_coefficients(algebra)), data.draw(_coefficients(algebra))
    assert relative_error(kernel, formula, [a, b]) < TOL


@pytest.mark.parametrize("op", tiered(sorted(VERSOR), {"inverse"}))
@settings(max_examples=50)
@given(data=st.data())
def test_sympy_backend_versor(op, data):
    algebra = ALGEBRAS["cga2d"]
    formula, kernel = _kernel("cga2d", "versor", op, "sympy")
    v = _versor(algebra, data.draw(far_from_null_vectors(algebra)))
    assert relative_error(kernel, formula, [v]) < TOL
