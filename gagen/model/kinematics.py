"""Serial kinematic chains as motors [COOP 2.2, SMC III]: fixed link transforms and joint motions.

A chain is a list of :class:`Joint`: URDF-style, each with the fixed transform from its parent
frame (``xyz``, ``rpy``) followed by its motion about or along ``axis``. Fixed transforms become
*exact* constant motors: translations are the exact values of the given doubles, and rpy angles
within ``SNAP`` of a multiple of π/4 are taken as that multiple, so a URDF's 90° turns give exact
0, ±1 and ±√½ and the sparsity analysis removes what they zero out.

FK: V_M(q) = Π_j F_j J_j(q_j) with F_j the fixed motor and J_j the joint rotor
cos(q/2) − sin(q/2) (n3 e12 − n2 e13 + n1 e23) (revolute) or translator 1 − ½ q n∧e∞ (prismatic);
the end point is P(q) = V_M e0 V_M~.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import sympy

from gagen.model.conformal import e0, vector
from gagen.model.versors import exp_translator, translator
from gagen.symbolic.backend import to_exact

SNAP = 1e-9  # rpy angles this close to a multiple of π/4 are taken as exactly that multiple
JOINT_KINDS = ("revolute", "continuous", "prismatic", "fixed")


@dataclass(frozen=True)
class Joint:
    """One URDF-style joint: fixed transform (xyz, rpy) from the parent frame, then motion."""

    name: str
    kind: str
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        if self.kind not in JOINT_KINDS:
            raise ValueError(f"joint {self.name!r}: kind {self.kind!r} is not one of "
                             f"{', '.join(JOINT_KINDS)}")
        if self.moves and not math.isclose(sum(a * a for a in self.axis), 1.0, rel_tol=1e-9):
            raise ValueError(f"joint {self.name!r}: axis {self.axis} is not a unit vector")

    @property
    def moves(self) -> bool:
        return self.kind != "fixed"


def exact_angle(angle: float) -> sympy.Expr:
    """An rpy angle as an exact value: a multiple of π/4 when within SNAP of one."""
    k = round(angle / (math.pi / 4))
    if abs(angle - k * math.pi / 4) <= SNAP:
        return k * sympy.pi / 4
    return to_exact(angle)


def _axis_rotor(like: Any, axis: int, angle: Any) -> Any:
    """Rotor about a basis axis (0, 1, 2 = x, y, z) by an exact or symbolic angle."""
    m = like.math
    c, s = m.cos(angle * sympy.Rational(1, 2)), m.sin(angle * sympy.Rational(1, 2))
    plane = ("e23", "e13", "e12")[axis]
    sign = -1 if axis != 1 else 1  # generator n* has +n1 on e23, −n2 on e13, +n3 on e12
    return like.make({"1": c, plane: sign * s})


_FIXED_MOTORS: dict[tuple, Any] = {}


def fixed_motor(like: Any, joint: Joint) -> Any:
    """The joint's fixed transform T(xyz) Rz(yaw) Ry(pitch) Rx(roll), with exact constants.

    Memoised per implementation, algebra and backend: it is a constant, and building it from the
    exact angles costs the interpreter more than the rest of a chain."""
    key = (type(like), like.algebra, getattr(like, "backend", None), joint)
    if key not in _FIXED_MOTORS:
        if len(_FIXED_MOTORS) > 4096:  # many short-lived backends: keep the memo bounded
            _FIXED_MOTORS.clear()
        _FIXED_MOTORS[key] = _fixed_motor(like, joint)
    return _FIXED_MOTORS[key]


def _fixed_motor(like: Any, joint: Joint) -> Any:
    return translator(vector(like, [to_exact(v) for v in joint.xyz])) * fixed_rotation(like, joint)


_FIXED_ROTATIONS: dict[tuple, Any] = {}


def fixed_rotation(like: Any, joint: Joint) -> Any:
    """The rotor of the joint's fixed rpy, Rz(yaw) Ry(pitch) Rx(roll), with exact constants (memoised)."""
    key = (type(like), like.algebra, getattr(like, "backend", None), joint.rpy)
    if key not in _FIXED_ROTATIONS:
        if len(_FIXED_ROTATIONS) > 4096:
            _FIXED_ROTATIONS.clear()
        roll, pitch, yaw = (exact_angle(a) for a in joint.rpy)
        _FIXED_ROTATIONS[key] = (_axis_rotor(like, 2, yaw) * _axis_rotor(like, 1, pitch)
                                 * _axis_rotor(like, 0, roll))
    return _FIXED_ROTATIONS[key]


def _unscaled(rotation: Any) -> tuple[Any, Any]:
    """(R~, s) with R = s R~ and s the common magnitude of R's nonzero coefficients, when they share
    one (quarter and half turns); (R, 1) otherwise."""
    magnitudes = {abs(rotation[b]) for b in ("1", "e12", "e13", "e23")} - {0}
    if len(magnitudes) != 1:
        return rotation, 1
    s = magnitudes.pop()
    return (rotation, 1) if s == 1 else (rotation * (1 / s), s)


def joint_motor(like: Any, joint: Joint, q: Any) -> Any:
    """Motion of a joint by q: rotor about its axis, or translator along it."""
    n = [to_exact(a) for a in joint.axis]
    if joint.kind == "prismatic":
        return exp_translator(like.make({f"e{i + 1}inf": n[i] * q for i in range(3)}))
    m = like.math
    c, s = m.cos(q * 0.5), m.sin(q * 0.5)
    return like.make({"1": c, "e12": -s * n[2], "e13": s * n[1], "e23": -s * n[0]})


def joint_generator(like: Any, joint: Joint) -> Any:
    """The joint's unit generator B in its own frame, J(q) = e^{−qB/2}: n* for a revolute joint
    (n3 e12 − n2 e13 + n1 e23), n ∧ e∞ for a prismatic one."""
    n = [to_exact(a) for a in joint.axis]
    if joint.kind == "prismatic":
        return like.make({f"e{i + 1}inf": n[i] for i in range(3)})
    return like.make({"e12": n[2], "e13": -n[1], "e23": n[0]})


def chain_kinematics(like: Any, joints: Sequence[Joint], q: Sequence[Any]) -> tuple[Any, list[Any]]:
    """(V_M(q), [L'_1 … L'_n]): the FK motor and each moving joint's generator carried to the base
    frame by everything before the joint's motion, L'_i = A_i B_i A_i~ [SMC Eq. 17-20].

    Since ∂V_M/∂q_i = −½ L'_i V_M, the spatial Jacobian −2 J_A V_M~ has exactly the columns L'_i:
    the O(n) construction, one carried bivector per joint. See :func:`chain_pose`.
    """
    motor, lines, _ = chain_pose(like, joints, q)
    return motor, lines


def chain_pose(like: Any, joints: Sequence[Joint], q: Sequence[Any]) -> tuple[Any, list[Any], Any]:
    """(V_M, [L'_i], t): the FK motor, the carried joint lines and the end position t.

    The chain is carried as a rotor R and a position t rather than as one motor (A = T(t) R): a joint
    rotation then touches only the four rotor coefficients, where a motor product would also rework
    the four translational ones; fixed offsets move t by R x R~; each line is T(t) (R B R~) T(t)~, and
    V_M = T(t) R is assembled once at the end. The rotor runs on unnormalised fixed rotations
    (F = s F~ with unit entries where F has ±√½, as a URDF's quarter turns do): the scale Λ = Π s is
    applied to V_M once, and as Λ² (an exact power of ½ for quarter turns) to rotated vectors and lines.
    """
    moving = [j for j in joints if j.moves]
    if len(q) != len(moving):
        raise ValueError(f"chain has {len(moving)} moving joints, got {len(q)} joint values")
    rotation, scale = like.make({"1": 1}), 1
    position = like.make({})
    lines = []
    values = iter(q)

    def rotate(x: Any) -> Any:  # R x R~ with the unnormalised rotor
        return rotation.sandwich(x) * (scale * scale)

    for joint in joints:
        offset = vector(like, [to_exact(v) for v in joint.xyz])
        if any(v != 0 for v in joint.xyz):
            position = position + rotate(offset)
        fixed, s = _unscaled(fixed_rotation(like, joint))
        rotation, scale = rotation * fixed, scale * s
        if not joint.moves:
            continue
        lines.append(translator(position).sandwich(rotate(joint_generator(like, joint))))
        value = next(values)
        if joint.kind == "prismatic":
            position = position + rotate(vector(like, [to_exact(a) * value for a in joint.axis]))
        else:
            rotation = rotation * joint_motor(like, joint, value)
    motor = translator(position) * (rotation if scale == 1 else rotation * scale)
    return motor, lines, position


def forward_kinematics(like: Any, joints: Sequence[Joint], q: Sequence[Any]) -> Any:
    """V_M(q) = Π_j F_j J_j(q_j) for a chain; q has one entry per moving joint."""
    return chain_kinematics(like, joints, q)[0]


def spatial_jacobian(lines: Sequence[Any]) -> list[Any]:
    """−2 J_A V_M~, columns [e12, e13, e23, e1∞, e2∞, e3∞] = [ωz, −ωy, ωx, v] about the base origin."""
    return list(lines)


def body_jacobian(motor: Any, lines: Sequence[Any]) -> list[Any]:
    """−2 V_M~ J_A [COOP Eq. 8]: the spatial columns seen from the end-effector frame."""
    inverse = ~motor
    return [inverse.sandwich(line) for line in lines]


def analytic_jacobian(motor: Any, lines: Sequence[Any]) -> list[Any]:
    """J_A = ∂V_M/∂q, column i = −½ L'_i V_M."""
    return [(line * motor) * -0.5 for line in lines]


def point_jacobian(motor: Any, lines: Sequence[Any], point: Any = None) -> list[Any]:
    """∂P/∂q_i for P = V_M e0 V_M~: ½(P L'_i − L'_i P), the commutator [COOP Eq. 17]. ``point`` may
    pass P when it is at hand (e.g. P(t) from :func:`chain_pose`)."""
    p = end_point(motor) if point is None else point
    return [p.commutator(line) for line in lines]


def line_jacobian(motor: Any, lines: Sequence[Any], tool_line: Any) -> list[Any]:
    """∂L'_p/∂q_i for a line (bivector) fixed in the tool, L'_p = V_M L_p V_M~:
    ½(L'_p L'_i − L'_i L'_p) [SMC Eq. 20]."""
    carried = motor.sandwich(tool_line)
    return [carried.commutator(line) for line in lines]


def end_point(motor: Any) -> Any:
    """P(q) = V_M e0 V_M~ [COOP Eq. 17 context]."""
    return motor.sandwich(e0(motor))

