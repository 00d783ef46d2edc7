"""Planar linkages in 2D CGA (issue 15, first part): the spec's errors, the constraint Jacobian against
differences, and the Lie-algebra Newton solver on the bundled four-bar and slider-crank against their
closed forms (circle intersection; the in-line slider-crank's y = B_y + √(l² − B_x²)), with the
residual, the link lengths and the branch checked after every step and Newton's quadratic rate."""

from __future__ import annotations

from itertools import combinations, pairwise
from pathlib import Path

import numpy as np
import pytest

from gagen.apps.linkage.kernels import linkage_kernels, point_labels
from gagen.apps.linkage.solver import kernels, newton, point_index, simulate
from gagen.apps.linkage.spec import load_linkage
from gagen.errors import SpecError

ROBOTS = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "linkage" / "robots"
FOUR_BAR = ROBOTS / "four_bar.yaml"
SLIDER = ROBOTS / "slider_crank.yaml"
SLIDER_ROCKER = ROBOTS / "slider_rocker.yaml"
# the in-line slider-crank with a slider block (two constraints) in place of the pin in a slot
BLOCK_CRANK = ("app: linkage\nname: block_crank\nground: {A: [0, 0]}\nbodies:\n"
               "  crank: {A: [0, 0], B: [1, 0]}\n"
               "  coupler: {B: [1, 0], P: [0, 3.872983346207417]}\n"
               "  block: {P: [0, 3.872983346207417], Q: [0.3, 3.872983346207417]}\njoints:\n"
               "  - {revolute: [crank.A, ground.A]}\n  - {revolute: [crank.B, coupler.B]}\n"
               "  - {revolute: [coupler.P, block.P]}\n"
               "  - {slider: {point: block.P, slot: ground, through: [0, 0], direction: [0, 1]}}\n"
               "driver: {body: crank}\ntrace: block.Q\n")
ANGLES = np.linspace(0.0, 2 * np.pi, 361)  # a full revolution in 1° steps

HEAD = "app: linkage\nname: m\nground: {A: [0, 0], D: [4, 0]}\n"
BODIES = ("bodies:\n  crank: {A: [0, 0], B: [1, 0]}\n  coupler: {B: [1, 0], C: [4, 3]}\n"
          "  rocker: {C: [4, 3], D: [4, 0]}\n")
JOINTS = ("joints:\n  - {revolute: [crank.A, ground.A]}\n  - {revolute: [crank.B, coupler.B]}\n"
          "  - {revolute: [coupler.C, rocker.C]}\n  - {revolute: [rocker.D, ground.D]}\n")
DRIVER = "driver: {body: crank, pivot: ground.A}\n"
# a slider block driving a four-bar's coupler: block P on y = 0 (a true prismatic pair: it cannot turn)
BLOCK = ("app: linkage\nname: m\nground: {D: [4, 0]}\nbodies:\n  block: {P: [1, 0], Q: [1.5, 0]}\n"
         "  coupler: {P: [1, 0], C: [4, 3]}\n  rocker: {C: [4, 3], D: [4, 0]}\njoints:\n"
         "  - {slider: {point: block.P, slot: ground, through: [0, 0], direction: [1, 0], travel: [-1, 3]}}\n"
         "  - {revolute: [block.P, coupler.P]}\n  - {revolute: [coupler.C, rocker.C]}\n"
         "  - {revolute: [rocker.D, ground.D]}\ndriver: {body: block}\n")


def _error(tmp_path, text: str) -> SpecError:
    path = tmp_path / "m.yaml"
    path.write_text(text)
    with pytest.raises(SpecError) as e:
        load_linkage(path)
    assert e.value.file == str(path)
    return e.value


def _joints(old: str, new: str) -> str:
    return HEAD + BODIES + JOINTS.replace(old, new) + DRIVER


@pytest.mark.parametrize(("text", "field", "message"), [
    (_joints("rocker.D, ground.D", "rocker.D, ground.E"), "joints[3].revolute[1]", "ground has no point 'E'"),
    (_joints("coupler.C, rocker.C", "coupler.C, slider.C"), "joints[2].revolute[1]", "unknown body 'slider'"),
    (_joints("coupler.C, rocker.C", "coupler.C, coupler.B"), "joints[2].revolute", "joins coupler to itself"),
    (HEAD + BODIES + "  spare: {S: [9, 9]}\n" + JOINTS + DRIVER, "joints", "dangling bodies"),
    (HEAD + BODIES + JOINTS + "  - {revolute: [coupler.B, ground.D]}\n" + DRIVER, "joints",
     "over-constrained"),
    (_joints("  - {revolute: [rocker.D, ground.D]}\n", ""), "driver",
     "under-constrained: Grübler–Kutzbach counts 3"),
    (HEAD + BODIES + JOINTS + "driver: {body: crank, pivot: ground.D}\n", "driver.pivot",
     "no revolute joint pins crank to ground.D"),
    (HEAD + BODIES + JOINTS + "driver: {body: crank, pivot: ground.A, rate: 0}\n", "driver.rate",
     "non-zero rate"),
    (HEAD + BODIES + JOINTS + "driver: {body: crank, speed: 1}\n", "driver.speed", "unknown key 'speed'"),
    (HEAD + BODIES + JOINTS + "driver: {body: coupler}\n", "driver",
     "coupler is pinned to the ground by 0 revolute and 0 slider joint(s)"),
    (BLOCK.replace(", travel: [-1, 3]", ""), "driver", "give the slider joint a travel"),
    (BLOCK.replace("travel: [-1, 3]", "travel: [-1, 0.5]"), "driver", "initial position 1 strictly inside"),
    (HEAD + BODIES + JOINTS + "  - {prismatic: {point: coupler.C, on: ground, through: [0, 0], "
     "direction: [0, 1]}}\n" + DRIVER, "joints[4].prismatic.True", "unknown key True"),  # YAML: on = true
])
def test_malformed_spec_names_file_field_and_expectation(tmp_path, text, field, message):
    e = _error(tmp_path, text)
    assert e.field.startswith(field) and message in e.message, (e.field, e.message)


def test_under_constrained_mechanism_is_named(tmp_path):
    """Two cranks' worth of freedom (a five-bar) under one driver: Grübler–Kutzbach counts 2."""
    text = (HEAD + "bodies:\n  crank: {A: [0, 0], B: [1, 0]}\n  l2: {B: [1, 0], C: [2, 3]}\n"
            "  l3: {C: [2, 3], E: [3, 3]}\n  l4: {E: [3, 3], D: [4, 0]}\n"
            "joints:\n  - {revolute: [crank.A, ground.A]}\n  - {revolute: [crank.B, l2.B]}\n"
            "  - {revolute: [l2.C, l3.C]}\n  - {revolute: [l3.E, l4.E]}\n"
            "  - {revolute: [l4.D, ground.D]}\n" + DRIVER)
    e = _error(tmp_path, text)
    assert "under-constrained" in e.message and "counts 2" in e.message


def _block_crank(tmp_path) -> Path:
    path = tmp_path / "block_crank.yaml"
    path.write_text(BLOCK_CRANK)
    return path


@pytest.mark.parametrize("spec", ["four_bar", "slider_crank", "slider_rocker", "block_crank"])
def test_constraint_jacobian_matches_differences_through_the_retraction(spec, tmp_path):
    """J = ∂F/∂ε from commutators, against central differences of F along the Newton update
    R ← T(Δt) R(Δθ) R (which agrees with e^{−εB/2} R to first order), on the interpreter: revolute,
    pin-in-slot and slider-block rows, under a crank and a slider driver."""
    linkage = load_linkage(_block_crank(tmp_path) if spec == "block_crank" else ROBOTS / f"{spec}.yaml")
    by_name = {k.name: k for k in linkage_kernels(linkage)}
    constraint, retract = by_name["constraints"], by_name["retract"]
    rng = np.random.default_rng(1)
    n = 3 * len(linkage.unknown)
    for _ in range(5):
        R = np.concatenate([[np.cos(a / 2), -np.sin(a / 2), *rng.uniform(-0.1, 0.1, 2)]
                            for a in rng.uniform(-0.5, 0.5, len(linkage.unknown))])
        theta = np.array([rng.uniform(-np.pi, np.pi)])
        _, J = constraint.reference(R, theta)
        for c in range(n):
            step = np.zeros(n)
            step[c] = 1e-6
            plus, minus = (retract.reference(R, s)[0].ravel() for s in (step, -step))
            fd = (constraint.reference(plus, theta)[0] - constraint.reference(minus, theta)[0]).ravel() / 2e-6
            np.testing.assert_allclose(J[:, c], fd, atol=2e-9)


def _lengths(linkage, points: np.ndarray) -> np.ndarray:
    """Every distance between two points of one body."""
    labels, out = point_labels(linkage), []
    for body, named in linkage.bodies.items():
        for a, b in combinations(named, 2):
            i, j = labels.index(f"{body}_{a}_x"), labels.index(f"{body}_{b}_x")
            out.append(np.hypot(*(points[..., i:i + 2] - points[..., j:j + 2]).T))
    return np.array(out)


def _check_trajectory(linkage, trajectory) -> None:
    assert not trajectory.failures
    assert trajectory.residuals.max() < 1e-12
    initial = _lengths(linkage, np.concatenate([[*linkage.bodies[b][p]] for b in linkage.bodies
                                                for p in linkage.bodies[b]]))
    np.testing.assert_allclose(_lengths(linkage, trajectory.points).T, np.broadcast_to(initial, (len(
        trajectory.angles), len(initial))), atol=1e-12)
    # no branch jump: no point moves more per 1° step than 20× the crank's farthest point does
    steps = np.abs(np.diff(trajectory.points, axis=0)).max()
    assert steps < 20 * np.radians(1.0) * 1.0 + 1e-12


@pytest.mark.compiling
def test_four_bar_follows_the_circle_intersection():
    linkage = load_linkage(FOUR_BAR)
    trajectory = simulate(kernels(linkage), linkage, ANGLES)
    _check_trajectory(linkage, trajectory)
    A, D, crank, coupler, rocker = np.zeros(2), np.array([4.0, 0.0]), 1.0, np.hypot(3, 3), 3.0
    i = point_index(linkage, "coupler", "C")
    for theta, points in zip(ANGLES, trajectory.points, strict=True):
        B = A + crank * np.array([np.cos(theta), np.sin(theta)])
        d = np.linalg.norm(D - B)
        a = (coupler ** 2 - rocker ** 2 + d ** 2) / (2 * d)
        C = B + a * (D - B) / d + np.sqrt(coupler ** 2 - a ** 2) * np.array([B[1] - D[1], D[0] - B[0]]) / d
        np.testing.assert_allclose(points[i:i + 2], C, atol=1e-10)  # the branch the spec starts on


@pytest.mark.compiling
def test_slider_crank_runs_between_3_and_5_on_x_0():
    linkage = load_linkage(SLIDER)
    trajectory = simulate(kernels(linkage), linkage, ANGLES)
    _check_trajectory(linkage, trajectory)
    i = point_index(linkage, "coupler", "P")
    B = np.c_[np.cos(ANGLES), np.sin(ANGLES)]
    np.testing.assert_allclose(trajectory.points[:, i], 0.0, atol=1e-12)
    np.testing.assert_allclose(trajectory.points[:, i + 1], B[:, 1] + np.sqrt(16 - B[:, 0] ** 2), atol=1e-11)
    assert trajectory.points[:, i + 1].min() == pytest.approx(3.0, abs=1e-9)
    assert trajectory.points[:, i + 1].max() == pytest.approx(5.0, abs=1e-9)


def _circle_intersection(centre_a, radius_a, centre_b, radius_b, side: float) -> np.ndarray:
    """The intersection of two circles on one side (±1) of the line from a to b, per row."""
    d = np.linalg.norm(centre_b - centre_a, axis=-1, keepdims=True)
    u = (centre_b - centre_a) / d
    a = (radius_a ** 2 - radius_b ** 2 + d ** 2) / (2 * d)
    return centre_a + a * u + side * np.sqrt(radius_a ** 2 - a ** 2) * np.c_[-u[:, 1], u[:, 0]]


@pytest.mark.compiling
def test_slider_driver_moves_the_rocker_as_the_circle_intersection():
    """slider_rocker: the block P = (2 + s, 0) runs its stroke s = a sin φ over its travel [1, 2.6];
    the rocker's C is the intersection of the circles about D (1.5) and P (2) on the spec's branch,
    the block never turns, and the stroke reaches both ends of the travel."""
    from gagen.apps.linkage.demo import driver_path

    linkage = load_linkage(SLIDER_ROCKER)
    assert linkage.driver.kind == "slider" and linkage.stroke() == pytest.approx((-1.0, 0.6), abs=1e-15)
    values, phases = driver_path(linkage, 360)
    trajectory = simulate(kernels(linkage), linkage, values, phases=phases)
    assert not trajectory.failures and trajectory.residuals.max() < 1e-12 and trajectory.limits == []
    assert values.min() == pytest.approx(-1.0, abs=1e-15) and values.max() == pytest.approx(0.6, abs=1e-15)
    P = np.c_[2 + values, np.zeros_like(values)]
    C = _circle_intersection(np.array([0.0, 2.0]), 1.5, P, 2.0, side=1.0)
    i, p, q = (point_index(linkage, *ref) for ref in (("coupler", "C"), ("block", "P"), ("block", "Q")))
    np.testing.assert_allclose(trajectory.points[:, p:p + 2], P, atol=1e-14)
    np.testing.assert_allclose(trajectory.points[:, q:q + 2] - P, np.tile([0.5, 0.0], (len(values), 1)),
                               atol=1e-14)  # a translation: the block does not turn
    np.testing.assert_allclose(trajectory.points[:, i:i + 2], C, atol=1e-10)


@pytest.mark.compiling
def test_slider_block_joint_keeps_the_block_on_its_line_without_turning(tmp_path):
    """The in-line slider-crank with a slider block (two rows: on the line, no turn) in place of the pin
    in a slot: P at y = B_y + √(16 − B_x²) on x = 0, and the block's Q stays 0.3 to the right of P."""
    linkage = load_linkage(_block_crank(tmp_path))
    assert linkage.mobility() == 1 and linkage.constraint_rows == 6
    trajectory = simulate(kernels(linkage), linkage, ANGLES)
    _check_trajectory(linkage, trajectory)
    B = np.c_[np.cos(ANGLES), np.sin(ANGLES)]
    P = np.c_[np.zeros(len(ANGLES)), B[:, 1] + np.sqrt(16 - B[:, 0] ** 2)]
    p, q = point_index(linkage, "block", "P"), point_index(linkage, "block", "Q")
    np.testing.assert_allclose(trajectory.points[:, p:p + 2], P, atol=1e-11)
    np.testing.assert_allclose(trajectory.points[:, q:q + 2] - trajectory.points[:, p:p + 2],
                               np.tile([0.3, 0.0], (len(ANGLES), 1)), atol=1e-12)


@pytest.mark.compiling
def test_newton_converges_quadratically():
    """From a configuration 0.1 rad and 0.05 m off the solution: each residual is at most C × the
    previous one squared, until rounding."""
    linkage = load_linkage(FOUR_BAR)
    k = kernels(linkage)
    solved = simulate(k, linkage, [0.0, 0.3])
    off = solved.motors[-1] + np.tile([0.0, 0.05, 0.025, -0.025], len(linkage.unknown))
    residuals = newton(k, off, 0.3).residuals
    assert residuals[-1] < 1e-12 and len(residuals) <= 7
    for before, after in pairwise(residuals):
        if before > 1e-7:
            assert after <= 2.0 * before ** 2, residuals


@pytest.mark.compiling
def test_a_rank_deficient_start_is_reported_beside_gruebler(tmp_path):
    """A four-bar assembled folded flat (every point on the x axis): Grübler–Kutzbach counts 1, but
    the constraint Jacobian loses rank there; the solver says so instead of stepping on silently."""
    path = tmp_path / "flat.yaml"
    path.write_text("app: linkage\nname: flat\nground: {A: [0, 0], D: [4, 0]}\n"
                    "bodies:\n  crank: {A: [0, 0], B: [1, 0]}\n  coupler: {B: [1, 0], C: [2.5, 0]}\n"
                    "  rocker: {C: [2.5, 0], D: [4, 0]}\n" + JOINTS + DRIVER)
    linkage = load_linkage(path)
    assert linkage.mobility() == 1
    trajectory = simulate(kernels(linkage), linkage, [0.0])
    assert trajectory.rank < trajectory.unknowns == 6
    assert any("rank" in f and "under-constrained" in f for f in trajectory.failures), trajectory.failures


def test_motor_pose_matches_the_sandwich():
    """solver._pose reads R and t of T(t) R(φ) from the motor's four coefficients (the travel check's
    frame change), against the motor acting on points on the interpreter."""
    from gagen.apps.linkage.constraints import location, rotor, translator, up
    from gagen.apps.linkage.solver import _pose
    from gagen.interp import MultiVector, preset

    zero, rng = MultiVector.zero(preset("cga2d")), np.random.default_rng(4)
    for _ in range(20):
        motor = translator(zero, list(rng.normal(size=2))) * rotor(zero, rng.uniform(-np.pi, np.pi))
        rotation, shift = _pose([motor[b] for b in ("1", "e12", "e1inf", "e2inf")])
        x = rng.normal(size=2)
        moved = location(motor.sandwich(up(zero, list(x))))
        np.testing.assert_allclose(moved, rotation @ x + shift, atol=1e-14)


@pytest.mark.compiling
def test_a_slider_leaving_its_travel_is_reported(tmp_path):
    """The slider-crank's P runs over y = 3 … 5: within travel [3, 5] nothing is reported; with the
    travel cut to [3.5, 5] the steps where P is below 3.5 are named."""
    linkage = load_linkage(SLIDER)
    assert simulate(kernels(linkage), linkage, ANGLES).limits == []
    path = tmp_path / "short.yaml"
    path.write_text(SLIDER.read_text().replace("travel: [3, 5]", "travel: [3.5, 5]").replace(
        "name: slider_crank", "name: short_slider"))
    short = load_linkage(path)
    limits = simulate(kernels(short), short, ANGLES).limits
    assert len(limits) == 1 and "coupler.P" in limits[0] and "[3.5, 5]" in limits[0]
    assert "from 3 to 5" in limits[0]


@pytest.mark.parametrize(("old", "new", "field"), [
    ("name: m", 'name: "m */ __attribute__((constructor)) /*"', "name"),
    ("crank:", '"../crank":', "bodies.../crank"),
    ("B: [1, 0]}\n  coupler", 'B: [1, 0], "#error x": [2, 2]}\n  coupler', "bodies.crank.#error x"),
])
def test_hostile_names_are_refused_before_they_name_anything(tmp_path, old, new, field):
    """Names reach C symbols, Python attributes and row labels: a name that is no identifier is
    refused by the loader, naming the field."""
    e = _error(tmp_path, (HEAD + BODIES + JOINTS + DRIVER).replace(old, new, 1))
    assert e.field.startswith(field), (e.field, e.message)
    assert "letter" in e.message, e.message  # the identifier rule: a letter, then letters, digits, _


SCOTCH_YOKE = ("app: linkage\nname: scotch_yoke\nground: {A: [0, 0]}\nbodies:\n"
               "  crank: {A: [0, 0], B: [1, 0]}\n  yoke: {P: [1, 0], Q: [1, 1]}\njoints:\n"
               "  - {revolute: [crank.A, ground.A]}\n"
               "  - {prismatic: {point: crank.B, slot: yoke, through: [1, 0], direction: [0, 1]}}\n"
               "  - {slider: {point: yoke.P, slot: ground, through: [0, 0], direction: [1, 0], "
               "travel: [-1.5, 1.5]}}\ndriver: {body: crank}\ntrace: yoke.Q\n")


@pytest.mark.parametrize("spec", ["four_bar", "slider_crank", "slider_rocker", "six_bar", "ten_bar", "jansen",
                                  "block_crank", "scotch_yoke"])
def test_the_structured_newton_solve_equals_the_dense_one(spec, tmp_path):
    """``elimination.structured_solve`` (a revolute tree's 2 × 2 blocks, then the turns) gives the step
    −J⁻¹F of numpy's dense solve, at configurations off the solution; a mechanism whose body hangs on
    slots alone (the Scotch yoke) has no revolute tree and keeps the general solve."""
    import casadi as ca

    from gagen.apps.linkage.elimination import revolute_tree, structured_solve
    from gagen.apps.linkage.kernels import _near

    path = tmp_path / f"{spec}.yaml"
    path.write_text({"block_crank": BLOCK_CRANK, "scotch_yoke": SCOTCH_YOKE}.get(spec, "") or
                    (ROBOTS / f"{spec}.yaml").read_text())
    linkage = load_linkage(path)
    traced = {k.name: k for k in linkage_kernels(linkage)}["constraints"].trace()
    symbols = [ca.SX.sym(p.name, p.size) for p in traced.inputs]
    F, J = traced.function(*symbols)
    step = structured_solve(linkage, F, J)
    assert (step is None) == (spec == "scotch_yoke") == (revolute_tree(linkage) is None)
    if step is None:
        return
    solve = ca.Function("structured", symbols, [step, F, J])
    rng = np.random.default_rng(3)
    for _ in range(5):
        got, F_, J_ = (np.asarray(v) for v in solve(*_near(linkage, rng)))
        expected = -np.linalg.solve(J_, F_.reshape(-1))
        scale = max(1.0, np.abs(expected).max())
        np.testing.assert_allclose(got.reshape(-1), expected, rtol=0, atol=1e-11 * scale)


@pytest.mark.compiling
def test_scotch_yoke_moves_as_the_cosine(tmp_path):
    """A pin in the yoke's slot and the yoke on a ground slider (no revolute path to it: the general
    solve): the yoke's P is at (cos θ, 0) and its Q at (cos θ, 1)."""
    path = tmp_path / "scotch_yoke.yaml"
    path.write_text(SCOTCH_YOKE)
    linkage = load_linkage(path)
    trajectory = simulate(kernels(linkage), linkage, ANGLES)
    assert not trajectory.failures and trajectory.residuals.max() < 1e-12 and trajectory.limits == []
    p, q = point_index(linkage, "yoke", "P"), point_index(linkage, "yoke", "Q")
    x = np.cos(ANGLES)
    np.testing.assert_allclose(trajectory.points[:, p:p + 2], np.c_[x, 0 * x], atol=1e-12)
    np.testing.assert_allclose(trajectory.points[:, q:q + 2], np.c_[x, 1 + 0 * x], atol=1e-12)
