"""The bundled mechanisms (issue 15, item 4): every spec in the robots folder loads with mobility 1 and
runs a full crank revolution with the residual, the link lengths and the branch checked after every
step; the six-bar, ten-bar and Jansen leg against their circle-intersection closed forms
(``gagen.apps.linkage.assemble``); the Jansen leg's lengths against the published holy numbers and its
foot path's flat bottom."""

from __future__ import annotations

from itertools import combinations, pairwise
from pathlib import Path

import numpy as np
import pytest

from gagen.apps.linkage.assemble import HOLY, JANSEN, MECHANISMS, positions, spec_text
from gagen.apps.linkage.demo import driver_path
from gagen.apps.linkage.solver import kernels, point_index, simulate
from gagen.apps.linkage.spec import Revolute, load_linkage

ROBOTS = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "linkage" / "robots"
SPECS = sorted(ROBOTS.glob("*.yaml"))
ANGLES = np.linspace(0.0, 2 * np.pi, 361)  # a full revolution in 1° steps
JUMP = 5.0  # no point moves more per step than this many times the crank pin does (Jansen's foot: 3.6)


def test_the_bundled_mechanisms_are_there():
    bundled = {"four_bar", "slider_crank", "slider_rocker", "six_bar", "ten_bar", "jansen"}
    assert bundled <= {p.stem for p in SPECS}


@pytest.mark.parametrize("spec", SPECS, ids=lambda p: p.stem)
def test_spec_loads_with_mobility_1(spec):
    linkage = load_linkage(spec)
    assert linkage.mobility() == len(linkage.drivers)  # 1, or k for k drivers (five_bar, crank_slider)
    assert linkage.constraint_rows == 3 * len(linkage.unknown)  # no redundant joint
    assert linkage.trace is not None


@pytest.mark.parametrize(("name", "links", "revolutes"), [("six_bar", 6, 7), ("ten_bar", 10, 13),
                                                          ("jansen", 8, 10)])
def test_link_and_joint_counts_and_a_ternary_link(name, links, revolutes):
    linkage = load_linkage(ROBOTS / f"{name}.yaml")
    assert len(linkage.bodies) + 1 == links
    assert len(linkage.joints) == revolutes and all(isinstance(j, Revolute) for j in linkage.joints)
    jointed = {body: {p for j in linkage.joints for b, p in (j.a, j.b) if b == body}
               for body in linkage.bodies}
    assert max(len(points) for points in jointed.values()) == 3  # a ternary link


@pytest.mark.parametrize("name", sorted(MECHANISMS))
def test_spec_is_the_generators_and_assembled(name):
    """The committed spec is what the generator writes, and its joint points coincide exactly."""
    mechanism = MECHANISMS[name]
    assert (ROBOTS / f"{name}.yaml").read_text() == spec_text(mechanism)
    linkage = load_linkage(ROBOTS / f"{name}.yaml")
    at = positions(mechanism, 0.0)
    for points in linkage.bodies.values():
        for point, xy in points.items():
            assert xy == tuple(at[point])
    for j in linkage.joints:
        assert linkage.point(j.a) == linkage.point(j.b)


def test_jansen_lengths_are_the_holy_numbers():
    """Every link length of the spec (read from its points) against Theo Jansen's published numbers."""
    linkage = load_linkage(ROBOTS / "jansen.yaml")
    bars = {"crank_m": {("O", "A"): "m"}, "bar_j": {("A", "C"): "j"}, "bar_k": {("A", "E"): "k"},
            "bar_c": {("B", "E"): "c"}, "bar_f": {("D", "F"): "f"},
            "triangle_bde": {("B", "C"): "b", ("B", "D"): "d", ("C", "D"): "e"},
            "triangle_ghi": {("E", "F"): "g", ("F", "G"): "h", ("E", "G"): "i"}}
    assert set(bars) == set(linkage.bodies)
    for body, pairs in bars.items():
        points = linkage.bodies[body]
        assert len(pairs) == len(list(combinations(points, 2)))
        for (p, q), letter in pairs.items():
            assert np.hypot(*np.subtract(points[p], points[q])) == pytest.approx(HOLY[letter], abs=1e-12)
    assert linkage.ground == {"O": (0.0, 0.0), "B": (-38.0, -7.8)}  # the crank axle; (−a, −l)
    assert linkage.pivot == "O"
    # the real leg's branch: C above and the foot G far below the axle
    assert linkage.bodies["bar_j"]["C"][1] > 0 and linkage.bodies["triangle_ghi"]["G"][1] < -80


def _lengths(linkage, points: np.ndarray) -> np.ndarray:
    """Every distance between two points of one body, (pairs, steps)."""
    out = []
    for body, named in linkage.bodies.items():
        for a, b in combinations(named, 2):
            i, j = point_index(linkage, body, a), point_index(linkage, body, b)
            out.append(np.hypot(*(points[..., i:i + 2] - points[..., j:j + 2]).T))
    return np.array(out)


def _input_motion(linkage, values: np.ndarray) -> np.ndarray:
    """Per step, how far the driven body's farthest point moves: the crank radius × the turn, or the
    slider's displacement."""
    from gagen.apps.linkage.solver import _driver_motion

    return np.array([_driver_motion(linkage, a, b) for a, b in pairwise(values)])


_runs: dict[str, object] = {}


def _run(spec: Path):
    """The full cycle of a spec (a crank's revolution, a slider's stroke) in 360 steps, solved once per
    session."""
    if spec.stem not in _runs:
        linkage = load_linkage(spec)
        values, phases = driver_path(linkage, 360)
        _runs[spec.stem] = linkage, simulate(kernels(linkage), linkage, values, phases=phases)
    return _runs[spec.stem]


@pytest.mark.compiling
@pytest.mark.parametrize("spec", SPECS, ids=lambda p: p.stem)
def test_full_revolution_keeps_residual_lengths_and_branch(spec):
    linkage, trajectory = _run(spec)
    assert not trajectory.failures
    assert trajectory.residuals.max() < 1e-12
    initial = np.concatenate([linkage.bodies[b][p] for b in linkage.bodies for p in linkage.bodies[b]])
    np.testing.assert_allclose(_lengths(linkage, trajectory.points),
                               np.repeat(_lengths(linkage, initial)[:, None], len(ANGLES), axis=1), rtol=0,
                               atol=1e-12)
    moved = np.diff(trajectory.points, axis=0).reshape(len(ANGLES) - 1, -1, 2)
    bound = JUMP * _input_motion(linkage, trajectory.angles) + 1e-12
    assert (np.hypot(moved[..., 0], moved[..., 1]).max(axis=1) < bound).all()
    assert trajectory.points[-1] == pytest.approx(trajectory.points[0], abs=1e-10)  # the cycle closes


@pytest.mark.compiling
@pytest.mark.parametrize("name", sorted(MECHANISMS))
def test_full_revolution_follows_the_circle_intersections(name):
    """Every point at every step against the closed form on the spec's assembly branch: the branch
    is kept (a jump to another assembly would be off by the order of the links)."""
    linkage, trajectory = _run(ROBOTS / f"{name}.yaml")
    closed = positions(MECHANISMS[name], ANGLES)
    for body, points in linkage.bodies.items():
        for point in points:
            i = point_index(linkage, body, point)
            np.testing.assert_allclose(trajectory.points[:, i:i + 2], closed[point], rtol=0, atol=1e-10)


@pytest.mark.compiling
def test_jansen_foot_path_has_a_flat_bottom():
    """The known property of the holy numbers: over the lowest third of the cycle (the 120° of crank
    whose highest foot point is lowest) the foot rises and falls by 0.32 (0.327 in 1° steps, 0.318 in
    0.1°), under 1 % of its 46 of horizontal travel there; the stride (the path's horizontal extent)
    is 67.9."""
    linkage, trajectory = _run(ROBOTS / "jansen.yaml")
    assert linkage.trace == ("triangle_ghi", "G")
    i = point_index(linkage, *linkage.trace)
    foot = trajectory.points[:-1, i:i + 2]  # 360 steps of 1°
    windows = (np.arange(120 + 1)[None, :] + np.arange(360)[:, None]) % 360
    low = windows[np.argmin(foot[windows, 1].max(axis=1))]
    flat, travel = np.ptp(foot[low, 1]), np.ptp(foot[low, 0])
    assert flat == pytest.approx(0.32, abs=0.01) and travel == pytest.approx(46.3, abs=0.2)
    assert flat < 0.01 * travel
    assert np.ptp(foot[:, 0]) == pytest.approx(67.91, abs=0.01)
    assert np.ptp(foot[:, 1]) == pytest.approx(22.46, abs=0.01)
    assert JANSEN.trace == "triangle_ghi.G"
