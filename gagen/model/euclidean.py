"""Euclidean geometry in PGA and in CGA behind one interface: points, translations, lines as motor
generators, planes, incidence, distances and projections [HEX 2.2, 9.1].

A formula written against :class:`Geometry` (a hexapod leg's forward kinematics, say) runs in either
algebra, so the two can be compiled side by side and held against each other. The conventions:

- PGA G(3,0,1), e0² = 0 (``pga3d``): a point is the trivector P = e123 − x e023 + y e013 − z e012, a
  plane n·x = d is the vector n1 e1 + n2 e2 + n3 e3 − d e0, a translator by t is 1 − ½(t1 e01 +
  t2 e02 + t3 e03);
- CGA G(4,1) with the null basis e0, e∞ (``cga3d``): a point is e0 + x + ½|x|² e∞, a plane n·x = d is
  the OPNS 4-vector undual(n + d e∞), a translator by t is 1 − ½ t∧e∞.

In both, a rotation by θ about the unit axis u through the origin is cos(θ/2) − sin(θ/2) B with
B = u3 e12 − u2 e13 + u1 e23, and a line through c along u is the motor generator L = T(c) B T(c)~
(L² = −1), so the screw motion about it is e^{−θL/2} = cos(θ/2) − sin(θ/2) L. Its twist (the
velocity at the origin v and the angular velocity ω of the unit-rate motion) is read from L's
coefficients: ω = (L_e23, −L_e13, L_e12), v on the translation blades (e01, e02, e03 in PGA,
e1∞, e2∞, e3∞ in CGA); v = c × u for a line through c.

The incidence Π ∧ P is a multiple of the pseudoscalar: the signed distance of P above Π times the
weights of both (zero exactly when P lies on Π).
"""

from __future__ import annotations

from collections.abc import Sequence

from gagen.algebra.protocol import Multivector
from gagen.algebra.scalars import Scalar
from gagen.model import conformal
from gagen.model.guarded import safe_reciprocal
from gagen.model.versors import translator as conformal_translator

Vec3 = list[Scalar]  # three scalars (numbers or symbolic)

ROTATION = ("e23", "e13", "e12")  # ω1 on e23, −ω2 on e13, ω3 on e12 (the generator u*)


def cross(a: Sequence[Scalar], b: Sequence[Scalar]) -> Vec3:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def dot(a: Sequence[Scalar], b: Sequence[Scalar]) -> Scalar:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


class Geometry:
    """The Euclidean constructions of one algebra; subclasses fill in the algebra-specific ones."""

    algebra: str  # preset name
    point_kind: str = "point"
    TRANSLATION: tuple[str, str, str]
    PSEUDOSCALAR: str

    # -- algebra-specific -------------------------------------------------------------------------
    def point(self, like: Multivector, xyz: Sequence[Scalar]) -> Multivector:
        raise NotImplementedError

    def location(self, p: Multivector, unit: bool = False) -> Vec3:
        """The Euclidean position of a (possibly scaled) point; ``unit``: its weight is known to be 1
        (a unit versor acting on a normalised point), so it is not divided by."""
        raise NotImplementedError

    def translator(self, like: Multivector, t: Sequence[Scalar]) -> Multivector:
        raise NotImplementedError

    def plane(self, like: Multivector, normal: Sequence[Scalar], offset: Scalar) -> Multivector:
        """The plane n·x = offset (n a unit normal: its positive side is where n points)."""
        raise NotImplementedError

    def plane_normal(self, plane: Multivector) -> Vec3:
        """The plane's (unnormalised) normal n, of length its weight."""
        raise NotImplementedError

    def point_weight(self, p: Multivector) -> Scalar:
        raise NotImplementedError

    def project(self, plane: Multivector, p: Multivector) -> Multivector:
        """The foot of the perpendicular from p on the plane, as a normalised point."""
        raise NotImplementedError

    # -- shared -------------------------------------------------------------------------------------
    def rotation_generator(self, like: Multivector, axis: Sequence[Scalar]) -> Multivector:
        """B = u3 e12 − u2 e13 + u1 e23: e^{−θB/2} turns by θ about u (right-handed)."""
        return like.make({"e23": axis[0], "e13": -axis[1], "e12": axis[2]})

    def line(self, like: Multivector, centre: Sequence[Scalar], axis: Sequence[Scalar]) -> Multivector:
        """The line through ``centre`` along the unit ``axis``, as the motor generator T(c) B T(c)~."""
        return self.translator(like, centre).sandwich(self.rotation_generator(like, axis))

    def screw(self, line: Multivector, angle: Scalar) -> Multivector:
        """e^{−θL/2} = cos(θ/2) − sin(θ/2) L: the turn by θ about a unit line L (L² = −1)."""
        m = line.math
        screw: Multivector = m.cos(angle * 0.5) - line * m.sin(angle * 0.5)  # a Scalar (Any) minus it is Any
        return screw

    def rotate(self, line: Multivector, cos: Scalar, sin: Scalar, x: Multivector) -> Multivector:
        """e^{−θL/2} X e^{θL/2} for a unit line L, from cos θ and sin θ: X + sin θ D(X) + (1 − cos θ) D²(X)
        with D(X) = X × L = ½(XL − LX) (the commutator). Exact because D³ = −D: the rotation about
        L has the eigenvalues 0 and ±i on every grade. For a constant L, D is a constant linear map,
        and a component that L leaves fixed (a parallel axis's direction) stays exactly fixed, where
        the sandwich would carry cos²(θ/2) + sin²(θ/2) for the compiler to evaluate."""
        once = x.commutator(line)
        turned: Multivector = x + once * sin + once.commutator(line) * (1 - cos)
        return turned

    def twist(self, line: Multivector) -> tuple[Vec3, Vec3]:
        """(v, ω) of the unit-rate screw motion about L: v the velocity of the point at the origin."""
        w = [line["e23"], -line["e13"], line["e12"]]
        v = [line[b] for b in self.TRANSLATION]
        return v, w

    def origin(self, like: Multivector) -> Multivector:
        return self.point(like, [0, 0, 0])

    def incidence(self, plane: Multivector, p: Multivector) -> Scalar:
        """Π ∧ P as a scalar (its pseudoscalar coefficient): zero exactly when P lies on Π."""
        return (plane ^ p)[self.PSEUDOSCALAR]

    def signed_distance(self, plane: Multivector, p: Multivector) -> Scalar:
        """Height of P above Π along its normal: Π ∧ P over the weights of both."""
        m = p.math
        n = self.plane_normal(plane)
        weight = m.sqrt(dot(n, n)) * self.point_weight(p)
        return self.incidence(plane, p) * safe_reciprocal(m, weight)


class Projective(Geometry):
    """PGA G(3,0,1) (``pga3d``)."""

    algebra = "pga3d"
    TRANSLATION = ("e01", "e02", "e03")
    PSEUDOSCALAR = "e0123"

    def point(self, like: Multivector, xyz: Sequence[Scalar]) -> Multivector:
        return like.make({"e123": 1, "e023": -xyz[0], "e013": xyz[1], "e012": -xyz[2]})

    def point_weight(self, p: Multivector) -> Scalar:
        return p["e123"]

    def location(self, p: Multivector, unit: bool = False) -> Vec3:
        w = 1 if unit else safe_reciprocal(p.math, p["e123"])
        return [-p["e023"] * w, p["e013"] * w, -p["e012"] * w]

    def translator(self, like: Multivector, t: Sequence[Scalar]) -> Multivector:
        return like.make({"1": 1, "e01": -0.5 * t[0], "e02": -0.5 * t[1], "e03": -0.5 * t[2]})

    def plane(self, like: Multivector, normal: Sequence[Scalar], offset: Scalar) -> Multivector:
        return like.make({"e1": normal[0], "e2": normal[1], "e3": normal[2], "e0": -offset})

    def plane_normal(self, plane: Multivector) -> Vec3:
        return [plane["e1"], plane["e2"], plane["e3"]]

    def project(self, plane: Multivector, p: Multivector) -> Multivector:
        # (Π⌋P) is the line through P perpendicular to Π; its product with Π is the foot point
        foot = (plane | p) * plane
        foot = foot.grade(3)
        projected: Multivector = foot * safe_reciprocal(p.math, foot["e123"])
        return projected


class Conformal(Geometry):
    """CGA G(4,1) with the null basis e0, e∞ (``cga3d``)."""

    algebra = "cga3d"
    TRANSLATION = ("e1inf", "e2inf", "e3inf")
    PSEUDOSCALAR = "e0123inf"

    def point(self, like: Multivector, xyz: Sequence[Scalar]) -> Multivector:
        return conformal.point(conformal.vector(like, xyz))

    def point_weight(self, p: Multivector) -> Scalar:
        return conformal.point_weight(p)

    def location(self, p: Multivector, unit: bool = False) -> Vec3:
        x = p if unit else conformal.location(p)
        return [x[b] for b in conformal.EUCLID]

    def translator(self, like: Multivector, t: Sequence[Scalar]) -> Multivector:
        return conformal_translator(conformal.vector(like, t))

    def plane(self, like: Multivector, normal: Sequence[Scalar], offset: Scalar) -> Multivector:
        dual = like.make({"e1": normal[0], "e2": normal[1], "e3": normal[2], "einf": offset})
        return dual.undual()

    def plane_normal(self, plane: Multivector) -> Vec3:
        dual = plane.dual()  # n + d e∞
        return [dual[b] for b in conformal.EUCLID]

    def project(self, plane: Multivector, p: Multivector) -> Multivector:
        # P − (P·π)π/|π|² (π = n + d e∞, the plane's dual) has the foot's location; it is not null,
        # so the foot is embedded again from that location
        pi = plane.dual()
        n = self.plane_normal(plane)
        moved = p - pi * (p.sp(pi) * safe_reciprocal(p.math, dot(n, n)))
        return self.point(p, self.location(moved))


PROJECTIVE = Projective()
CONFORMAL = Conformal()
GEOMETRIES = {g.algebra: g for g in (PROJECTIVE, CONFORMAL)}


def geometry(algebra: str) -> Geometry:
    """The geometry of an algebra by preset name (``pga3d`` or ``cga3d``)."""
    if algebra not in GEOMETRIES:
        raise KeyError(f"no Euclidean geometry for algebra {algebra!r}; known: {', '.join(GEOMETRIES)}")
    return GEOMETRIES[algebra]
