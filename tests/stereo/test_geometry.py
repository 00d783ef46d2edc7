"""The stereo geometry (``gagen.apps.stereo.geometry``) and its generated kernels
(``gagen.apps.stereo.kernels``) against closed forms in plain numpy: image lines through the camera
matrices, plane normals, the intersection line of two planes, perspective and orthogonal projections
of 3D lines, triangulation of known points, and the degenerate epipolar case.

Two rigs: the bundled one (the right camera 25 cm along the left one's x, no rotation) and a rotated
one (a turned and offset right camera), so that the stereo motor's rotation is exercised too."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from gagen.apps.stereo import geometry as geo
from gagen.apps.stereo.calibration import Pose, Rig, load_rig, rpy_matrix
from gagen.apps.stereo.kernels import KERNELS, axis_line, random_scene, stereo_kernels
from gagen.interp import MultiVector, cga3d, conformal_point

SPEC = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "stereo" / "robots" / "stereo_rig.yaml"
BUNDLED = load_rig(SPEC)
ROTATED = dataclasses.replace(BUNDLED, name="rotated_rig", right_in_left=Pose(
    rpy_matrix((0.03, -0.08, 0.05)), np.array([0.12, 0.01, -0.015])))
# the right camera 12 cm BELOW the left one: vertical image lines x = r (θ = 0, exact cos and sin) are
# epipolar lines, whose planes coincide exactly
VERTICAL = dataclasses.replace(BUNDLED, name="vertical_rig",
                               right_in_left=Pose(np.eye(3), np.array([0.0, 0.12, 0.0])))
RIGS = {"bundled": BUNDLED, "rotated": ROTATED}
GA = MultiVector.zero(cga3d())
TOL = 1e-12
EXAMPLES = settings(max_examples=30)


# -- closed forms ----------------------------------------------------------------------------------------

def camera_matrices(rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """P = K [R | t] of each camera, world = the left camera's frame (X_right = Rᵀ (X_left − t))."""
    R, t = rig.right_in_left.R, rig.right_in_left.t
    return (rig.left.K @ np.hstack([np.eye(3), np.zeros((3, 1))]),
            rig.right.K @ np.hstack([R.T, (-R.T @ t)[:, None]]))


def pixels(P: np.ndarray, X: np.ndarray) -> np.ndarray:
    h = P @ np.append(X, 1.0)
    return h[:2] / h[2]


def normalised(rig: Rig, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The normalised image points of a 3D point in both cameras, through the camera matrices."""
    P_l, P_r = camera_matrices(rig)
    return rig.left.normalised(pixels(P_l, X)), rig.right.normalised(pixels(P_r, X))


def image_lines(rig: Rig, p: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(θ, r) of the images of the 3D line p + s d in both cameras: the homogeneous line l = x_a × x_b
    through the normalised images of two of its points, l0 x + l1 y + l2 = 0."""
    out = []
    for a, b in zip(normalised(rig, p - 0.2 * d), normalised(rig, p + 0.3 * d), strict=True):
        h = np.cross(np.append(a, 1.0), np.append(b, 1.0))
        out.append(np.array([math.atan2(h[1], h[0]), -h[2] / math.hypot(h[0], h[1])]))
    return out[0], out[1]


def same_image_line(h1, h2, tol: float = TOL) -> bool:
    """(θ, r) and (θ', r') describe the same line: (cos θ, sin θ, −r) equal up to sign."""
    v1, v2 = (np.array([math.cos(h[0]), math.sin(h[0]), -h[1]]) for h in (h1, h2))
    return min(np.abs(v1 - v2).max(), np.abs(v1 + v2).max()) <= tol


def sine_between_planes(rig: Rig, p: np.ndarray, d: np.ndarray) -> float:
    """The sine of the angle between the planes through each camera centre and the 3D line."""
    n_l, n_r = np.cross(p, d), np.cross(p - rig.right_in_left.t, d)
    return float(np.linalg.norm(np.cross(n_l, n_r)) / (np.linalg.norm(n_l) * np.linalg.norm(n_r)))


def closest_to_origin(p: np.ndarray, d: np.ndarray) -> np.ndarray:
    return p - d * (p @ d) / (d @ d)


def coefficients(x: MultiVector, blades) -> np.ndarray:
    return np.array([x[b] for b in blades])


def contains(line: MultiVector, X: np.ndarray) -> float:
    """|up(X) ∧ L|: zero when the point lies on the line (or plane)."""
    return float(np.abs((conformal_point(cga3d(), list(X)) ^ line).coeffs).max())


def motor(rig: Rig) -> MultiVector:
    return geo.stereo_motor(GA, rig.right_in_left)


# -- strategies: a 3D axis in front of both cameras, well conditioned ------------------------------------

@st.composite
def axes(draw) -> tuple[np.ndarray, np.ndarray]:
    p = np.array([draw(st.floats(-0.3, 0.3)), draw(st.floats(-0.3, 0.3)), draw(st.floats(0.6, 1.5))])
    azimuth, elevation = draw(st.floats(-math.pi, math.pi)), draw(st.floats(-1.3, 1.3))
    d = np.array([math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
                  math.sin(elevation)])
    return p, d


def well_conditioned(rig: Rig, p: np.ndarray, d: np.ndarray) -> bool:
    """The planes meet at a sine ≥ 0.02 and neither image line is near infinity (the line pointing at a
    camera centre)."""
    R, t = rig.right_in_left.R, rig.right_in_left.t
    normals = (np.cross(p, d), np.cross(R.T @ (p - t), R.T @ d))
    flat = min(np.linalg.norm(n[:2]) / np.linalg.norm(n) for n in normals)
    return sine_between_planes(rig, p, d) >= 0.02 and flat > 0.2


# -- Eq. 21-27: image lines, the motor, the planes -----------------------------------------------------------

@EXAMPLES
@given(st.floats(-math.pi, math.pi), st.floats(-1.0, 1.0))
def test_image_line_is_the_hesse_line_on_the_image_plane(theta, r):
    L = geo.image_line(GA, theta, r)
    c, s = math.cos(theta), math.sin(theta)
    p0 = np.array([r * c, r * s, 1.0])
    for k in (-1.0, 0.0, 2.5):  # points x cos θ + y sin θ = r of z = 1 lie on it
        assert contains(L, p0 + k * np.array([-s, c, 0.0])) <= TOL
    assert contains(L, p0 + np.array([c, s, 0.0]) * 0.1) > 1e-3  # and a point off it does not
    np.testing.assert_allclose(geo.line_direction(L), [-s, c, 0.0], rtol=0, atol=TOL)
    # the plane through the left camera centre: normal (cos θ, sin θ, −r), through the origin
    plane = geo.back_projection(GA, motor(BUNDLED), (theta, r), (theta, r)).plane_l
    np.testing.assert_allclose(geo.plane_normal(plane), [c, s, -r], rtol=0, atol=TOL)
    assert abs(plane.dual()["einf"]) <= TOL


@pytest.mark.parametrize("rig", RIGS.values(), ids=RIGS)
@EXAMPLES
@given(x=st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3))
def test_the_stereo_motor_maps_right_coordinates_to_left(rig, x):
    M = motor(rig)
    R, t = rig.right_in_left.R, rig.right_in_left.t
    moved = M.sandwich(conformal_point(cga3d(), x))
    np.testing.assert_allclose(coefficients(moved, ("e1", "e2", "e3")) / -moved.sp(GA.make({"einf": 1})),
                               R @ np.array(x) + t, rtol=0, atol=TOL)
    c_l, c_r = geo.camera_centres(GA, M)
    np.testing.assert_allclose(coefficients(c_l, ("e0", "e1", "e2", "e3", "einf")), [1, 0, 0, 0, 0], atol=0)
    np.testing.assert_allclose(coefficients(c_r, ("e1", "e2", "e3")), t, rtol=0, atol=TOL)


@pytest.mark.parametrize("rig", RIGS.values(), ids=RIGS)
@EXAMPLES
@given(st.floats(-math.pi, math.pi), st.floats(-0.5, 0.5))
def test_the_right_plane_is_the_rotated_hesse_normal_through_the_right_centre(rig, theta, r):
    """π_r = c_r ∧ M L M~ is the plane n·x = n·t with n = R (cos θ, sin θ, −r) (up to scale)."""
    R, t = rig.right_in_left.R, rig.right_in_left.t
    planes = geo.back_projection(GA, motor(rig), (0.1, 0.2), (theta, r))
    dual = planes.plane_r.dual()
    n = R @ np.array([math.cos(theta), math.sin(theta), -r])
    got = np.array([*geo.plane_normal(planes.plane_r), dual["einf"]])
    expected = np.array([*n, n @ t])
    np.testing.assert_allclose(got / np.linalg.norm(got[:3]), expected / np.linalg.norm(n), rtol=0, atol=TOL)
    p0 = R @ [r * math.cos(theta), r * math.sin(theta), 1] + t  # the right image line's foot, moved
    assert contains(planes.plane_r, t) <= TOL and contains(planes.line_r, p0) <= TOL


# -- Eq. 28: the axis -------------------------------------------------------------------------------------

@EXAMPLES
@given(st.floats(-math.pi, math.pi), st.floats(-0.5, 0.5), st.floats(-math.pi, math.pi), st.floats(-0.5, 0.5))
def test_the_meet_is_the_intersection_line_of_the_two_planes(theta_l, r_l, theta_r, r_r):
    """Direction ∥ n_l × n_r, the point on both planes and closest to the origin, conditioning the sine
    between the normals; any image lines (of the rotated rig), not only consistent ones."""
    R, t = ROTATED.right_in_left.R, ROTATED.right_in_left.t
    n_l = np.array([math.cos(theta_l), math.sin(theta_l), -r_l])
    n_r = R @ np.array([math.cos(theta_r), math.sin(theta_r), -r_r])
    cross = np.cross(n_l, n_r)
    sine = np.linalg.norm(cross) / (np.linalg.norm(n_l) * np.linalg.norm(n_r))
    assume(sine > 1e-3)
    axis = geo.symmetry_axis(GA, motor(ROTATED), (theta_l, r_l), (theta_r, r_r))
    d, p = np.array(axis.direction), np.array(axis.point)
    np.testing.assert_allclose(d, cross / np.linalg.norm(cross) * np.sign(cross @ geo.AXIS_REFERENCE),
                               rtol=0, atol=1e-10)
    assert d @ geo.AXIS_REFERENCE >= 0
    scale = max(1.0, np.linalg.norm(p))
    assert max(abs(n_l @ p), abs(n_r @ (p - t)), abs(p @ d)) <= 1e-10 * scale
    assert abs(axis.conditioning - sine) <= 1e-12
    np.testing.assert_allclose(coefficients(axis.line, ("e01inf", "e02inf", "e03inf")), d, rtol=0, atol=1e-10)
    assert contains(axis.line, p) <= 1e-10 * scale and contains(axis.line, p + d) <= 1e-10 * scale


@pytest.mark.parametrize("rig", RIGS.values(), ids=RIGS)
@EXAMPLES
@given(axes())
def test_a_known_axis_is_recovered_from_its_two_images(rig, axis):
    p, d = axis
    # (an axis perpendicular to the sign reference has either sign, whichever rounding gives)
    assume(well_conditioned(rig, p, d) and abs(d @ geo.AXIS_REFERENCE) > 1e-9)
    left, right = image_lines(rig, p, d)
    got = geo.symmetry_axis(GA, motor(rig), left, right)
    sign = 1.0 if d @ geo.AXIS_REFERENCE >= 0 else -1.0
    np.testing.assert_allclose(got.point, closest_to_origin(p, d), rtol=0, atol=TOL)
    np.testing.assert_allclose(got.direction, sign * d, rtol=0, atol=TOL)
    assert abs(got.conditioning - sine_between_planes(rig, p, d)) <= TOL


# -- Eq. 30-31: back onto the images --------------------------------------------------------------------

@pytest.mark.parametrize("rig", RIGS.values(), ids=RIGS)
@EXAMPLES
@given(axes())
def test_reprojection_is_the_perspective_image_through_the_camera_matrices(rig, axis):
    p, d = axis
    assume(well_conditioned(rig, p, d))
    left, right = image_lines(rig, p, d)
    images = geo.reproject(GA, motor(rig), conformal_point(cga3d(), list(p)) ^ GA.make(
        dict(zip(("e1", "e2", "e3"), d, strict=True))) ^ GA.make({"einf": 1}))
    assert same_image_line(images.hesse_l, left) and same_image_line(images.hesse_r, right)
    R, t = rig.right_in_left.R, rig.right_in_left.t
    for image, ortho, (q, u) in ((images.image_l, images.ortho_l, (p, d)),
                                 (images.image_r, images.ortho_r, (R.T @ (p - t), R.T @ d))):
        for s in (-0.2, 0.4):  # the images of points of the line lie on the image line, on z = 1
            X = q + s * u
            assert contains(image, X / X[2]) <= TOL
        # Eq. 30-31: the orthogonal projection onto z = 1, through (q_x, q_y, 1) along (u_x, u_y, 0)
        foot, along = np.array([q[0], q[1], 1.0]), np.array([u[0], u[1], 0.0])
        expected = axis_line(foot, along)
        np.testing.assert_allclose(coefficients(ortho, ("e01inf", "e02inf", "e12inf", "e03inf", "e13inf",
                                                        "e23inf")), expected, rtol=0, atol=TOL)


@EXAMPLES
@given(st.floats(-3.0, 3.0), st.floats(-1.0, 1.0))
def test_an_image_line_reprojects_onto_itself_with_its_orientation(theta, r):
    images = geo.reproject(GA, motor(BUNDLED), geo.image_line(GA, theta, r))
    assert abs(math.remainder(images.hesse_l[0] - theta, 2 * math.pi)) <= TOL
    assert abs(images.hesse_l[1] - r) <= TOL
    np.testing.assert_allclose(images.image_l.coeffs, geo.image_line(GA, theta, r).coeffs, rtol=0, atol=TOL)


def test_a_line_through_a_camera_centre_reprojects_to_zeros():
    """Its plane with the centre is zero: (θ, r) = (0, 0), finite."""
    through = conformal_point(cga3d(), [0, 0, 0]) ^ conformal_point(cga3d(), [0.1, 0.2, 1]) \
        ^ GA.make({"einf": 1})
    images = geo.reproject(GA, motor(BUNDLED), through)
    assert images.hesse_l == (0.0, 0.0) and np.all(images.image_l.coeffs == 0)
    assert all(math.isfinite(v) for v in images.hesse_r)


# -- Eq. 29 and triangulation ----------------------------------------------------------------------------

@pytest.mark.parametrize("rig", RIGS.values(), ids=RIGS)
@EXAMPLES
@given(st.lists(st.floats(-0.4, 0.4), min_size=2, max_size=2), st.floats(0.5, 2.0))
def test_viewing_lines_and_triangulation_of_a_known_point(rig, xy, depth):
    X = np.array([*xy, depth])
    left, right = normalised(rig, X)
    view_l, view_r = geo.viewing_lines(GA, motor(rig), left, right)
    t = rig.right_in_left.t
    assert max(contains(view_l, X), contains(view_l, np.zeros(3)), contains(view_r, X),
               contains(view_r, t)) <= TOL
    np.testing.assert_allclose(geo.line_direction(view_l), -np.append(left, 1.0), rtol=0, atol=TOL)  # c − X
    point, gap = geo.triangulate(GA, motor(rig), left, right)
    np.testing.assert_allclose(point, X, rtol=0, atol=TOL)
    assert gap <= TOL


@pytest.mark.parametrize("rig", RIGS.values(), ids=RIGS)
@EXAMPLES
@given(st.lists(st.floats(-0.4, 0.4), min_size=4, max_size=4))
def test_triangulation_of_inconsistent_points_is_the_common_perpendicular(rig, image):
    """Against a least-squares solve of c_l + s u_l = c_r + t u_r and the line distance
    |(c_r − c_l)·(u_l × u_r)| / |u_l × u_r|."""
    R, t = rig.right_in_left.R, rig.right_in_left.t
    u_l, u_r = np.array([image[0], image[1], 1.0]), R @ np.array([image[2], image[3], 1.0])
    assume(np.linalg.norm(np.cross(u_l, u_r)) > 1e-3)
    (s, k), *_ = np.linalg.lstsq(np.column_stack([u_l, -u_r]), t, rcond=None)
    expected = (s * u_l + t + k * u_r) / 2
    point, gap = geo.triangulate(GA, motor(rig), image[:2], image[2:])
    np.testing.assert_allclose(point, expected, rtol=0, atol=1e-10)
    n = np.cross(u_l, u_r)
    assert abs(gap - abs(t @ n) / np.linalg.norm(n)) <= 1e-10


def test_parallel_viewing_lines_give_finite_values():
    """Equal image points and no rotation: parallel viewing lines (a point at infinity). The fallback
    takes the left centre and its foot on the right line: the midpoint is half the baseline's part
    across the lines, the gap the distance of the lines."""
    point, gap = geo.triangulate(GA, motor(BUNDLED), (0.1, -0.2), (0.1, -0.2))
    u, t = np.array([0.1, -0.2, 1.0]), BUNDLED.right_in_left.t
    foot = t + u * ((-t) @ u) / (u @ u)
    np.testing.assert_allclose(point, foot / 2, rtol=0, atol=TOL)
    assert abs(gap - np.linalg.norm(foot)) <= TOL


# -- the per-frame estimate --------------------------------------------------------------------------------

@pytest.mark.parametrize("rig", RIGS.values(), ids=RIGS)
@EXAMPLES
@given(axes(), st.floats(-0.1, 0.1), st.lists(st.floats(-0.02, 0.02), min_size=3, max_size=3))
def test_estimate_gives_the_axis_and_the_centre_projected_onto_it(rig, axis, along, off):
    p, d = axis
    assume(well_conditioned(rig, p, d))
    centre = p + along * d + np.array(off)
    left, right = image_lines(rig, p, d)
    centre_l, centre_r = normalised(rig, centre)
    e = geo.estimate(GA, motor(rig), [*left, *right], [*centre_l, *centre_r])
    foot = p + d * ((centre - p) @ d)
    np.testing.assert_allclose(e.centre, centre, rtol=0, atol=TOL)
    np.testing.assert_allclose(e.reference, foot, rtol=0, atol=TOL)
    np.testing.assert_allclose(e.axis.point, closest_to_origin(p, d), rtol=0, atol=TOL)
    assert e.gap <= TOL and e.axis.direction @ d != 0


# -- degenerate geometry: the axis in an epipolar plane ------------------------------------------------------

def epipolar_axis(rig: Rig, p: np.ndarray, tilt: float) -> np.ndarray:
    """A unit direction in the epipolar plane of p (through both centres), tilted out of it by ``tilt``."""
    t = rig.right_in_left.t
    in_plane = t / np.linalg.norm(t) + 0.3 * (p / np.linalg.norm(p))
    in_plane /= np.linalg.norm(in_plane)
    normal = np.cross(p, t)
    normal /= np.linalg.norm(normal)
    return math.cos(tilt) * in_plane + math.sin(tilt) * normal


def finite(*values) -> bool:
    return all(np.all(np.isfinite(np.asarray(v, dtype=float))) for v in values)


@pytest.mark.parametrize("rig", RIGS.values(), ids=RIGS)
@pytest.mark.parametrize("p", [(0.05, 0.1, 1.0), (-0.2, 0.25, 0.7), (0.3, -0.1, 1.4)])
def test_an_axis_in_the_epipolar_plane_has_conditioning_zero(rig, p):
    p = np.array(p)
    left, right = image_lines(rig, p, epipolar_axis(rig, p, 0.0))
    e = geo.estimate(GA, motor(rig), [*left, *right], [*normalised(rig, p)[0], *normalised(rig, p)[1]])
    assert e.axis.conditioning <= 1e-12
    assert finite(e.axis.point, e.axis.direction, e.axis.line.coeffs, e.centre, e.reference, e.gap)


@pytest.mark.parametrize("rig", RIGS.values(), ids=RIGS)
@pytest.mark.parametrize("tilt", [1e-2, 1e-4])
def test_a_nearly_epipolar_axis_has_a_small_positive_conditioning(rig, tilt):
    p = np.array([0.05, 0.1, 1.0])
    d = epipolar_axis(rig, p, tilt)
    left, right = image_lines(rig, p, d)
    axis = geo.symmetry_axis(GA, motor(rig), left, right)
    expected = sine_between_planes(rig, p, d)
    assert 0 < axis.conditioning < 10 * tilt
    assert abs(axis.conditioning - expected) <= 1e-9 * expected
    # the axis itself is still there, to the accuracy the conditioning allows
    np.testing.assert_allclose(axis.point, closest_to_origin(p, d), rtol=0, atol=1e-14 / tilt)


def test_coinciding_planes_meet_in_zero_and_every_output_is_zero():
    """The right camera below the left one: vertical image lines x = r (θ = 0) are epipolar lines and
    their planes coincide exactly. The meet is the zero line: conditioning 0, zeros elsewhere."""
    e = geo.estimate(GA, motor(VERTICAL), [0.0, 0.1, 0.0, 0.1], [0.1, 0.0, 0.1, -0.12])
    assert e.axis.conditioning == 0.0
    assert not np.any(e.axis.point) and not np.any(e.axis.direction) and not np.any(e.axis.line.coeffs)
    assert finite(e.centre, e.reference, e.gap)
    np.testing.assert_allclose(e.reference, 0.0, atol=0)  # the foot on a zero axis: its zero point


def test_parallel_planes_meet_at_infinity_with_finite_outputs():
    """Planes that are parallel but apart (inconsistent detections) meet in a line at infinity: no
    direction, only a moment. The axis is zero (rather than the moment blown up by 1/|d|), conditioning 0."""
    axis = geo.axis_of(GA.math, GA.make({"e12inf": 0.3, "e13inf": -0.2}), [0, 1, -0.1], [0, 1, -0.1])
    assert axis.conditioning == 0.0
    assert not np.any(axis.point) and not np.any(axis.direction) and not np.any(axis.line.coeffs)


# -- the catalogue -----------------------------------------------------------------------------------------

def test_the_catalogue_and_the_spec_app():
    from gagen.build import spec_kind

    assert tuple(k.name for k in stereo_kernels(BUNDLED)) == KERNELS
    kind = spec_kind(SPEC)
    assert (kind.name, kind.source) == ("stereo", "gagen.apps.stereo.kernels:stereo_source")


def test_random_scenes_are_well_conditioned_and_consistent():
    rng = np.random.default_rng(5)
    for rig in RIGS.values():
        for _ in range(20):
            s = random_scene(rig, rng)
            assert sine_between_planes(rig, s.point, s.direction) >= 0.03
            left, right = image_lines(rig, s.point, s.direction)
            assert same_image_line(s.lines[:2], left, 1e-12) and same_image_line(s.lines[2:], right, 1e-12)
            np.testing.assert_allclose(s.centres, np.concatenate(normalised(rig, s.centre)), rtol=0, atol=TOL)


# -- the compiled kernels: C single, C batched, CasADi -------------------------------------------------------

@pytest.fixture(scope="module")
def compiled(tmp_path_factory):
    """Both rigs' modules: the bundled one built from its file as ``gagen build`` does (the committed
    generated/stereo_rig, built on first use), the rotated one through ``compile_kernels``."""
    from gagen.build import compile_kernels
    from gagen.modules import bundled_module

    folder = tmp_path_factory.mktemp("stereo")
    rotated = compile_kernels(stereo_kernels(ROTATED), name="rotated_rig", folder=folder / "rotated")
    return {"bundled": bundled_module(SPEC).c, "rotated": rotated}


def _scenes(rig: Rig, n: int, seed: int):
    rng = np.random.default_rng(seed)
    return [random_scene(rig, rng) for _ in range(n)]


@pytest.mark.compiling
@pytest.mark.parametrize("name", RIGS)
def test_compiled_estimate_matches_the_closed_forms_and_the_interpreter(compiled, name):
    rig, kernels = RIGS[name], compiled[name]
    scenes = _scenes(rig, 40, 11)
    obs = np.array([np.concatenate([s.lines, s.centres]) for s in scenes])
    point, direction, conditioning, centre, reference, gap = kernels.estimate.batch(obs)
    ca_outputs = [np.asarray(v).reshape(-1) for v in kernels.estimate.casadi(obs[0])]
    for k, s in enumerate(scenes):
        sign = 1.0 if s.direction @ geo.AXIS_REFERENCE >= 0 else -1.0
        np.testing.assert_allclose(point[k], closest_to_origin(s.point, s.direction), rtol=0, atol=TOL)
        np.testing.assert_allclose(direction[k], sign * s.direction, rtol=0, atol=TOL)
        assert abs(conditioning[k, 0] - sine_between_planes(rig, s.point, s.direction)) <= TOL
        np.testing.assert_allclose(centre[k], s.centre, rtol=0, atol=TOL)
        foot = s.point + s.direction * ((s.centre - s.point) @ s.direction)
        np.testing.assert_allclose(reference[k], foot, rtol=0, atol=TOL)
        single = kernels.estimate(obs[k])
        e = geo.estimate(GA, motor(rig), s.lines, s.centres)
        interpreted = (e.axis.point, e.axis.direction, [e.axis.conditioning], e.centre, e.reference, [e.gap])
        for got, batch, ref in zip(single, (point, direction, conditioning, centre, reference, gap),
                                   interpreted, strict=True):
            np.testing.assert_allclose(got, batch[k], rtol=0, atol=TOL)
            np.testing.assert_allclose(got, ref, rtol=0, atol=TOL)
        if k == 0:
            for got, c in zip(single, ca_outputs, strict=True):
                np.testing.assert_allclose(got, c, rtol=0, atol=TOL)


@pytest.mark.compiling
@pytest.mark.parametrize("name", RIGS)
def test_compiled_kernels_match_the_interpreter(compiled, name):
    """Every kernel of the catalogue, C single and batched and CasADi, against the geometry on the
    interpreter (its kernel's reference) at well-conditioned samples."""
    rig, kernels = RIGS[name], compiled[name]
    rng = np.random.default_rng(2)
    for kernel in stereo_kernels(rig):
        compiled_kernel = getattr(kernels, kernel.name)
        samples = [kernel.sample(rng) for _ in range(5)]
        ports = compiled_kernel.casadi.n_in()
        assert ports == len(samples[0])
        batched = compiled_kernel.batch(*[np.array([s[i] for s in samples]) for i in range(ports)])
        batched = batched if isinstance(batched, tuple) else (batched,)
        for k, sample in enumerate(samples):
            reference = kernel.reference(*sample)
            single = compiled_kernel(*sample)
            single = single if isinstance(single, tuple) else (single,)
            via_casadi = compiled_kernel.casadi(*sample)
            via_casadi = via_casadi if isinstance(via_casadi, (list, tuple)) else [via_casadi]
            for ref, got, batch, c in zip(reference, single, batched, via_casadi, strict=True):
                ref = ref.reshape(-1)
                np.testing.assert_allclose(got.reshape(-1), ref, rtol=0, atol=TOL, err_msg=kernel.name)
                np.testing.assert_allclose(batch[k].reshape(-1), ref, rtol=0, atol=TOL, err_msg=kernel.name)
                np.testing.assert_allclose(np.asarray(c).reshape(-1), ref, rtol=0, atol=TOL,
                                           err_msg=kernel.name)


@pytest.mark.compiling
@pytest.mark.parametrize("name", RIGS)
def test_compiled_degenerate_and_nearly_degenerate_axes(compiled, name):
    rig, kernels = RIGS[name], compiled[name]
    rows, tilts = [], [0.0, 0.0, 1e-3]
    for p, tilt in zip([(0.05, 0.1, 1.0), (-0.2, 0.25, 0.7), (0.05, 0.1, 1.0)], tilts, strict=True):
        p = np.array(p)
        left, right = image_lines(rig, p, epipolar_axis(rig, p, tilt))
        rows.append(np.concatenate([left, right, *normalised(rig, p)]))
    rows.append(np.zeros(8))  # both image lines x = 0: parallel planes on the bundled rig, and zeros
    rows.append(np.array([math.pi / 2, 0.0, math.pi / 2, 0.0, 0.1, 0.0, 0.1, 0.0]))  # parallel viewing lines
    outputs = kernels.estimate.batch(np.array(rows))
    assert all(np.all(np.isfinite(o)) for o in outputs)
    conditioning = outputs[2][:, 0]
    assert conditioning[0] <= 1e-12 and conditioning[1] <= 1e-12
    assert 1e-6 < conditioning[2] < 1e-2
    for row in rows:  # C single agrees, also here
        assert all(np.all(np.isfinite(o)) for o in kernels.estimate(row))
