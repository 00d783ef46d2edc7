"""Conformal embedding of 3D Euclidean space in CGA (cga3d): basis helpers and points [COOP Eq. 1].

Blade groups used across the model, in gagen's (gafro's) bitmask order.
"""

from __future__ import annotations

from collections.abc import Sequence

from gagen.algebra.protocol import Multivector
from gagen.algebra.scalars import Scalar
from gagen.model.guarded import safe_reciprocal

EUCLID = ("e1", "e2", "e3")
POINT = ("e0", "e1", "e2", "e3", "einf")
ROTATION = ("e12", "e13", "e23")  # B_R = θ (n3 e12 − n2 e13 + n1 e23) for angle θ about unit n
DILATION = ("e0inf",)
TRANSLATION = ("e1inf", "e2inf", "e3inf")
MOTOR = ("1", "e12", "e13", "e23", "e1inf", "e2inf", "e3inf", "e123inf")
MOTOR_GENERATOR = ROTATION + TRANSLATION
SIMILARITY_GENERATOR = ROTATION + DILATION + TRANSLATION
SIMILARITY = ("1", "e12", "e13", "e23", "e0inf", "e1inf", "e2inf", "e012inf", "e3inf", "e013inf",
              "e023inf", "e123inf")


def part(x: Multivector, blades: Sequence[str]) -> Multivector:
    """The multivector made of x's coefficients on ``blades`` only."""
    return x.make({b: x[b] for b in blades})


def e0(like: Multivector) -> Multivector:
    return like.make({"e0": 1})


def einf(like: Multivector) -> Multivector:
    return like.make({"einf": 1})


def vector(like: Multivector, xyz: Sequence[Scalar]) -> Multivector:
    """Euclidean vector x1 e1 + x2 e2 + x3 e3."""
    return like.make(dict(zip(EUCLID, xyz, strict=True)))


def point(x: Multivector) -> Multivector:
    """P(x) = e0 + x + ½|x|² e∞ for a Euclidean vector x (a multivector on e1, e2, e3)."""
    p: Multivector = e0(x) + x + einf(x) * (0.5 * x.sp(x))  # typed: a product with a Scalar (Any) is Any
    return p


def point_weight(p: Multivector) -> Scalar:
    """−P·e∞: 1 for a normalised point, the scale of a scaled one."""
    return -p.sp(einf(p))


def location(p: Multivector) -> Multivector:
    """Euclidean vector of a (possibly scaled) point: its e1, e2, e3 part divided by −P·e∞
    (guarded: a zero weight, from a degenerate construction, gives a finite result)."""
    v: Multivector = part(p, EUCLID) * safe_reciprocal(p.math, point_weight(p))
    return v


def normalized_point(p: Multivector) -> Multivector:
    """The point scaled so that −P·e∞ = 1 (guarded like ``location``)."""
    normalized: Multivector = p * safe_reciprocal(p.math, point_weight(p))
    return normalized


def unit(v: Multivector) -> Multivector:
    """v / |v| for a Euclidean vector; a zero vector (degenerate input) stays zero, finite."""
    m = v.math
    u: Multivector = v * safe_reciprocal(m, m.sqrt(v.sp(v)))
    return u


def norm2(x: Multivector) -> Scalar:
    """Σ of squared coefficients (the Euclidean 2-norm² of the coefficient array) [COOP Eq. 9]."""
    return sum((x[m] * x[m] for m in range(x.algebra.size)), start=0)
