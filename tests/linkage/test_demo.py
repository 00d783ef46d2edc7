"""The linkage pictures and ``gagen linkage`` (issue 15, items 3-4): the drawing geometry against rigid
motions applied by hand (fast), the PNGs and the GIF of a simulated four-bar read back with PIL (their
colours, frame count, a trace that grows), and the command's exit statuses (0, 1 on a crank that cannot
turn, 2 on a bad spec)."""

from __future__ import annotations

import dataclasses
from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from gagen.apps.linkage import plots
from gagen.apps.linkage.demo import bundled, crank_angles, summary
from gagen.apps.linkage.kernels import point_labels
from gagen.apps.linkage.solver import Trajectory, kernels, simulate
from gagen.apps.linkage.spec import GROUND, Linkage, Prismatic, load_linkage
from gagen.cli import main

ROBOTS = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "linkage" / "robots"
FOUR_BAR = ROBOTS / "four_bar.yaml"
SLIDER = ROBOTS / "slider_crank.yaml"
GREEN, BLUE, TRACE = (44, 160, 44), (31, 119, 180), (204, 0, 204)  # crank, ground, traced curve (magenta)


def _turn(angle: float) -> np.ndarray:
    return np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])


def _moved(linkage: Linkage, motions: dict[str, tuple[float, np.ndarray]]) -> np.ndarray:
    """A ``Trajectory.points`` row: every body's spec points moved by its (angle, translation)."""
    row = np.zeros(len(point_labels(linkage)))
    labels = point_labels(linkage)
    for body, points in linkage.bodies.items():
        angle, shift = motions[body]
        for name, xy in points.items():
            i = labels.index(f"{body}_{name}_x")
            row[i:i + 2] = _turn(angle) @ np.array(xy) + shift
    return row


def _closed_form_four_bar(linkage: Linkage, angles: np.ndarray) -> Trajectory:
    """The four-bar's points by circle intersection (its assembly branch: C above the line B–D)."""
    A, D = np.array(linkage.ground["A"]), np.array(linkage.ground["D"])
    B0, C0 = (np.array(linkage.bodies["coupler"][n]) for n in "BC")
    l2, l3 = np.linalg.norm(C0 - B0), np.linalg.norm(C0 - D)
    rows = []
    for theta in angles:
        B = A + _turn(theta) @ (B0 - A)
        d = np.linalg.norm(D - B)
        a = (l2**2 - l3**2 + d**2) / (2 * d)
        u = (D - B) / d
        C = B + a * u + np.sqrt(l2**2 - a**2) * np.array([-u[1], u[0]])
        phi = np.arctan2(*(C - B)[::-1]) - np.arctan2(*(C0 - B0)[::-1])
        rocker = np.arctan2(*(C - D)[::-1]) - np.arctan2(*(C0 - D)[::-1])
        rows.append(_moved(linkage, {"crank": (theta, A - _turn(theta) @ A),
                                     "coupler": (phi, B - _turn(phi) @ B0),
                                     "rocker": (rocker, D - _turn(rocker) @ D)}))
    n = len(angles)
    return Trajectory(angles, np.zeros((n, 8)), np.array(rows), np.full(n, 3), np.full(n, 1e-15),
                      np.full(n, 0.3), np.full(n, 20.0), np.zeros(n, dtype=int))


# --- drawing geometry (fast) ------------------------------------------------------------------------------

def test_bodies_are_drawn_through_their_moved_points_in_angle_order():
    linkage = load_linkage(FOUR_BAR)
    motions = {"crank": (0.7, np.array([0.0, 0.0])), "coupler": (-1.1, np.array([0.3, -2.0])),
               "rocker": (2.5, np.array([-1.0, 4.0]))}
    drawn = plots.body_points(linkage, _moved(linkage, motions))
    assert plots.outline(linkage, "coupler") == ["B", "C", "P"]  # angles about (7/3, 2): −146°, −18°, 162°
    for body, points in linkage.bodies.items():
        angle, shift = motions[body]
        order = plots.outline(linkage, body)
        expected = np.array([_turn(angle) @ np.array(points[n]) + shift for n in order])
        np.testing.assert_allclose(drawn[body], expected, rtol=0, atol=1e-14)
        R, t = plots.rigid_motion(np.array([points[n] for n in order]), drawn[body])
        np.testing.assert_allclose(R, _turn(angle), rtol=0, atol=1e-12)
        np.testing.assert_allclose(t, shift, rtol=0, atol=1e-12)
    np.testing.assert_allclose(drawn[GROUND], [[4, 0], [0, 0]], rtol=0, atol=0)  # D at 0°, A at 180°
    assert plots.body_colours(linkage)["crank"] == "tab:green"
    assert "tab:blue" not in plots.body_colours(linkage).values()  # blue is the ground's


def test_a_slot_is_its_travel_carried_by_its_body():
    slider = load_linkage(SLIDER)
    row = _moved(slider, {"crank": (1.0, np.zeros(2)), "coupler": (0.4, np.array([1.0, 2.0]))})
    [(on, segment)] = plots.slot_segments(slider, row)
    assert on == GROUND
    np.testing.assert_allclose(segment, [[0, 3], [0, 5]], rtol=0, atol=1e-15)  # x = 0, 3 ≤ y ≤ 5
    four = load_linkage(FOUR_BAR)  # a slot on the rocker (drawing only: no mobility check here)
    slot = Prismatic(("coupler", "P"), "rocker", (4.0, 1.0), (0.6, 0.8), (-1.0, 2.0))
    carried = dataclasses.replace(four, joints=(*four.joints, slot))
    angle, shift = 0.9, np.array([4.0, 0.0]) - _turn(0.9) @ np.array([4.0, 0.0])  # the rocker about D
    row = _moved(four, {"crank": (0.0, np.zeros(2)), "coupler": (0.0, np.zeros(2)), "rocker": (angle, shift)})
    [(on, segment)] = plots.slot_segments(carried, row)
    ends = np.array([[4.0 - 0.6, 1.0 - 0.8], [4.0 + 1.2, 1.0 + 1.6]])
    assert on == "rocker"
    np.testing.assert_allclose(segment, ends @ _turn(angle).T + shift, rtol=0, atol=1e-12)


def test_paths_skip_fixed_points_and_merge_joints():
    linkage = load_linkage(FOUR_BAR)
    trajectory = _closed_form_four_bar(linkage, crank_angles(36))
    paths = plots.paths(linkage, trajectory)
    # crank.A and rocker.D stay on the ground; crank.B = coupler.B and coupler.C = rocker.C coincide
    assert set(paths) == {("crank", "B"), ("coupler", "C"), ("coupler", "P")}
    np.testing.assert_allclose(np.hypot(*paths[("crank", "B")].T), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.hypot(*(paths[("coupler", "C")] - [4, 0]).T), 3.0, rtol=0, atol=1e-12)
    assert plots.traced(linkage) == [("coupler", "P")]
    untraced = dataclasses.replace(linkage, trace=None)
    assert plots.traced(untraced) == [("coupler", "B"), ("coupler", "C"), ("coupler", "P"), ("rocker", "C")]


def test_summary_names_the_worst_step():
    linkage = load_linkage(FOUR_BAR)
    trajectory = _closed_form_four_bar(linkage, crank_angles(36))
    trajectory.sigma_min[9] = 1e-3
    trajectory.iterations[20] = 7
    trajectory.halvings[20] = 2
    text = summary(linkage, trajectory)
    assert "36 crank steps over 360°" in text
    assert "min 1.000e-03 at crank 90.000°" in text
    assert "max 7 (at crank 200.000°)" in text
    assert "step halvings: 2 in 1 step(s) (max 2, first at crank 200.000°)" in text
    assert "failures: 0" in text


def test_bundled_lists_every_spec_by_name():
    specs = bundled()
    assert specs == sorted(ROBOTS.glob("*.yaml")) and FOUR_BAR in specs and SLIDER in specs


def test_malformed_spec_exits_2_with_the_spec_error(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(FOUR_BAR.read_text().replace("rocker.D, ground.D", "rocker.D, ground.E"))
    out = tmp_path / "out"
    assert main(["linkage", str(FOUR_BAR), str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"error: {bad}: joints[3].revolute[1] (line 14): ground has no point 'E'" in err
    assert not out.exists()  # every spec is read before anything runs
    assert main(["linkage", str(tmp_path / "missing.yaml"), "--out", str(out)]) == 2
    assert "missing.yaml" in capsys.readouterr().err


# --- pictures of a simulated four-bar (compiling) --------------------------------------------------------

@pytest.fixture(scope="module")
def four_bar() -> tuple[Linkage, Trajectory]:
    linkage = load_linkage(FOUR_BAR)
    return linkage, simulate(kernels(linkage), linkage, crank_angles(120))


def _count(image: Image.Image, colour: tuple[int, int, int], tolerance: int = 12) -> int:
    pixels = np.asarray(image.convert("RGB"), dtype=int)
    return int(np.count_nonzero(np.all(np.abs(pixels - colour) <= tolerance, axis=-1)))


@pytest.mark.compiling
def test_coupler_curve_png_shows_crank_ground_and_trace(four_bar, tmp_path):
    linkage, trajectory = four_bar
    path = plots.coupler_curve(linkage, trajectory, tmp_path / "curve.png")
    with Image.open(path) as image:
        assert image.size == (700, 600)
        assert _count(image, GREEN) > 200 and _count(image, BLUE) > 200  # the bars; the pivots' triangles
        traced = _count(image, TRACE)
    # the same figure with the mechanism frozen at its first step: the trace shrinks to a dot
    t = trajectory
    still = Trajectory(t.angles, t.motors, np.repeat(t.points[:1], len(t.angles), 0), t.iterations,
                       t.residuals, t.sigma_min, t.condition, t.halvings)
    with Image.open(plots.coupler_curve(linkage, still, tmp_path / "still.png")) as image:
        assert traced > 500 and _count(image, TRACE) < 50


@pytest.mark.compiling
def test_solver_stats_png(four_bar, tmp_path):
    linkage, trajectory = four_bar
    path = plots.solver_stats(linkage, trajectory, tmp_path / "stats.png")
    with Image.open(path) as image:
        assert image.size == (900, 800)
        assert _count(image, GREEN) > 300  # σ_min's curve (tab:green)
        assert _count(image, (214, 39, 40)) > 100  # the tolerance line (tab:red)


@pytest.mark.compiling
@pytest.mark.slow
def test_animation_has_its_frames_and_a_growing_trace(four_bar, tmp_path):
    linkage, trajectory = four_bar
    path = plots.animate(linkage, trajectory, tmp_path / "four_bar.gif", frames=24, fps=12)
    assert 20e3 < path.stat().st_size < 3e6
    with Image.open(path) as gif:
        assert gif.n_frames == 24
        frames = []
        for i in range(gif.n_frames):
            gif.seek(i)
            frames.append(np.asarray(gif.convert("RGB"), dtype=int))
    assert all(np.any(a != b) for a, b in pairwise(frames))
    traced = [_count(Image.fromarray(f.astype(np.uint8)), TRACE, tolerance=30) for f in frames]  # palette
    assert traced[0] < 20 and traced[12] > 80 and traced[-1] > traced[12] + 80  # the trace grows
    assert _count(Image.fromarray(frames[5].astype(np.uint8)), GREEN) > 50


@pytest.mark.compiling
def test_cli_writes_the_report_and_files(tmp_path, capsys):
    out = tmp_path / "linkage"
    assert main(["linkage", str(FOUR_BAR), "--steps", "60", "--frames", "8", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "four_bar: 60 crank steps over 360°" in text and "failures: 0" in text
    for name in ("coupler_curve.png", "solver_stats.png", "four_bar.gif"):
        assert (out / "four_bar" / name).stat().st_size > 10e3
    with Image.open(out / "four_bar" / "four_bar.gif") as gif:
        assert gif.n_frames == 8


@pytest.mark.compiling
@pytest.mark.slow
def test_cli_exits_1_naming_the_crank_angle_a_crank_cannot_reach(tmp_path, capsys):
    # not Grashof (s + l = 1.5 + 4 > 2 + 2.5): the "crank" of 2 rocks and cannot pass ~±80°
    spec = tmp_path / "rocker.yaml"
    spec.write_text("app: linkage\nname: triple_rocker\nground: {A: [0, 0], D: [4, 0]}\nbodies:\n"
                    "  crank: {A: [0, 0], B: [2, 0]}\n  coupler: {B: [2, 0], C: [4, 1.5]}\n"
                    "  rocker: {C: [4, 1.5], D: [4, 0]}\njoints:\n  - {revolute: [crank.A, ground.A]}\n"
                    "  - {revolute: [crank.B, coupler.B]}\n  - {revolute: [coupler.C, rocker.C]}\n"
                    "  - {revolute: [rocker.D, ground.D]}\ndriver: {body: crank, pivot: ground.A}\n")
    out = tmp_path / "out"
    assert main(["linkage", str(spec), "--steps", "4", "--no-animation", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "error: triple_rocker: step 1 (crank 90.000°)" in err
    assert (out / "triple_rocker" / "coupler_curve.png").exists()  # still drawn, to show where
