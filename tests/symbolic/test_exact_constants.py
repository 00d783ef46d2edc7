"""Exact constants and term merging in the scalar layer, seen through op counts and values."""

import math

import casadi as ca
import numpy as np
import pytest
import sympy
from hypothesis import given
from hypothesis import strategies as st

from gagen.algebra import SparseMultivector, cga3d
from gagen.symbolic import CasadiBackend, SympyBackend, to_exact
from gagen.symbolic.flatten import flatten


@given(st.floats(allow_nan=False, allow_infinity=False, width=64))
def test_floats_become_their_exact_binary_value(x):
    exact = to_exact(x)
    assert float(exact) == x  # round trip to the last bit


def test_non_finite_constants_are_refused():
    with pytest.raises(ValueError, match="non-finite"):
        to_exact(math.inf)


def test_identical_monomials_cancel_before_emission():
    b = CasadiBackend()
    x, y = b.symbols("v", ["x", "y"])
    assert b.sub(b.mul(x, y), b.mul(y, x)) == 0
    assert b.add(b.mul(2, x), b.mul(-2, x)) == 0
    three_x = b.native(b.add(x, x, x))
    f = ca.Function("f", [x], [three_x])
    assert float(f(1.5)) == 4.5


def test_chains_of_exact_constants_cancel_inside_sums():
    """½(x − y) + ½(x + y) − x is exactly zero even though its parts were built separately."""
    b = CasadiBackend()
    x, y = b.symbols("v", ["x", "y"])
    half = sympy.Rational(1, 2)
    total = b.sub(b.add(b.mul(half, b.sub(x, y)), b.mul(half, b.add(x, y))), x)
    assert total == 0


def test_exact_constants_fold_exactly():
    b = CasadiBackend()
    c = b.call("cos", sympy.pi / 2)
    assert c == 0  # exact zero, not 6e-17
    r = b.mul(b.call("sqrt", 2), b.call("sqrt", 2), sympy.Rational(1, 2))
    assert r == 1


@pytest.mark.parametrize("backend", [CasadiBackend(), SympyBackend()], ids=lambda b: b.name)
def test_quarter_turn_rotor_costs_no_multiplication(backend):
    """A 90° rotor (exact √½ coefficients) moves a symbolic vector with sign flips only."""
    a = cga3d()
    half_angle = sympy.pi / 4
    x = SparseMultivector.symbolic(a, backend, "x", ["e1", "e2", "e3"])
    rotor = x.make({"1": sympy.cos(half_angle), "e12": -sympy.sin(half_angle)})  # e^{−(π/2) e12 / 2}
    y = rotor.sandwich(x)
    kernel = flatten("rot", [("x", x)], [("y", y)], backend)
    assert kernel.op_count.mul == 0 and kernel.op_count.add == 0
    assert y.support == (a.blade("e1"), a.blade("e2"), a.blade("e3"))
    out = kernel([1.0, 2.0, 3.0])[0]
    # rotation by +90° about e3 (e1 → e2): (1, 2, 3) → (−2, 1, 3)
    np.testing.assert_array_equal(out, [-2.0, 1.0, 3.0])


def test_transcendental_constants_become_their_nearest_double_exactly():
    """cos(1/7) is not carried symbolically: it becomes the exact value of the nearest double,
    while cos(π/4) stays the algebraic √2/2."""
    from gagen.symbolic.backend import exact_call

    value = exact_call("cos", sympy.Rational(1, 7))
    assert value.is_Rational and float(value) == math.cos(1 / 7)
    assert exact_call("cos", sympy.pi / 4) == sympy.sqrt(2) / 2


@given(c=st.floats(-10, 10), d=st.floats(-10, 10), x=st.floats(-10, 10))
def test_a_sums_constant_term_survives_adding_constants(c, d, x):
    """(c + x) + d = c + d + x, also after a product: the Poly's own constant term and a loose
    constant add up (a regression: the loose one used to replace it)."""
    b = CasadiBackend()
    (sym,) = b.symbols("v", ["x"])
    expressions = [b.add(b.add(c, sym), d), b.add(d, b.add(sym, c)), b.add(b.mul(b.add(c, sym), 3), d)]
    f = ca.Function("f", [b.native(b.lift(sym))], [b.native(e) for e in expressions])
    values = [float(v) for v in f(x)]
    expected = [c + x + d, d + x + c, 3 * (c + x) + d]
    np.testing.assert_allclose(values, expected, rtol=1e-12, atol=1e-12)


def test_sums_equal_up_to_a_constant_share_one_node():
    """s·(−½s) + ½s² is exactly zero although both s and −½s become nodes before the products: the
    scalar layer materialises a sum once and takes its multiples as multiples of that node (a
    translator T = 1 − ½t e∞ and its reverse meet in every sandwich)."""
    b = CasadiBackend()
    x, y, z = b.symbols("v", ["x", "y", "z"])
    s = b.add(x, y)
    minus_half = b.mul(sympy.Rational(-1, 2), s)
    product = b.mul(s, minus_half)
    assert len(product) == 1  # one term: −½ · node²
    assert b.add(product, b.mul(sympy.Rational(1, 2), b.mul(s, s))) == 0
    # x − y and y − x too; an unrelated sum does not share it
    assert b.add(b.mul(b.sub(x, y), z), b.mul(b.sub(y, x), z)) == 0
    other = b.add(x, z)
    assert b.native(b.mul(other, s)).n_dep() == 2
    value = ca.Function("f", [x, y, z], [b.native(b.mul(s, minus_half))])
    assert float(value(1.0, 2.0, 0.0)) == -4.5
