"""Interpolating two primitives of one kind through their similarity versors [COOP Section 3.3, Fig. 4].

With V_i = V_S(X_u, X_i) the similarity taking the unit primitive of the kind to X_i
(``cooperative_similarity``), the path is

    V(t) = V1 exp(t Ω),  Ω = log(V1~ V2),  X(t) = V(t) X_u V(t)~,

with the similarity group's own exp and log (``exp_similarity_lie``, ``log_similarity_lie``), so
V1~ V(t) runs along a one-parameter subgroup: the speed ‖log(V(t)~ V(t+h))‖ = h‖Ω‖ is constant, a
pure translation moves a centre linearly, a pure dilation scales a radius geometrically
(r1^(1−t) r2^t), a turn about a fixed centre turns at a constant rate. X(0) ∝ X1 and X(1) ∝ X2 up
to the positive scale the dilation leaves on a blade.

Conditioning: the smaller of the two similarities' conditioning (0 for degenerate spanning points,
or a primitive opposite to the unit primitive's orientation, where V_S is a guarded half turn)
times cos²(θ/2) of the turn θ of V1~ V2 (0 for a half turn between the two, e.g. X2 = −X1, where
the shortest path is not unique). Values stay finite everywhere; a conditioning near 0 says they
are not meaningful.
"""

from __future__ import annotations

from typing import Any, NamedTuple

from gagen.algebra.protocol import Multivector
from gagen.algebra.scalars import Scalar
from gagen.model.conformal import ROTATION, part
from gagen.model.guarded import cos_half_sqrt
from gagen.model.primitives import unit_primitive
from gagen.model.similarity import cooperative_similarity
from gagen.model.versors import exp_similarity_lie, log_similarity_lie


class VersorPath(NamedTuple):
    """V(t) = start · exp(t · generator), and the conditioning of the pair (module docstring)."""

    start: Any
    generator: Any
    conditioning: Scalar

    def at(self, t: Scalar) -> Any:
        """V(t)."""
        return self.start * exp_similarity_lie(self.generator * t)


class Interpolated(NamedTuple):
    """X(t), the versor V(t) with X(t) = V(t) X_u V(t)~, and the pair's conditioning."""

    primitive: Any
    versor: Any
    conditioning: Scalar


def versor_path(kind: str, x1: Multivector, x2: Multivector) -> VersorPath:
    """The similarity path V(t) from V_S(X_u, X1) (t = 0) to ±V_S(X_u, X2) (t = 1)."""
    v1, conditioning1 = cooperative_similarity(kind, x1)
    v2, conditioning2 = cooperative_similarity(kind, x2)
    generator = log_similarity_lie(~v1 * v2)
    m = x1.math
    turn = part(generator, ROTATION)
    half_turn = cos_half_sqrt(m, turn.sp(~turn))  # cos(θ/2) of the relative turn
    smaller = m.if_else(m.lt(conditioning1, conditioning2), conditioning1, conditioning2)
    return VersorPath(v1, generator, smaller * half_turn * half_turn)


def interpolate(kind: str, x1: Multivector, x2: Multivector, t: Scalar) -> Interpolated:
    """X(t) = V(t) X_u V(t)~ between two primitives of ``kind`` (see the module docstring)."""
    path = versor_path(kind, x1, x2)
    v = path.at(t)
    return Interpolated(v.sandwich(unit_primitive(kind, x1)), v, path.conditioning)
