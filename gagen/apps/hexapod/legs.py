"""A hexapod leg's kinematics as formulas over either algebra [HEX 5-7], [MATH §8].

Forward kinematics is the product of exponentials M(q) = S1(q1) S2(q2) S3(q3) M_home in the body
frame: S_j = e^{−q_j L_j/2} turns about the joint line L_j (the hip-frame line through c_j along u_j,
carried to the body by the mount motor), and M_home places the toe frame at (l1 + l2 + l3, 0, 0) of
the hip frame. (The paper's listing ends with Translator(l3) alone, which puts the toe at (l3, 0, 0):
MATH §8.) The toe is P = M O M~ with O the origin point.

The Jacobian columns are read from the joint lines at q, L_j(q) = (S1…S_{j−1}) L_j (S1…S_{j−1})~: their
twists (v_j, ω_j) are the spatial Jacobian's columns (Pinocchio's order: linear, then angular), and
the toe's linear velocity per joint is v_j + ω_j × p = u_j × (p − c_j) [HEX Eq. 6.1].

The analytic IK [HEX 7.1] solves hip yaw by atan2 in the hip frame, towards the target's heading and
away from it (+π: a toe behind the yaw axis), then for each yaw the planar two-link problem of thigh
and knee with the l1 offset removed, by the cosine law in a form that stays accurate at full stretch:
sin φ3 = √(((l2+l3)² − d²)(d² − (l2−l3)²)) / (2 l2 l3). A target outside the annulus
|l2 − l3| ≤ d ≤ l2 + l3 gives the nearest pose (the leg stretched or folded towards it) with the flag
``reach`` = 0 and the distance to it in ``excess``. Per knee branch the yaw nearer the target wins,
and of two that reach it the one nearer the joint limits; NaN, inf and huge targets give finite angles
flagged unreachable, and no branch of it can give a NaN or inf. It needs the planar structure (yaw
about ±z, thigh and knee about ±y of the hip frame): a leg without it raises :class:`AnalyticIKError`
and has only the numerical IK (damped least squares on the Jacobian).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from gagen.algebra.protocol import Multivector
from gagen.apps.hexapod.spec import Leg
from gagen.model.euclidean import Geometry, cross, dot
from gagen.model.kinematics import Joint, fixed_rotation
from gagen.symbolic.backend import to_exact

REACH_TOLERANCE = 1e-9  # a target this far outside the annulus still counts as reachable, relative to the
# leg's size 1 + max|mount| + Σ lengths (m): the hip-frame target carries the rounding of the mount's offset
BRANCH_TOLERANCE = 1e-12  # m: two IK branches this close to a target are equally near (then: limits)
MAX_TARGET = 1e9  # m: a target farther (or NaN) is not solved but flagged unreachable
AXIS_TOLERANCE = 1e-12  # how far from ±z / ±y an axis may be for the analytic IK


class AnalyticIKError(ValueError):
    """A leg the analytic IK cannot solve: names the leg and the axes at fault."""


def _exact(values: Sequence[float]) -> list[Any]:
    return [to_exact(v) for v in values]


def _constant(like: Multivector, value: float) -> Any:
    """A spec number as a scalar of the path: a float on the interpreter, exact in the compiler."""
    return like.make({"1": to_exact(value)}).scalar()


def mount(geo: Geometry, like: Multivector, leg: Leg) -> Multivector:
    """The hip frame on the body: T(xyz) Rz(yaw) Ry(pitch) Rx(roll), exact constants."""
    rotation = fixed_rotation(like, Joint(f"{leg.name}_mount", "fixed", leg.xyz, leg.rpy))
    return geo.translator(like, _exact(leg.xyz)) * rotation


def _rpy_matrix(rpy: Sequence[float]) -> np.ndarray:
    (cr, cp, cy), (sr, sp, sy) = np.cos(rpy), np.sin(rpy)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def folded(leg: Leg) -> tuple[Leg, float]:
    """The leg with its mount's rotation moved into the hip joint's angle, and that angle α, when the
    mount turns about the hip axis (which passes through the hip frame's origin): then
    T(xyz) R_u(α) S1(q1) = T(xyz) S1(q1 + α), and the joint lines stay as sparse as in the hip frame
    (a hexagonal body's 30° mounts would otherwise fill them). (leg, 0) when the mount turns otherwise."""
    if leg.rpy == (0.0, 0.0, 0.0):
        return leg, 0.0
    R, u = _rpy_matrix(leg.rpy), np.array(leg.axes[0])
    if np.linalg.norm(R @ u - u) > AXIS_TOLERANCE:
        return leg, 0.0
    e = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
    e /= np.linalg.norm(e)
    turned = R @ e
    return replace(leg, rpy=(0.0, 0.0, 0.0)), math.atan2(float(u @ np.cross(e, turned)), float(e @ turned))


def joint_lines(geo: Geometry, like: Multivector, leg: Leg) -> list[Multivector]:
    """The three joint lines at the zero pose, in the body frame (exact constants)."""
    carry = mount(geo, like, leg)
    return [carry.sandwich(geo.line(like, _exact(c), _exact(u)))
            for c, u in zip(leg.centres, leg.axes, strict=True)]


def _angles(like: Multivector, q: Sequence[Any]) -> list[tuple[Any, Any, Any, Any]]:
    """cos and sin of each half angle (for the screws) and of the full angle (for the rotations),
    the full ones by the double-angle formulas: three sin/cos pairs in all."""
    m = like.math
    out = []
    for angle in q:
        c, s = m.cos(angle * 0.5), m.sin(angle * 0.5)
        out.append((c, s, 1 - 2 * s * s, 2 * s * c))
    return out


def _folded_angles(leg: Leg, q: Sequence[Any]) -> tuple[Leg, list[Any]]:
    leg, offset = folded(leg)
    return leg, [q[0] + offset if offset else q[0], *q[1:]]


def leg_motor(geo: Geometry, like: Multivector, leg: Leg, q: Sequence[Any]) -> Multivector:
    """M(q) = S1 S2 S3 M_home in the body frame, S_j = cos(q_j/2) − sin(q_j/2) L_j (with the mount's
    turn about the hip axis, if any, in the hip angle: :func:`folded`)."""
    leg, q = _folded_angles(leg, q)
    motor = mount(geo, like, leg) * geo.translator(like, _exact(leg.toe))
    for line, (c, s, _, _) in reversed(list(zip(joint_lines(geo, like, leg), _angles(like, q), strict=True))):
        motor = (c - line * s) * motor
    return motor


def leg_kinematics(geo: Geometry, like: Multivector, leg: Leg, q: Sequence[Any]) -> dict[str, Any]:
    """The FK motor, the toe point, its position p, the point Jacobian J (3 columns u_j × (p − c_j))
    and the spatial Jacobian S (3 columns of (v, ω)), all in the body frame.

    The toe and the joint lines at q are the zero-pose ones turned about the constant joint lines,
    last joint first (:meth:`Geometry.rotate`): P(q) = R1 R2 R3 P_home, L_j(q) = R1 … R_{j−1} L_j; the
    motor, an output of its own, is the product of the screws. Rotations keep a point's weight
    exactly, so p is read without dividing by it."""
    motor = leg_motor(geo, like, leg, q)
    leg, q = _folded_angles(leg, q)
    lines, angles = joint_lines(geo, like, leg), _angles(like, q)

    def turned(x: Multivector, joints: int) -> Multivector:  # R1 … R_joints x
        for line, (_, _, c, s) in reversed(list(zip(lines[:joints], angles[:joints], strict=True))):
            x = geo.rotate(line, c, s, x)
        return x

    home = (mount(geo, like, leg) * geo.translator(like, _exact(leg.toe))).sandwich(geo.origin(like))
    toe = turned(home, 3)
    p = geo.location(toe, unit=True)
    twists = [geo.twist(turned(line, j)) for j, line in enumerate(lines)]
    J = [[vi + wp for vi, wp in zip(v, cross(w, p), strict=True)] for v, w in twists]
    S = [[*v, *w] for v, w in twists]
    return {"motor": motor, "toe": toe, "p": p, "J": J, "S": S}


# -- analytic IK ----------------------------------------------------------------------------------------

def planar_signs(leg: Leg) -> tuple[int, int, int]:
    """(s1, s2, s3) with the axes s1·z, s2·y, s3·y, or AnalyticIKError naming what is not planar."""
    def sign(axis: Sequence[float], unit: int) -> int | None:
        off = [a for i, a in enumerate(axis) if i != unit]
        if all(abs(a) <= AXIS_TOLERANCE for a in off) and abs(abs(axis[unit]) - 1) <= AXIS_TOLERANCE:
            return 1 if axis[unit] > 0 else -1
        return None

    yaw, thigh, knee = leg.axes
    parallel = abs(abs(dot(thigh, knee)) - 1) <= AXIS_TOLERANCE
    advice = "use the numerical IK (damped least squares on the leg's Jacobian) for it"
    if not parallel:
        raise AnalyticIKError(f"leg {leg.name}: the thigh axis {tuple(thigh)} and the knee axis "
                              f"{tuple(knee)} are not parallel, thigh and knee are no planar two-link chain "
                              f"and the analytic IK does not apply; {advice}")
    s1, s2, s3 = sign(yaw, 2), sign(thigh, 1), sign(knee, 1)
    if s1 is None:
        raise AnalyticIKError(f"leg {leg.name}: the hip axis {tuple(yaw)} is not ±z of the hip frame; the "
                              f"analytic IK needs hip yaw about z; {advice}")
    if s2 is None or s3 is None:
        raise AnalyticIKError(f"leg {leg.name}: the thigh and knee axes {tuple(thigh)} are not ±y of the hip "
                              f"frame (perpendicular to the leg and the yaw axis); {advice}")
    return s1, s2, s3


def _max0(m: Any, x: Any) -> Any:
    return m.if_else(m.lt(x, 0), 0.0, x)


def _min(m: Any, a: Any, b: Any) -> Any:
    return m.if_else(m.lt(a, b), a, b)


def hip_target(geo: Geometry, like: Multivector, leg: Leg, target: Sequence[Any]) -> list[Any]:
    """A body-frame position in the leg's hip frame: M~ P M with M the mount."""
    return geo.location((~mount(geo, like, leg)).sandwich(geo.point(like, list(target))))


def _bounded(m: Any, target: Sequence[Any]) -> tuple[list[Any], Any]:
    """(target, ok): the target where its coordinates' magnitudes sum to less than MAX_TARGET, else the
    origin, and the condition ok that it is kept. Every comparison with a NaN is false, and a sum past
    the largest double is inf, so NaN, inf and huge targets are replaced: no square can overflow."""
    ok = m.lt(sum((m.fabs(t) for t in target), start=0.0), MAX_TARGET)
    return [m.if_else(ok, t, 0.0) for t in target], ok


def _half_turn(m: Any, v: Any) -> Any:
    """An angle within ±2π (a sum or difference of two atan2) turned into [−π, π]."""
    v = m.if_else(m.lt(math.pi, v), v - 2 * math.pi, v)
    return m.if_else(m.lt(v, -math.pi), v + 2 * math.pi, v)


def _into_limits(m: Any, v: Any, limits: tuple[float, float]) -> tuple[Any, Any]:
    """(angle, violation) of an angle ``v`` within [−π, π]: ``v`` itself where it is within [lo, hi];
    else v ± 2π where that is within them; else ``v``, with its distance (rad) from the limits."""
    lo, hi = limits
    if -math.pi <= lo and hi <= math.pi:  # no other turn of v can be within them: the cheap case
        return v, _max0(m, lo - v) + _max0(m, v - hi)
    turn = 2 * math.pi
    shift = turn * math.floor((lo + math.pi) / turn)  # lo − shift ∈ [−π, π): w − lo ∈ (−2π, 2π)
    w = v + shift if shift else v
    w = m.if_else(m.lt(w, lo), w + turn, w)
    w = m.if_else(m.lt(w - turn, lo), w, w - turn)  # the turn of v in [lo, lo + 2π)
    if hi - lo >= turn:  # w is within the limits
        return m.if_else(m.lt(v, lo), w, m.if_else(m.lt(hi, v), w, v)), 0.0
    over = m.lt(hi, w)
    turned = m.if_else(over, v, w)
    angle = m.if_else(m.lt(v, lo), turned, m.if_else(m.lt(hi, v), turned, v))
    return angle, m.if_else(over, _min(m, w - hi, lo + turn - w), 0.0)


def _within(m: Any, leg: Leg, q: Sequence[Any]) -> tuple[list[Any], Any]:
    """The joint angles moved into the limits where a turn does it, and their total violation."""
    moved = [_into_limits(m, v, limits) for v, limits in zip(q, leg.limits, strict=True)]
    return [a for a, _ in moved], sum((b for _, b in moved), start=0.0)


def analytic_ik(geo: Geometry, like: Multivector, leg: Leg, target: Sequence[Any]) -> dict[str, Any]:
    """Joint angles reaching ``target`` (body frame) with the knee up and down, the flag ``reach``
    (1 reachable, 0 clamped to the nearest pose) and ``excess`` (m from the target to the nearest toe).

    The hip yaw turns the thigh joint towards the target's heading (atan2) or away from it (+π): with
    the toe behind the yaw axis only the second may be within the limits, and with l2 ≠ l3 only the
    second may reach (the first can leave the target inside the annulus's hole |l2 − l3|). Per knee
    branch the yaw branch nearer the target wins; where both reach it (to BRANCH_TOLERANCE), the one
    nearer the joint limits (each angle within [−π, π], or turned by 2π into limits outside those). A
    target farther than MAX_TARGET (|x| + |y| + |z|; inf, NaN) is replaced by the body origin: finite
    angles, ``reach`` 0, ``excess`` MAX_TARGET."""
    s1, s2, s3 = planar_signs(leg)
    m = like.math
    l1, l2, l3 = (_constant(like, v) for v in leg.lengths)
    bounded, ok = _bounded(m, target)
    x, y, z = hip_target(geo, like, leg, bounded)
    heading = m.atan2(y, x)
    r = m.sqrt(x * x + y * y)
    b = -z  # downwards: a positive thigh pitch about +y swings the leg down
    outer, inner = (l2 + l3) ** 2, (l2 - l3) ** 2
    two_l2l3 = 2 * l2 * l3
    branches = []
    # the yaw towards the heading (the thigh joint at l1 along it) and away from it (at −l1)
    for yaw, rho in ((heading, r - l1), (m.if_else(m.lt(0, heading), heading - math.pi, heading + math.pi),
                                         -r - l1)):
        d2 = rho * rho + b * b
        cos3 = (d2 - l2 * l2 - l3 * l3) / two_l2l3
        sin3 = m.sqrt(_max0(m, (outer - d2) * (d2 - inner))) / two_l2l3
        towards = m.atan2(b, rho)
        d = m.sqrt(d2)
        excess = _max0(m, m.if_else(m.lt(d2, inner), m.fabs(l2 - l3) - d, d - (l2 + l3)))
        # knee down mirrors knee up about the line to the target: atan2 is odd in y (exactly, in IEEE
        # arithmetic), so both knees share two atan2 calls
        knee = m.atan2(sin3, cos3)
        bend = m.atan2(l3 * sin3, l2 + l3 * cos3)  # the thigh's angle below the line to the target
        up = _within(m, leg, [s1 * yaw, s2 * _half_turn(m, towards - bend), s3 * knee])
        down = _within(m, leg, [s1 * yaw, s2 * _half_turn(m, towards + bend), -s3 * knee])
        branches.append((excess, up, down))
    (near, up_a, down_a), (far, up_b, down_b) = branches

    def pick(a: tuple[list[Any], Any], b: tuple[list[Any], Any]) -> list[Any]:
        # 1 where the away branch wins: nearer the target, or as near and nearer the limits
        nearer_limits = m.if_else(m.lt(b[1], a[1]), 1.0, 0.0)
        away = m.if_else(m.lt(far + BRANCH_TOLERANCE, near), 1.0,
                         m.if_else(m.lt(near + BRANCH_TOLERANCE, far), 0.0, nearer_limits))
        return [m.if_else(m.lt(0.5, away), qb, qa) for qa, qb in zip(a[0], b[0], strict=True)]

    excess = m.if_else(ok, _min(m, near, far), MAX_TARGET)
    size = 1 + max(abs(float(v)) for v in leg.xyz) + sum(float(v) for v in leg.lengths)
    reach = m.if_else(m.lt(REACH_TOLERANCE * size, excess), 0.0, 1.0)
    return {"q_up": pick(up_a, up_b), "q_down": pick(down_a, down_b), "reach": reach, "excess": excess}


# -- numerical IK -------------------------------------------------------------------------------------

def dls_step(geo: Geometry, like: Multivector, leg: Leg, q: Sequence[Any], target: Sequence[Any],
             damping: Any) -> dict[str, Any]:
    """One damped least-squares step: q + Jᵀ (J Jᵀ + λ² I)⁻¹ (target − p), in closed form (the 3×3
    system by its adjugate; λ > 0 keeps it invertible), and the error |target − p| before it."""
    m = like.math
    kin = leg_kinematics(geo, like, leg, q)
    p, cols = kin["p"], kin["J"]  # cols[j] = ∂p/∂q_j
    e = [t - pi for t, pi in zip(target, p, strict=True)]
    a = [[sum(cols[k][i] * cols[k][j] for k in range(3)) + (damping * damping if i == j else 0)
          for j in range(3)] for i in range(3)]
    adj = [[a[(j + 1) % 3][(i + 1) % 3] * a[(j + 2) % 3][(i + 2) % 3]
            - a[(j + 1) % 3][(i + 2) % 3] * a[(j + 2) % 3][(i + 1) % 3] for j in range(3)] for i in range(3)]
    det = sum(a[0][k] * adj[k][0] for k in range(3))
    w = [sum(adj[i][j] * e[j] for j in range(3)) / det for i in range(3)]
    step = [dot(cols[j], w) for j in range(3)]
    return {"q_next": [qj + sj for qj, sj in zip(q, step, strict=True)], "error": m.sqrt(dot(e, e))}
