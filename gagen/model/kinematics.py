"""Serial kinematic chains as motors [COOP 2.2, SMC III]: fixed link transforms and joint motions.

A chain is a list of :class:`Joint`: URDF-style, each with the fixed transform from its parent
frame (``xyz``, ``rpy``) followed by its motion about or along ``axis``. Fixed transforms become
*exact* constant motors: translations are the exact values of the given doubles, and rpy angles
within ``SNAP`` of a multiple of π/4 are taken as that multiple, so a URDF's 90° turns give exact
0, ±1 and ±√½ and the sparsity analysis removes what they zero out. That snapping moves a URDF's
``1.57079632679`` by 5e-12 rad to π/2; a joint with ``snap=False`` (a spec's ``snap: false``) keeps its
angles as written, exact doubles like the translations.

FK: V_M(q) = Π_j F_j J_j(q_j) with F_j the fixed motor and J_j the joint rotor
cos(q/2) − sin(q/2) (n3 e12 − n2 e13 + n1 e23) (revolute) or translator 1 − ½ q n∧e∞ (prismatic);
the end point is P(q) = V_M e0 V_M~.

Mimic joints (URDF ``<mimic>``): a follower turns by multiplier·q_leader + offset and has no entry of
its own in q. A chain's joint variables (:func:`chain_variables`) are its moving joints with each
follower replaced by its leader, which may lie outside the chain (a gripper's second finger mimics
the first); the carried lines are summed per variable with the multipliers (the chain rule), so every
Jacobian, being linear in the lines, is taken with respect to the variables.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Hashable, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import sympy

from gagen.algebra.protocol import Multivector
from gagen.algebra.scalars import Scalar
from gagen.model.conformal import e0, einf, vector
from gagen.model.versors import exp_translator, translator
from gagen.symbolic.backend import to_exact

SNAP = 1e-9  # rpy angles this close to a multiple of π/4 are taken as exactly that multiple
JOINT_KINDS = ("revolute", "continuous", "prismatic", "fixed")
TOOL_LINE = "e12"  # the tool's z axis through its origin, as a line bivector (rotation about z)


@dataclass(frozen=True)
class Joint:
    """One URDF-style joint: fixed transform (xyz, rpy) from the parent frame, then motion."""

    name: str
    kind: str
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    # (leader joint name, multiplier, offset): this joint turns by multiplier·q_leader + offset
    mimic: tuple[str, float, float] | None = field(default=None, repr=False)
    # (lower, upper) of the URDF <limit> (rad, or m for prismatic joints), or None: used to sample
    # `--check` configurations only, so it is left out of the repr (the build key) and of equality
    limits: tuple[float, float] | None = field(default=None, repr=False, compare=False)
    # snap the rpy angles to exact multiples of π/4 (:func:`exact_angle`); False keeps them as written.
    # In the repr (the build key) only when False, so the reprs of snapped systems do not change
    snap: bool = field(default=True, repr=False)

    def __post_init__(self) -> None:
        if self.kind not in JOINT_KINDS:
            raise ValueError(f"joint {self.name!r}: kind {self.kind!r} is not one of "
                             f"{', '.join(JOINT_KINDS)}")
        if self.moves and not math.isclose(sum(a * a for a in self.axis), 1.0, rel_tol=1e-9):
            raise ValueError(f"joint {self.name!r}: axis {self.axis} is not a unit vector")
        if self.mimic is not None:
            leader, multiplier, offset = self.mimic
            if not self.moves:
                raise ValueError(f"joint {self.name!r}: a fixed joint cannot mimic {leader!r}")
            if not isinstance(leader, str) or leader == self.name:
                raise ValueError(f"joint {self.name!r}: mimics {leader!r}; expected another joint's name")
            if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in (multiplier, offset)):
                raise ValueError(f"joint {self.name!r}: mimic multiplier {multiplier!r} and offset "
                                 f"{offset!r} must be finite numbers")

    def __repr__(self) -> str:
        # the dataclass repr, plus ``mimic`` only when set: Systems without mimic joints keep their
        # repr, which the build key hashes
        shown = [f"{f.name}={getattr(self, f.name)!r}" for f in fields(self) if f.repr]
        if self.mimic is not None:
            shown.append(f"mimic={self.mimic!r}")
        if not self.snap:
            shown.append("snap=False")
        return f"Joint({', '.join(shown)})"

    @property
    def moves(self) -> bool:
        return self.kind != "fixed"


def exact_angle(angle: float, snap: bool = True) -> sympy.Expr:
    """An rpy angle as an exact value: a multiple of π/4 when within SNAP of one (a URDF's
    ``1.57079632679`` becomes exactly π/2, so cos gives an exact 0), else, or with ``snap=False``, the
    exact value of the double as written."""
    k = round(angle / (math.pi / 4))
    if snap and abs(angle - k * math.pi / 4) <= SNAP:
        return k * sympy.pi / 4
    return to_exact(angle)


def _axis_rotor(like: Multivector, axis: int, angle: Scalar) -> Multivector:
    """Rotor about a basis axis (0, 1, 2 = x, y, z) by an exact or symbolic angle."""
    m = like.math
    c, s = m.cos(angle * sympy.Rational(1, 2)), m.sin(angle * sympy.Rational(1, 2))
    plane = ("e23", "e13", "e12")[axis]
    sign = -1 if axis != 1 else 1  # generator n* has +n1 on e23, −n2 on e13, +n3 on e12
    return like.make({"1": c, plane: sign * s})


_FIXED_MOTORS: dict[tuple[Hashable, ...], Multivector] = {}


def fixed_motor(like: Multivector, joint: Joint) -> Multivector:
    """The joint's fixed transform T(xyz) Rz(yaw) Ry(pitch) Rx(roll), with exact constants.

    Memoised per implementation, algebra and backend: it is a constant, and building it from the
    exact angles costs the interpreter more than the rest of a chain."""
    key = (type(like), like.algebra, getattr(like, "backend", None), joint)
    if key not in _FIXED_MOTORS:
        if len(_FIXED_MOTORS) > 4096:  # many short-lived backends: keep the memo bounded
            _FIXED_MOTORS.clear()
        _FIXED_MOTORS[key] = _fixed_motor(like, joint)
    return _FIXED_MOTORS[key]


def _fixed_motor(like: Multivector, joint: Joint) -> Multivector:
    return translator(vector(like, [to_exact(v) for v in joint.xyz])) * fixed_rotation(like, joint)


_FIXED_ROTATIONS: dict[tuple[Hashable, ...], Multivector] = {}


def fixed_rotation(like: Multivector, joint: Joint) -> Multivector:
    """The rotor of the joint's fixed rpy, Rz(yaw) Ry(pitch) Rx(roll), with exact constants (memoised)."""
    key = (type(like), like.algebra, getattr(like, "backend", None), joint.rpy, joint.snap)
    if key not in _FIXED_ROTATIONS:
        if len(_FIXED_ROTATIONS) > 4096:
            _FIXED_ROTATIONS.clear()
        roll, pitch, yaw = (exact_angle(a, joint.snap) for a in joint.rpy)
        _FIXED_ROTATIONS[key] = (_axis_rotor(like, 2, yaw) * _axis_rotor(like, 1, pitch)
                                 * _axis_rotor(like, 0, roll))
    return _FIXED_ROTATIONS[key]


def _unscaled(rotation: Multivector) -> tuple[Any, Any]:
    """(R~, s) with R = s R~ and s the common magnitude of R's nonzero coefficients, when they share
    one (quarter and half turns); (R, 1) otherwise."""
    magnitudes = {abs(rotation[b]) for b in ("1", "e12", "e13", "e23")} - {0}
    if len(magnitudes) != 1:
        return rotation, 1
    s = magnitudes.pop()
    return (rotation, 1) if s == 1 else (rotation * (1 / s), s)


def joint_motor(like: Multivector, joint: Joint, q: Scalar) -> Multivector:
    """Motion of a joint by q: rotor about its axis, or translator along it."""
    n = [to_exact(a) for a in joint.axis]
    if joint.kind == "prismatic":
        return exp_translator(like.make({f"e{i + 1}inf": n[i] * q for i in range(3)}))
    m = like.math
    c, s = m.cos(q * 0.5), m.sin(q * 0.5)
    return like.make({"1": c, "e12": -s * n[2], "e13": s * n[1], "e23": -s * n[0]})


def chain_variables(joints: Sequence[Joint]) -> list[str]:
    """The names of a chain's joint variables, its entries of q: each moving joint, a mimic follower
    replaced by its leader, in order of first appearance. Raises ValueError for a mimic of a fixed
    joint or of another follower (chained mimics are resolved when loading: ``gagen.robots.urdf``)."""
    by_name = {j.name: j for j in joints}
    names = []
    for joint in joints:
        if not joint.moves:
            continue
        name = joint.name
        if joint.mimic is not None:
            name = joint.mimic[0]
            leader = by_name.get(name)
            if leader is not None and not leader.moves:
                raise ValueError(f"joint {joint.name!r} mimics the fixed joint {name!r}")
            if leader is not None and leader.mimic is not None:
                raise ValueError(f"joint {joint.name!r} mimics {name!r}, itself a mimic of "
                                 f"{leader.mimic[0]!r}: chained mimics must be resolved to the first leader")
        if name not in names:
            names.append(name)
    return names


def _mimics(joints: Sequence[Joint]) -> bool:
    return any(j.mimic is not None for j in joints)


def _constant(value: Scalar, c: float) -> Scalar:
    """c as a plain float beside plain numbers (the interpreter), else as the exact value of the double."""
    return float(c) if isinstance(value, numbers.Real) and not isinstance(value, sympy.Basic) else to_exact(c)


def _scaled(value: Scalar, factor: float) -> Scalar:
    """value·factor, skipping the product for ±1."""
    if factor == 1:
        return value
    return -value if factor == -1 else value * _constant(value, factor)


def joint_values(joints: Sequence[Joint], q: Sequence[Scalar]) -> list[Scalar]:
    """Each moving joint's value from the chain's variables q (:func:`chain_variables`): a follower's
    is multiplier·q_leader + offset."""
    names = chain_variables(joints)
    if len(q) != len(names):
        raise ValueError(f"chain has {len(names)} joint variables, got {len(q)} joint values")
    if not _mimics(joints):
        return list(q)
    index = {name: i for i, name in enumerate(names)}
    values = []
    for joint in (j for j in joints if j.moves):
        if joint.mimic is None:
            values.append(q[index[joint.name]])
            continue
        leader, multiplier, offset = joint.mimic
        value = _scaled(q[index[leader]], multiplier)
        values.append(value if offset == 0 else value + _constant(value, offset))
    return values


def variable_columns(joints: Sequence[Joint], columns: Sequence[Any]) -> list[Any]:
    """Columns per moving joint (∂/∂ joint value) → columns per chain variable: the chain rule sums a
    leader's own column and multiplier × each follower's."""
    names = chain_variables(joints)
    if not _mimics(joints):
        return list(columns)
    index = {name: i for i, name in enumerate(names)}
    out: list[Any] = [None] * len(names)
    for joint, column in zip((j for j in joints if j.moves), columns, strict=True):
        name, multiplier = (joint.name, 1.0) if joint.mimic is None else joint.mimic[:2]
        term = _scaled(column, multiplier)
        i = index[name]
        out[i] = term if out[i] is None else out[i] + term
    return out


def chain_kinematics(like: Multivector, joints: Sequence[Joint],
                     q: Sequence[Scalar]) -> tuple[Any, list[Any]]:
    """(V_M(q), [L'_1 … L'_n]): the FK motor and each moving joint's generator carried to the base
    frame by everything before the joint's motion, L'_i = A_i B_i A_i~ [SMC Eq. 17-20].

    Since ∂V_M/∂q_i = −½ L'_i V_M, the spatial Jacobian −2 J_A V_M~ has exactly the columns L'_i:
    the O(n) construction, one carried bivector per joint. See :func:`chain_pose`.
    """
    motor, lines, _ = chain_pose(like, joints, q)
    return motor, lines


def chain_pose(like: Any, joints: Sequence[Joint], q: Sequence[Scalar], *,
               with_motor: bool = True) -> tuple[Any, list[Any], Any]:
    """(V_M, [L'_i], t): the FK motor, the carried joint lines and the end position t.

    q holds the chain's variables (:func:`chain_variables`: one per moving joint unless some mimic
    another); the lines are per variable, a leader's line plus multiplier × its followers' lines.

    With ``with_motor=False`` the motor is None and the frame turns by cos q and sin q directly
    (Rodrigues) instead of by the joint rotor's half angles, whose cos q = c² − s², sin q = 2cs cost
    5 flops a joint: for kernels that need positions and lines only.

    The chain carries its frame as the images a_k = A e_k A~ of the basis vectors, a position t and
    a rotor R (A = T(t) R). A versor V of the chain acts on the frame linearly: a_k ← Σ_j (V e_k V~)_j a_j,
    with V e_k V~ taken in the link's own coordinates, where the engine folds it to exact constants
    (quarter turns: signs and swaps, no flop) or to cos q, sin q of the joint (a rotation about a link
    axis touches two of the three vectors: 12 mul + 6 add). Offsets move t by Σ xyz_k a_k; each line is
    T(t) (n_world)* T(t)~ with n_world = Σ n_k a_k; the rotor (for V_M only) runs on unnormalised
    fixed rotations F = s F~ (unit entries where F has ±√½) with the scale Λ = Π s applied once.
    Kernels that need no V_M (positions, point Jacobians) lose the rotor chain in flattening.
    """
    values = iter(joint_values(joints, q))
    basis = [vector(like, row) for row in ((1, 0, 0), (0, 1, 0), (0, 0, 1))]
    frame = list(basis)
    rotation, scale = like.make({"1": 1}), 1
    position = like.make({})
    lines = []

    def along(coefficients: Sequence[Any]) -> Any:  # Σ c_k a_k: a link-frame vector in the base frame
        total = like.make({})
        for c, a in zip(coefficients, frame, strict=True):
            if not (isinstance(c, (int, float)) and c == 0):
                total = total + a * c
        return total

    def carried(versor: Any) -> list[Any]:  # the frame after a versor of the link: a_k ← Σ_j (V e_k V~)_j a_j
        return moved([versor.sandwich(e) for e in basis])

    def moved(images: Sequence[Any]) -> list[Any]:  # the frame after a rotation of the link, from its images
        m = like.math  # each entry (exact, or e.g. cos q = c² − s²) computed once, reused by 3 products
        return [along([m.shared(image[b]) for b in ("e1", "e2", "e3")]) for image in images]

    for joint in joints:
        if any(v != 0 for v in joint.xyz):
            position = position + along([to_exact(v) for v in joint.xyz])
        fixed_rot = fixed_rotation(like, joint)
        frame = carried(fixed_rot)
        fixed, s = _unscaled(fixed_rot)
        rotation, scale = rotation * fixed, scale * s
        if not joint.moves:
            continue
        axis = along([to_exact(a) for a in joint.axis])
        value = next(values)
        if joint.kind == "prismatic":
            lines.append(axis ^ einf(axis))
            position = position + axis * value
        else:
            generator = axis.make({"e12": axis["e3"], "e13": -axis["e2"], "e23": axis["e1"]})
            lines.append(translator(position).sandwich(generator))
            if with_motor:
                motion = joint_motor(like, joint, value)
                frame = carried(motion)
                rotation = rotation * motion
            else:
                frame = moved(_rotated_basis(like, joint.axis, value))
    lines = variable_columns(joints, lines)
    if not with_motor:
        return None, lines, position
    motor = translator(position) * (rotation if scale == 1 else rotation * scale)
    return motor, lines, position


def _rotated_basis(like: Multivector, axis: Sequence[float], q: Scalar) -> list[Multivector]:
    """The basis vectors turned by q about the unit axis n (link coordinates), by Rodrigues:
    R e_k = cos q e_k + sin q (n × e_k) + (1 − cos q) n_k n."""
    m = like.math
    c, s = m.cos(q), m.sin(q)
    n: list[Scalar] = [to_exact(a) for a in axis]  # exact: to_exact is None only for a non-number
    images = []
    for k in range(3):
        e = [1 if j == k else 0 for j in range(3)]
        cross = [n[1] * e[2] - n[2] * e[1], n[2] * e[0] - n[0] * e[2], n[0] * e[1] - n[1] * e[0]]
        images.append(vector(like, [c * e[j] + s * cross[j] + (1 - c) * (n[k] * n[j]) for j in range(3)]))
    return images


def forward_kinematics(like: Multivector, joints: Sequence[Joint], q: Sequence[Scalar]) -> Multivector:
    """V_M(q) = Π_j F_j J_j(q_j) for a chain; q has one entry per moving joint."""
    motor: Multivector = chain_kinematics(like, joints, q)[0]
    return motor


def spatial_jacobian(lines: Sequence[Multivector]) -> list[Multivector]:
    """−2 J_A V_M~, columns [e12, e13, e23, e1∞, e2∞, e3∞] = [ωz, −ωy, ωx, v] about the base origin."""
    return list(lines)


def body_jacobian(motor: Multivector, lines: Sequence[Multivector]) -> list[Multivector]:
    """−2 V_M~ J_A [COOP Eq. 8]: the spatial columns seen from the end-effector frame."""
    inverse = ~motor
    return [inverse.sandwich(line) for line in lines]


def analytic_jacobian(motor: Multivector, lines: Sequence[Multivector]) -> list[Multivector]:
    """J_A = ∂V_M/∂q, column i = −½ L'_i V_M."""
    return [(line * motor) * -0.5 for line in lines]


def point_jacobian(motor: Multivector | None, lines: Sequence[Multivector],
                   point: Multivector | None = None) -> list[Multivector]:
    """∂P/∂q_i for P = V_M e0 V_M~: ½(P L'_i − L'_i P), the commutator [COOP Eq. 17]. ``point`` may
    pass P when it is at hand (e.g. P(t) from :func:`chain_pose`); then ``motor`` may be None."""
    if point is None:
        if motor is None:
            raise ValueError("point_jacobian needs the motor V_M or the point P")
        point = end_point(motor)
    return [point.commutator(line) for line in lines]


def line_jacobian(motor: Multivector, lines: Sequence[Multivector],
                  tool_line: Multivector) -> list[Multivector]:
    """∂L'_p/∂q_i for a line (bivector) fixed in the tool, L'_p = V_M L_p V_M~:
    ½(L'_p L'_i − L'_i L'_p) [SMC Eq. 20]."""
    carried = motor.sandwich(tool_line)
    return [carried.commutator(line) for line in lines]


def end_point(motor: Multivector) -> Multivector:
    """P(q) = V_M e0 V_M~ [COOP Eq. 17 context]."""
    return motor.sandwich(e0(motor))

