"""Geometric primitives of CGA (OPNS) and their queries [COOP Eq. 2-5, 24-27; SMC II.A].

Constructors take conformal points. Queries work on any scale of the primitive unless stated.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import reduce

from gagen.algebra.protocol import Multivector
from gagen.algebra.scalars import Scalar
from gagen.model.conformal import EUCLID, einf, norm2, normalized_point, part, point, unit, vector

KINDS = ("point", "point_pair", "line", "circle", "plane", "sphere")
ROUNDS = ("point_pair", "circle", "sphere")
FLATS = ("line", "plane")

# points each kind is spanned by, and whether e∞ closes the outer product
_SPAN = {"point": (1, False), "point_pair": (2, False), "line": (2, True), "circle": (3, False),
         "plane": (3, True), "sphere": (4, False)}


def points_needed(kind: str) -> int:
    """How many points span a primitive of this kind."""
    return _SPAN[check_kind(kind)][0]


def through(kind: str, points: Sequence[Multivector]) -> Multivector:
    """The primitive of ``kind`` through the given conformal points (Table 1)."""
    count, closed = _SPAN[check_kind(kind)]
    if len(points) != count:
        raise ValueError(f"a {kind} is spanned by {count} points, got {len(points)}")
    x = reduce(lambda a, b: a ^ b, points)
    return x ^ einf(x) if closed else x


def check_kind(kind: str) -> str:
    """The kind, if gagen knows it; a ValueError naming the known kinds otherwise."""
    if kind not in _SPAN:
        raise ValueError(f"unknown primitive kind {kind!r}; expected one of {', '.join(KINDS)}")
    return kind


# unit primitives at the origin [COOP Eq. 28, 40]: the points they are spanned by
_UNIT_POINTS: dict[str, tuple[tuple[int, int, int], ...]] = {
    "point": ((0, 0, 0),),
    "point_pair": ((-1, 0, 0), (1, 0, 0)),
    "line": ((0, 0, 0), (1, 0, 0)),
    "circle": ((1, 0, 0), (0, 1, 0), (-1, 0, 0)),
    "plane": ((0, 0, 0), (1, 0, 0), (0, 1, 0)),
    "sphere": ((1, 0, 0), (0, 1, 0), (-1, 0, 0), (0, 0, 1)),
}


def unit_primitive(kind: str, like: Multivector) -> Multivector:
    """X_u: point e0; point pair P(−e1)∧P(e1); line through 0 along e1; unit circle in the e1e2
    plane (normal +e3); plane z = 0 (normal +e3); unit sphere at the origin. Exact constants."""
    return through(kind, [point(vector(like, xyz)) for xyz in _UNIT_POINTS[check_kind(kind)]])


# -- queries ------------------------------------------------------------------------------------------
def centre(x: Multivector) -> Multivector:
    """Centre of a round, normalised: X e∞ X (infinity reflected in X) [COOP Eq. 27]."""
    return normalized_point((x * einf(x) * x).grade(1))


def radius_squared_parts(x: Multivector) -> tuple[Scalar, Scalar]:
    """(numerator, denominator) of r² = −⟨X X~⟩₀ / ⟨(e∞⌋X)(e∞⌋X)~⟩₀ for a round (OPNS).

    The denominator vanishes exactly for degenerate rounds (coincident, collinear or coplanar
    points), which makes it the conditioning figure of everything built on the radius.
    """
    n = einf(x).lc(x)
    return -x.norm_squared(), n.norm_squared()


def radius_squared(x: Multivector) -> Scalar:
    num, den = radius_squared_parts(x)
    return num / den


def radius(x: Multivector) -> Scalar:
    return x.math.sqrt(radius_squared(x))


def carrier_plane(x: Multivector) -> Multivector:
    """Plane of a circle (or line of a point pair): X ∧ e∞."""
    return x ^ einf(x)


def unit_normal(circle: Multivector) -> Multivector:
    """Unit normal of a circle's carrier plane: the Euclidean part of (X ∧ e∞)* [COOP Eq. 25],
    oriented like (x2 − x1) × (x3 − x1) for the circle P1 ∧ P2 ∧ P3."""
    return -unit(part(carrier_plane(circle).dual(), EUCLID))


def direction(line: Multivector) -> Multivector:
    """Unit direction of a line P1∧P2∧e∞, along x2 − x1: its e0∧d∧e∞ part. For a point pair,
    pass its carrier line ``carrier_plane(pp)``."""
    return unit(vector(line, [line[f"e0{k}inf"] for k in "123"]))


def project_point(p: Multivector, x: Multivector) -> Multivector:
    """Projection of a point onto a primitive: (P·X) X⁻¹ [COOP Eq. 4] (a scaled point for flats)."""
    return (p | x) * x.inverse()


def split_point_pair(pp: Multivector) -> tuple[Scalar, Scalar]:
    """The two normalised points of a real point pair: (PP ∓ √(PP·PP)) / (−e∞·PP) [SMC Eq. 7]."""
    root = pp.math.sqrt(pp.sp(pp))
    v = -(einf(pp).lc(pp))
    inv = v.inverse()
    return normalized_point((pp - root) * inv), normalized_point((pp + root) * inv)


def contains_cost(x: Multivector, p: Multivector) -> Scalar:
    """‖X ∧ P‖²: zero exactly when the point P lies on X [COOP Eq. 3, 9]."""
    return norm2(x ^ p)


def meet(x: Multivector, y: Multivector) -> Multivector:
    """Intersection (X1* ∧ X2*)* [COOP Eq. 5]: the regressive product."""
    return x & y
