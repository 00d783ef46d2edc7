"""exp/log charts and versor constructions: round trips, behaviour at the identity, derivatives,
and the flattened CasADi kernels against the interpreter."""

from __future__ import annotations

from functools import cache

import casadi as ca
import numpy as np
import pytest
from conftest import tiered
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from gagen.algebra.signature import cga3d
from gagen.crosscheck import Formula, dense_outputs, flatten_formula, interpret, relative_error
from gagen.interp import MultiVector
from gagen.model import versors as V
from gagen.model.conformal import (
    DILATION,
    EUCLID,
    MOTOR,
    MOTOR_GENERATOR,
    ROTATION,
    SIMILARITY,
    SIMILARITY_GENERATOR,
    TRANSLATION,
)

ALG = cga3d()
ROTOR = ("1", *ROTATION)
TRANSLATOR = ("1", *TRANSLATION)
DILATOR = ("1", *DILATION)

# name -> (input blades, function, generator blades of the chart, versor blades)
CHARTS = {
    "rotor": (ROTATION, V.exp_rotor, V.log_rotor, ROTOR),
    "translator": (TRANSLATION, V.exp_translator, V.log_translator, TRANSLATOR),
    "dilator": (DILATION, V.exp_dilator, V.log_dilator, DILATOR),
    "motor": (MOTOR_GENERATOR, V.exp_motor, V.log_motor, MOTOR),
    "similarity": (SIMILARITY_GENERATOR, V.exp_similarity, V.log_similarity, SIMILARITY),
}


def _generator(name: str, values: np.ndarray, angle_limit: float = 3.0) -> np.ndarray:
    """Chart coordinates in the domain: rotation angle |θ| < angle_limit < π."""
    blades = CHARTS[name][0]
    values = np.array(values, dtype=float)
    rot = [i for i, b in enumerate(blades) if b in ROTATION]
    if rot:
        norm = np.linalg.norm(values[rot])
        if norm > angle_limit:
            values[rot] *= angle_limit / norm
    return values


def _mv(blades, values) -> MultiVector:
    return MultiVector.from_blades(ALG, dict(zip(blades, values, strict=True)))


def _coeffs(x: MultiVector, blades) -> np.ndarray:
    return np.array([x[b] for b in blades])


@cache
def _kernel(name: str, which: str):
    gens, exp, log, versor = CHARTS[name]
    formula = (Formula(f"exp_{name}", ALG, (("b", gens),), exp) if which == "exp"
               else Formula(f"log_{name}", ALG, (("v", versor),), log))
    return formula, flatten_formula(formula)


def _gen_values(name):
    n = len(CHARTS[name][0])
    return arrays(np.float64, n, elements=st.floats(-3, 3, allow_subnormal=False)).map(
        lambda v: _generator(name, v))


# -- round trips on the interpreter and through the kernels ------------------------------------------
@pytest.mark.parametrize("name", tiered(sorted(CHARTS), {"similarity"}))
@settings(max_examples=200)
@given(data=st.data())
def test_log_of_exp_is_identity(name, data):
    gens, exp, log, versor = CHARTS[name]
    b = data.draw(_gen_values(name))
    v = exp(_mv(gens, b))
    back = _coeffs(log(v), gens)
    np.testing.assert_allclose(back, b, rtol=0, atol=1e-11)
    # the same through the flattened kernels
    (_, exp_k), (_, log_k) = _kernel(name, "exp"), _kernel(name, "log")
    v_k = dense_outputs(exp_k, ALG, exp_k(b))[0]
    np.testing.assert_allclose(v_k, v.coeffs, rtol=0, atol=1e-12)
    back_k = dense_outputs(log_k, ALG, log_k(_coeffs(v, versor)))[0]
    np.testing.assert_allclose([back_k[ALG.blade(g)] for g in gens], b, rtol=0, atol=1e-11)


@pytest.mark.parametrize("name", tiered(sorted(CHARTS), {"similarity"}))
@settings(max_examples=200)
@given(data=st.data())
def test_exp_of_log_is_identity_and_versors_are_unit(name, data):
    gens, exp, log, _versor = CHARTS[name]
    v = exp(_mv(gens, data.draw(_gen_values(name))))
    np.testing.assert_allclose((v * ~v).coeffs, _mv(("1",), [1.0]).coeffs, atol=1e-12)
    np.testing.assert_allclose(exp(log(v)).coeffs, v.coeffs, atol=1e-12)


@pytest.mark.parametrize("name", sorted(CHARTS))
@pytest.mark.parametrize("offset", [0.0, 1e-300, 1e-12, 1e-9, 1e-6, 1e-3, 1e-2, 0.011])
def test_kernels_are_exact_and_finite_at_and_near_the_identity(name, offset):
    """Exactly at the identity and within 1e-9 of it: no NaN or Inf, values and round trip exact."""
    gens, exp, _log, versor = CHARTS[name]
    rng = np.random.default_rng(7)
    direction = rng.normal(size=len(gens))
    b = offset * direction / np.linalg.norm(direction)
    (_, exp_k), (_, log_k) = _kernel(name, "exp"), _kernel(name, "log")
    v = exp_k(b)[0]
    assert np.all(np.isfinite(v))
    v_dense = dense_outputs(exp_k, ALG, [v])[0]
    np.testing.assert_allclose(v_dense, exp(_mv(gens, b)).coeffs, rtol=0, atol=1e-15)
    back = dense_outputs(log_k, ALG, log_k([v_dense[ALG.blade(x)] for x in versor]))[0]
    assert np.all(np.isfinite(back))
    np.testing.assert_allclose([back[ALG.blade(g)] for g in gens], b, rtol=1e-12, atol=1e-300)


# -- derivatives: CasADi AD against central finite differences of the interpreter ---------------------
def _ad_jacobian(kernel, x: np.ndarray) -> np.ndarray:
    f = kernel.function
    sym = ca.SX.sym("x", f.size1_in(0))
    jac = ca.Function("jacobian", [sym], [ca.jacobian(f(sym), sym)])
    return np.asarray(jac(x), dtype=float)


def _fd_jacobian(formula: Formula, kernel, x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    blades = [ALG.blade(label) for label in kernel.outputs[0].rows]
    cols = []
    for i in range(len(x)):
        step = np.zeros_like(x)
        step[i] = h
        plus, minus = interpret(formula, [x + step])[0], interpret(formula, [x - step])[0]
        cols.append((plus[blades] - minus[blades]) / (2 * h))
    return np.array(cols).T


def _point_in_domain(name: str, which: str, rng, at_identity: bool) -> np.ndarray:
    gens, exp, _, versor = CHARTS[name]
    b = np.zeros(len(gens)) if at_identity else _generator(name, rng.uniform(-2, 2, len(gens)), 2.5)
    return b if which == "exp" else _coeffs(exp(_mv(gens, b)), versor)


@pytest.mark.parametrize("which", ["exp", "log"])
@pytest.mark.parametrize("name", sorted(CHARTS))
@pytest.mark.parametrize("at_identity", [True, False], ids=["identity", "random"])
def test_casadi_jacobian_matches_central_differences(name, which, at_identity):
    formula, kernel = _kernel(name, which)
    rng = np.random.default_rng(11)
    for _ in range(1 if at_identity else 5):
        x = _point_in_domain(name, which, rng, at_identity)
        ad = _ad_jacobian(kernel, x)
        assert np.all(np.isfinite(ad))
        fd = _fd_jacobian(formula, kernel, x)
        np.testing.assert_allclose(ad, fd, rtol=1e-6, atol=2e-8)


# -- versor constructions -----------------------------------------------------------------------------
unit3 = arrays(np.float64, 3, elements=st.floats(-1, 1, allow_subnormal=False)).filter(
    lambda v: np.linalg.norm(v) > 0.1).map(lambda v: v / np.linalg.norm(v))


@settings(max_examples=200)
@given(unit3, unit3)
def test_rotor_between_turns_a_onto_b(a, b):
    va, vb = _mv(EUCLID, a), _mv(EUCLID, b)
    r, conditioning = V.rotor_between(va, vb)
    np.testing.assert_allclose(_coeffs(r.sandwich(va), EUCLID), b, atol=1e-9)
    np.testing.assert_allclose((r * ~r).coeffs[0], 1.0, atol=1e-12)
    assert abs(conditioning - (1 + a @ b) / 2) < 1e-12


@pytest.mark.parametrize("axis", [(1, 0, 0), (0, 1, 0), (0, 0, 1), (0.6, 0.8, 0), (0.95, 0.1, 0.3)])
def test_rotor_between_antiparallel_vectors_is_a_half_turn(axis):
    a = np.array(axis, dtype=float) / np.linalg.norm(axis)
    r, conditioning = V.rotor_between(_mv(EUCLID, a), _mv(EUCLID, -a))
    assert abs(conditioning) < 1e-15
    np.testing.assert_allclose(_coeffs(r.sandwich(_mv(EUCLID, a)), EUCLID), -a, atol=1e-12)


@pytest.mark.parametrize("name", sorted(CHARTS))
def test_every_chart_kernel_equals_the_interpreter(name):
    rng = np.random.default_rng(3)
    for which in ("exp", "log"):
        formula, kernel = _kernel(name, which)
        for _ in range(50):
            x = _point_in_domain(name, which, rng, at_identity=False)
            assert relative_error(kernel, formula, [x]) < 1e-12


@pytest.mark.parametrize("name", ["rotor", "motor", "similarity"])
@pytest.mark.parametrize("shortfall", [0.0, 1e-12, 1e-9, 1e-6])
def test_log_is_finite_and_correct_at_and_near_a_half_turn(name, shortfall):
    """θ = π − shortfall: exp then log gives the generator back (no NaN at θ = π itself)."""
    gens, exp, _log, versor = CHARTS[name]
    rng = np.random.default_rng(5)
    b = rng.normal(size=len(gens))
    rot = [i for i, g in enumerate(gens) if g in ROTATION]
    b[rot] *= (np.pi - shortfall) / np.linalg.norm(b[rot])
    (_, log_k) = _kernel(name, "log")
    v = exp(_mv(gens, b))
    back = dense_outputs(log_k, ALG, log_k(_coeffs(v, versor)))[0]
    assert np.all(np.isfinite(back))
    np.testing.assert_allclose([back[ALG.blade(g)] for g in gens], b, atol=1e-9)
