"""Singular configurations along a driven cycle (issue 32, item 3): the four-bar's dead centres and
branch points found by ``singularity.analyse`` against their closed forms in the Grashof cases
(1e-9 rad), every point of the followed path against the closed-form assembly branches, and the
branch switching at a dead centre and at a change point landing on the other closed-form branch."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gagen.apps.linkage.assemble import intersect
from gagen.apps.linkage.singularity import BRANCH_POINT, DEAD_CENTRE, analyse, four_bar_text, table
from gagen.apps.linkage.solver import kernels, point_index
from gagen.apps.linkage.spec import load_linkage
from gagen.cli import main

ANGLE = 1.3  # the initial crank angle (rad): off the 1° grid, so no step lands on a singular point
# (ground, crank, coupler, rocker) of the Grashof cases
CRANK_ROCKER = (4.0, 1.0, 3 * np.sqrt(2), 3.0)  # s + l < p + q, the crank shortest
DOUBLE_ROCKER = (3.0, 3.5, 1.0, 3.0)  # s + l < p + q, the coupler shortest
CHANGE_POINT = (2.0, 1.0, 3.0, 2.0)  # s + l = p + q: folds flat at crank angle 0
EXACT = 1e-9  # rad, against the closed forms
PATH = 1e-10  # path points against the closed-form branch (Newton to max |F| 1e-13 near singular poses)


def _setup(tmp_path: Path, lengths, driver: str = "crank", angle: float = ANGLE):
    path = tmp_path / f"{driver}_{len(list(tmp_path.iterdir()))}.yaml"
    path.write_text(four_bar_text("grashof_case", *lengths, angle, driver))
    linkage = load_linkage(path)
    return linkage, kernels(linkage)


def _points(linkage, analysis) -> tuple[np.ndarray, np.ndarray]:
    b, c = point_index(linkage, "crank", "B"), point_index(linkage, "coupler", "C")
    return analysis.points[:, b:b + 2], analysis.points[:, c:c + 2]


def _sides(lengths, values: np.ndarray, B: np.ndarray, C: np.ndarray, driver: str,
           singular: list[int]) -> np.ndarray:
    """Per path point, which closed-form branch it is on (+1: left of B → D for a crank input, of
    A → C for a rocker input; −1: right; 0 at a singular point, on both), asserting that it is on one
    of them to PATH, or to 1e-6 at the ``singular`` points: located 1e-12 from where two branches
    meet, a configuration there is determined to √1e-12 only."""
    ground, crank, coupler, rocker = lengths
    A, D = np.zeros(2), np.array([ground, 0.0])
    out = []
    if driver == "crank":
        angle = ANGLE + values
        Bc = crank * np.stack([np.cos(angle), np.sin(angle)], axis=-1)
        np.testing.assert_allclose(B, Bc, rtol=0, atol=PATH)
        branches = {s: intersect(Bc, coupler, D, rocker, s) for s in (1, -1)}
        moving = C
    else:
        C0 = intersect(np.array([crank * np.cos(ANGLE), crank * np.sin(ANGLE)]), coupler, D, rocker, 1)
        phi = np.arctan2(C0[1], C0[0] - ground) + values
        Cc = D + rocker * np.stack([np.cos(phi), np.sin(phi)], axis=-1)
        np.testing.assert_allclose(C, Cc, rtol=0, atol=PATH)
        branches = {s: intersect(np.tile(A, (len(values), 1)), crank, Cc, coupler, s) for s in (1, -1)}
        moving = B
    for i in range(len(values)):
        distance = {s: float(np.abs(moving[i] - branches[s][i]).max()) for s in (1, -1)}
        side = min(distance, key=lambda s: distance[s])
        assert distance[side] <= (1e-6 if i in singular else PATH), (i, distance)
        out.append(0 if i in singular else side)
    return np.array(out)


@pytest.mark.compiling
def test_crank_rocker_has_no_dead_centre_of_its_crank(tmp_path):
    linkage, k = _setup(tmp_path, CRANK_ROCKER)
    analysis = analyse(k, linkage, 360, switch=True)
    assert analysis.closed and len(analysis.values) == 361 and not analysis.singularities
    assert np.abs(analysis.tau).min() > 0.05 and analysis.residuals.max() < 1e-12
    B, C = _points(linkage, analysis)
    assert (_sides(CRANK_ROCKER, analysis.values, B, C, "crank", []) == 1).all()
    assert "(none" in table(linkage, analysis)


@pytest.mark.compiling
def test_crank_rocker_driven_by_its_rocker_has_two_dead_centres(tmp_path):
    """The rocker's extreme angles, where crank and coupler align: |AC| = b ± a, so
    cos φ = ((b ± a)² − g² − c²) / (2 g c)."""
    g, a, b, c = CRANK_ROCKER
    linkage, k = _setup(tmp_path, CRANK_ROCKER, "rocker")
    analysis = analyse(k, linkage, 360, switch=True)
    C0 = intersect(np.array([a * np.cos(ANGLE), a * np.sin(ANGLE)]), b, np.array([g, 0.0]), c, 1)
    phi0 = np.arctan2(C0[1], C0[0] - g)
    expected = sorted(np.arccos(((b + s * a) ** 2 - g * g - c * c) / (2 * g * c)) - phi0 for s in (1, -1))
    found = sorted(s.value for s in analysis.singularities)
    assert [s.kind for s in analysis.singularities] == [DEAD_CENTRE] * 2
    np.testing.assert_allclose(found, expected, rtol=0, atol=EXACT)
    assert min(s.sigma_full for s in analysis.singularities) > 0.1  # a fold: the full Jacobian is regular
    assert analysis.closed and analysis.residuals.max() < 1e-12
    B, C = _points(linkage, analysis)
    first, second = (s.index for s in analysis.singularities)
    sides = _sides(CRANK_ROCKER, analysis.values, B, C, "rocker", [first, second])
    assert (sides[:first] == sides[0]).all() and (sides[first + 1:second] == -sides[0]).all()
    assert (sides[second + 1:] == sides[0]).all()


@pytest.mark.compiling
def test_double_rocker_input_range_ends_where_coupler_and_output_align(tmp_path):
    """The input's limits: |BD| = c ± b, so cos θ = (a² + g² − (c ± b)²) / (2 a g); without switching
    the path ends at the first."""
    g, a, b, c = DOUBLE_ROCKER
    linkage, k = _setup(tmp_path, DOUBLE_ROCKER)
    expected = sorted(np.arccos((a * a + g * g - (c + s * b) ** 2) / (2 * a * g)) - ANGLE for s in (1, -1))
    stopped = analyse(k, linkage, 360)
    assert len(stopped.singularities) == 1 and not stopped.closed
    assert stopped.singularities[0].value == pytest.approx(expected[1], abs=EXACT)
    assert stopped.singularities[0].index == len(stopped.values) - 1  # the path ends there
    analysis = analyse(k, linkage, 360, switch=True)
    assert [s.kind for s in analysis.singularities] == [DEAD_CENTRE] * 2 and analysis.closed
    np.testing.assert_allclose(sorted(s.value for s in analysis.singularities), expected, rtol=0, atol=EXACT)
    assert all(s.sigma_passive < 1e-5 < 0.1 < s.sigma_full for s in analysis.singularities)


@pytest.mark.compiling
def test_change_point_four_bar_has_branch_points_where_it_folds_flat(tmp_path):
    """s + l = p + q: at crank angle 0 all four joints lie on the ground line and the two assembly
    branches cross (σ_min of the full Jacobian vanishes too). Followed smoothly the path changes
    branch there and closes after two turns; switching keeps C on its side and closes after one."""
    linkage, k = _setup(tmp_path, CHANGE_POINT)
    smooth = analyse(k, linkage, 360, max_steps=800)
    assert [s.kind for s in smooth.singularities] == [BRANCH_POINT] * 2 and smooth.closed
    np.testing.assert_allclose([s.value for s in smooth.singularities],
                               [2 * np.pi - ANGLE, 4 * np.pi - ANGLE], rtol=0, atol=EXACT)
    assert all(s.sigma_full < 1e-6 for s in smooth.singularities)
    assert len(smooth.values) == 2 * 360 + 1 + 2  # two turns, and the two located points
    switched = analyse(k, linkage, 360, switch=True)
    assert len(switched.singularities) == 1 and switched.singularities[0].switched and switched.closed
    assert switched.singularities[0].value == pytest.approx(2 * np.pi - ANGLE, abs=EXACT)
    assert len(switched.values) == 360 + 1 + 1


@pytest.mark.compiling
@pytest.mark.parametrize(("lengths", "switch", "flips"), [(DOUBLE_ROCKER, True, True),
                                                          (CHANGE_POINT, False, True),
                                                          (CHANGE_POINT, True, False)])
def test_branch_switching_lands_on_the_other_closed_form_branch(tmp_path, lengths, switch, flips):
    """Just before and just after the first singular point: the constraints hold to 1e-12 and the
    coupler point C is on a closed-form branch (to 1e-10), the other one exactly where the path
    changes branch (a dead centre passed with switching, a branch point passed smoothly), the same
    one where switching at a branch point keeps C on its side."""
    linkage, k = _setup(tmp_path, lengths)
    analysis = analyse(k, linkage, 360, switch=switch, max_steps=400)
    singular = analysis.singularities[0]
    before, after = singular.index - 1, singular.index + 1
    assert analysis.residuals[[before, singular.index, after]].max() < 1e-12
    B, C = _points(linkage, analysis)
    sides = _sides(lengths, analysis.values, B, C, "crank", [s.index for s in analysis.singularities])
    assert sides[before] == 1 and sides[singular.index] == 0
    assert sides[after] == (-1 if flips else 1)
    assert abs(analysis.values[after] - singular.value) <= np.radians(1.0)


@pytest.mark.compiling
def test_singularities_verb_prints_the_table_and_plots(tmp_path, capsys):
    spec = tmp_path / "double_rocker.yaml"
    spec.write_text(four_bar_text("double_rocker", *DOUBLE_ROCKER, ANGLE))
    out = tmp_path / "out"
    assert main(["singularities", str(spec), "--switch", "--steps", "90", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    g, a, b, c = DOUBLE_ROCKER
    upper = np.degrees(np.arccos((a * a + g * g - (c + b) ** 2) / (2 * a * g)) - ANGLE)
    rows = [line.split() for line in printed.splitlines() if line.startswith("dead centre")]
    assert len(rows) == 2 and float(rows[0][2].rstrip("°")) == pytest.approx(upper, abs=np.degrees(EXACT))
    assert (out / "double_rocker" / "singularities.png").stat().st_size > 10_000


def test_singularities_verb_refuses_a_bad_spec_and_two_drivers(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("app: linkage\nname: x\n")
    assert main(["singularities", str(bad), "--out", str(tmp_path)]) == 2
    five = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "linkage" / "robots" / "five_bar.yaml"
    assert main(["singularities", str(five), "--out", str(tmp_path)]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 2 and "bad.yaml" in errors[0] and "five_bar.yaml: driver:" in errors[1]
