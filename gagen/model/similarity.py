"""Similarity transformation between two primitives of the same kind [COOP Section 3.3].

``similarity(kind, x1, x2)`` returns V = V_T V_R V_D with x2 = V x1 V~ up to a positive scale,
and a **conditioning** figure: 0 exactly at the degenerate configurations, positive otherwise.
Nothing divides by zero on the way (guarded), so degenerate inputs give finite values and a
conditioning that says they are meaningless; they are never a silent NaN.

Conditioning per kind (each is a continuous function of the inputs):
- point: 1.
- point pair, circle, sphere: the smaller of the two radius denominators ⟨(e∞⌋X)(e∞⌋X)~⟩₀,
  proportional to |x2 − x1|² (pair), the squared triangle area (circle) or the squared
  tetrahedron volume (sphere) of the spanning points, so zero for coincident, collinear or
  coplanar points; for pairs and circles multiplied by the rotor's (1 + a·b)/2, zero when the
  two are oppositely oriented (then the rotor is a guarded half turn).
- line, plane: K0/4 of Eq. 21 (1 for equal flats, 0 for opposite orientation) times the smaller
  |X²| of the two (zero for coincident points).

Near a degeneracy every output stays finite (``tests/cooperative/test_degenerate_sweep.py`` sweeps each
kind to ε = 1e-15 and exactly degenerate), but the derivatives are the geometry's: |J_G| grows like 1/ε
towards coincident, collinear, coplanar or concyclic points (≈ 10-800/ε on 1-3 m configurations:
1e9-1e11 at ε = 1e-9), like 1/ε² towards antiparallel flats (≈ 6-8/ε² until the half-turn switch),
and is not clamped, since any clamp would change meaningful results. Precision runs out first for the
point pair: its r² numerator −⟨XX~⟩ cancels to a relative error ≈ 1e-16·|x|⁵/ε³, i.e. all digits at
ε ≈ 1e-5 m for |x| ≈ 1 m, so below that the dilation (and its row of J_G, up to ~1e27 at ε = 1e-14)
is rounding noise; the bounded dilator (``_dilator_between``) keeps it finite.
"""

from __future__ import annotations

from typing import Any, NamedTuple

from gagen.algebra.protocol import Multivector
from gagen.algebra.scalars import Scalar
from gagen.model.conformal import SIMILARITY, location
from gagen.model.guarded import safe_reciprocal
from gagen.model.primitives import (
    carrier_plane,
    centre,
    check_kind,
    direction,
    radius_squared_parts,
    unit_normal,
    unit_primitive,
)
from gagen.model.versors import (
    Versor,
    rotor_between,
    translator,
    versor_between,
)

SIGMA = {"line": 1, "plane": -1}  # X² sign of P∧P∧e∞ and P∧P∧P∧e∞
DEGENERATE_BELOW = 1e-30  # conditioning below this: the versor is replaced by the identity


class Factored(NamedTuple):
    """V = factors[0] factors[1] … (V_T V_R V_D for rounds, one motor for flats), its conditioning,
    and whether the spanning points are degenerate (a native boolean, or a bool when known)."""

    factors: tuple[Any, ...]
    conditioning: Scalar
    degenerate: Any

    def versor(self) -> Any:
        """The product of the factors, or the identity where the spanning points are degenerate."""
        v = self.factors[0]
        for f in self.factors[1:]:
            v = v * f
        m = v.math
        return v.make({k: m.if_else(self.degenerate, 1.0 if k == "1" else 0.0, v[k]) for k in SIMILARITY})


def similarity(kind: str, x1: Multivector, x2: Multivector) -> Versor:
    """V_S(X1, X2) and its conditioning (see the module docstring).

    When the spanning points are degenerate to below ``DEGENERATE_BELOW`` (the size part of the
    conditioning, not the orientation part) the versor is the identity: an exactly degenerate
    input then gives finite values on every path (guarded intermediate values can overflow there).
    """
    factored = similarity_factors(kind, x1, x2)
    return Versor(factored.versor(), factored.conditioning)


def similarity_factors(kind: str, x1: Multivector, x2: Multivector) -> Factored:
    """The factors of V_S(X1, X2), its conditioning and the degeneracy test (see ``similarity``).

    The factors let a Jacobian use the product rule at the group level (``gagen.apps.cooperative.catalogue``):
    each factor depends on few of the inputs' degrees of freedom (T on the centre, R on the axis,
    D on the radius), so its own derivative is cheap."""
    factors, conditioning, size = _similarity(check_kind(kind), x1, x2)
    m = x1.math
    return Factored(factors, conditioning, m.lt(m.fabs(size), DEGENERATE_BELOW))


def _similarity(kind: str, x1: Multivector, x2: Multivector) -> tuple[tuple[Any, ...], Scalar, Scalar]:
    """(factors, conditioning, size): size is the part of the conditioning that measures how
    degenerate the spanning points are, without the orientation factor."""
    m = x1.math
    if kind == "point":
        return (translator(location(x2) - location(x1)),), 1, 1
    if kind in SIGMA:
        v, k = versor_between(x1, x2, SIGMA[kind])
        size = m.fabs(x1.sp(x1))
        size2 = m.fabs(x2.sp(x2))
        smaller = m.if_else(m.lt(size, size2), size, size2)
        return (v,), k * smaller, smaller
    num1, den1 = radius_squared_parts(x1)
    num2, den2 = radius_squared_parts(x2)
    size = m.if_else(m.lt(den1, den2), den1, den2)
    conditioning = size
    d = _dilator_between(x1, num1 * safe_reciprocal(m, den1), num2 * safe_reciprocal(m, den2))
    if kind == "sphere":
        turn: tuple[Any, ...] = ()
        rd = d
    else:
        axis = direction(carrier_plane(x1)) if kind == "point_pair" else unit_normal(x1)
        axis2 = direction(carrier_plane(x2)) if kind == "point_pair" else unit_normal(x2)
        r, health = rotor_between(axis, axis2)
        turn, rd = (r,), r * d
        conditioning = conditioning * health
    # the centre is covariant: centre(RD X1 (RD)~) = RD centre(X1) (RD)~, which for the unit
    # primitives is the origin exactly (no AD through the moved round's centre)
    t = translator(location(centre(x2)) - location(rd.sandwich(centre(x1))))
    return (t, *turn, d), conditioning, size


RATIO_BOUND = 1e-24  # squared-radius ratios are squashed into (1e-24, 1e24): the dilator's k into (1e-6, 1e6)


def _dilator_between(like: Multivector, r1_squared: Scalar, r2_squared: Scalar) -> Multivector:
    """The dilator taking radius r1 to r2, from the squared radii, with no logarithm:
    D = ½(k + 1/k) − ½(k − 1/k) e0∞ with k⁴ = r1²/r2², squashed as k⁴ = (N + εN')/(N' + εN),
    N = |r1²|, N' = |r2²|, ε = RATIO_BOUND.

    For 1e-8 < N/N' < 1e8 the ε terms vanish in rounding and k⁴ = N·(1/N') to the last bit (as
    before this guard); beyond, k⁴ is bounded smoothly by 1/ε, so k stays within 1e±6 (a radius
    ratio of 1e±12) and log V_D = 2 atanh((k² − 1)/(k² + 1)) stays finite (it overflowed past
    k ≈ 1e8). Why no 1/r2²: near coincident points r2² cancels to ~0 (or a rounding-sign negative,
    hence |…|); its guarded reciprocal was finite, but its AD derivative −1/r2⁴ overflowed and
    put inf·0 = NaN into J_G. Here the denominator stays ≥ ε·N."""
    m = like.math
    n, n2 = m.fabs(r1_squared), m.fabs(r2_squared)
    k = m.sqrt(m.sqrt((n + n2 * RATIO_BOUND) * safe_reciprocal(m, n2 + n * RATIO_BOUND)))
    inv = 1 / k
    return like.make({"1": (k + inv) * 0.5, "e0inf": (inv - k) * 0.5})


def cooperative_similarity(kind: str, xc: Multivector) -> Versor:
    """V_Sc = V_S(X_u, X_c) [COOP Eq. 28]: the similarity taking the unit primitive to X_c."""
    return similarity(kind, unit_primitive(kind, xc), xc)
