"""Closed-form Jacobians of the circle similarity V_Sc = V_T V_R V_D [COOP Appendix B, Eq. 78-91].

Given the cooperative circle X_c and its Jacobian columns J_c = ∂X_c/∂q_j (one multivector per
joint), ``circle_similarity_jacobian`` returns J_A,Sc = ∂V_Sc/∂q by the product rule [Eq. 29]

    J_A = J_T V_R V_D + V_T J_R V_D + V_T V_R J_D,

each factor's Jacobian in closed form: no automatic differentiation anywhere, so it cross-checks
the AD Jacobians of ``gagen.apps.cooperative.catalogue``. Written against the multivector
protocol, it runs on the interpreter (numbers) and on the compiler's symbolic multivectors.

The factors are gagen's (``gagen.model.similarity``), rebuilt here from the same intermediate
values: V_T = T(c) with c the centre of X_c; V_R = R̃/|R̃|, R̃ = 1 + n̄ e3, the rotor turning the unit
circle's normal e3 onto the unit normal n̄ of X_c; V_D = ½(k + 1/k) + ½(1/k − k) e0∞ with
k⁴ = r_u²/r² (r_u = 1), which scales by r.

Deviations from the paper's text (errata found while deriving gagen's closed forms; the paper is
read from a PDF text extraction, so the "as printed" forms are those of the extraction):

1. Eq. 79 (and its uses Eq. 85, 87) differentiates |X X~| as if X X~ > 0. For X X~ < 0 (a circle)
   it needs sign(X X~); the sign-free form used here is
   ∂X̄ = |X X~|^{-1/2} (J − ½ (X X~)⁻¹ ⟨J X~ + X J~⟩₀ X).
2. Eq. 24: with P = (e∞⌋X) X⁻¹ (Eq. 83), P P~ = −1/r², so ‖P‖ = 1/r, not r. Eq. 82's leading
   −¼ is consistent with this (−¼ d ln(P P~) = ½ d ln r).
3. Eq. 82 lacks the factor e0∞: dV_D = ½ d(ln r) e0∞ V_D, i.e.
   J_D = −¼ (P P~)⁻¹ ⟨J_1 P~ + P J_1~⟩₀ e0∞ V_D. As printed, J_D ∝ V_D would be the derivative of
   a scale, not of a dilator.
4. Eq. 84 is not the product rule of Eq. 83: its second term (e∞·X) ∧ J_c must be
   (e∞⌋X) ∂(X⁻¹), with ∂(X⁻¹) from Eq. 81: J_1 = (e∞⌋J_c) X⁻¹ + (e∞⌋X) ∂(X⁻¹).
5. Eq. 25 and 88: the normal of the plane E (E* = n + δe∞) is E* + (E*·e0) e∞ (e0·e∞ = −1);
   the text reads −½(E*·e0) e∞, which leaves 3δ/2 e∞ in N, hence e3∞ terms in "V_R". gagen
   orients n like (x2 − x1) × (x3 − x1), which with its dual X I⁻¹ is −(E* + (E*·e0) e∞).
6. Eq. 26: 1 + N1 N2 turns N2 onto N1; the rotor taking X_u (normal e3) to X_c (normal n̄) with
   X_c = V X_u V~ is 1 + N2 N1 = 1 + n̄ e3 (the second line of Eq. 26 and Eq. 86's
   e3·J̄_N − e3∧J̄_N = J̄_N e3 agree with this order).
7. Eq. 90: the centre c = P_c/α with α = −e∞·P_c (the text writes ⟨P_c⟩₀, which for a vector is 0:
   read as its e0 weight); then J_T = −½ α⁻¹ (J_P − α⁻¹ (−e∞·J_P) P_c) ∧ e∞: the wedge with e∞
   applies to both terms and the second carries α⁻² overall.
8. gagen's dilator bounds k⁴ smoothly into (1e-24, 1e24) (``similarity._dilator_between``); inside
   that range (radius ratios 1e±12) the bound changes k by < 1e-24 relative, which this closed
   form neglects.

Degenerate inputs: every division is guarded (finite results); where the spanning points are
degenerate (``similarity.DEGENERATE_BELOW``) V_Sc is the identity and J_A is zero, like the AD
kernels; the conditioning (as ``similarity``'s: the smaller radius denominator times
(1 + n̄·e3)/2) says when the values mean nothing (it is 0 for collinear points or a half turn).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

from gagen.algebra.protocol import Multivector
from gagen.algebra.scalars import Scalar
from gagen.model.conformal import EUCLID, SIMILARITY, e0, einf, part, point_weight
from gagen.model.guarded import safe_reciprocal
from gagen.model.primitives import carrier_plane, radius_squared_parts, unit_primitive
from gagen.model.similarity import DEGENERATE_BELOW, RATIO_BOUND
from gagen.model.versors import translator

UNIT_NORMAL = "e3"  # the normal of the unit circle X_u (``primitives.unit_primitive``)


# -- B.1, B.2: normalisation and inverse ----------------------------------------------------------------
def normalization_derivative(x: Multivector, jx: Multivector) -> Multivector:
    """∂X̄ for X̄ = X |X X~|^{-1/2} along J = ∂X [Eq. 78-79], for either sign of X X~ (erratum 1):
    |X X~|^{-1/2} (J − ½ (X X~)⁻¹ ⟨J X~ + X J~⟩₀ X)."""
    m = x.math
    s = x.norm_squared()
    ds = 2 * jx.sp(~x)  # ⟨J X~ + X J~⟩₀ = 2⟨J X~⟩₀
    # (shared: one reciprocal node, not one division per coefficient)
    along = m.shared(0.5 * ds * m.shared(safe_reciprocal(m, s)))
    derivative: Multivector = (jx - x * along) * m.shared(safe_reciprocal(m, m.sqrt(m.fabs(s))))
    return derivative


def inverse_derivative(x: Multivector, jx: Multivector) -> Multivector:
    """∂(X⁻¹) for X⁻¹ = X~ (X X~)⁻¹ along J = ∂X [Eq. 80-81]: (X X~)⁻¹ J~ − 2 (X X~)⁻² X~ ⟨X J~⟩₀."""
    m = x.math
    inv = m.shared(safe_reciprocal(m, x.norm_squared()))
    derivative: Multivector = ~jx * inv - ~x * m.shared(2 * x.sp(~jx) * inv * inv)
    return derivative


# -- B.3: the three factors --------------------------------------------------------------------------------
class Factor(NamedTuple):
    """A factor of V_Sc and its Jacobian columns."""

    value: Any
    jacobian: list[Any]


def infinity_projection(x: Multivector) -> Multivector:
    """P = (e∞⌋X) X⁻¹, infinity projected onto the round X [Eq. 83]; P P~ = −1/r² (erratum 2)."""
    projected: Multivector = (einf(x).lc(x) * _inverse(x)).grade(1)  # a vector projected is a vector
    return projected


def _inverse(x: Multivector) -> Multivector:
    """X⁻¹ = X~ (X X~)⁻¹ [Eq. 80], guarded (finite for a degenerate X)."""
    inverse: Multivector = ~x * x.math.shared(safe_reciprocal(x.math, x.norm_squared()))
    return inverse


def dilator_factor(x: Multivector, jc: Sequence[Multivector]) -> Factor:
    """V_D (scaling by the radius r of X) and J_D = −¼ (P P~)⁻¹ ⟨J_1 P~ + P J_1~⟩₀ e0∞ V_D
    [Eq. 82-84, errata 3-4], with J_1 = (e∞⌋J) X⁻¹ + (e∞⌋X) ∂(X⁻¹)."""
    m = x.math
    num_u, den_u = radius_squared_parts(unit_primitive("circle", x))
    num, den = radius_squared_parts(x)
    # k⁴ = r_u²/r², bounded like gagen's dilator (erratum 8): finite for coincident points
    n_u, n = m.fabs(num_u * safe_reciprocal(m, den_u)), m.fabs(num * safe_reciprocal(m, den))
    k = m.sqrt(m.sqrt((n_u + n * RATIO_BOUND) * safe_reciprocal(m, n + n_u * RATIO_BOUND)))
    inv = 1 / k
    d = x.make({"1": (k + inv) * 0.5, "e0inf": (inv - k) * 0.5})
    p = infinity_projection(x)
    contracted, x_inv = einf(x).lc(x), _inverse(x)
    scale = m.shared(-0.25 * safe_reciprocal(m, p.norm_squared()))
    moved = x.make({"e0inf": 1}) * d  # e0∞ V_D
    columns = []
    for j in jc:
        j1 = (einf(j).lc(j) * x_inv + contracted * inverse_derivative(x, j)).grade(1)
        columns.append(moved * m.shared(scale * 2 * j1.sp(~p)))  # ⟨J_1 P~ + P J_1~⟩₀ = 2⟨J_1 P~⟩₀
    return Factor(d, columns)


def plane_normal(plane: Multivector) -> Multivector:
    """The (unnormalised) normal of a plane E = X ∧ e∞, oriented as gagen's ``unit_normal``:
    −(E* + (E*·e0) e∞) [Eq. 25, erratum 5]; linear in E, so also the Jacobian J_N of Eq. 88."""
    dual = plane.dual()
    normal = dual + einf(plane) * (e0(plane) | dual).scalar()
    return -part(normal, EUCLID)


def rotor_factor(x: Multivector, jc: Sequence[Multivector]) -> tuple[Factor, Scalar]:
    """V_R = R̃ |R̃ R̃~|^{-1/2} with R̃ = 1 + n̄ e3 (erratum 6) and its Jacobian by Eq. 85-89:
    J_R̃ = J̄_N e3 (Eq. 86), J̄_N the normalised normal's derivative (Eq. 87-89). Also the rotor's
    conditioning (1 + n̄·e3)/2 (0 for the half turn, where gagen switches to a guarded rotor)."""
    m = x.math
    e3 = x.make({UNIT_NORMAL: 1})
    normal = plane_normal(carrier_plane(x))
    unit = normal * m.shared(safe_reciprocal(m, m.sqrt(normal.norm_squared())))
    raw = 1 + unit * e3
    r = raw * m.shared(safe_reciprocal(m, m.sqrt(m.fabs(raw.norm_squared()))))
    columns = []
    for j in jc:
        j_unit = normalization_derivative(normal, plane_normal(carrier_plane(j)))  # Eq. 87-89
        columns.append(normalization_derivative(raw, j_unit * e3))  # Eq. 85-86
    return Factor(r, columns), (1 + unit.sp(e3)) * 0.5


def translator_factor(x: Multivector, jc: Sequence[Multivector]) -> Factor:
    """V_T = T(c), c the centre of X (P_c = X e∞ X, Eq. 27, normalised), and
    J_T = −½ α⁻¹ (J_P − α⁻¹ (−e∞·J_P) P_c) ∧ e∞ with J_P = J e∞ X + X e∞ J and α = −e∞·P_c
    [Eq. 90-91, erratum 7]. (The unit circle's centre is the origin, which V_R V_D keep.)"""
    m = x.math
    inf = einf(x)
    pc = (x * inf * x).grade(1)
    inv_alpha = m.shared(safe_reciprocal(m, point_weight(pc)))
    t = translator(part(pc, EUCLID) * inv_alpha)
    columns = []
    for j in jc:
        jp = (j * inf * x + x * inf * j).grade(1)
        weight = m.shared(point_weight(jp) * inv_alpha * inv_alpha)
        dc = part(jp, EUCLID) * inv_alpha - part(pc, EUCLID) * weight
        columns.append((dc ^ inf) * -0.5)
    return Factor(t, columns)


# -- Eq. 29 ---------------------------------------------------------------------------------------------
class CircleSimilarityJacobian(NamedTuple):
    """J_A,Sc = ∂V_Sc/∂q (one similarity multivector per joint), its three factors with their own
    Jacobians, V_Sc, the conditioning and the degeneracy flag (see the module docstring)."""

    J_A: list[Any]
    translator: Factor
    rotor: Factor
    dilator: Factor
    versor: Any
    conditioning: Scalar
    degenerate: Any


def circle_similarity_jacobian(xc: Multivector, jc: Sequence[Multivector]) -> CircleSimilarityJacobian:
    """The analytic circle similarity Jacobian from X_c and J_c [COOP Eq. 29, 78-91]."""
    m = xc.math
    t = translator_factor(xc, jc)
    r, health = rotor_factor(xc, jc)
    d = dilator_factor(xc, jc)
    rd = r.value * d.value
    tr = t.value * r.value
    _, den_u = radius_squared_parts(unit_primitive("circle", xc))
    _, den = radius_squared_parts(xc)
    size = m.if_else(m.lt(den_u, den), den_u, den)
    degenerate = m.lt(m.fabs(size), DEGENERATE_BELOW)
    versor = tr * d.value
    identity = versor.make({b: m.if_else(degenerate, 1.0 if b == "1" else 0.0, versor[b])
                            for b in SIMILARITY})
    columns = []
    for jt, jr, jd in zip(t.jacobian, r.jacobian, d.jacobian, strict=True):
        column = jt * rd + t.value * jr * d.value + tr * jd
        columns.append(column.make({b: m.if_else(degenerate, 0.0, column[b]) for b in SIMILARITY}))
    return CircleSimilarityJacobian(columns, t, r, d, identity, size * health, degenerate)
