"""Stating goals (``gagen.control.goals``: V_Sd from a desired primitive) and the chain
kernels' layouts
(``gagen.conventions``: J_S in Pinocchio's [v; ω] WORLD layout, the motor as a 4 × 4 transform).

Goals are checked by what the similarity does to points, not by how it was built: V_Sd must carry
the unit primitive's own spanning points onto the desired primitive (centre, radius, normal,
direction and orientation as closed forms), and IK on a generated task kernel must reach it.
Layouts are checked against Pinocchio on the same URDF."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import bundled_module
from hypothesis import given, settings
from hypothesis import strategies as st

from gagen.algebra.signature import cga3d
from gagen.control import goals, solve_ik
from gagen.conventions import from_pinocchio_world, motor_to_homogeneous, to_pinocchio_world
from gagen.interp import MultiVector
from gagen.model.conformal import SIMILARITY

ROOT = Path(__file__).resolve().parents[2]
ALG = cga3d()

coordinate = st.floats(-2.0, 2.0, allow_nan=False)
position = st.tuples(coordinate, coordinate, coordinate).map(np.array)
direction = position.filter(lambda v: np.linalg.norm(v) > 0.1)
radius = st.floats(0.01, 3.0)


def _versor(V_Sd: np.ndarray) -> MultiVector:
    return MultiVector.from_blades(ALG, dict(zip(SIMILARITY, V_Sd, strict=True)))


def _image(V_Sd: np.ndarray, xyz) -> np.ndarray:
    """Where the similarity V_Sd takes the Euclidean point xyz (through the conformal sandwich)."""
    x = np.asarray(xyz, dtype=float)
    p = MultiVector.from_blades(ALG, {"e0": 1.0, "e1": x[0], "e2": x[1], "e3": x[2],
                                      "einf": 0.5 * float(x @ x)})
    image = _versor(V_Sd).sandwich(p)
    weight = -image.sp(MultiVector.from_blades(ALG, {"einf": 1}))
    return np.array([image["e1"], image["e2"], image["e3"]]) / weight


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


@settings(max_examples=25)
@given(position, radius, direction)
def test_circle_goal_carries_the_unit_circle_onto_the_circle(centre, r, normal):
    V = goals.circle(centre, r, normal)
    a, b, c = (_image(V, p) for p in ((1, 0, 0), (0, 1, 0), (-1, 0, 0)))
    origin = _image(V, (0, 0, 0))  # the unit circle's centre
    np.testing.assert_allclose(origin, centre, atol=1e-9 * max(1, r))
    for p in (a, b, c):
        assert abs(np.linalg.norm(p - centre) - r) <= 1e-9 * max(1, r)
        assert abs(_unit(normal) @ (p - centre)) <= 1e-9 * max(1, r)  # in the plane
    # counter-clockwise about the normal, as P(e1), P(e2), P(−e1) about +e3
    assert np.cross(a - centre, b - centre) @ normal > 0


@settings(max_examples=20)
@given(position, radius)
def test_sphere_goal(centre, r):
    V = goals.sphere(centre, r)
    np.testing.assert_allclose(_image(V, (0, 0, 0)), centre, atol=1e-9 * max(1, r))
    for p in np.eye(3):
        assert abs(np.linalg.norm(_image(V, p) - centre) - r) <= 1e-9 * max(1, r)


def _away_from(axis):
    """Directions more than 0.01 rad from ``axis``: Eq. 21 loses eps/K0 next to a flat's opposite."""
    return direction.filter(lambda v: _unit(v) @ np.asarray(axis, dtype=float) < np.cos(0.01))


@settings(max_examples=25)
@given(position, _away_from((-1, 0, 0)))
def test_line_goal(point, d):
    V = goals.line(point, d)
    p0, p1 = _image(V, (0, 0, 0)), _image(V, (1, 0, 0))
    u = _unit(d)
    off = (p0 - point) - ((p0 - point) @ u) * u
    assert np.linalg.norm(off) <= 1e-9 * max(1, np.linalg.norm(point))  # on the line
    np.testing.assert_allclose(p1 - p0, u, atol=1e-9)  # a motor: unit length, oriented along d


@settings(max_examples=25)
@given(position, _away_from((0, 0, -1)))
def test_plane_goal(point, normal):
    V = goals.plane(point, normal)
    p0, p1, p2 = (_image(V, p) for p in ((0, 0, 0), (1, 0, 0), (0, 1, 0)))
    n = _unit(normal)
    for p in (p0, p1, p2):
        assert abs((p - point) @ n) <= 1e-9 * max(1, np.linalg.norm(point))
    np.testing.assert_allclose(np.cross(p1 - p0, p2 - p0), n, atol=1e-9)  # oriented along the normal


@settings(max_examples=20)
@given(position, position.filter(lambda v: np.linalg.norm(v) > 0.05))
def test_point_and_point_pair_goals(a, offset):
    np.testing.assert_allclose(_image(goals.point(a), (0, 0, 0)), a, atol=1e-12)
    b = a + offset
    V = goals.point_pair(a, b)
    np.testing.assert_allclose(_image(V, (-1, 0, 0)), a, atol=1e-9)
    np.testing.assert_allclose(_image(V, (1, 0, 0)), b, atol=1e-9)


@pytest.mark.parametrize("call, message", [
    (lambda: goals.circle([0, 0, 0], 0.0, [0, 0, 1]), "radius"),
    (lambda: goals.circle([0, 0, 0], 1.0, [0, 0, 0]), "non-zero direction"),
    (lambda: goals.circle([np.nan, 0, 0], 1.0, [0, 0, 1]), "finite"),
    (lambda: goals.sphere([0, 0, 0], -1.0), "radius"),
    (lambda: goals.through("circle", [[0, 0, 0], [1, 0, 0], [2, 0, 0]]), "collinear"),
    (lambda: goals.through("sphere", [[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]]), "coplanar"),
    (lambda: goals.point_pair([1, 2, 3], [1, 2, 3]), "coincide"),
    (lambda: goals.line([0, 0, 0], [0, 0, 1e-15]), "non-zero direction"),
    (lambda: goals.point([1e9, 0, 0]), "beyond"),
    (lambda: goals.line([0, 0, 1], [-1, 0, 1e-6]), "opposite orientation"),
    (lambda: goals.through("circle", [[0, 0, 0], [1, 0, 0]]), "spanned by 3 points"),
    (lambda: goals.through("cone", [[0, 0, 0]]), "unknown primitive kind"),
    (lambda: goals.plane([0, 0], [0, 0, 1]), "3 coordinates"),
])
def test_degenerate_or_malformed_goals_are_refused(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_ik_reaches_a_circle_stated_by_centre_radius_normal():
    """The user's path: state the circle, solve IK on the generated task kernel, get that circle."""
    m = bundled_module("three_pandas_circle")
    task = m.casadi.task

    def kernel(q, V_Sd):
        e, J = task(q, V_Sd)
        return np.array(e).ravel(), np.array(J)

    from gagen.robots.spec import load_system

    _, configurations = load_system(ROOT / "robots" / "three_pandas_circle.yaml")
    q0 = np.array(configurations["ready"])
    goal = goals.circle(centre=[0.02, -0.03, 0.55], radius=0.45, normal=[0.05, 0.0, 1.0])
    result = solve_ik(kernel, q0, goal, tol=1e-10)
    assert result.converged, result
    x_c = np.array(m.casadi.primitive(result.q)[0]).ravel()
    x_d = goals.primitive("circle", goal)
    rows = next(p["rows"] for k in m.manifest["kernels"] if k["name"] == "primitive" for p in k["outputs"]
                if p["name"] == "X_c")
    x_d = np.array([x_d[b] for b in rows])
    cos = x_c @ x_d / np.linalg.norm(x_c) / np.linalg.norm(x_d)
    assert cos > 1 - 1e-12  # X_c(q*) = λ X_d with λ > 0


@pytest.fixture(scope="module")
def panda():
    model = pin.buildModelFromUrdf(str(ROOT / "robots" / "panda" / "panda.urdf"))
    module = bundled_module("panda_point")
    return model, model.createData(), model.getFrameId("panda_link8"), module


def test_spatial_jacobian_and_motor_in_pinocchio_layout(panda):
    model, data, frame, m = panda
    rng = np.random.default_rng(7)
    samples = []
    for _ in range(20):
        q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
        M, _, J_S = (np.array(x) for x in m.casadi.arm0_fk_jacobian(q[:7]))
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        world = pin.computeFrameJacobian(model, data, q, frame, pin.ReferenceFrame.WORLD)[:, :7]
        np.testing.assert_allclose(to_pinocchio_world(J_S), world, atol=1e-12)
        np.testing.assert_allclose(from_pinocchio_world(world), J_S, atol=1e-12)
        np.testing.assert_allclose(motor_to_homogeneous(M.ravel()), data.oMf[frame].homogeneous, atol=1e-12)
        samples.append((M.ravel(), J_S, world, data.oMf[frame].homogeneous.copy()))
    # batches: (m, 6, n), column layout (6, n, m), twists (m, 6), motors (m, 8)
    Ms, Js, worlds, Hs = (np.array(x) for x in zip(*samples, strict=True))
    np.testing.assert_allclose(to_pinocchio_world(Js), worlds, atol=1e-12)
    np.testing.assert_allclose(to_pinocchio_world(Js.transpose(1, 2, 0), axis=0), worlds.transpose(1, 2, 0),
                               atol=1e-12)
    np.testing.assert_allclose(to_pinocchio_world(Js[:, :, 3], axis=-1), worlds[:, :, 3], atol=1e-12)
    np.testing.assert_allclose(motor_to_homogeneous(Ms), Hs, atol=1e-12)
    with pytest.raises(ValueError, match="6 rows"):
        to_pinocchio_world(np.zeros((7, 7)))
