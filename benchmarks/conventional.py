"""The reaching task written the way a CasADi user writes it by hand: the honest OCP baseline.

gagen's ``task`` kernel gives e(q) = log(V_Sc(q)~ V_Sd) from CGA formulas flattened into one SX graph.
A user without gagen writes the same error with a URDF kinematics library and 3-vector algebra:

- forward kinematics from the URDF by adam-robotics (``adam.casadi.KinDynComputations``, CasADi SX),
  the chain's base placement from the system spec (``robots/<system>.yaml``), the end point the tip
  frame's origin (plus R_tip·tool.xyz where the spec names a tool); joints shared by chains of one
  robot (a humanoid's waist) are one column of q;
- the similarity S(x) = s R(q) x + t taking the unit primitive onto the primitive of the end points
  ([COOP Eq. 21, 26, 28]: gagen's canonical V_S = V_T V_R V_D), as (t, unit quaternion q, s):
  circle: circumcentre c, radius r, the shortest-arc quaternion turning e3 onto the unit normal along
  (p2 − p1) × (p3 − p1): (c, q, r); sphere: circumcentre and radius, no rotation; line (through p1
  along p2 − p1; the unit line runs through 0 along e1): the screw along the two lines' common
  perpendicular, i.e. the shortest-arc turn of e1 onto the direction about the perpendicular through
  the closest points a_u (on the unit line) and a (on the line): t = a − R a_u; plane (unit plane
  z = 0, normal e3; the plane n·x = δ, n along (p2 − p1) × (p3 − p1)): the turn of e3 onto n about the
  planes' intersection line, t = δ (n + e3)/(1 + n3);
- the error of the current similarity S_c against the desired one S_d: the relative similarity
  S_c⁻¹ S_d is x ↦ (s_d/s_c) q̄_c q_d x + q̄_c (t_d − t_c)/s_c (q̄ the conjugate), and its log in gagen's
  chart [COOP Eq. 77] is (rotation vector ω of q̄_c ⊗ q_d, −ln(s_d/s_c), translation), laid out on
  gagen's rows e12 e13 e23 e0∞ e1∞ e2∞ e3∞ as (ω3, −ω2, ω1, ln(s_c/s_d), t1, t2, t3): the rotor of angle
  θ about n is θ(n3 e12 − n2 e13 + n1 e23) and λ e0∞ scales by e^{−λ}.

The target is the desired similarity (t_d, q_d, s_d), passed in the parameter vector that gagen's NLP
reserves for V_Sd (12 slots: ``pack``, the last four unused), so that
``gagen.control.ocp.ReachingOCP`` runs the identical NLP on either ``task`` Function.

Written for generic configurations, as a user would: no guards at the degenerate ones that gagen guards
(a circle's normal or a plane's normal opposite to e3, a line parallel to e1, coincident or collinear
points), where this baseline divides by zero.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

ROOT = Path(__file__).resolve().parents[1]
ROBOTS = ROOT / "robots"
TARGET_SLOTS = 12  # gagen's V_Sd parameter; the conventional target (t, q, s) uses the first 8
ROTVEC_SERIES_BELOW = 1e-10  # |v|² below this: atan2(|v|, w)/|v| by its series (smooth at the identity)
POINTS = {"line": 2, "circle": 3, "plane": 3, "sphere": 4}


@dataclass(frozen=True)
class ChainFK:
    """One chain: its joints' columns in the system's q, and its end point as a CasADi Function."""

    name: str
    columns: list[int]
    point: ca.Function


def _rpy_matrix(rpy: ArrayLike) -> NDArray[np.float64]:
    """URDF convention: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = (float(a) for a in rpy)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _placement(entry: dict[str, Any] | None) -> NDArray[np.float64]:
    H = np.eye(4)
    if entry:
        H[:3, :3] = _rpy_matrix(entry.get("rpy", (0.0, 0.0, 0.0)))
        H[:3, 3] = entry.get("xyz", (0.0, 0.0, 0.0))
    return H


def chains(system: str, joints: list[str]) -> list[ChainFK]:
    """The spec's chains with adam's CasADi FK. ``joints``: the system's q rows (``robot/joint``, as in
    gagen's manifest, the robot label being the chain's name unless the spec names a shared robot)."""
    from adam.casadi import KinDynComputations

    spec = yaml.safe_load((ROBOTS / f"{system}.yaml").read_text())
    out = []
    for chain in spec["chains"]:
        prefix = f"{chain.get('robot', chain['name'])}/"
        columns = [i for i, j in enumerate(joints) if j.startswith(prefix)]
        names = [joints[i][len(prefix):] for i in columns]  # every joint of the robot: adam fixes the rest
        kd = KinDynComputations(str(ROBOTS / chain["urdf"]), names)
        # adam's FK starts at the URDF's root link; every bundled chain's base_link is that root
        if kd.rbdalgos.model.tree.root != chain["base_link"]:
            raise ValueError(f"{system}: {chain['name']} starts at {chain['base_link']}, not the URDF root")
        fk = kd.forward_kinematics_fun(chain["tip_link"])
        s = ca.SX.sym("s", len(names))
        H = ca.DM(_placement(chain.get("base"))) @ fk(ca.DM.eye(4), s)
        tool = np.asarray((chain.get("tool") or {}).get("xyz", (0.0, 0.0, 0.0)), dtype=float)
        p = H[:3, 3] + H[:3, :3] @ ca.DM(tool)
        out.append(ChainFK(chain["name"], columns, ca.Function(f"{chain['name']}_point", [s], [p])))
    return out


def points_function(system: str, joints: list[str]) -> ca.Function:
    """q -> the chains' end points (one 3-vector output per chain), by adam's FK."""
    q = ca.SX.sym("q", len(joints))
    points = [fk.point(ca.vertcat(*[q[i] for i in fk.columns])) for fk in chains(system, joints)]
    return ca.Function(f"{system}_points", [q], points)


# -- quaternions (w, x, y, z) ------------------------------------------------------------------------------
def quat_between(a: Any, b: Any) -> Any:
    """The shortest-arc unit quaternion turning the unit vector a onto the unit vector b (b ≠ −a)."""
    return ca.vertcat(1 + ca.dot(a, b), ca.cross(a, b)) / ca.sqrt(2 * (1 + ca.dot(a, b)))


def quat_mul(p: Any, q: Any) -> Any:
    pw, pv, qw, qv = p[0], p[1:], q[0], q[1:]
    return ca.vertcat(pw * qw - ca.dot(pv, qv), pw * qv + qw * pv + ca.cross(pv, qv))


def quat_conj(q: Any) -> Any:
    return ca.vertcat(q[0], -q[1:])


def quat_rotate(q: Any, v: Any) -> Any:
    """q v q̄ for a unit quaternion q."""
    w, u = q[0], q[1:]
    return v + 2 * w * ca.cross(u, v) + 2 * ca.cross(u, ca.cross(u, v))


def quat_log(q: Any) -> Any:
    """Rotation vector 2 atan2(|v|, w) v/|v| of a unit quaternion (series near the identity)."""
    w, v = q[0], q[1:]
    s2 = ca.dot(v, v)
    small = s2 < ROTVEC_SERIES_BELOW
    z2 = s2 / (w * w)
    series = (1 - z2 / 3 + z2 * z2 / 5) / w
    s = ca.sqrt(ca.if_else(small, 1.0, s2))
    return 2 * ca.if_else(small, series, ca.atan2(s, w) / s) * v


# -- the primitive's similarity (t, q, s) from its points ---------------------------------------------------
E1, E3 = ca.DM([1.0, 0.0, 0.0]), ca.DM([0.0, 0.0, 1.0])
IDENTITY = ca.DM([1.0, 0.0, 0.0, 0.0])


def circumcircle(p1: Any, p2: Any, p3: Any) -> tuple[Any, Any, Any]:
    """(centre, unit normal along (p2 − p1) × (p3 − p1), radius) of the circle through three points."""
    a, b = p2 - p1, p3 - p1
    n = ca.cross(a, b)
    n2 = ca.dot(n, n)
    c = p1 + ca.cross(ca.dot(a, a) * b - ca.dot(b, b) * a, n) / (2 * n2)
    return c, n / ca.sqrt(n2), ca.norm_2(c - p1)


def circumsphere(p1: Any, p2: Any, p3: Any, p4: Any) -> tuple[Any, Any]:
    """(centre, radius) of the sphere through four points: Cramer's rule on
    2(p_i − p1)·(c − p1) = |p_i − p1|²."""
    a, b, d = p2 - p1, p3 - p1, p4 - p1
    c = p1 + (ca.dot(a, a) * ca.cross(b, d) + ca.dot(b, b) * ca.cross(d, a) + ca.dot(d, d) * ca.cross(a, b)) \
        / (2 * ca.dot(a, ca.cross(b, d)))
    return c, ca.norm_2(c - p1)


def similarity(kind: str, points: list[Any]) -> tuple[Any, Any, Any]:
    """(t, q, s) of S(x) = s R(q) x + t taking the unit primitive onto the one through the points."""
    if kind == "circle":
        c, n, r = circumcircle(*points)
        return c, quat_between(E3, n), r
    if kind == "sphere":
        c, r = circumsphere(*points)
        return c, IDENTITY, r
    if kind == "line":  # unit line: through 0 along e1; line: through p1 along d
        p1, p2 = points
        d = (p2 - p1) / ca.norm_2(p2 - p1)
        b, e, f = d[0], d.T @ -p1, -p1[0]  # closest points s e1 and p1 + u d of the two lines
        s = (b * e - f) / (1 - b * b)
        u = (e - b * f) / (1 - b * b)
        q = quat_between(E1, d)
        return p1 + u * d - quat_rotate(q, s * E1), q, 1
    if kind == "plane":  # unit plane z = 0; plane n·x = δ; turned about their intersection line
        p1, p2, p3 = points
        n = ca.cross(p2 - p1, p3 - p1)
        n = n / ca.norm_2(n)
        # t = (I − R) a for a on the intersection line is δ (n + e3)/(1 + n3): in the plane of e3 and n,
        # with n·t = δ (no 1/(1 − n3²) of a itself, so nothing cancels near parallel planes)
        return ca.dot(n, p1) * (n + E3) / (1 + n[2]), quat_between(E3, n), 1
    raise ValueError(f"no conventional formulation for a {kind}")


def similarity_error(current: tuple[Any, Any, Any], desired: tuple[Any, Any, Any]) -> Any:
    """e = log(S_c⁻¹ S_d) on gagen's rows e12 e13 e23 e0∞ e1∞ e2∞ e3∞ (see the module docstring)."""
    (t_c, q_c, s_c), (t_d, q_d, s_d) = current, desired
    w = quat_log(quat_mul(quat_conj(q_c), q_d))
    t = quat_rotate(quat_conj(q_c), t_d - t_c) / s_c
    return ca.vertcat(w[2], -w[1], w[0], ca.log(s_c / s_d), t)


def pack(t: ArrayLike, q: ArrayLike, s: float) -> NDArray[np.float64]:
    """The target similarity in the 12 parameter slots: t, unit quaternion q, scale s, zeros."""
    out = np.zeros(TARGET_SLOTS)
    out[:3], out[3:7], out[7] = np.ravel(t), np.ravel(q), float(s)
    return out


def unpack(target: Any) -> tuple[Any, Any, Any]:
    return target[:3], target[3:7], target[7]


# -- the task Function and its targets ----------------------------------------------------------------------
def task(system: str, kind: str, joints: list[str]) -> ca.Function:
    """task(q, target) -> e: the conventional terminal error (target: ``pack``-ed, see ``target_at``)."""
    points = points_function(system, joints)
    if points.n_out() != POINTS[kind]:
        raise ValueError(f"{system}: a {kind} is spanned by {POINTS[kind]} chains, got {points.n_out()}")
    q, target = ca.SX.sym("q", len(joints)), ca.SX.sym("target", TARGET_SLOTS)
    e = similarity_error(similarity(kind, points(q)), unpack(target))
    return ca.Function("task_conventional", [q, target], [e], ["q", "V_Sd"], ["e"])


def target_of(kind: str, points: list[ArrayLike]) -> NDArray[np.float64]:
    """The packed target similarity of the primitive through the given (numeric) points."""
    t, q, s = similarity(kind, [ca.DM(np.asarray(p, dtype=float)) for p in points])
    return pack(np.array(ca.DM(t)), np.array(ca.DM(q)), float(ca.DM(s)))


def moved(kind: str, points: list[ArrayLike], translation: ArrayLike = (0.0, 0.0, 0.0),
          rotation: tuple[ArrayLike, float] | None = None, dilation: float = 1.0) -> NDArray[np.float64]:
    """The packed target of the primitive through ``points`` moved as ``gagen.control.ocp.target_from``
    moves it: dilated about its reference point c = S(0) (the centre of a round; dilation leaves a flat
    as it is), turned by (world axis, angle) about the axis through c, then translated."""
    c = target_of(kind, points)[:3]
    R = np.eye(3)
    if rotation is not None:
        axis, angle = rotation
        k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        R = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K  # Rodrigues
    shift = c + np.asarray(translation, dtype=float)
    return target_of(kind, [shift + dilation * R @ (np.asarray(p, dtype=float) - c) for p in points])


def target_at(points: ca.Function, kind: str, q: ArrayLike) -> NDArray[np.float64]:
    """The packed target of the primitive at configuration q (``points``: from ``points_function``)."""
    return target_of(kind, [np.array(p).ravel() for p in points(q)])
