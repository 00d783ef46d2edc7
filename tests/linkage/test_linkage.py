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
ANGLES = np.linspace(0.0, 2 * np.pi, 361)  # a full revolution in 1° steps

HEAD = "app: linkage\nname: m\nground: {A: [0, 0], D: [4, 0]}\n"
BODIES = ("bodies:\n  crank: {A: [0, 0], B: [1, 0]}\n  coupler: {B: [1, 0], C: [4, 3]}\n"
          "  rocker: {C: [4, 3], D: [4, 0]}\n")
JOINTS = ("joints:\n  - {revolute: [crank.A, ground.A]}\n  - {revolute: [crank.B, coupler.B]}\n"
          "  - {revolute: [coupler.C, rocker.C]}\n  - {revolute: [rocker.D, ground.D]}\n")
DRIVER = "driver: {body: crank, pivot: ground.A}\n"


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
    (_joints("  - {revolute: [rocker.D, ground.D]}\n", ""), "joints",
     "under-constrained: Grübler–Kutzbach counts 3"),
    (HEAD + BODIES + JOINTS + "driver: {body: crank, pivot: ground.D}\n", "driver.pivot",
     "no revolute joint pins crank to ground.D"),
    (HEAD + BODIES + JOINTS + "driver: {body: crank, pivot: ground.A, rate: 1}\n", "driver.rate",
     "unknown key 'rate'"),
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


@pytest.mark.parametrize("spec", [FOUR_BAR, SLIDER])
def test_constraint_jacobian_matches_differences_through_the_retraction(spec):
    """J = ∂F/∂ε from commutators, against central differences of F along the Newton update
    R ← T(Δt) R(Δθ) R (which agrees with e^{−εB/2} R to first order), on the interpreter."""
    linkage = load_linkage(spec)
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
