"""What the viewer draws, in plain numpy: the chains' joint frames and the primitive through their end points.

A robot's stick figure (and, where its URDF has no visuals, the robot) is drawn from its kinematic
chain (``gagen.viewer.visuals`` places the URDF's meshes and shapes): the origin of every joint frame
along it (the base placement first, the chain's end point last). Each frame is the URDF
composition T ← T · T(xyz) Rz(yaw) Ry(pitch) Rx(roll), then the joint's motion (a rotation about its
axis or a translation along it) — the same convention as ``gagen.model.kinematics``, computed here with
4 × 4 matrices so that drawing needs no algebra (the tests hold the end points to the generated FK).

The primitive is drawn from its spanning end points [COOP Table 1]: a point; a point pair; the line
through two points; the circle through three (circumcentre, radius, normal (x2 − x1) × (x3 − x1)); the
plane through three; the sphere through four (circumsphere). Points that do not span the primitive
(collinear for a circle, coplanar for a sphere, coincident for a line) give a ``Shape`` with
``degenerate`` set, drawn as the polyline through the points.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.model.kinematics import Joint
from gagen.robots.system import System

TOLERANCE = 1e-9  # relative: below it, points are taken as not spanning their primitive
Array = NDArray[np.float64]


# -- chains --------------------------------------------------------------------------------------------
def rotation(axis: Sequence[float], angle: float) -> Array:
    """Rotation matrix by ``angle`` about the unit ``axis`` (Rodrigues)."""
    x, y, z = axis
    k: Array = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def rpy_matrix(rpy: Sequence[float]) -> Array:
    """URDF rpy: Rz(yaw) Ry(pitch) Rx(roll)."""
    roll, pitch, yaw = rpy
    return rotation((0, 0, 1), yaw) @ rotation((0, 1, 0), pitch) @ rotation((1, 0, 0), roll)


def _transform(r: Array, t: ArrayLike) -> Array:
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = r, t
    return m


@dataclass(frozen=True)
class ChainPose:
    """One chain at one configuration: ``frames`` (k + 1, 4, 4) are the frame of each of its k joints
    (after the joint's fixed transform, before its motion: its origin lies on the joint axis) and, last,
    the end frame (after every joint: its origin is the chain's end point); ``moving`` (k,) marks the
    moving joints."""

    name: str
    frames: Array
    moving: tuple[bool, ...]

    @property
    def origins(self) -> Array:
        """(k + 1, 3): every joint origin along the chain, then the end point."""
        return self.frames[:, :3, 3]

    @property
    def end_point(self) -> Array:
        return self.frames[-1, :3, 3]


def chain_frames(joints: Sequence[Joint], values: Sequence[float]) -> Array:
    """(k + 1, 4, 4): see :class:`ChainPose`; ``values`` holds each moving joint's value in chain order
    (mimic followers included: ``Chain.joint_values``)."""
    moving = iter(values)
    frame = np.eye(4)
    frames = []
    for joint in joints:
        frame = frame @ _transform(rpy_matrix(joint.rpy), joint.xyz)
        frames.append(frame)
        if joint.moves:
            value = float(next(moving))
            if joint.kind == "prismatic":
                frame = frame @ _transform(np.eye(3), value * np.asarray(joint.axis, dtype=float))
            else:
                frame = frame @ _transform(rotation(joint.axis, value), (0.0, 0.0, 0.0))
    if next(moving, None) is not None:
        raise ValueError(f"more joint values than the chain's {sum(j.moves for j in joints)} moving joints")
    frames.append(frame)
    return np.array(frames)


def system_pose(system: System, q: ArrayLike) -> list[ChainPose]:
    """Every chain of ``system`` at q (the system's joint vector, ``System.split`` order)."""
    return [ChainPose(chain.name, chain_frames(chain.joints, values), tuple(j.moves for j in chain.joints))
            for chain, values in zip(system.chains, system.joint_values(list(np.asarray(q, dtype=float))),
                                     strict=True)]


# -- primitives ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Shape:
    """The primitive of ``kind`` through ``points`` (n, 3). Rounds: ``centre``, ``radius`` and, for a
    circle, the unit ``normal`` ((x2 − x1) × (x3 − x1) direction); a line: ``centre`` = the points' midpoint,
    ``direction`` (x2 − x1, unit); a plane: ``centre`` = the centroid, ``normal`` as for a circle. A
    point pair: ``centre`` (midpoint) and ``radius`` (half the distance)."""

    kind: str
    points: Array
    centre: Array
    radius: float = 0.0
    normal: Array | None = None
    direction: Array | None = None
    degenerate: bool = False

    @property
    def size(self) -> float:
        """A length for drawing flats: the largest distance of a point from the centre (≥ 5 cm)."""
        return max(0.05, float(np.max(np.linalg.norm(self.points - self.centre, axis=1))))


def _scale(points: Array) -> float:
    return max(1.0, float(np.max(np.abs(points))))


def circumcircle(a: Array, b: Array, c: Array) -> tuple[Array, float, Array] | None:
    """(centre, radius, unit normal) of the circle through three points; None when they are collinear."""
    u, v = b - a, c - a
    n = np.cross(u, v)
    nn = float(n @ n)
    if math.sqrt(nn) <= TOLERANCE * float(np.linalg.norm(u) * np.linalg.norm(v)):  # sin of the angle at a
        return None
    centre = a + (float(u @ u) * np.cross(v, n) + float(v @ v) * np.cross(n, u)) / (2.0 * nn)
    return centre, float(np.linalg.norm(centre - a)), n / math.sqrt(nn)


def circumsphere(points: Array) -> tuple[Array, float] | None:
    """(centre, radius) of the sphere through four points; None when they are coplanar."""
    a = points[0]
    rows = points[1:] - a  # |x − a|² = r² for the others: 2 (p_i − a)·(x − a) = |p_i − a|²
    # the volume against the edge lengths' product: scale-free, zero for coplanar points
    if abs(float(np.linalg.det(rows))) <= TOLERANCE * float(np.prod(np.linalg.norm(rows, axis=1))):
        return None
    offset = np.linalg.solve(2.0 * rows, np.einsum("ij,ij->i", rows, rows))
    return a + offset, float(np.linalg.norm(offset))


def shape(kind: str, points: Array | Sequence[Sequence[float]]) -> Shape:
    """The primitive of ``kind`` through ``points``; see :class:`Shape`."""
    p = np.asarray(points, dtype=float)
    need = {"point": 1, "point_pair": 2, "line": 2, "circle": 3, "plane": 3, "sphere": 4}
    if kind not in need:
        raise ValueError(f"unknown primitive kind {kind!r}; expected one of {', '.join(need)}")
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < need[kind] or (kind == "point_pair" and len(p) != 2):
        raise ValueError(f"a {kind} is drawn through {need[kind]} points (or fitted to more), got an array "
                         f"of shape {p.shape}")
    if len(p) > need[kind]:  # more chains than the kind needs: the best fit, drawn with every point
        spanning, conditioning = _fitted(kind, p)
        fitted = shape(kind, spanning)
        return replace(fitted, points=p, degenerate=fitted.degenerate or conditioning < TOLERANCE)
    centroid = p.mean(axis=0)
    if kind == "point":
        return Shape(kind, p, p[0])
    if kind in ("point_pair", "line"):
        d = p[1] - p[0]
        length = float(np.linalg.norm(d))
        degenerate = length <= TOLERANCE * _scale(p)
        direction = None if degenerate else d / length
        return Shape(kind, p, centroid, radius=length / 2.0, direction=direction, degenerate=degenerate)
    if kind in ("circle", "plane"):
        fit = circumcircle(*p)
        if fit is None:
            return Shape(kind, p, centroid, degenerate=True)
        centre, radius, normal = fit
        return (Shape(kind, p, centre, radius, normal) if kind == "circle"
                else Shape(kind, p, centroid, normal=normal))
    sphere = circumsphere(p)
    if sphere is None:
        return Shape(kind, p, centroid, degenerate=True)
    return Shape(kind, p, sphere[0], sphere[1])


def _fitted(kind: str, points: Array) -> tuple[Array, float]:
    """The points ``gagen.model.fitting.best_fit`` spans its fit by (projected onto it), and its
    conditioning: the same fit as the kernels', on the reference interpreter."""
    from gagen.interp import MultiVector, preset
    from gagen.model.conformal import point, vector
    from gagen.model.fitting import best_fit

    like = MultiVector.zero(preset("cga3d"))
    fit = best_fit(kind, [point(vector(like, [float(c) for c in row])) for row in points])
    return np.array(fit.spanning, dtype=float), float(fit.conditioning)


def goal_shape(kind: str, parameters: Mapping[str, Any]) -> Shape:
    """The primitive of a goal stated by its parameters (a spec's ``goals:`` entry, as
    ``gagen.robots.goals.PRIMITIVE_PARAMETERS`` names them): point ``position``; point_pair ``first``,
    ``second``; line ``point``, ``direction``; circle ``centre``, ``radius``, ``normal``; plane ``point``,
    ``normal``; sphere ``centre``, ``radius``. The Shape is made through points that span it."""
    def v(name: str) -> Array:
        return np.asarray(parameters[name], dtype=float).reshape(3)

    if kind == "point":
        return shape(kind, np.array([v("position")]))
    if kind == "point_pair":
        return shape(kind, np.array([v("first"), v("second")]))
    if kind == "line":
        d = v("direction") / np.linalg.norm(v("direction"))
        return shape(kind, np.array([v("point") - 0.1 * d, v("point") + 0.1 * d]))
    if kind in ("circle", "plane"):
        a, b = basis(v("normal"))  # (a, b, normal) right-handed: the points turn about +normal
        if kind == "plane":
            return shape(kind, np.array([v("point"), v("point") + 0.1 * a, v("point") + 0.1 * b]))
        r, c = float(parameters["radius"]), v("centre")
        return shape(kind, np.array([c + r * a, c + r * b, c - r * a]))
    if kind == "sphere":
        r, c = float(parameters["radius"]), v("centre")
        return shape(kind, np.array([c + r * e for e in (*np.eye(3), -np.eye(3)[0])]))
    raise ValueError(f"unknown primitive kind {kind!r}")


def reference_point(kind: str, points: Array) -> Array:
    """The primitive's reference point that a goal's ``move`` turns and dilates about: the image of the
    origin under the similarity V_Sc from the unit primitive to the one through ``points`` (or their best
    fit) [COOP Eq. 28]
    (the centre of a round, a point of a flat; ``gagen.control.ocp.target_from``), computed with the
    interpreter."""
    from gagen.algebra.signature import cga3d
    from gagen.interp import MultiVector
    from gagen.model.conformal import e0, location, point, vector
    from gagen.model.fitting import span
    from gagen.model.similarity import cooperative_similarity

    like = MultiVector.from_blades(cga3d(), {})
    ends = [point(vector(like, [float(c) for c in p])) for p in np.asarray(points, dtype=float)]
    x = span(kind, ends).primitive
    v = cooperative_similarity(kind, x).versor
    c = location(v.sandwich(e0(v)))
    return np.array([float(c[b]) for b in ("e1", "e2", "e3")])


def moved(s: Shape, translation: Sequence[float] = (0.0, 0.0, 0.0),
          rotation_axis_angle: tuple[Sequence[float], float] | None = None, dilation: float = 1.0) -> Shape:
    """The primitive ``s`` moved as a spec goal's ``move`` says: dilated by ``dilation`` about its
    reference point c (:func:`reference_point`), turned by ``rotation_axis_angle`` = (world axis, angle)
    about the axis through c, then translated: each spanning point p goes to c + t + R·(k (p − c)) (a
    flat keeps its own points' spread: dilation does not change it)."""
    c = reference_point(s.kind, s.points)
    r = np.eye(3)
    if rotation_axis_angle is not None:
        axis = np.asarray(rotation_axis_angle[0], dtype=float)
        r = rotation(tuple(axis / np.linalg.norm(axis)), float(rotation_axis_angle[1]))
    k = float(dilation) if s.kind not in ("line", "plane") else 1.0
    points = c + np.asarray(translation, dtype=float) + (k * (s.points - c)) @ r.T
    return shape(s.kind, points)


def basis(normal: Array) -> tuple[Array, Array]:
    """Two unit vectors completing ``normal`` to a right-handed orthonormal frame (a, b, normal)."""
    n = normal / np.linalg.norm(normal)
    a = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    return a, np.cross(n, a)


def ring(centre: Array, radius: float, normal: Array, samples: int = 129) -> Array:
    """(samples, 3): the closed polyline of a circle (first point repeated last)."""
    a, b = basis(normal)
    t = np.linspace(0.0, 2.0 * np.pi, samples)
    polyline: Array = centre + radius * (np.outer(np.cos(t), a) + np.outer(np.sin(t), b))  # ufuncs: Any dtype
    return polyline


def polylines(s: Shape, extent: float | None = None) -> list[Array]:
    """Polylines (each (k, 3)) that draw the shape: a circle; a sphere's three great circles (in the
    coordinate planes); a line's segment through the points extended by ``extent`` (default: half their
    distance, at least 10 cm) each way; a plane's square patch outline of half-size ``extent`` (default
    1.5 × ``Shape.size``) with its diagonals; a point pair's segment; a point's three-axis cross. A
    degenerate shape: the polyline through its points."""
    if s.degenerate:
        return [s.points]
    if s.kind == "circle":
        assert s.normal is not None  # set for every circle that is not degenerate
        return [ring(s.centre, s.radius, s.normal)]
    if s.kind == "sphere":
        return [ring(s.centre, s.radius, np.eye(3)[i]) for i in range(3)]
    if s.kind == "line":
        assert s.direction is not None  # set for every line that is not degenerate
        e = max(0.1, s.radius) if extent is None else extent
        return [np.array([s.points[0] - e * s.direction, s.points[1] + e * s.direction])]
    if s.kind == "plane":
        assert s.normal is not None  # set for every plane that is not degenerate
        h = 1.5 * s.size if extent is None else extent
        a, b = basis(s.normal)
        corners = [s.centre + h * (i * a + j * b) for i, j in ((1, 1), (-1, 1), (-1, -1), (1, -1), (1, 1))]
        return [np.array(corners), np.array([corners[0], corners[2]]), np.array([corners[1], corners[3]])]
    if s.kind == "point_pair":
        return [s.points]
    h = 0.04 if extent is None else extent
    return [np.array([s.centre - h * e, s.centre + h * e]) for e in np.eye(3)]


def segments(lines: Sequence[Array]) -> Array:
    """(n, 2, 3): the segments of polylines, as line-segment primitives take them."""
    parts = [np.stack([line[:-1], line[1:]], axis=1) for line in lines if len(line) > 1]
    return np.concatenate(parts) if parts else np.zeros((0, 2, 3))


def quaternion(r: Array) -> Array:
    """(w, x, y, z) of a rotation matrix (Shepperd's method: the largest diagonal term first)."""
    t = float(np.trace(r))
    if t > 0.0:
        s = 2.0 * math.sqrt(1.0 + t)
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(max(0.0, 1.0 + r[i, i] - r[j, j] - r[k, k]))
        q = [0.0, 0.0, 0.0, 0.0]
        q[0] = (r[k, j] - r[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (r[j, i] + r[i, j]) / s
        q[1 + k] = (r[k, i] + r[i, k]) / s
    v: Array = np.array(q)
    return v / np.linalg.norm(v)


def aligning(direction: Array) -> Array:
    """A rotation matrix taking +z to the unit ``direction`` (a cylinder's axis)."""
    z = direction / np.linalg.norm(direction)
    a, b = basis(z)
    return np.column_stack([a, b, z])
