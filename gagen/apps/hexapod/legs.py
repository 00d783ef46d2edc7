"""A hexapod leg's kinematics as formulas over either algebra [HEX 5-7], [MATH §8].

Forward kinematics is the product of exponentials M(q) = S1(q1) S2(q2) S3(q3) M_home in the body
frame: S_j = e^{−q_j L_j/2} turns about the joint line L_j (the hip-frame line through c_j along u_j,
carried to the body by the mount motor), and M_home places the toe frame at (l1 + l2 + l3, 0, 0) of
the hip frame. (The paper's listing ends with Translator(l3) alone, which puts the toe at (l3, 0, 0):
MATH §8.) The toe is P = M O M~ with O the origin point.

The Jacobian columns are read from the joint lines at q, L_j(q) = (S1…S_{j−1}) L_j (S1…S_{j−1})~: their
twists (v_j, ω_j) are the spatial Jacobian's columns (Pinocchio's order: linear, then angular), and
the toe's linear velocity per joint is v_j + ω_j × p = u_j × (p − c_j) [HEX Eq. 6.1].

The analytic IK [HEX 7.1] solves hip yaw by atan2 in the hip frame, then the planar two-link problem of
thigh and knee with the l1 offset removed, by the cosine law in a form that stays accurate at full
stretch: sin φ3 = √(((l2+l3)² − d²)(d² − (l2−l3)²)) / (2 l2 l3). A target outside the annulus
|l2 − l3| ≤ d ≤ l2 + l3 gives the nearest pose (the leg stretched or folded towards it) with the flag
``reach`` = 0 and the distance outside in ``excess``; no branch of it can give a NaN. It needs the
planar structure (yaw about ±z, thigh and knee about ±y of the hip frame): a leg without it raises
:class:`AnalyticIKError` and has only the numerical IK (damped least squares on the Jacobian).
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

REACH_TOLERANCE = 1e-9  # m: a target this far outside the annulus still counts as reachable
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


def hip_target(geo: Geometry, like: Multivector, leg: Leg, target: Sequence[Any]) -> list[Any]:
    """A body-frame position in the leg's hip frame: M~ P M with M the mount."""
    return geo.location((~mount(geo, like, leg)).sandwich(geo.point(like, list(target))))


def analytic_ik(geo: Geometry, like: Multivector, leg: Leg, target: Sequence[Any]) -> dict[str, Any]:
    """Joint angles reaching ``target`` (body frame) with the knee up and down, the flag ``reach``
    (1 reachable, 0 clamped to the nearest pose) and ``excess`` (m outside the annulus)."""
    s1, s2, s3 = planar_signs(leg)
    m = like.math
    l1, l2, l3 = (_constant(like, v) for v in leg.lengths)
    x, y, z = hip_target(geo, like, leg, target)
    yaw = m.atan2(y, x)
    rho = m.sqrt(x * x + y * y) - l1  # along the leg from the thigh joint
    b = -z  # downwards: a positive thigh pitch about +y swings the leg down
    d2 = rho * rho + b * b
    outer, inner = (l2 + l3) ** 2, (l2 - l3) ** 2
    two_l2l3 = 2 * l2 * l3
    cos3 = (d2 - l2 * l2 - l3 * l3) / two_l2l3
    sin3 = m.sqrt(_max0(m, (outer - d2) * (d2 - inner))) / two_l2l3
    towards = m.atan2(b, rho)
    d = m.sqrt(d2)
    excess = _max0(m, m.if_else(m.lt(d2, inner), m.fabs(l2 - l3) - d,
                               d - (l2 + l3)))
    # knee down mirrors knee up about the line to the target: atan2 is odd in y (exactly, in IEEE
    # arithmetic), so both branches share two atan2 calls
    knee = m.atan2(sin3, cos3)
    bend = m.atan2(l3 * sin3, l2 + l3 * cos3)  # the thigh's angle below the line to the target
    reach = m.if_else(m.lt(REACH_TOLERANCE, excess), 0.0, 1.0)
    return {"q_up": [s1 * yaw, s2 * (towards - bend), s3 * knee],
            "q_down": [s1 * yaw, s2 * (towards + bend), -s3 * knee], "reach": reach, "excess": excess}


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
