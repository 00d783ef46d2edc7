"""The viewer's numpy geometry against independent computations: the generated FK kernels (end points),
yourdfpy (every joint origin of a URDF chain), the conformal primitive's centre, radius and normal,
closed-form circles and spheres, and viser's own rotation conversions (the camera)."""

import math

import numpy as np
import pytest
import yaml
from conftest import FAST_MODULES, tiered
from hypothesis import given
from hypothesis import strategies as st

from gagen.apps.cooperative.bundled import (
    bundled_specs,
    bundled_systems,
    ready_configuration,
    system_module,
)
from gagen.viewer.camera import Camera, framing
from gagen.viewer.geometry import (
    TOLERANCE,
    circumcircle,
    polylines,
    quaternion,
    rotation,
    segments,
    shape,
    system_pose,
)
from gagen.viewer.scene import loopback

SYSTEMS = sorted(bundled_systems())


def _kernel_points(m, system, q):
    """Each chain's end point from its generated ``<chain>_fk`` kernel (rows e0 e1 e2 e3 e∞)."""
    points = []
    for chain, qi in zip(system.chains, system.split(list(q)), strict=True):
        p = np.array(getattr(m.c, f"{chain.name}_fk")(np.array(qi))[1])
        points.append(p[1:4] / p[0])
    return np.array(points)


@pytest.mark.parametrize("name", tiered(SYSTEMS, FAST_MODULES, pytest.mark.compiling))
def test_end_points_match_the_generated_fk(name):
    system = bundled_systems()[name]
    m = system_module(name)
    rng = np.random.default_rng(7)
    for q in [np.array(ready_configuration(system)), *rng.uniform(-1.5, 1.5, (3, system.dof))]:
        ours = np.array([pose.end_point for pose in system_pose(system, q)])
        np.testing.assert_allclose(ours, _kernel_points(m, system, q), rtol=0, atol=1e-12)


def test_joint_origins_match_yourdfpy():
    """Every joint origin of each Panda chain: the base placement, then the URDF's own FK (yourdfpy)."""
    import yourdfpy

    spec_path = bundled_specs()["three_pandas_circle"]
    spec = yaml.safe_load(spec_path.read_text())
    system = bundled_systems()["three_pandas_circle"]
    q = np.random.default_rng(3).uniform(-1.0, 1.0, system.dof)
    for chain_spec, chain, qi, pose in zip(spec["chains"], system.chains, system.split(list(q)),
                                           system_pose(system, q), strict=True):
        urdf = yourdfpy.URDF.load(str(spec_path.parent / chain_spec["urdf"]), load_meshes=False)
        urdf.update_cfg(dict(zip([j.name for j in chain.joints if j.moves], qi, strict=True)))
        base = np.eye(4)
        base[:3, :3] = rotation((0, 0, 1), chain_spec["base"]["rpy"][2])
        base[:3, 3] = chain_spec["base"]["xyz"]
        np.testing.assert_allclose(pose.origins[0], base[:3, 3], atol=1e-15)
        compared = 0
        for i, joint in enumerate(chain.joints):
            if joint.name in urdf.joint_map:  # the origin of the joint = that of its child link
                child = urdf.joint_map[joint.name].child
                expected = base @ urdf.get_transform(child, chain_spec["base_link"])
                np.testing.assert_allclose(pose.frames[i][:3, 3], expected[:3, 3], rtol=0, atol=1e-12)
                compared += 1
        assert compared == 8  # 7 revolute joints and the flange


def test_circle_matches_the_conformal_primitive():
    """The circle through the end points (numpy) is the generated X_c's centre, radius and normal."""
    from gagen.control.ocp import multivector
    from gagen.model.conformal import EUCLID, location
    from gagen.model.primitives import centre, radius, unit_normal

    system = bundled_systems()["three_pandas_circle"]
    m = system_module(system.name)
    rows = next(p["rows"] for k in m.manifest["kernels"] if k["name"] == "primitive"
                for p in k["outputs"] if p["name"] == "X_c")
    for q in [np.array(ready_configuration(system)), np.random.default_rng(5).uniform(-1, 1, system.dof)]:
        X = multivector(rows, m.c.primitive(q)[0])
        s = shape("circle", [pose.end_point for pose in system_pose(system, q)])
        xyz = lambda v: np.array([v[k] for k in EUCLID])  # noqa: E731
        np.testing.assert_allclose(s.centre, xyz(location(centre(X))), atol=1e-12)
        assert s.radius == pytest.approx(float(radius(X)), rel=1e-12)
        normal = xyz(unit_normal(X))
        assert abs(float(s.normal @ normal)) == pytest.approx(1.0, abs=1e-12)  # ± (orientation differs)


unit = st.floats(-1.0, 1.0)
vectors = st.tuples(unit, unit, unit).map(np.array).filter(lambda v: np.linalg.norm(v) > 0.1)


@given(centre=vectors, radius=st.floats(0.01, 3.0), normal=vectors,
       angles=st.lists(st.floats(0.0, 2 * math.pi), min_size=3, max_size=3))
def test_circle_through_three_points(centre, radius, normal, angles):
    a = np.sort(angles)
    if min(np.diff(np.r_[a, a[0] + 2 * math.pi])) < 0.05:  # nearly coincident points
        return
    n = normal / np.linalg.norm(normal)
    u = np.cross(n, [1, 0, 0] if abs(n[0]) < 0.9 else [0, 1, 0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    points = [centre + radius * (math.cos(t) * u + math.sin(t) * v) for t in angles]
    s = shape("circle", points)
    assert not s.degenerate
    np.testing.assert_allclose(s.centre, centre, atol=1e-8 * max(1.0, radius / 0.05))
    assert s.radius == pytest.approx(radius, rel=1e-8)
    expected = np.cross(points[1] - points[0], points[2] - points[0])
    np.testing.assert_allclose(s.normal, expected / np.linalg.norm(expected), atol=1e-9)
    ring = polylines(s)[0]
    np.testing.assert_allclose(np.linalg.norm(ring - centre, axis=1), radius, rtol=1e-8)
    np.testing.assert_allclose((ring - centre) @ n, 0.0, atol=1e-8)


@given(centre=vectors, radius=st.floats(0.01, 3.0),
       directions=st.lists(vectors, min_size=4, max_size=4))
def test_sphere_through_four_points(centre, radius, directions):
    d = np.array([v / np.linalg.norm(v) for v in directions])
    rows = d[1:] - d[0]
    if abs(np.linalg.det(rows)) < 1e-2:  # nearly coplanar points: an ill-conditioned sphere
        return
    s = shape("sphere", centre + radius * d)
    assert not s.degenerate
    np.testing.assert_allclose(s.centre, centre, atol=1e-7 * max(radius, 1.0))
    assert s.radius == pytest.approx(radius, rel=1e-7)


def test_degenerate_points_are_flagged_and_drawn_through():
    line = np.array([[0.0, 0, 0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]])
    assert circumcircle(*line) is None
    for kind in ("circle", "plane"):
        s = shape(kind, line)
        assert s.degenerate
        np.testing.assert_array_equal(polylines(s)[0], line)
    coplanar = np.array([[0.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0], [1.0, 1.0, 0]])
    assert shape("sphere", coplanar).degenerate
    assert shape("line", [[1.0, 2, 3], [1.0, 2, 3 + TOLERANCE / 10]]).degenerate
    with pytest.raises(ValueError, match="a circle is drawn through 3 points"):
        shape("circle", line[:2])
    with pytest.raises(ValueError, match="unknown primitive kind 'conic'"):
        shape("conic", line)


def test_flats_and_point_pairs():
    p = np.array([[0.0, 0, 1], [1.0, 0, 1], [0.0, 1.0, 1]])
    plane = shape("plane", p)
    np.testing.assert_allclose(plane.normal, [0, 0, 1])
    outline, *_ = polylines(plane)
    np.testing.assert_allclose(outline[:, 2], 1.0)
    line = shape("line", p[:2])
    (segment,) = polylines(line, extent=0.5)
    np.testing.assert_allclose(segment, [[-0.5, 0, 1], [1.5, 0, 1]])
    pair = shape("point_pair", p[:2])
    assert pair.radius == pytest.approx(0.5)
    assert segments(polylines(pair)).shape == (1, 2, 3)
    sphere = shape("sphere", [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, 0, 1]])
    assert segments(polylines(sphere)).shape == (3 * 128, 2, 3)  # three great circles


@given(axis=vectors, angle=st.floats(-math.pi, math.pi))
def test_quaternion_agrees_with_viser(axis, angle):
    tf = pytest.importorskip("viser.transforms")
    r = rotation(axis / np.linalg.norm(axis), angle)
    theirs = tf.SO3.from_matrix(r).wxyz
    ours = quaternion(r)
    assert min(np.abs(ours - theirs).max(), np.abs(ours + theirs).max()) < 1e-9


def test_camera_projection():
    camera = Camera((3.0, 0.0, 0.0), (0.0, 0.0, 0.0), fov=math.radians(60))
    r = camera.rotation()
    np.testing.assert_allclose(r, [[0, 0, -1], [1, 0, 0], [0, -1, 0]], atol=1e-15)  # right, down, forward
    f = 300.0 / math.tan(math.radians(30))
    uv = camera.project(np.array([[0, 0, 0], [0, 0.5, 0], [0, 0, 0.5], [4.0, 0, 0]]), 800, 600)
    np.testing.assert_allclose(uv[0], [400, 300])
    np.testing.assert_allclose(uv[1], [400 + f * 0.5 / 3, 300])  # +y is to the right, seen from +x
    np.testing.assert_allclose(uv[2], [400, 300 - f * 0.5 / 3])  # up is up
    assert np.all(np.isnan(uv[3]))  # behind the camera
    with pytest.raises(ValueError, match="looks along its up direction"):
        Camera((0, 0, 3.0), (0, 0, 0)).rotation()


def test_framing_keeps_every_point_in_view():
    points = np.random.default_rng(1).uniform(-1, 1, (50, 3)) * [2.0, 0.5, 0.3]
    camera = framing(points, aspect=4 / 3, fill=0.85)
    uv = camera.project(points, 800, 600)
    assert np.all((uv >= 0) & (uv <= [800, 600]))
    extent = np.max(np.abs(uv / [400, 300] - 1))
    assert extent == pytest.approx(0.85, abs=0.02)


def test_the_server_only_listens_on_loopback():
    for host in ("127.0.0.1", "127.0.0.2", "::1", "localhost"):
        assert loopback(host) == host
    for host in ("0.0.0.0", "::", "192.168.1.10", "example.com", ""):
        with pytest.raises(ValueError, match="only listens on a loopback address"):
            loopback(host)


@given(centre=vectors, radius=st.floats(0.05, 3.0), normal=vectors,
       angles=st.lists(st.floats(0.0, 2 * math.pi), min_size=4, max_size=7, unique=True),
       noise=st.floats(0.0, 0.02))
def test_more_points_than_a_circle_needs_are_fitted(centre, radius, normal, angles, noise):
    """Four to seven points near a circle (more chains than the kind needs): the viewer draws the best
    fit, held against numpy's own fit (the plane by SVD, then the algebraic circle by lstsq with its
    centre held in that plane),
    and keeps every point; exactly on the circle, the fit is the circle."""
    a = np.sort(angles)
    if min(np.diff(np.r_[a, a[0] + 2 * math.pi])) < 0.3:  # points bunched on one arc: ill-conditioned
        return
    n = normal / np.linalg.norm(normal)
    u = np.cross(n, [1, 0, 0] if abs(n[0]) < 0.9 else [0, 1, 0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    wobble = noise * radius * np.sin(3.7 * np.arange(len(angles)) + 1.0)
    points = np.array([centre + (radius + w) * (math.cos(t) * u + math.sin(t) * v) + w * n
                       for t, w in zip(angles, wobble, strict=True)])
    s = shape("circle", points)
    assert not s.degenerate and s.points.shape == points.shape
    mean = points.mean(axis=0)
    normal_fit = np.linalg.svd(points - mean)[2][2]
    e1 = np.cross(normal_fit, u if abs(normal_fit @ u) < 0.9 else v)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal_fit, e1)
    xy = np.c_[(points - mean) @ e1, (points - mean) @ e2]
    # the algebraic fit |x_i − c|² = r² with the centre c = x̄ + cx e1 + cy e2 held in the fitted plane
    squared = ((points - mean) ** 2).sum(axis=1)
    (cx, cy, k), *_ = np.linalg.lstsq(np.c_[2 * xy, np.ones(len(xy))], squared, rcond=None)
    np.testing.assert_allclose(s.centre, mean + cx * e1 + cy * e2, atol=1e-9 * max(1.0, radius))
    assert s.radius == pytest.approx(math.sqrt(k + cx * cx + cy * cy), rel=1e-9)
    assert abs(float(s.normal @ normal_fit)) == pytest.approx(1.0, abs=1e-9)
    if noise == 0.0:
        np.testing.assert_allclose(s.centre, centre, atol=1e-9 * max(1.0, radius))


def test_more_points_than_needed_degenerate_and_refused():
    collinear = np.array([[0.0, 0, 0], [1.0, 1, 1], [2.0, 2, 2], [3.0, 3, 3]])
    assert shape("circle", collinear).degenerate
    with pytest.raises(ValueError, match="a point_pair is drawn through 2 points"):
        shape("point_pair", collinear[:3])
