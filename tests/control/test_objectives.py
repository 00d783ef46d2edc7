"""Mixed objectives [COOP Eq. 5, 9, 25-28, 40]: residuals against closed forms, the Jacobian against
central differences, IK and the OCP's terminal cost reaching closed-form optima, the objectives file.

Most scenarios use three Cartesian chains (prismatic x, y, z joints each): their end points are the
joint values themselves, so every optimum below is a closed form in numpy (a circumcentre, a
line-plane intersection, the weighted least-squares point of Eq. 9's quadratic forms).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gagen.check import joint_limits
from gagen.control import goals
from gagen.control import objectives as O
from gagen.control.objectives_file import load_objectives, objective_from_file
from gagen.control.ocp import ReachingOCP
from gagen.errors import SpecError
from gagen.robots.spec import load_system

ROOT = Path(__file__).resolve().parents[2]
AXIS = "\n".join(f"      - {{name: {n}, type: prismatic, axis: {a}}}"
                 for n, a in (("x", "[1, 0, 0]"), ("y", "[0, 1, 0]"), ("z", "[0, 0, 1]")))
SPEC = "name: cartesian_three\nprimitive: circle\nchains:\n" + "".join(
    f"  - name: {c}\n    joints:\n{AXIS}\n" for c in "abc") + \
    "configurations:\n  ready: [1.0, 0.0, 0.2, -0.5, 0.8, 0.1, -0.5, -0.8, 0.3]\n"
CIRCLE = O.Cooperative("circle", ("a", "b", "c"))


@pytest.fixture(scope="module")
def cartesian(tmp_path_factory: pytest.TempPathFactory) -> tuple[O.System, np.ndarray]:
    path = tmp_path_factory.mktemp("spec") / "cartesian_three.yaml"
    path.write_text(SPEC)
    system, configurations = load_system(path)
    return system, np.array(configurations["ready"])


def circumcircle(points: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """(centre, radius, unit normal along (b − a) × (c − a)) of three points."""
    a, b, c = points
    ab, ac = b - a, c - a
    n = np.cross(ab, ac)
    centre = a + (ac @ ac * np.cross(n, ab) + ab @ ab * np.cross(ac, n)) / (2 * n @ n)
    return centre, float(np.linalg.norm(a - centre)), n / np.linalg.norm(n)


def line_measure(x: np.ndarray, a: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 9 for a point x and the line through a along unit d is ‖M x − c‖²: the rows d × (x − a) and
    det(a, d, x) = (a × d)·x. Returns (M, c)."""
    cross = np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
    return np.vstack([cross, np.cross(a, d)]), np.concatenate([cross @ a, [0.0]])


def line_plane(a: np.ndarray, d: np.ndarray, p: np.ndarray, n: np.ndarray) -> np.ndarray:
    return a + d * ((p - a) @ n) / (d @ n)


LINES = [(np.array([0.3, -0.2, 0.5]), np.array([1.0, 2.0, 2.0]) / 3),
         (np.array([-0.4, 0.6, 0.1]), np.array([0.0, 0.6, 0.8]))]
PLANE = (np.array([0.1, 0.2, 0.7]), np.array([2.0, -1.0, 2.0]) / 3)


# -- the operands and Eq. 9 --------------------------------------------------------------------------------
@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-1.5, 1.5), min_size=9, max_size=9))
def test_measures_centre_and_meet_match_closed_forms(cartesian, values) -> None:
    system, _ = cartesian
    q = np.array(values)
    points = q.reshape(3, 3)
    if np.linalg.norm(np.cross(points[1] - points[0], points[2] - points[0])) < 1e-2:
        return  # (nearly) collinear: no circle
    objective = _measures(system)
    r = objective.residual(q)
    x = points[0]
    for i, (a, d) in enumerate(LINES):
        M, c = line_measure(x, a, d)
        assert np.linalg.norm(r[objective.rows[f"line{i}"]]) == pytest.approx(np.linalg.norm(M @ x - c),
                                                                                 rel=1e-12, abs=1e-12)
    p, n = PLANE
    distance = abs(n @ (x - p))
    assert np.linalg.norm(r[objective.rows["plane"]]) == pytest.approx(distance, rel=1e-12, abs=1e-12)
    centre, radius, normal = circumcircle(points)
    assert np.allclose(objective.position(O.Centre(CIRCLE), q), centre, rtol=1e-9, atol=1e-9)
    assert r[objective.rows["radius"]][0] == pytest.approx(radius - 0.5, rel=1e-9, abs=1e-9)
    assert np.allclose(r[objective.rows["normal"]], normal - np.array([0, 0, 1.0]), atol=1e-9)
    ab = O.Cooperative("line", ("a", "b"))
    if abs((points[1] - points[0]) @ n) > 1e-2 * np.linalg.norm(points[1] - points[0]):
        meet = objective.position(O.Meet(ab, O.plane(p, n)), q)
        assert np.allclose(meet, line_plane(points[0], points[1] - points[0], p, n), rtol=1e-9, atol=1e-9)


_MEASURES: dict[int, O.Objective] = {}


def _measures(system: O.System) -> O.Objective:
    if id(system) not in _MEASURES:
        a = O.end_point("a")
        terms = [O.Incidence(a, O.line(*LINES[0]), name="line0"),
                 O.Incidence(O.line(*LINES[1]), a, name="line1"),
                 O.Incidence(a, O.plane(*PLANE), name="plane"), O.Radius(CIRCLE, 0.5, name="radius"),
                 O.Normal(CIRCLE, [0, 0, 1], name="normal")]
        _MEASURES[id(system)] = O.Objective(system, terms)
    return _MEASURES[id(system)]


def test_composite_jacobian_matches_central_differences(cartesian) -> None:
    system, _ = cartesian
    ab = O.Cooperative("line", ("a", "b"))
    objective = O.Objective(system, [
        O.PrimitiveTarget(("a", "b"), "line", goals.line([0.3, 0.0, 0.5], [0, 1, 0]), weight=2.0),
        O.PrimitiveTarget(("a", "b", "c"), "circle", goals.circle([0.1, 0.0, 0.4], 0.6, [0, 0.6, 0.8])),
        O.Radius(CIRCLE, 0.5, weight=3.0), O.Normal(CIRCLE, [0, 0, 1]),
        O.Incidence(O.Centre(CIRCLE), O.line(*LINES[0]), weight=5.0),
        O.Incidence(O.Meet(ab, O.plane(*PLANE)), O.point_at([0.2, 0.1, 0.3]))])
    rng = np.random.default_rng(3)
    for q in rng.uniform(-1, 1, (5, system.dof)):
        r, J = objective(q)
        h = 1e-6
        numeric = np.column_stack([(objective.residual(q + h * e) - objective.residual(q - h * e)) / (2 * h)
                                   for e in np.eye(system.dof)])
        assert r.shape == (objective.size,) and J.shape == (objective.size, system.dof)
        assert np.abs(J - numeric).max() <= 1e-7 * max(1.0, np.abs(J).max())


# -- IK and the OCP: closed-form optima ---------------------------------------------------------------------
def _intersection_objective(system: O.System) -> tuple[O.Objective, np.ndarray, np.ndarray]:
    """A circle of radius 0.4 about the normal n, its centre on a line and on a plane: the centre is the
    line-plane intersection."""
    normal = np.array([1.0, -2.0, 2.0]) / 3
    (a, d), (p, n) = LINES[0], PLANE
    objective = O.Objective(system, [
        O.Radius(CIRCLE, 0.4), O.Normal(CIRCLE, normal, weight=2.0),
        O.Incidence(O.Centre(CIRCLE), O.line(a, d), weight=3.0),
        O.Incidence(O.Centre(CIRCLE), O.plane(p, n))])
    return objective, line_plane(a, d, p, n), normal


@pytest.mark.parametrize("method", ["lm", "ipopt"])
def test_ik_puts_the_centre_on_the_line_plane_intersection(cartesian, method) -> None:
    system, q0 = cartesian
    objective, expected, normal = _intersection_objective(system)
    result = O.solve_ik(objective, q0, method=method)
    centre, radius, n = circumcircle(result.q.reshape(3, 3))
    assert result.converged and np.linalg.norm(result.residual) <= 1e-10
    assert np.abs(centre - expected).max() <= 1e-10
    assert radius == pytest.approx(0.4, abs=1e-10) and np.abs(n - normal).max() <= 1e-10


@pytest.mark.parametrize("method", ["lm", "ipopt"])
@pytest.mark.parametrize("weights", [(1.0, 1.0), (1.0, 9.0), (20.0, 0.5)])
def test_weights_trade_two_lines_for_the_weighted_least_squares_point(cartesian, method, weights) -> None:
    """The circle's centre pulled toward two skew lines with weights w1, w2 (radius and normal free to
    hold): the centre minimises Σ w_i ‖M_i x − c_i‖², solved here by the normal equations."""
    system, q0 = cartesian
    terms = [O.Radius(CIRCLE, 0.4), O.Normal(CIRCLE, [0, 0, 1])]
    terms += [O.Incidence(O.Centre(CIRCLE), O.line(a, d), weight=w)
              for (a, d), w in zip(LINES, weights, strict=True)]
    result = O.solve_ik(O.Objective(system, terms), q0, method=method, gtol=1e-11)
    blocks = [line_measure(np.zeros(3), a, d) for a, d in LINES]
    H = sum(w * M.T @ M for (M, _), w in zip(blocks, weights, strict=True))
    expected = np.linalg.solve(H, sum(w * M.T @ c for (M, c), w in zip(blocks, weights, strict=True)))
    centre, radius, _ = circumcircle(result.q.reshape(3, 3))
    assert result.converged, result.message
    assert np.abs(centre - expected).max() <= 1e-8 and radius == pytest.approx(0.4, abs=1e-9)
    assert np.linalg.norm(np.cross(*(p - result.q.reshape(3, 3)[0] for p in result.q.reshape(3, 3)[1:]))
                          ) > 1e-3  # a real circle


def test_the_same_objective_as_the_ocp_terminal_cost(cartesian) -> None:
    system, q0 = cartesian
    objective, expected, normal = _intersection_objective(system)
    ocp = ReachingOCP(objective.task, system.dof, N=10, horizon=1.0)
    result = ocp.solve(q0, np.zeros(12), tol=1e-11)
    centre, radius, n = circumcircle(result.q[-1].reshape(3, 3))
    assert result.success and result.error.shape == (objective.size,)
    assert np.abs(centre - expected).max() <= 1e-8
    assert radius == pytest.approx(0.4, abs=1e-8) and np.abs(n - normal).max() <= 1e-8
    assert result.dynamics_residual() <= 1e-9 and np.abs(result.qdot[-1]).max() <= 1e-9


# -- a real robot: three Pandas ----------------------------------------------------------------------------
PANDAS_FILE = """start: ready
objectives:
  - name: ring
    radius: {of: {circle: [arm0, arm1, arm2]}, radius: 0.3}
  - name: level
    normal: {of: {circle: [arm0, arm1, arm2]}, normal: [0, 0, 1]}
  - name: axis
    incidence:
      a: {centre: {circle: [arm0, arm1, arm2]}}
      b: {line: {point: [0.05, 0.05, 0.0], direction: [0, 0, 1]}}
    weight: 4
"""


@pytest.fixture(scope="module")
def pandas(tmp_path_factory: pytest.TempPathFactory):
    system, configurations = load_system(ROOT / "robots/three_pandas_circle.yaml")
    path = tmp_path_factory.mktemp("objectives") / "keep_circle.yaml"
    path.write_text(PANDAS_FILE)
    loaded = load_objectives(path, system, configurations)
    return system, np.array(configurations[loaded.start]), O.Objective(system, loaded.terms)


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' rotation matrix."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _flanges(system: O.System, q: np.ndarray) -> np.ndarray:
    """The end positions by 3 × 3 matrices from the joints' xyz, rpy and axes (URDF: R = Rz Ry Rx),
    no geometric algebra."""
    ends = []
    for chain, qc in zip(system.chains, system.split(list(q)), strict=True):
        rotation, position, values = np.eye(3), np.zeros(3), iter(qc)
        for joint in chain.joints:
            position = position + rotation @ np.array(joint.xyz)
            r, p, y = joint.rpy
            rotation = rotation @ _rotation(np.array([0, 0, 1.0]), y) @ _rotation(np.array([0, 1.0, 0]), p) \
                @ _rotation(np.array([1.0, 0, 0]), r)
            if joint.kind == "prismatic":
                position = position + rotation @ np.array(joint.axis) * next(values)
            elif joint.moves:
                rotation = rotation @ _rotation(np.array(joint.axis), next(values))
        ends.append(position)
    return np.array(ends)


def _check_pandas_circle(system: O.System, q: np.ndarray) -> None:
    centre, radius, n = circumcircle(_flanges(system, q))
    assert radius == pytest.approx(0.3, abs=1e-8) and np.abs(n - [0, 0, 1]).max() <= 1e-8
    assert np.abs(centre[:2] - [0.05, 0.05]).max() <= 1e-8


def test_three_pandas_keep_the_circle_on_a_vertical_line_by_ik(pandas) -> None:
    system, q0, objective = pandas
    lower, upper, _ = joint_limits(system)
    result = O.solve_ik(objective, q0, limits=(lower, upper))
    assert np.linalg.norm(result.residual) <= 1e-8, result.message
    assert np.all(result.q >= lower) and np.all(result.q <= upper)
    _check_pandas_circle(system, result.q)


def test_three_pandas_keep_the_circle_on_a_vertical_line_by_the_ocp(pandas) -> None:
    system, q0, objective = pandas
    lower, upper, _ = joint_limits(system)
    ocp = ReachingOCP(objective.task, system.dof, N=20, horizon=2.0)
    result = ocp.solve(q0, np.zeros(12), limits=(lower, upper), tol=1e-10)
    assert result.success and result.error_norm <= 1e-8, result.message
    assert np.all(result.q >= lower - 1e-9) and np.all(result.q <= upper + 1e-9)
    _check_pandas_circle(system, result.q[-1])


# -- the objectives file ---------------------------------------------------------------------------------
def test_file_states_the_same_objective_as_python(pandas, tmp_path) -> None:
    system, q0, objective = pandas
    circle = O.Cooperative("circle", ("arm0", "arm1", "arm2"))
    axis = O.line([0.05, 0.05, 0.0], [0, 0, 1])
    same = O.Objective(system, [O.Radius(circle, 0.3), O.Normal(circle, [0, 0, 1]),
                                O.Incidence(O.Centre(circle), axis, weight=4)])
    assert np.array_equal(objective.residual(q0), same.residual(q0))
    path = tmp_path / "target.yaml"
    path.write_text("objectives:\n  - target:\n      of: {line: [arm0, arm1]}\n"
                    "      goal: {line: {point: [0.3, 0.0, 0.5], direction: [0, 1, 0]}}\n")
    target = O.PrimitiveTarget(("arm0", "arm1"), "line", goals.line([0.3, 0.0, 0.5], [0, 1, 0]))
    assert np.array_equal(objective_from_file(path, system).residual(q0),
                          O.Objective(system, [target]).residual(q0))


BAD = [  # (what the mutation replaces, with what, the message expected)
    ("radius: 0.3", "radus: 0.3",
     "objectives[0].radius.radus (line 4): unknown key 'radus'; did you mean 'radius'?"),
    ("arm1, arm2]}, radius", "arm1, arm3]}, radius",
     "objectives[0].radius.of.circle[2] (line 4): unknown chain 'arm3' of system 'three_pandas_circle'; "
     "did you mean 'arm2'?"),
    ("weight: 4", "weight: -4", "objectives[2].weight (line 11): got -4; expected a number > 0"),
    ("centre:", "center:",
     "objectives[2].incidence.a.center (line 9): unknown key 'center'; did you mean 'centre'?"),
    ("start: ready", "start: redy", "start (line 1): unknown configuration 'redy'; did you mean 'ready'?"),
    ("direction: [0, 0, 1]", "direction: [0, 0, 0]",
     "objectives[2].incidence.b.line (line 10): line direction: expected a non-zero direction"),
    ("{centre: {circle: [arm0, arm1, arm2]}}", "{centre: {line: [arm0, arm1]}}",
     "objectives[2].incidence.a.centre (line 9): centre: expected a round"),
    ("objectives:", "objective:", "objective (line 2): unknown key 'objective'; did you mean 'objectives'?"),
    ("  - name: level\n", "  - name: level\n    radius: {of: {circle: [arm0, arm1, arm2]}, radius: 1}\n",
     "objectives[1] (line 5): states radius, normal; expected exactly one of"),
]


@pytest.mark.parametrize(("old", "new", "message"), BAD)
def test_bad_files_are_refused_in_one_line(pandas, tmp_path, old, new, message) -> None:
    system, _, _ = pandas
    path = tmp_path / "bad.yaml"
    assert old in PANDAS_FILE
    path.write_text(PANDAS_FILE.replace(old, new, 1))
    with pytest.raises(SpecError) as error:
        load_objectives(path, system, {"ready": []})
    text = str(error.value)
    assert "\n" not in text and text.startswith(str(path)) and message in text


def test_bad_terms_are_refused_in_python(cartesian) -> None:
    system, _ = cartesian
    with pytest.raises(ValueError, match="unknown chain 'bb' of system 'cartesian_three'; did you mean 'b'"):
        O.Objective(system, [O.Incidence(O.end_point("bb"), O.line([0, 0, 0], [1, 0, 0]))])
    with pytest.raises(ValueError, match="one operand must be a point"):
        O.Incidence(CIRCLE, O.line([0, 0, 0], [1, 0, 0]))
    with pytest.raises(ValueError, match="weight: expected a finite number > 0"):
        O.Radius(CIRCLE, 0.3, weight=float("nan"))
    with pytest.raises(ValueError, match="meet: expected a line and a plane"):
        O.Meet(CIRCLE, O.plane([0, 0, 0], [0, 0, 1]))


# -- the dilation force index as an objective [COOP Sec. 3.11] ----------------------------------------------
ARMS = ("arm0", "arm1", "arm2")


@pytest.fixture(scope="module")
def pandas_force(pandas):
    """The three Pandas' C module (the committed one: the ``similarity`` kernel's J_G is the reference)
    and the objective 'hold the circle of ``ready`` (hard), maximise β_D'."""
    import gagen

    system, ready, _ = pandas
    module = gagen.load(ROOT / "generated/three_pandas_circle")
    V_Sd = np.array(module.c.similarity(ready)[0]).ravel()
    objective = O.Objective(system, [O.PrimitiveTarget(ARMS, "circle", V_Sd, hard=True, name="hold"),
                                     O.DilationForce(ARMS, "circle", name="beta")])
    return system, ready, module, V_Sd, objective


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_dilation_force_term_is_the_kernels_dilation_row(pandas_force, seed) -> None:
    """r = J_Gᵀ e_D (AD of V_Sc in the objective's graph) against the e0∞ row of the ``similarity``
    kernel's J_G, and ‖r‖ = 1/β_D of ``force_manipulability``."""
    from gagen.control import force_manipulability as fm

    _, ready, module, _, objective = pandas_force
    q = ready + 0.4 * np.random.default_rng(seed).standard_normal(ready.size)
    J_G = np.array(module.c.similarity(q)[2])
    r = objective.residual(q)[objective.rows["beta"]]
    np.testing.assert_allclose(r, J_G[fm.DILATION_ROW], rtol=0, atol=1e-12 * np.abs(J_G[3]).max())
    assert 1 / np.linalg.norm(r) == pytest.approx(fm.dilation_force_index(J_G), rel=1e-12)


def test_dilation_force_jacobian_matches_central_differences(pandas_force) -> None:
    _, ready, _, _, objective = pandas_force
    q = ready + 0.3 * np.random.default_rng(11).standard_normal(ready.size)
    _, J = objective(q)
    h = 1e-6
    numeric = np.column_stack([(objective.residual(q + h * e) - objective.residual(q - h * e)) / (2 * h)
                               for e in np.eye(q.size)])
    rows = objective.rows["beta"]
    assert np.abs(J[rows] - numeric[rows]).max() <= 1e-7 * np.abs(numeric[rows]).max()
    assert np.abs(J - numeric).max() <= 1e-7 * np.abs(numeric).max()


@settings(max_examples=10, deadline=None)
@given(s=st.floats(-0.3, 0.6))
def test_dilation_force_of_prismatic_points_in_closed_form(tmp_path_factory, s) -> None:
    """Three points sliding along the radii of a horizontal circle (bases at radius 0.5, 0°, 120°, 240°):
    at q = (s, s, s), J_Gᵀ e_D = −(1, 1, 1)/(3r) and β_D = √3 r, r = 0.5 + s."""
    import math

    system = _prisms(tmp_path_factory)
    objective = O.Objective(system, [O.DilationForce(("arm0", "arm1", "arm2"), "circle")])
    r = 0.5 + s
    residual = objective.residual(np.full(3, s))
    np.testing.assert_allclose(residual, np.full(3, -1 / (3 * r)), rtol=1e-12)
    assert 1 / np.linalg.norm(residual) == pytest.approx(math.sqrt(3) * r, rel=1e-12)


_PRISMS: dict[str, O.System] = {}


def _prisms(tmp_path_factory: pytest.TempPathFactory) -> O.System:
    import math

    if "system" not in _PRISMS:
        chains = "".join(
            f"  - name: arm{i}\n    base: {{xyz: [{0.5 * math.cos(a)!r}, {0.5 * math.sin(a)!r}, 0.0], "
            f"rpy: [0.0, 0.0, {a!r}]}}\n    joints:\n"
            "      - {name: slide, type: prismatic, axis: [1, 0, 0]}\n"
            for i, a in ((i, 2 * math.pi * i / 3) for i in range(3)))
        path = tmp_path_factory.mktemp("prisms") / "prisms.yaml"
        path.write_text("name: prisms\nprimitive: circle\nchains:\n" + chains)
        _PRISMS["system"] = load_system(path)[0]
    return _PRISMS["system"]


def test_ipopt_maximises_the_dilation_force_with_the_circle_held(pandas_force) -> None:
    """min ‖J_Gᵀ e_D‖² s.t. e(q) = 0 in the URDF limits from ``ready``: e (the C ``task`` kernel) stays 0,
    the KKT conditions of max β_D hold (∇β_D = J_Gᵀ μ + Σ_held ν_i e_i with the held joints' ν pushing
    out of the box; ∇β_D by central differences of the ``similarity`` kernel), and β_D ends far above
    the nullspace ascent's default 60 steps (3.0526 -> 3.2662; the IPOPT optimum 6.2481, 3 wrists at
    their lower limit)."""
    from gagen.control import force_manipulability as fm

    system, ready, module, V_Sd, objective = pandas_force
    lower, upper, _ = joint_limits(system)
    result = O.solve_ik(objective, ready, limits=(lower, upper), method="ipopt", max_iterations=500)
    assert result.converged and result.message == "IPOPT Solve_Succeeded"
    q = result.q
    assert np.linalg.norm(np.array(module.c.task(q, V_Sd)[0])) <= 1e-9  # measured 6e-16
    # (IPOPT relaxes the bounds by 1e-8 relative: the held joints end 1.0e-8 outside)
    assert result.constraint <= 1e-9 and np.all((q >= lower - 2e-8) & (q <= upper + 2e-8))
    J_G, dJ = fm.jacobian_derivatives(module.c.similarity, q)
    beta = fm.dilation_force_index(J_G)
    assert beta == pytest.approx(1 / np.sqrt(result.cost), rel=1e-12)
    gradient = fm.dilation_force_gradient(J_G, dJ)
    at_upper, at_lower = q >= upper - 1e-9, q <= lower + 1e-9
    held = np.flatnonzero(at_upper | at_lower)
    basis = np.hstack([J_G.T, np.eye(q.size)[:, held]])
    multipliers, *_ = np.linalg.lstsq(basis, gradient, rcond=None)
    assert np.linalg.norm(basis @ multipliers - gradient) <= 1e-6 * np.linalg.norm(gradient)  # 2.7e-10
    nu = multipliers[7:]
    assert np.all(nu[at_upper[held]] > 0) and np.all(nu[at_lower[held]] < 0)  # the limits stop the ascent
    ascent = fm.maximise(module.c.similarity, module.c.task, ready)
    assert beta >= ascent.dilation[-1] * 1.5 and ascent.dilation[-1] > ascent.dilation[0]


def test_hard_targets_and_the_dilation_term_in_the_file_and_refusals(pandas, tmp_path) -> None:
    system, _, _ = pandas
    text = PANDAS_FILE + """  - target:
      of: {circle: [arm0, arm1, arm2]}
      goal: {circle: {centre: [0.0, 0.0, 0.5], radius: 0.3, normal: [0, 0, 1]}}
    hard: true
  - dilation_force: {of: {circle: [arm0, arm1, arm2]}}
    weight: 0.5
"""
    path = tmp_path / "force.yaml"
    path.write_text(text)
    terms = load_objectives(path, system).terms
    assert isinstance(terms[3], O.PrimitiveTarget) and terms[3].hard
    assert isinstance(terms[4], O.DilationForce) and terms[4].weight == 0.5 and terms[4].kind == "circle"
    path.write_text(text.replace("    weight: 4\n", "    weight: 4\n    hard: true\n"))
    with pytest.raises(SpecError, match=r"objectives\[2\]\.hard .*expected true or false, and true only on"):
        load_objectives(path, system)
    objective = O.Objective(system, terms)
    assert objective.hard == ("primitivetarget3",)
    with pytest.raises(ValueError, match="hard terms \\(primitivetarget3\\) are equality constraints, "
                                         "which need method 'ipopt'"):
        O.solve_ik(objective, np.zeros(system.dof))
    with pytest.raises(ValueError, match="dilation force: expected a primitive that dilates"):
        O.DilationForce(("arm0", "arm1"), "line")
    with pytest.raises(ValueError, match="hard: expected True or False"):
        O.PrimitiveTarget(ARMS, "circle", goals.circle([0, 0, 0.5], 0.3, [0, 0, 1]), hard=1)  # type: ignore[arg-type]


def test_the_command_solves_a_file_with_a_hard_target_by_ipopt_by_default(tmp_path, capsys):
    """A file holding the three Pandas' ready circle where it is (hard) while maximising the dilation
    force: the default method follows the file (IPOPT, which takes equality constraints), the held term's
    residual ends at rounding, and "lm" with a hard term is refused in one line."""
    import gagen
    from gagen.cli import main
    from gagen.robots.points import end_points

    m = gagen.load(Path(__file__).resolve().parents[2] / "generated" / "three_pandas_circle")
    a, b, c = end_points(m, np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785] * 3))
    u, v = b - a, c - a
    n = np.cross(u, v)
    centre = a + (u @ u * np.cross(v, n) + v @ v * np.cross(n, u)) / (2 * n @ n)  # circumcentre
    path = tmp_path / "hold.yaml"
    path.write_text(
        "start: ready\nobjectives:\n"
        "  - name: hold\n    target:\n      of: {circle: [arm0, arm1, arm2]}\n"
        f"      goal: {{circle: {{centre: {centre.tolist()}, radius: {float(np.linalg.norm(a - centre))}, "
        f"normal: {(n / np.linalg.norm(n)).tolist()}}}}}\n    hard: true\n"
        "  - name: squeeze\n    dilation_force: {of: {circle: [arm0, arm1, arm2]}}\n")
    out_folder = str(tmp_path / "o")
    assert main(["objectives", "three_pandas_circle", str(path), "--N", "0", "--out", out_folder]) == 0
    out = capsys.readouterr().out
    assert "IK (ipopt)" in out
    hold = next(line for line in out.splitlines() if line.strip().startswith("hold"))
    assert float(hold.split("->")[1]) <= 1e-9, hold
    assert main(["objectives", "three_pandas_circle", str(path), "--N", "0", "--method", "lm",
                 "--out", out_folder]) == 2
    assert capsys.readouterr().err.count("\n") == 1
