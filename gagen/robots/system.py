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
from gagen.model.fitting import span
from gagen.model.primitives import check_kind, points_needed
from gagen.model.similarity import cooperative_similarity
from gagen.model.versors import log_similarity


@dataclass(frozen=True)
class Chain:
    """A serial chain from the system's base frame to one spanning point.

    ``robot`` labels the physical robot the chain belongs to: chains with the same label share the
    moving joints that have the same name (a humanoid's waist joints drive both of its arms).
    A mimic joint is no variable of its own: its leader's is (:func:`kinematics.chain_variables`).
    A ``measured`` chain (a human's hand, a tracked tool) is no robot: its joints are inputs (q_m), not
    variables of q.
    """

    name: str
    joints: tuple[K.Joint, ...]
    robot: str = ""
    measured: bool = False

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

    q holds every distinct joint variable of the robot chains once (a mimic joint's is its leader's), in
    order of first appearance along the chains; q_m likewise the joints of the measured chains (inputs,
    not variables: a leader's hand). Without measured chains q_m is empty and everything is as before.
    """

    name: str
    kind: str
    chains: tuple[Chain, ...]

    def __post_init__(self) -> None:
        check_kind(self.kind)
        need = points_needed(self.kind)  # more chains: their points' best fit (gagen.model.fitting)
        if len(self.chains) < need or (self.kind == "point_pair" and len(self.chains) > need):
            more = "" if self.kind == "point_pair" else " (more are fitted)"
            raise ValueError(f"system {self.name!r}: a {self.kind} is spanned by {need} chains{more}, "
                             f"got {len(self.chains)}")
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
        for key in self.joint_keys + self.measured_keys:
            if key in followers:
                raise ValueError(f"system {self.name!r}: joint {key[1]!r} of robot {key[0]!r} is mimicked "
                                 f"in one chain but mimics {followers[key][0]!r} in another: chained "
                                 f"mimics must be resolved to the first leader")
        shared = set(self.joint_keys) & set(self.measured_keys)
        if shared:
            robot, name = sorted(shared)[0]
            raise ValueError(f"system {self.name!r}: joint {name!r} of robot {robot!r} is in a measured "
                             f"chain and in a robot chain; a measured chain's joints are inputs, not "
                             f"variables")
        if all(chain.measured for chain in self.chains):
            raise ValueError(f"system {self.name!r}: every chain is measured; at least one must be a robot's")

    @property
    def joint_keys(self) -> list[tuple[str, str]]:
        """(robot, joint name) of each entry of q (the robot chains' joints)."""
        return list(dict.fromkeys(key for chain in self.chains if not chain.measured
                                  for key in chain.joint_keys()))

    @property
    def dof(self) -> int:
        return len(self.joint_keys)

    @property
    def measured_keys(self) -> list[tuple[str, str]]:
        """(robot, joint name) of each entry of q_m (the measured chains' joints; empty without them)."""
        return list(dict.fromkeys(key for chain in self.chains if chain.measured
                                  for key in chain.joint_keys()))

    @property
    def measured_dof(self) -> int:
        return len(self.measured_keys)

    @property
    def measured_chains(self) -> tuple[Chain, ...]:
        return tuple(chain for chain in self.chains if chain.measured)

    def chain_indices(self) -> list[list[int]]:
        """Per chain, the index of each of its moving joints in (q, q_m) joined (in q alone without
        measured chains)."""
        index = {key: i for i, key in enumerate(self.joint_keys + self.measured_keys)}
        return [[index[key] for key in chain.joint_keys()] for chain in self.chains]

    def split(self, q: Sequence[Any], q_m: Sequence[Any] = ()) -> list[list[Any]]:
        """Each chain's joint variables, picked from q (shared joints appear in several chains) and, for a
        measured chain, from q_m: the input of its chain kernels and of ``kinematics.chain_pose``."""
        if len(q) != self.dof:
            raise ValueError(f"system {self.name!r} has {self.dof} joints, got {len(q)} values")
        if len(q_m) != self.measured_dof:
            names = ", ".join(repr(c.name) for c in self.measured_chains) or "none"
            raise ValueError(f"system {self.name!r} has {self.measured_dof} measured joints (q_m; measured "
                             f"chains: {names}), got {len(q_m)} values")
        joined = [*q, *q_m]
        return [[joined[i] for i in indices] for indices in self.chain_indices()]

    def joint_values(self, q: Sequence[Any], q_m: Sequence[Any] = ()) -> list[list[Any]]:
        """Each chain's value of every moving joint, mimic followers expanded (multiplier·q + offset)."""
        return [chain.joint_values(qc) for chain, qc in zip(self.chains, self.split(q, q_m), strict=True)]


def points_and_jacobians(zero: Any, system: System, q: Sequence[Any],
                         q_m: Sequence[Any] = ()) -> list[tuple[Any, list[Any]]]:
    """Per chain: (end point P_i, its point Jacobian columns ∂P_i/∂q_i)."""
    result = []
    for chain, qi in zip(system.chains, system.split(q, q_m), strict=True):
        motor, lines = K.chain_kinematics(zero, chain.joints, qi)
        result.append((K.end_point(motor), K.point_jacobian(motor, lines)))
    return result


def cooperative_primitive(zero: Any, system: System, q: Sequence[Any], q_m: Sequence[Any] = ()) -> Any:
    """X_c(q) = P_1 ∧ … ∧ P_n (∧ e∞ for lines and planes) [COOP Eq. 14]; with more chains than the kind
    needs, the best fit through their points (``gagen.model.fitting``)."""
    return span(system.kind, [p for p, _ in points_and_jacobians(zero, system, q, q_m)]).primitive


def cooperative_jacobian(zero: Any, system: System, q: Sequence[Any], q_m: Sequence[Any] = ()) -> list[Any]:
    """J_c = ∂X_c/∂q [COOP Eq. 15-17]; see :func:`primitive_jacobian` (with measured chains: ∂X_c/∂(q, q_m),
    the q_m columns last)."""
    return primitive_jacobian(system, points_and_jacobians(zero, system, q, q_m))


def primitive_jacobian(system: System, points: Sequence[tuple[Any, Sequence[Any]]]) -> list[Any]:
    """J_c from each chain's (P_i, ∂P_i/∂q_i): the column of joint j is Σ_i P_1 ∧ … ∧ ∂P_i/∂q_j ∧ … ∧ P_n
    (∧ e∞ for lines and planes) over the chains i that contain joint j (one unless it is shared)."""
    if len(points) != points_needed(system.kind):
        raise ValueError(f"system {system.name!r}: the closed-form J_c spans {points_needed(system.kind)} "
                         f"points, got {len(points)}; a fitted X_c's J_c is the catalogue's primitive kernel")
    closed = system.kind in ("line", "plane")
    columns: list[Any] = [None] * (system.dof + system.measured_dof)
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


def similarity_of(zero: Any, system: System, q: Sequence[Any], q_m: Sequence[Any] = ()) -> tuple[Any, Any]:
    """(V_Sc(q), conditioning) [COOP Eq. 28] (times the fit's conditioning where X_c is fitted)."""
    spanned = span(system.kind, [p for p, _ in points_and_jacobians(zero, system, q, q_m)])
    v, conditioning = cooperative_similarity(system.kind, spanned.primitive)
    return v, conditioning * spanned.conditioning if spanned.fitted else conditioning


def task_error(zero: Any, system: System, q: Sequence[Any], desired: Any, q_m: Sequence[Any] = ()) -> Any:
    """e(q) = log(V_Sc(q)~ V_Sd) [COOP Eq. 40-44] for a desired similarity versor V_Sd."""
    v, _ = similarity_of(zero, system, q, q_m)
    return log_similarity(~v * desired)
