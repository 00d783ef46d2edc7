"""Stating a goal: the desired similarity V_Sd of a cooperative task from a desired primitive.

Every control entry point (``solve_ik``, ``reach``, the ``task`` kernel) takes V_Sd, the 12
coefficients of the similarity versor that moves the unit primitive X_u onto the desired primitive
X_d, in the ``V_Sd`` row order of the ``task`` kernel (``SIMILARITY``). This module builds it from
what a user knows about X_d:

    from gagen.control import goals
    V_Sd = goals.circle(centre=[0.6, 0.0, 0.5], radius=0.25, normal=[0, 0, 1])
    V_Sd = goals.line(point=[0.5, 0, 0.4], direction=[0, 1, 0])
    V_Sd = goals.plane(point=[0.3, 0, 0.2], normal=[0, 0, 1])
    V_Sd = goals.sphere(centre=[0.5, 0, 0.5], radius=0.1)
    V_Sd = goals.point_pair([0.4, -0.2, 0.3], [0.4, 0.2, 0.3])
    V_Sd = goals.point([0.5, 0.1, 0.4])
    V_Sd = goals.through("circle", [p1, p2, p3])     # any kind, from its spanning points

V_Sd is the canonical V_S(X_u, X_d) that the ``similarity`` kernel builds for X_c [COOP Eq. 28], so
the task error e(q) = log(V_Sc(q)~ V_Sd) is exactly 0 when X_c(q) is X_d up to a positive scale.

Orientation follows the unit primitives (README, Conventions): a circle's points run
counter-clockwise about its normal, a plane's normal is (p2 − p1) × (p3 − p1), a line runs from its
first point to its second, a point pair from P(−e1) to P(e1). A goal whose similarity from X_u is
degenerate (coincident, collinear or coplanar spanning points, a zero radius or direction) or whose
versor does not reproduce X_d to 1e-9 is refused with a ``ValueError`` saying why,
never returned as a NaN.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.algebra.signature import cga3d
from gagen.interp import MultiVector
from gagen.model.conformal import SIMILARITY
from gagen.model.conformal import point as conformal_point
from gagen.model.conformal import vector as conformal_vector
from gagen.model.primitives import points_needed, unit_primitive
from gagen.model.primitives import through as primitive_through
from gagen.model.similarity import similarity
from gagen.robots.goals import PRIMITIVE_PARAMETERS, Goal

__all__ = ["circle", "line", "plane", "point", "point_pair", "primitive", "sphere", "through"]

# spanning points this close to degenerate (relative: see _shape) are refused, and so are coordinates
# beyond MAX_COORDINATE metres (the conformal e∞ part grows with |x|²)
MIN_SHAPE = 1e-9
MAX_COORDINATE = 1e6


def _position(value: ArrayLike, what: str) -> NDArray[np.float64]:
    array = np.asarray(value, dtype=float)
    if array.shape != (3,):
        raise ValueError(f"{what}: expected 3 coordinates (x, y, z), got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{what}: expected finite coordinates, got {array.tolist()}")
    return array


def _direction(value: ArrayLike, what: str) -> NDArray[np.float64]:
    array = _position(value, what)
    norm = float(np.linalg.norm(array))
    if norm < 1e-12:
        raise ValueError(f"{what}: expected a non-zero direction, got {array.tolist()}")
    return array / norm


def _frame(normal: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Unit u, v with u × v = normal (unit): the plane's in-plane axes, right-handed about it."""
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    u = np.cross(helper, normal)
    u /= np.linalg.norm(u)
    return u, np.cross(normal, u)


def through(kind: str, points: Sequence[ArrayLike]) -> NDArray[np.float64]:
    """V_Sd for the primitive of ``kind`` through ``points`` (3-vectors, as many as the kind needs:
    1 point, 2 point pair, 2 line, 3 circle, 3 plane, 4 sphere), in the ``V_Sd`` row order."""
    count = points_needed(kind)  # raises for an unknown kind, naming the known ones
    if len(points) != count:
        raise ValueError(f"a {kind} is spanned by {count} points, got {len(points)}")
    xyz = [_position(p, f"{kind} point {i}") for i, p in enumerate(points)]
    if max(float(np.abs(p).max()) for p in xyz) > MAX_COORDINATE:
        raise ValueError(f"{kind} goal: coordinates beyond {MAX_COORDINATE:g} m: {[p.tolist() for p in xyz]}")
    if _shape(xyz) <= MIN_SHAPE:
        raise ValueError(f"degenerate {kind} goal: {_why(kind)}; points {[p.tolist() for p in xyz]}")
    zero = MultiVector.zero(cga3d())
    # the model's functions keep the kind of multivector they are given (an interpreter one here)
    x_d = cast(MultiVector, primitive_through(kind, [conformal_point(conformal_vector(zero, list(p)))
                                                     for p in xyz]))
    versor, _ = similarity(kind, unit_primitive(kind, zero), x_d)
    coefficients = np.array([versor[b] for b in SIMILARITY])
    # the versor must move X_u onto X_d with a positive scale; Eq. 21 cannot for a flat exactly
    # opposite to X_u (and loses accuracy close to it)
    moved = versor.sandwich(unit_primitive(kind, zero)).coeffs
    scale = float(moved @ x_d.coeffs) / float(x_d.coeffs @ x_d.coeffs)
    if not (np.all(np.isfinite(coefficients)) and scale > 0
            and np.linalg.norm(moved - scale * x_d.coeffs) <= 1e-9 * np.linalg.norm(moved)):
        flat = kind in ("line", "plane")
        raise ValueError(f"{kind} goal: its similarity from the unit {kind} does not reproduce it to 1e-9"
                         + (" (a flat within about 1e-3 rad of the unit flat's opposite orientation: Eq. 21 "
                            "loses eps/K0 there; give the points in the other order)" if flat else "")
                         + f"; points {[p.tolist() for p in xyz]}")
    return coefficients


def _shape(xyz: list[NDArray[np.float64]]) -> float:
    """How far the spanning points are from degenerate, scale-free: 1 for a well-spread set, 0 for
    coincident (pair, line), collinear (circle, plane) or coplanar (sphere) points."""
    if len(xyz) == 1:
        return 1.0
    edges = [p - xyz[0] for p in xyz[1:]]
    spread = max(float(np.linalg.norm(e)) for e in edges)
    if spread == 0.0:
        return 0.0
    edges = [e / spread for e in edges]
    if len(edges) == 1:
        return spread / max(1.0, float(np.linalg.norm(xyz[0])))
    if len(edges) == 2:
        return float(np.linalg.norm(np.cross(edges[0], edges[1])))
    return abs(float(np.linalg.det(np.array(edges))))


def _why(kind: str) -> str:
    return {"point_pair": "the two points coincide",
            "line": "the two points coincide",
            "circle": "the three points are collinear or coincide",
            "plane": "the three points are collinear or coincide",
            "sphere": "the four points are coplanar or coincide"}.get(kind, "")


def point(position: ArrayLike) -> NDArray[np.float64]:
    """V_Sd for the point at ``position``: a pure translation."""
    return through("point", [position])


def point_pair(first: ArrayLike, second: ArrayLike) -> NDArray[np.float64]:
    """V_Sd for the point pair from ``first`` to ``second``."""
    return through("point_pair", [first, second])


def line(point: ArrayLike, direction: ArrayLike) -> NDArray[np.float64]:
    """V_Sd for the line through ``point`` along ``direction`` (oriented)."""
    p, d = _position(point, "line point"), _direction(direction, "line direction")
    return through("line", [p, p + d])


def plane(point: ArrayLike, normal: ArrayLike) -> NDArray[np.float64]:
    """V_Sd for the plane through ``point`` with unit normal along ``normal`` (oriented)."""
    p, n = _position(point, "plane point"), _direction(normal, "plane normal")
    u, v = _frame(n)
    return through("plane", [p, p + u, p + v])


def _radius(radius: float, kind: str) -> float:
    r = float(radius)
    if not np.isfinite(r) or r <= 0:
        raise ValueError(f"{kind} radius: expected a positive finite number, got {radius!r}")
    return r


def circle(centre: ArrayLike, radius: float, normal: ArrayLike) -> NDArray[np.float64]:
    """V_Sd for the circle of ``radius`` about ``centre`` in the plane with normal ``normal``
    (oriented counter-clockwise about it, as the unit circle about +e3)."""
    c, n = _position(centre, "circle centre"), _direction(normal, "circle normal")
    r = _radius(radius, "circle")
    u, v = _frame(n)
    return through("circle", [c + r * u, c + r * v, c - r * u])


def sphere(centre: ArrayLike, radius: float) -> NDArray[np.float64]:
    """V_Sd for the sphere of ``radius`` about ``centre`` (the unit sphere's orientation)."""
    c, r = _position(centre, "sphere centre"), _radius(radius, "sphere")
    e = np.eye(3)
    return through("sphere", [c + r * e[0], c + r * e[1], c - r * e[0], c + r * e[2]])


def primitive(kind: str, V_Sd: ArrayLike) -> MultiVector:
    """X_d = V_Sd X_u V_Sd~: the primitive a goal stands for (an interpreter multivector; index it
    by blade name, e.g. ``X["e12inf"]``), to compare with the ``primitive`` kernel's X_c."""
    values = np.asarray(V_Sd, dtype=float).ravel()
    if values.shape != (len(SIMILARITY),):
        raise ValueError(f"V_Sd: expected {len(SIMILARITY)} coefficients, got shape {values.shape}")
    v = MultiVector.from_blades(cga3d(), dict(zip(SIMILARITY, values, strict=True)))
    return v.sandwich(cast(MultiVector, unit_primitive(kind, v)))  # (an interpreter one, as v)


def desired(goal: Goal, V_Sc0: ArrayLike, kind: str) -> NDArray[np.float64]:
    """V_Sd of a spec's goal (``gagen.robots.goals``) for a system spanning a ``kind``: a ``move`` of the
    primitive of V_Sc0 (its similarity at the start, e.g. the ``ready`` configuration; see
    ``gagen.control.ocp.target_from``), or the stated primitive through this module's constructors. A
    ValueError when the goal's primitive is not the system's kind, or degenerate."""
    if goal.is_move:
        from gagen.control.ocp import target_from

        return target_from(V_Sc0, goal.translation, goal.rotation, goal.dilation, kind=kind)
    if goal.kind != kind:
        raise ValueError(f"goal {goal.name!r} is a {goal.kind}; the system spans a {kind}")
    makers: dict[str, Callable[..., NDArray[np.float64]]] = {
        "point": point, "point_pair": point_pair, "line": line, "circle": circle, "plane": plane,
        "sphere": sphere}
    return makers[kind](*(goal.parameters[name] for name in PRIMITIVE_PARAMETERS[kind]))
