"""Linkages of mobility k > 1 under k drivers (issue 32, item 2): the loader's refusals when the drivers
do not match Grübler–Kutzbach's count, the two-crank five-bar and the crank + slider against their
closed forms (circle–circle intersection of the two distal links, on the spec's assembly branch) over
a grid of both driver values, the compiled kernels against the interpreter, and the batch of several
five-bars of different dimensions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gagen.apps.linkage.assemble import intersect
from gagen.apps.linkage.kernels import _near, driver_labels, initial_points, linkage_kernels
from gagen.apps.linkage.solver import kernels, point_index, simulate
from gagen.apps.linkage.spec import load_linkage
from gagen.errors import SpecError

ROBOTS = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "linkage" / "robots"
FIVE_BAR, CRANK_SLIDER = ROBOTS / "five_bar.yaml", ROBOTS / "crank_slider.yaml"
# max |F| asked of Newton where points are checked to 1e-12: the default 1e-12 leaves them within
# 1e-12 / σ_min(J) ≈ 3e-12 (σ_min ≈ 0.33 here); one more quadratic iteration is far below
TIGHT = 1e-14


def _error(tmp_path: Path, text: str) -> SpecError:
    path = tmp_path / "spec.yaml"
    path.write_text(text)
    with pytest.raises(SpecError) as info:
        load_linkage(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)
    return info.value


FIVE = FIVE_BAR.read_text()
DRIVERS = ("driver:\n  - {body: left_crank, pivot: ground.A, rate: 1.0}\n"
           "  - {body: right_crank, pivot: ground.E, rate: -2.0}\n")


@pytest.mark.parametrize(("drivers", "field", "message"), [
    ("driver: {body: left_crank, pivot: ground.A}\n", "driver",
     "under-constrained: Grübler–Kutzbach counts 2 degrees of freedom (3 × 4 moving links − 2 per revolute "
     "or slider − 1 per prismatic joint) and 1 driver move it; give one driver per degree of freedom"),
    (DRIVERS + "  - {body: left_link, rate: 1.0}\n", "driver[2]", "pinned to the ground by 0 revolute"),
    ("driver:\n  - {body: left_crank}\n  - {body: left_crank}\n", "driver[1].body",
     "left_crank is driven twice"),
    ("driver:\n  - {body: left_crank}\n  - right_crank\n", "driver[1]", "got 'right_crank'; expected"),
    ("driver: []\n", "driver", "or a list of them (one per degree of freedom)"),
    ("driver:\n  - {body: left_crank}\n  - {body: right_crank, pivot: ground.A}\n", "driver[1].pivot",
     "no revolute joint pins right_crank to ground.A"),
])
def test_drivers_that_do_not_match_the_mobility_are_refused(tmp_path, drivers, field, message):
    e = _error(tmp_path, FIVE[:FIVE.index("driver:")] + drivers + "trace: left_link.P\n")
    assert e.field.startswith(field) and message in e.message, (e.field, e.message)


def test_two_drivers_on_a_four_bar_are_over_constrained(tmp_path):
    text = (ROBOTS / "four_bar.yaml").read_text().replace(
        "driver: {body: crank, pivot: ground.A}",
        "driver: [{body: crank, pivot: ground.A}, {body: rocker, pivot: ground.D}]")
    e = _error(tmp_path, text)
    assert e.field.startswith("driver") and "over-constrained: Grübler–Kutzbach counts 1" in e.message
    assert "2 drivers move it" in e.message


def test_bundled_two_driver_specs_load():
    for spec, driven in ((FIVE_BAR, ("left_crank", "right_crank")), (CRANK_SLIDER, ("crank", "block"))):
        linkage = load_linkage(spec)
        assert linkage.mobility() == 2 and linkage.driven == driven
        assert linkage.constraint_rows == 3 * len(linkage.unknown) == 6
        assert driver_labels(linkage) == tuple(f"{b}_{'s' if b == 'block' else 'theta'}" for b in driven)


# -- the closed forms --------------------------------------------------------------------------------------

def _crank(pivot: tuple[float, float], radius: float, start: float, theta: np.ndarray) -> np.ndarray:
    angle = start + theta
    return np.asarray(pivot) + radius * np.stack([np.cos(angle), np.sin(angle)], axis=-1)


def five_bar_closed_form(values: np.ndarray) -> dict[str, np.ndarray]:
    """B, C and P of the bundled five-bar at crank rotations (θ1, θ2) from the initial configuration
    (both cranks straight up): P the intersection of the circles of radius 2 about B and C, left of
    B → C."""
    B = _crank((0.0, 0.0), 0.5, np.pi / 2, values[:, 0])
    C = _crank((2.0, 0.0), 0.5, np.pi / 2, values[:, 1])
    return {"B": B, "C": C, "P": intersect(B, 2.0, C, 2.0, 1)}


def crank_slider_closed_form(values: np.ndarray) -> dict[str, np.ndarray]:
    """B, S and P of the bundled crank + slider at (θ, s): S = (2.25 + s, 0), P left of B → S."""
    B = _crank((0.0, 0.0), 0.5, np.pi / 2, values[:, 0])
    S = np.stack([2.25 + values[:, 1], np.zeros(len(values))], axis=-1)
    return {"B": B, "S": S, "P": intersect(B, 2.0, S, 2.0, 1)}


def serpentine(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """Every pair of a grid, row by row, every other row backwards: a path of small steps for the
    solver's continuation."""
    rows = [np.stack([np.full(len(second), a), second if i % 2 == 0 else second[::-1]], axis=1)
            for i, a in enumerate(first)]
    return np.concatenate(rows)


def _check_against(linkage, trajectory, closed: dict[str, np.ndarray], where: dict[str, tuple[str, str]]):
    assert not trajectory.failures and trajectory.residuals.max() < TIGHT
    worst = 0.0
    for name, (body, point) in where.items():
        i = point_index(linkage, body, point)
        worst = max(worst, float(np.abs(trajectory.points[:, i:i + 2] - closed[name]).max()))
    assert worst <= 1e-12, worst
    return worst


@pytest.mark.compiling
def test_five_bar_follows_the_closed_form_over_a_grid_of_both_cranks():
    linkage = load_linkage(FIVE_BAR)
    grid = np.radians(np.arange(0.0, 360.0, 15.0))  # 24 × 24 crank-angle pairs
    values = serpentine(grid, grid)
    trajectory = simulate(kernels(linkage), linkage, values, tolerance=TIGHT)
    closed = five_bar_closed_form(values)
    closed["P2"] = closed["P"]  # the joint point as each distal link carries it
    _check_against(linkage, trajectory, closed, {"B": ("left_link", "B"), "C": ("right_link", "C"),
                                                 "P": ("left_link", "P"), "P2": ("right_link", "P")})
    assert trajectory.iterations.max() <= 6


@pytest.mark.compiling
def test_crank_and_slider_follow_the_closed_form_over_a_grid():
    linkage = load_linkage(CRANK_SLIDER)
    lower, upper = linkage.stroke(linkage.drivers[1])
    assert (lower, upper) == pytest.approx((-0.75, 0.75), abs=1e-15)
    values = serpentine(np.radians(np.arange(0.0, 360.0, 15.0)), np.linspace(lower, upper, 16))
    trajectory = simulate(kernels(linkage), linkage, values, tolerance=TIGHT)
    _check_against(linkage, trajectory, crank_slider_closed_form(values),
                   {"B": ("upper", "B"), "S": ("lower", "S"), "P": ("lower", "P")})
    assert not trajectory.limits


@pytest.mark.compiling
def test_five_bar_kernels_equal_the_interpreter():
    """The compiled constraints, positions and Newton step (the structured solve) against the
    interpreter's reference (numpy's least squares for the step) near the initial configuration."""
    linkage = load_linkage(FIVE_BAR)
    compiled = kernels(linkage)
    reference = {k.name: k.reference for k in linkage_kernels(linkage)}
    rng = np.random.default_rng(7)
    for _ in range(5):
        R, q = _near(linkage, rng)
        assert q.shape == (2,)
        F, J = (np.asarray(v) for v in compiled.constraints(R, q))
        F_ref, J_ref = reference["constraints"](R, q)
        np.testing.assert_allclose(F.reshape(-1), F_ref.reshape(-1), rtol=0, atol=1e-13)
        np.testing.assert_allclose(J.reshape(J_ref.shape), J_ref, rtol=0, atol=1e-13)
        np.testing.assert_allclose(np.asarray(compiled.positions(R, q)).reshape(-1),
                                   reference["positions"](R, q)[0].reshape(-1), rtol=0, atol=1e-13)
        assert compiled.newton_step is not None
        R_next, residual = compiled.newton_step(R, q)
        R_ref, residual_ref = reference["newton_step"](R, q)
        np.testing.assert_allclose(np.asarray(R_next).reshape(-1), R_ref.reshape(-1), rtol=0, atol=1e-12)
        assert np.asarray(residual).reshape(-1)[0] == pytest.approx(np.asarray(residual_ref).reshape(-1)[0],
                                                                    abs=1e-15)


@pytest.mark.compiling
def test_batch_of_five_bars_of_different_dimensions_follows_their_closed_forms():
    """Three five-bars (the bundled one scaled: the same topology) in each SIMD-batched Newton call,
    both cranks driven: each against its own closed form."""
    from gagen.apps.linkage.batch import family, sweep

    linkage = load_linkage(FIVE_BAR)
    scales = np.array([1.0, 1.5, 0.8])
    X0 = np.array([initial_points(linkage) * s for s in scales])
    values = np.stack([np.linspace(0, 2 * np.pi, 73), np.linspace(0, -4 * np.pi, 73)], axis=1)
    result = sweep(family(linkage), linkage, X0, values, tolerance=TIGHT)
    assert (result.reached == len(values)).all() and np.nanmax(result.residuals) < TIGHT
    k = kernels(linkage)  # positions of the scaled mechanisms: the bundled kernels at scaled motors
    closed = five_bar_closed_form(values)["P"]
    i = point_index(linkage, "left_link", "P")
    for m, scale in enumerate(scales):
        R = result.motors[:, m].copy()
        R[:, 2::4] /= scale  # a translation part scales with the mechanism: back to the unit one
        R[:, 3::4] /= scale
        P = np.array([np.asarray(k.positions(r, q)).reshape(-1)[i:i + 2] for r, q in zip(R, values,
                                                                                       strict=True)])
        np.testing.assert_allclose(P * scale, closed * scale, rtol=0, atol=1e-12 * scale)
