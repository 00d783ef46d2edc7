"""The closed-form circle similarity Jacobians [COOP Appendix B] against AD and differences.

- at random configurations of the three-Panda and three-iiwa circle systems, the closed form (on the
  interpreter and as the traced kernel's CasADi Function) equals the AD J_A of ``similarity_jacobians``
  to 1e-12 of max |J_A|;
- at hypothesis-drawn point triples, it equals CasADi AD of gagen's V_Sc(X_u, X_c) through the points;
- each factor's Jacobian (J_T, J_R, J_D) equals 4th-order central differences of gagen's factor;
- Eq. 79 and Eq. 81 equal differences, and the printed forms of errata 1 and 3 do not.
"""

from __future__ import annotations

from functools import cache

import casadi as ca
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from gagen.algebra.multivector import SparseMultivector
from gagen.algebra.signature import cga3d
from gagen.apps.cooperative.catalogue import kernel_functions
from gagen.apps.cooperative.closed_form import closed_form_jacobian, similarity_closed_form
from gagen.interp import MultiVector
from gagen.model import closed_form_jacobians as C
from gagen.model.conformal import SIMILARITY, point, vector
from gagen.model.primitives import through, unit_normal, unit_primitive
from gagen.model.similarity import cooperative_similarity, similarity_factors
from gagen.robots.spec import load_system
from gagen.symbolic.casadi_backend import CasadiBackend

ALG = cga3d()
ZERO = MultiVector.zero(ALG)
TOLERANCE = 1e-12  # of max |J_A|
SYSTEMS = ("three_pandas_circle", "three_iiwas_circle")


def _matrix(columns) -> np.ndarray:
    return np.array([[c[b] for b in SIMILARITY] for c in columns]).T


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@cache
def _system(name: str):
    """(system, AD J_A Function, the closed-form KernelFunction, its traced Kernel)."""
    system, _ = load_system(f"robots/{name}.yaml")
    closed = similarity_closed_form(system)
    return system, kernel_functions(system)["similarity_jacobians"].trace().function, closed, closed.trace()


@pytest.mark.parametrize("name", SYSTEMS)
def test_closed_form_equals_the_ad_jacobian_of_the_system_kernel(name):
    system, ad, _, traced = _system(name)
    rng = np.random.default_rng(7)
    worst = 0.0
    for q in rng.uniform(-2.0, 2.0, (6, system.dof)):
        reference = np.array(ad(q)[0])
        interpreted = _matrix(closed_form_jacobian(ZERO, system, [float(v) for v in q]).J_A)
        compiled = np.array(traced.function(q))
        worst = max(worst, _relative(interpreted, reference), _relative(compiled, reference))
    assert worst < TOLERANCE


def test_the_kernel_reference_is_the_interpreter_and_other_kinds_are_refused():
    system, _, closed, traced = _system("three_pandas_circle")
    q = np.linspace(-1.0, 1.0, system.dof)
    reference = closed.reference(q, ports=(traced.inputs, traced.outputs))[0]
    np.testing.assert_allclose(np.array(traced.function(q)), reference, rtol=0,
                               atol=1e-14 * np.max(np.abs(reference)))
    point_system, _ = load_system("robots/panda_point.yaml")
    with pytest.raises(ValueError, match=r"primitive: .* circle system, got 'point'"):
        similarity_closed_form(point_system)


# -- point triples ------------------------------------------------------------------------------------------
def _circle(xyz: np.ndarray, like=ZERO):
    return through("circle", [point(vector(like, list(p))) for p in xyz.reshape(3, 3)])


def _point_columns(xyz: np.ndarray, like=ZERO) -> list:
    """∂X_c/∂x for the 9 coordinates: P_1 ∧ … ∧ (e_k + x_k e∞) ∧ … (dP/dx_k = e_k + x_k e∞)."""
    points = [point(vector(like, list(p))) for p in xyz.reshape(3, 3)]
    columns = []
    for i in range(3):
        for k in range(3):
            factors = list(points)
            factors[i] = like.make({f"e{k + 1}": 1, "einf": xyz.reshape(3, 3)[i, k]})
            columns.append(factors[0] ^ factors[1] ^ factors[2])
    return columns


@cache
def _ad_of_points() -> ca.Function:
    """CasADi AD of gagen's V_Sc(X_u, X_c) with X_c through three symbolic points (no factor rule)."""
    backend = CasadiBackend()
    x = ca.SX.sym("x", 9)
    zero = SparseMultivector(ALG, backend, {})
    xc = through("circle", [point(vector(zero, [backend.lift(x[3 * i + k]) for k in range(3)]))
                            for i in range(3)])
    v = cooperative_similarity("circle", xc).versor
    column = ca.vertcat(*[backend.native(v[b]) for b in SIMILARITY])
    return ca.Function("v", [x], [column, ca.jacobian(column, x)])


coordinates = st.lists(st.floats(-2.0, 2.0), min_size=9, max_size=9).map(np.array)


def _well_conditioned(xyz: np.ndarray) -> bool:
    p = xyz.reshape(3, 3)
    area = np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]))
    sides = max(np.linalg.norm(p[i] - p[j]) for i, j in ((0, 1), (1, 2), (0, 2)))
    result = C.circle_similarity_jacobian(_circle(xyz), [])
    return area > 0.05 * sides * sides and float(result.conditioning) > 1e-6 * sides ** 4


@settings(max_examples=25, deadline=None)
@given(coordinates)
def test_closed_form_equals_ad_for_random_point_triples(xyz):
    assume(_well_conditioned(xyz))
    value, jacobian = _ad_of_points()(xyz)
    result = C.circle_similarity_jacobian(_circle(xyz), _point_columns(xyz))
    np.testing.assert_allclose(_matrix([result.versor]).ravel(), np.array(value).ravel(), rtol=0, atol=1e-14)
    assert _relative(_matrix(result.J_A), np.array(jacobian)) < TOLERANCE


def _stencil(f, xyz: np.ndarray, h: float = 2e-4) -> np.ndarray:
    """4th-order central differences of f (→ coefficient array) in each of the 9 coordinates."""
    columns = []
    for c in range(9):
        e = np.zeros(9)
        e[c] = h
        columns.append((-f(xyz + 2 * e) + 8 * f(xyz + e) - 8 * f(xyz - e) + f(xyz - 2 * e)) / (12 * h))
    return np.array(columns).T


@settings(max_examples=15, deadline=None)
@given(coordinates)
def test_each_factor_jacobian_equals_differences_of_gagens_factor(xyz):
    assume(_well_conditioned(xyz))
    result = C.circle_similarity_jacobian(_circle(xyz), _point_columns(xyz))

    def factor(k):
        def value(x):
            xc = _circle(x)
            return similarity_factors("circle", unit_primitive("circle", xc), xc).factors[k].coeffs
        return value

    gagen = similarity_factors("circle", unit_primitive("circle", _circle(xyz)), _circle(xyz)).factors
    for k, ours in enumerate((result.translator, result.rotor, result.dilator)):
        np.testing.assert_allclose(ours.value.coeffs, gagen[k].coeffs, rtol=0, atol=1e-15)
        mine = np.array([c.coeffs for c in ours.jacobian]).T
        assert _relative(mine, _stencil(factor(k), xyz)) < 1e-9, ("T", "R", "D")[k]


def test_the_unit_circle_the_factors_start_from():
    """The closed forms assume X_u's normal e3, centre e0 and radius 1 (``unit_primitive``)."""
    xu = unit_primitive("circle", ZERO)
    assert np.allclose(unit_normal(xu).coeffs, ZERO.make({C.UNIT_NORMAL: 1}).coeffs, rtol=0, atol=0)
    result = C.circle_similarity_jacobian(xu, [])
    assert np.array_equal(result.versor.coeffs, ZERO.make({"1": 1}).coeffs)


def test_degenerate_points_give_a_zero_jacobian_and_zero_conditioning():
    xyz = np.array([0.0, 0, 0, 1, 1, 1, 2, 2, 2])  # collinear
    result = C.circle_similarity_jacobian(_circle(xyz), _point_columns(xyz))
    assert float(result.conditioning) == 0.0 and bool(result.degenerate)
    assert np.array_equal(_matrix(result.J_A), np.zeros((12, 9)))


# -- Eq. 79, 81 ---------------------------------------------------------------------------------------------
def _error(a: np.ndarray, b: np.ndarray) -> float:
    """max |a − b| relative to max |b|, or absolute where that is below 1 (a derivative that vanishes)."""
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1.0))


def _path(t: float, xyz: np.ndarray, direction: np.ndarray):
    return _circle(xyz + t * direction)


@settings(max_examples=25, deadline=None)
@given(coordinates, coordinates)
def test_normalisation_and_inverse_derivatives_equal_differences(xyz, direction):
    """Eq. 79 and 81 along a path of circles (X X~ < 0) and of the rotors 1 + n e3 (X X~ > 0)."""
    assume(_well_conditioned(xyz))
    x = _path(0.0, xyz, direction)
    dx = sum((c * d for c, d in zip(_point_columns(xyz), direction, strict=True)), ZERO)
    h = 1e-4

    def differences(f):
        return (-f(2 * h) + 8 * f(h) - 8 * f(-h) + f(-2 * h)) / (12 * h)

    for fn, exact in ((lambda y: y.normalized(), C.normalization_derivative),
                      (lambda y: y.inverse(), C.inverse_derivative)):
        expected = differences(lambda t, fn=fn: fn(_path(t, xyz, direction)).coeffs)
        assert _error(exact(x, dx).coeffs, expected) < 1e-9
    e3 = ZERO.make({"e3": 1})

    def rotor(t):
        return 1 + unit_normal(_path(t, xyz, direction)) * e3

    drotor = differences(lambda t: rotor(t).coeffs)
    expected = differences(lambda t: rotor(t).normalized().coeffs)
    assert _error(C.normalization_derivative(rotor(0.0), MultiVector(ALG, drotor)).coeffs, expected) < 1e-9


def test_the_printed_forms_of_errata_1_and_3_disagree():
    """Eq. 79 without sign(X X~) is wrong for a circle (X X~ < 0); Eq. 82 without e0∞ is wrong."""
    xyz = np.array([1.0, 0.2, 0.1, -0.3, 1.1, 0.4, -0.9, -0.5, 0.7])
    x, dx = _circle(xyz), _point_columns(xyz)[0]
    s = x.norm_squared()
    assert s < 0
    printed = dx * abs(s) ** -0.5 - x * (0.5 * abs(s) ** -1.5 * 2 * dx.sp(~x))
    assert _relative(printed.coeffs, C.normalization_derivative(x, dx).coeffs) > 0.1
    result = C.circle_similarity_jacobian(x, [dx])
    d, jd = result.dilator.value, result.dilator.jacobian[0]
    unprinted = jd * ZERO.make({"e0inf": 1})  # e0∞ J_D = (½ d ln r) V_D: the printed form
    assert _relative(jd.coeffs, unprinted.coeffs) > 0.1
    assert np.allclose((ZERO.make({"e0inf": 1}) * unprinted).coeffs, jd.coeffs, rtol=1e-14, atol=1e-16)
    assert abs(unprinted["e0inf"] / unprinted.scalar() - d["e0inf"] / d.scalar()) < 1e-12  # ∝ V_D
