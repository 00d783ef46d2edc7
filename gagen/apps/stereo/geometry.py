"""Stereo symmetry-line geometry in CGA [SMC IV, Eq. 21-31], written once against the multivector
protocol: on ``gagen.interp.MultiVector`` it is the reference, on the compiler's multivectors it
flattens into the generated kernels (``gagen.apps.stereo.kernels``).

Conventions (notes/COMMON16): camera frames are OpenCV's (x right, y down, z forward); an image line
(θ, r) is x cos θ + y sin θ = r in normalised image coordinates, i.e. on the image plane z = 1.
Everything 3D is in the LEFT camera's frame; the stereo motor M maps right-camera coordinates to left
ones (X_left = R X_right + t, ``Rig.right_in_left``).

- image line (Eq. 21, moved onto z = 1 so that c ∧ L is a plane): L = up(p0) ∧ d ∧ e∞ with
  p0 = (r cos θ, r sin θ, 1), d = (−sin θ, cos θ, 0) (= up(p0) ∧ up(p0 + d) ∧ e∞);
- L_l = L(θ_l, r_l), L_r = M L(θ_r, r_r) M~ (Eq. 22-23); c_l = e0, c_r = M e0 M~ (Eq. 24-25);
- planes π = c ∧ L (OPNS; Eq. 26-27); their duals are n + δ e∞ with n = −(p0 − c) × d, for the left
  camera n = (cos θ, sin θ, −r);
- the symmetry axis is their meet π_l ∨ π_r (Eq. 28), whose direction is −(n_l × n_r);
- conditioning = |n_l × n_r| / (|n_l| |n_r|), the sine of the angle between the planes: 0 when they
  coincide (the axis in an epipolar plane) or are parallel;
- the perspective image of a 3D line L in a camera is (c ∧ L) ∨ Π, Π the image plane z = 1 (the dual
  e3 + e∞); Eq. 30-31's (L·Π)Π⁻¹ is the orthogonal projection onto Π, a different line;
- the viewing line through an image point (x, y) is X ∧ c ∧ e∞ with X = up(x, y, 1) (Eq. 29);
- the 3D point of two image points is the midpoint of the two viewing lines' common perpendicular.

Every division is guarded (``gagen.model.guarded``): degenerate input (coincident or parallel planes,
a line through a camera centre, parallel viewing lines) gives finite values, never a NaN.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from gagen.algebra.protocol import Multivector
from gagen.apps.stereo.calibration import Pose
from gagen.model.conformal import EUCLID, e0, einf, location, point, vector
from gagen.model.euclidean import cross, dot
from gagen.model.guarded import safe_reciprocal
from gagen.model.kinematics import Joint, fixed_motor
from gagen.robots.urdf import rpy_from_matrix

# The axis direction is signed to have a non-negative component along this vector of the left camera's
# frame: its −y, "up" in the image. (For the bundled rig, looking down, that is the robot base's +y,
# the direction of the paper's reference [SMC Eq. 43].) An axis exactly perpendicular to it keeps the
# orientation of the meet.
AXIS_REFERENCE = (0.0, -1.0, 0.0)
# Viewing lines this close to parallel (sin² of their angle) are taken as parallel: far beyond any
# depth a stereo rig measures (sin² = 1e-20 is a 12 cm baseline at 1.2e9 m).
PARALLEL = 1e-20

Vec3 = list[Any]


# -- constants of a rig ----------------------------------------------------------------------------------

def stereo_motor(ga: Multivector, right_in_left: Pose) -> Multivector:
    """M = T(t) R with X_left = R X_right + t, an exact constant (rpy within 1e-9 of multiples of π/4
    snap to them, as for URDF link transforms)."""
    t = right_in_left.t
    joint = Joint("right_in_left", "fixed", (float(t[0]), float(t[1]), float(t[2])),
                  rpy_from_matrix(right_in_left.R))
    return fixed_motor(ga, joint)


def camera_centres(ga: Multivector, motor: Multivector) -> tuple[Multivector, Multivector]:
    """c_l = e0 and c_r = M e0 M~ (Eq. 24-25)."""
    c_l = e0(ga)
    return c_l, motor.sandwich(c_l)


def image_plane(ga: Multivector) -> Multivector:
    """Π: the image plane z = 1 of a camera in its own frame, undual(e3 + e∞)."""
    return ga.make({"e3": 1, "einf": 1}).undual()


# -- Euclidean read-outs ---------------------------------------------------------------------------------

def line_direction(line: Multivector) -> Vec3:
    """d of the line e0∧d∧e∞ + (p × d)* ∧ e∞ (up(a) ∧ up(b) ∧ e∞ has d = b − a)."""
    return [line["e01inf"], line["e02inf"], line["e03inf"]]


def line_moment(line: Multivector) -> Vec3:
    """p × d for any point p of the line."""
    return [line["e23inf"], -line["e13inf"], line["e12inf"]]


def plane_normal(plane: Multivector) -> Vec3:
    """n of the plane's dual n + δ e∞ (the plane n·x = δ)."""
    dual = plane.dual()
    return [dual[b] for b in EUCLID]


def scaled(v: Sequence[Any], s: Any) -> Vec3:
    return [x * s for x in v]


def norm(m: Any, v: Sequence[Any]) -> Any:
    return m.sqrt(dot(v, v))


# -- Eq. 21-28: image lines to the symmetry axis --------------------------------------------------------

def image_line(ga: Multivector, theta: Any, r: Any) -> Multivector:
    """The line x cos θ + y sin θ = r of the image plane z = 1, as a CGA line (Eq. 21 on z = 1)."""
    m = ga.math
    c, s = m.cos(theta), m.sin(theta)
    return point(vector(ga, [r * c, r * s, 1])) ^ vector(ga, [-s, c, 0]) ^ einf(ga)


@dataclass
class Planes:
    """The two image lines in the left frame, the camera centres and the back-projected planes."""

    line_l: Multivector
    line_r: Multivector
    centre_l: Multivector
    centre_r: Multivector
    plane_l: Multivector
    plane_r: Multivector


def back_projection(ga: Multivector, motor: Multivector, left: Sequence[Any],
                    right: Sequence[Any]) -> Planes:
    """L_l, L_r = M L M~, c_l, c_r and π_l = c_l ∧ L_l, π_r = c_r ∧ L_r (Eq. 22-27), for the image
    lines left = (θ_l, r_l) and right = (θ_r, r_r)."""
    line_l = image_line(ga, *left)
    line_r = motor.sandwich(image_line(ga, *right))
    c_l, c_r = camera_centres(ga, motor)
    return Planes(line_l, line_r, c_l, c_r, c_l ^ line_l, c_r ^ line_r)


@dataclass
class Axis:
    """The symmetry axis: the line up(point) ∧ direction ∧ e∞ (unit, oriented like ``direction``), its
    point closest to the left camera centre, its unit direction and the conditioning. Planes that
    coincide or are parallel meet in a zero line (or one at infinity): conditioning 0 and zeros for
    the rest; planes that coincide up to rounding give conditioning ~1e-16 and finite values."""

    line: Multivector
    point: Vec3
    direction: Vec3
    conditioning: Any


def conditioning(m: Any, direction: Sequence[Any], normal_l: Sequence[Any], normal_r: Sequence[Any]) -> Any:
    """|n_l × n_r| / (|n_l| |n_r|) from the meet's direction (= −n_l × n_r), clamped to [0, 1]."""
    ratio = dot(direction, direction) * safe_reciprocal(m, dot(normal_l, normal_l) * dot(normal_r, normal_r))
    return m.sqrt(m.if_else(m.lt(1.0, ratio), 1.0, ratio))


def axis_of(m: Any, line: Multivector, normal_l: Sequence[Any], normal_r: Sequence[Any],
            reference: Sequence[float] = AXIS_REFERENCE) -> Axis:
    """The Axis of the meet ``line`` of two planes with these normals."""
    d = line_direction(line)
    d2 = dot(d, d)
    sign = m.if_else(m.lt(dot(d, reference), 0.0), -1.0, 1.0)
    inverse_length = safe_reciprocal(m, m.sqrt(d2))
    closest = scaled(cross(d, line_moment(line)), safe_reciprocal(m, d2))  # d × (p × d) / |d|²
    direction = scaled(d, sign * inverse_length)
    # (rebuilt from its point and unit direction rather than scaled: planes that are parallel but apart
    # meet in a line at infinity, d = 0 and a moment that 1/|d| would blow up)
    unit_line = point(vector(line, closest)) ^ vector(line, direction) ^ einf(line)
    return Axis(unit_line, closest, direction, conditioning(m, d, normal_l, normal_r))


def symmetry_axis(ga: Multivector, motor: Multivector, left: Sequence[Any], right: Sequence[Any],
                  reference: Sequence[float] = AXIS_REFERENCE) -> Axis:
    """The 3D symmetry axis of the image lines (θ_l, r_l), (θ_r, r_r): π_l ∨ π_r (Eq. 28)."""
    planes = back_projection(ga, motor, left, right)
    meet = planes.plane_l & planes.plane_r
    return axis_of(ga.math, meet, plane_normal(planes.plane_l), plane_normal(planes.plane_r), reference)


# -- Eq. 30-31: a 3D line back onto the images -----------------------------------------------------------

def perspective_image(ga: Multivector, line: Multivector) -> Multivector:
    """The image of a 3D line (in the camera's own frame): (e0 ∧ L) ∨ Π, a line on z = 1. An image
    line L(θ, r) is its own image, with its orientation."""
    return (e0(ga) ^ line) & image_plane(ga)


def orthogonal_image(ga: Multivector, line: Multivector) -> Multivector:
    """The paper's (L·Π)Π⁻¹ (Eq. 30-31): the orthogonal projection of L onto the image plane."""
    plane = image_plane(ga)
    return ((line | plane) * plane.inverse()).grade(3)


def hesse(m: Any, image: Multivector) -> tuple[Any, Any]:
    """(θ, r) of a line on z = 1, oriented like it: d = |d|(−sin θ, cos θ), and the moment's z part
    x d_y − y d_x = |d| r. A zero line (the 3D line through the camera centre) gives (0, 0)."""
    dx, dy = image["e01inf"], image["e02inf"]
    return m.atan2(-dx, dy), image["e12inf"] * safe_reciprocal(m, m.sqrt(dx * dx + dy * dy))


@dataclass
class Reprojection:
    """A 3D line's images: (θ, r) per camera, the perspective image lines and the orthogonal
    projections of Eq. 30-31, each in its camera's own frame."""

    hesse_l: tuple[Any, Any]
    hesse_r: tuple[Any, Any]
    image_l: Multivector
    image_r: Multivector
    ortho_l: Multivector
    ortho_r: Multivector


def reproject(ga: Multivector, motor: Multivector, line: Multivector) -> Reprojection:
    """The images of a 3D line given in the left camera's frame."""
    in_right = (~motor).sandwich(line)
    image_l, image_r = perspective_image(ga, line), perspective_image(ga, in_right)
    m = ga.math
    return Reprojection(hesse(m, image_l), hesse(m, image_r), image_l, image_r,
                        orthogonal_image(ga, line), orthogonal_image(ga, in_right))


# -- Eq. 29 and the 3D mass centre ------------------------------------------------------------------------

def viewing_line(ga: Multivector, x: Any, y: Any) -> Multivector:
    """X ∧ c ∧ e∞ (Eq. 29) in the camera's own frame, X = up(x, y, 1), c = e0: direction −(x, y, 1)."""
    return point(vector(ga, [x, y, 1])) ^ e0(ga) ^ einf(ga)


def viewing_lines(ga: Multivector, motor: Multivector, left: Sequence[Any],
                  right: Sequence[Any]) -> tuple[Multivector, Multivector]:
    """The viewing lines of the image points left = (x_l, y_l) and right = (x_r, y_r), in the left
    frame (the right one M (X_r ∧ e0 ∧ e∞) M~ = (M X_r M~) ∧ c_r ∧ e∞)."""
    return viewing_line(ga, *left), motor.sandwich(viewing_line(ga, *right))


def common_perpendicular(m: Any, c1: Sequence[Any], u1: Sequence[Any], c2: Sequence[Any],
                         u2: Sequence[Any]) -> tuple[Vec3, Any]:
    """Midpoint and length of the common perpendicular of the lines c1 + s u1 and c2 + t u2: the
    closest points minimise |c1 + s u1 − c2 − t u2|², a 2×2 solve with determinant |u1 × u2|². For
    parallel lines (sin² of their angle below PARALLEL) s = 0, the foot of c1 on the second line."""
    w = [a - b for a, b in zip(c1, c2, strict=True)]
    a, b, c, d, e = dot(u1, u1), dot(u1, u2), dot(u2, u2), dot(u1, w), dot(u2, w)
    det = a * c - b * b
    parallel = m.lt(det, PARALLEL * a * c)
    inverse = 1 / (det + m.if_else(parallel, 1.0, 0.0))  # (the branch not taken never divides by 0)
    s = m.if_else(parallel, 0.0, (b * e - c * d) * inverse)
    t = m.if_else(parallel, e * safe_reciprocal(m, c), (a * e - b * d) * inverse)
    p1 = [ci + s * ui for ci, ui in zip(c1, u1, strict=True)]
    p2 = [ci + t * ui for ci, ui in zip(c2, u2, strict=True)]
    gap = [x - y for x, y in zip(p1, p2, strict=True)]
    return [(x + y) * 0.5 for x, y in zip(p1, p2, strict=True)], norm(m, gap)


def triangulate(ga: Multivector, motor: Multivector, left: Sequence[Any],
                right: Sequence[Any]) -> tuple[Vec3, Any]:
    """The 3D point of two image points (normalised coordinates) and the gap between their viewing
    lines (0 for consistent points): the viewing lines run from the camera centres along
    −direction(X ∧ c ∧ e∞)."""
    view_l, view_r = viewing_lines(ga, motor, left, right)
    c_l, c_r = camera_centres(ga, motor)
    along_l = [-v for v in line_direction(view_l)]
    along_r = [-v for v in line_direction(view_r)]
    m = ga.math
    return common_perpendicular(m, [c_l[b] for b in EUCLID], along_l, [location(c_r)[b] for b in EUCLID],
                                along_r)


def foot_on_axis(p: Sequence[Any], axis_point: Sequence[Any], direction: Sequence[Any]) -> Vec3:
    """The foot of the perpendicular from p onto the axis through axis_point along the unit direction."""
    along = dot([a - b for a, b in zip(p, axis_point, strict=True)], direction)
    return [a + along * u for a, u in zip(axis_point, direction, strict=True)]


@dataclass
class Estimate:
    """One frame's estimate in the left frame: the axis, the 3D mass centre, the gap of its viewing
    lines, and the reference point (the mass centre's foot on the axis)."""

    axis: Axis
    centre: Vec3
    gap: Any
    reference: Vec3


def estimate(ga: Multivector, motor: Multivector, lines: Sequence[Any], centres: Sequence[Any],
             reference: Sequence[float] = AXIS_REFERENCE) -> Estimate:
    """lines = (θ_l, r_l, θ_r, r_r), centres = (x_l, y_l, x_r, y_r) (normalised image coordinates)."""
    axis = symmetry_axis(ga, motor, lines[0:2], lines[2:4], reference)
    centre, gap = triangulate(ga, motor, centres[0:2], centres[2:4])
    return Estimate(axis, centre, gap, foot_on_axis(centre, axis.point, axis.direction))
