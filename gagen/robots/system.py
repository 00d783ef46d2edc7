"""The cooperative task space [COOP Section 3]: n chains span a primitive, a similarity moves X_u onto it.

A :class:`System` is a primitive kind and one chain per spanning point (base placement as a
leading fixed joint). Everything here is written against the protocol; the Jacobians that are
derivatives of a flat expression (J_A,Sc, J_B, J_Be) are taken on the flattened graph by
``gagen.apps.cooperative.catalogue``, and the ones with a closed construction (J_c, Eq. 15-17) are here.
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
    """A serial chain from the system's base frame to one spanning point.

    ``robot`` labels the physical robot the chain belongs to: chains with the same label share the
    moving joints that have the same name (a humanoid's waist joints drive both of its arms).
    A mimic joint is no variable of its own: its leader's is (:func:`kinematics.chain_variables`).
    """

    name: str
    joints: tuple[K.Joint, ...]
    robot: str = ""

    def __post_init__(self) -> None:
        K.chain_variables(self.joints)  # refuses mimics of fixed joints and chained mimics

    @property
    def dof(self) -> int:
        """The number of independent joint variables (mimic followers excluded)."""
        return len(K.chain_variables(self.joints))

    def joint_keys(self) -> list[tuple[str, str]]:
        """(robot, joint name) of each joint variable: equal keys are one physical joint."""
        return [(self.robot or self.name, name) for name in K.chain_variables(self.joints)]

    def joint_values(self, q: Sequence[Any]) -> list[Any]:
        """Every moving joint's value (mimic followers: multiplier·q_leader + offset) from the chain's
        variables."""
        return K.joint_values(self.joints, q)


@dataclass(frozen=True)
class System:
    """Chains whose end points span a primitive of ``kind`` (Table 1).

    q holds every distinct joint variable once (a mimic joint's is its leader's), in order of first
    appearance along the chains.
    """

    name: str
    kind: str
    chains: tuple[Chain, ...]

    def __post_init__(self) -> None:
        check_kind(self.kind)
        if len(self.chains) != points_needed(self.kind):
            raise ValueError(f"system {self.name!r}: a {self.kind} is spanned by "
                             f"{points_needed(self.kind)} chains, got {len(self.chains)}")
        names = [c.name for c in self.chains]
        if len(set(names)) != len(names):
            raise ValueError(f"system {self.name!r}: chain names must differ, got {names}")
        seen: dict[tuple[str, str], K.Joint] = {}
        for chain in self.chains:  # every moving joint by its own key, mimic followers included
            for joint in (j for j in chain.joints if j.moves):
                key = (chain.robot or chain.name, joint.name)
                if seen.setdefault(key, joint) != joint:
                    raise ValueError(f"system {self.name!r}: joint {key[1]!r} of robot {key[0]!r} is "
                                     f"shared by chains but differs between them")
        followers = {key: joint.mimic for key, joint in seen.items() if joint.mimic is not None}
        for key in self.joint_keys:
            if key in followers:
                raise ValueError(f"system {self.name!r}: joint {key[1]!r} of robot {key[0]!r} is mimicked "
                                 f"in one chain but mimics {followers[key][0]!r} in another: chained "
                                 f"mimics must be resolved to the first leader")

    @property
    def joint_keys(self) -> list[tuple[str, str]]:
        """(robot, joint name) of each entry of q."""
        return list(dict.fromkeys(key for chain in self.chains for key in chain.joint_keys()))

    @property
    def dof(self) -> int:
        return len(self.joint_keys)

    def chain_indices(self) -> list[list[int]]:
        """Per chain, the index in q of each of its moving joints."""
        index = {key: i for i, key in enumerate(self.joint_keys)}
        return [[index[key] for key in chain.joint_keys()] for chain in self.chains]

    def split(self, q: Sequence[Any]) -> list[list[Any]]:
        """Each chain's joint variables, picked from q (shared joints appear in several chains): the
        input of its chain kernels and of ``kinematics.chain_pose``."""
        if len(q) != self.dof:
            raise ValueError(f"system {self.name!r} has {self.dof} joints, got {len(q)} values")
        return [[q[i] for i in indices] for indices in self.chain_indices()]

    def joint_values(self, q: Sequence[Any]) -> list[list[Any]]:
        """Each chain's value of every moving joint, mimic followers expanded (multiplier·q + offset)."""
        return [chain.joint_values(qc) for chain, qc in zip(self.chains, self.split(q), strict=True)]


def points_and_jacobians(zero: Any, system: System, q: Sequence[Any]) -> list[tuple[Any, list[Any]]]:
    """Per chain: (end point P_i, its point Jacobian columns ∂P_i/∂q_i)."""
    result = []
    for chain, qi in zip(system.chains, system.split(q), strict=True):
        motor, lines = K.chain_kinematics(zero, chain.joints, qi)
        result.append((K.end_point(motor), K.point_jacobian(motor, lines)))
    return result


def cooperative_primitive(zero: Any, system: System, q: Sequence[Any]) -> Any:
    """X_c(q) = P_1 ∧ … ∧ P_n (∧ e∞ for lines and planes) [COOP Eq. 14]."""
    return through(system.kind, [p for p, _ in points_and_jacobians(zero, system, q)])


def cooperative_jacobian(zero: Any, system: System, q: Sequence[Any]) -> list[Any]:
    """J_c = ∂X_c/∂q [COOP Eq. 15-17]; see :func:`primitive_jacobian`."""
    return primitive_jacobian(system, points_and_jacobians(zero, system, q))


def primitive_jacobian(system: System, points: Sequence[tuple[Any, Sequence[Any]]]) -> list[Any]:
    """J_c from each chain's (P_i, ∂P_i/∂q_i): the column of joint j is Σ_i P_1 ∧ … ∧ ∂P_i/∂q_j ∧ … ∧ P_n
    (∧ e∞ for lines and planes) over the chains i that contain joint j (one unless it is shared)."""
    closed = system.kind in ("line", "plane")
    columns: list[Any] = [None] * system.dof
    for i, ((_, jacobian), indices) in enumerate(zip(points, system.chain_indices(), strict=True)):
        for column, j in zip(jacobian, indices, strict=True):
            factors = [p for p, _ in points]
            factors[i] = column
            x = factors[0]
            for f in factors[1:]:
                x = x ^ f
            x = x ^ einf(x) if closed else x
            columns[j] = x if columns[j] is None else columns[j] + x
    return columns


def similarity_of(zero: Any, system: System, q: Sequence[Any]) -> tuple[Any, Any]:
    """(V_Sc(q), conditioning) [COOP Eq. 28]."""
    return cooperative_similarity(system.kind, cooperative_primitive(zero, system, q))


def task_error(zero: Any, system: System, q: Sequence[Any], desired: Any) -> Any:
    """e(q) = log(V_Sc(q)~ V_Sd) [COOP Eq. 40-44] for a desired similarity versor V_Sd."""
    v, _ = similarity_of(zero, system, q)
    return log_similarity(~v * desired)
