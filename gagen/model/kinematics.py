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
    roll, pitch, yaw = (exact_angle(a) for a in joint.rpy)
    rotation = _axis_rotor(like, 2, yaw) * _axis_rotor(like, 1, pitch) * _axis_rotor(like, 0, roll)
    return translator(vector(like, [to_exact(v) for v in joint.xyz])) * rotation


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
    the O(n) construction, one sandwich of a bivector per joint.
    """
    moving = [j for j in joints if j.moves]
    if len(q) != len(moving):
        raise ValueError(f"chain has {len(moving)} moving joints, got {len(q)} joint values")
    # The chain runs on unnormalised fixed motors F_j = s_j F~_j (F~_j with unit rotation entries
    # where F_j has ±√½, as a URDF's quarter turns do): the scale Λ = Π s_j is applied once, to
    # the motor at the end and as Λ² (an exact power of ½) to each carried line.
    motor, scale = like.make({"1": 1}), 1
    lines = []
    values = iter(q)
    for joint in joints:
        fixed, s = _unscaled(fixed_motor(like, joint))
        motor, scale = motor * fixed, scale * s
        if joint.moves:
            lines.append(motor.sandwich(joint_generator(like, joint)) * (scale * scale))
            motor = motor * joint_motor(like, joint, next(values))
    return (motor if scale == 1 else motor * scale), lines


def _unscaled(fixed: Any) -> tuple[Any, Any]:
    """(F~, s) with F = s F~ and s the common magnitude of F's rotation coefficients, when they
    share one (quarter and half turns); (F, 1) otherwise."""
    magnitudes = {abs(fixed[b]) for b in ("1", "e12", "e13", "e23")} - {0}
    if len(magnitudes) != 1:
        return fixed, 1
    s = magnitudes.pop()
    return (fixed, 1) if s == 1 else (fixed * (1 / s), s)


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


def point_jacobian(motor: Any, lines: Sequence[Any]) -> list[Any]:
    """∂P/∂q_i for P = V_M e0 V_M~: ½(P L'_i − L'_i P), the commutator [COOP Eq. 17]."""
    p = end_point(motor)
    return [p.commutator(line) for line in lines]


def line_jacobian(motor: Any, lines: Sequence[Any], tool_line: Any) -> list[Any]:
    """∂L'_p/∂q_i for a line (bivector) fixed in the tool, L'_p = V_M L_p V_M~:
    ½(L'_p L'_i − L'_i L'_p) [SMC Eq. 20]."""
    carried = motor.sandwich(tool_line)
    return [carried.commutator(line) for line in lines]


def end_point(motor: Any) -> Any:
    """P(q) = V_M e0 V_M~ [COOP Eq. 17 context]."""
    return motor.sandwich(e0(motor))

