"""The cooperative task space [COOP Section 3]: n chains span a primitive, a similarity moves X_u onto it.

A :class:`System` is a primitive kind and one chain per spanning point (base placement as a
leading fixed joint). Everything here is written against the protocol; the Jacobians that are
derivatives of a flat expression (J_A,Sc, J_B, J_Be) are taken on the flattened graph by
``gagen.kernels``, and the ones with a closed construction (J_c, Eq. 15-17) are here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from gagen.model import kinematics as K
from gagen.model.conformal import einf
from gagen.model.primitives import check_kind, points_needed, through
from gagen.model.similarity import cooperative_similarity
from gagen.model.versors import log_similarity


@dataclass(frozen=True)
class Chain:
    name: str
    joints: tuple[K.Joint, ...]

    @property
    def dof(self) -> int:
        return sum(j.moves for j in self.joints)


@dataclass(frozen=True)
class System:
    """Chains whose end points span a primitive of ``kind`` (Table 1)."""

    name: str
    kind: str
    chains: tuple[Chain, ...]

    def __post_init__(self) -> None:
        check_kind(self.kind)
        if len(self.chains) != points_needed(self.kind):
            raise ValueError(f"system {self.name!r}: a {self.kind} is spanned by "
                             f"{points_needed(self.kind)} chains, got {len(self.chains)}")

    @property
    def dof(self) -> int:
        return sum(c.dof for c in self.chains)

    def split(self, q: Sequence[Any]) -> list[list[Any]]:
        """q = [q_1; …; q_n] cut into one joint vector per chain."""
        if len(q) != self.dof:
            raise ValueError(f"system {self.name!r} has {self.dof} joints, got {len(q)} values")
        out, start = [], 0
        for c in self.chains:
            out.append(list(q[start:start + c.dof]))
            start += c.dof
        return out


def end_points(zero: Any, system: System, q: Sequence[Any]) -> list[tuple[Any, list[Any]]]:
    """Per chain: (end point P_i, its point Jacobian columns ∂P_i/∂q_i)."""
    result = []
    for chain, qi in zip(system.chains, system.split(q), strict=True):
        motor, lines = K.chain_kinematics(zero, chain.joints, qi)
        result.append((K.end_point(motor), K.point_jacobian(motor, lines)))
    return result


def cooperative_primitive(zero: Any, system: System, q: Sequence[Any]) -> Any:
    """X_c(q) = P_1 ∧ … ∧ P_n (∧ e∞ for lines and planes) [COOP Eq. 14]."""
    return through(system.kind, [p for p, _ in end_points(zero, system, q)])


def cooperative_jacobian(zero: Any, system: System, q: Sequence[Any]) -> list[Any]:
    """J_c = ∂X_c/∂q: block i has columns P_1 ∧ … ∧ J_P,i ∧ … ∧ P_n (∧ e∞) [COOP Eq. 15-17]."""
    points = end_points(zero, system, q)
    closed = system.kind in ("line", "plane")
    columns = []
    for i, (_, jacobian) in enumerate(points):
        for column in jacobian:
            factors = [p for p, _ in points]
            factors[i] = column
            x = factors[0]
            for f in factors[1:]:
                x = x ^ f
            columns.append(x ^ einf(x) if closed else x)
    return columns


def similarity_of(zero: Any, system: System, q: Sequence[Any]) -> tuple[Any, Any]:
    """(V_Sc(q), conditioning) [COOP Eq. 28]."""
    return cooperative_similarity(system.kind, cooperative_primitive(zero, system, q))


def task_error(zero: Any, system: System, q: Sequence[Any], desired: Any) -> Any:
    """e(q) = log(V_Sc(q)~ V_Sd) [COOP Eq. 40-44] for a desired similarity versor V_Sd."""
    v, _ = similarity_of(zero, system, q)
    return log_similarity(~v * desired)
