"""The analytic IK on legs other than the bundled one (issue 29): thigh shorter than, equal to and
longer than the shank, flat and rolled/pitched mounts, flipped axis signs, limits a turn away from
[−π, π] or wider than it. Held against the 4×4 matrix chain (tests/hexapod/matrix_chain.py) and plain
numpy geometry, on the interpreter (``legs.analytic_ik``) and on the kernel's traced graph (``<leg>_ik``'s
CasADi function, the graph the C code is printed from; the compiled bundled module: test_ik.py):

- every toe of an in-limit configuration is reached (reach 1, both knee branches on the target to
  1e-12), and the branch of the sample's knee sign is in the limits: the toe behind the yaw axis
  needs yaw + π, and with l2 ≠ l3 the atan2 yaw alone leaves it inside the inner radius |l2 − l3|;
- any target (inside the inner radius, outside the outer one, on the yaw axis) gives the pose whose
  toe is ``excess`` from it, with ``excess`` the smaller of the two yaw branches' distances;
- NaN, infinite and huge targets give finite angles, reach 0 and a finite excess."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import tiered

from gagen.apps.hexapod.kernels import _ik_kernel
from gagen.apps.hexapod.legs import analytic_ik, leg_kinematics
from gagen.apps.hexapod.spec import Leg
from gagen.interp import MultiVector, preset
from gagen.model.euclidean import GEOMETRIES

from . import matrix_chain as mc

PGA = GEOMETRIES["pga3d"]
TOL = 1e-12
MAX_TARGET = 1e9  # legs.MAX_TARGET: the largest target coordinate the IK solves
LIMITS = ((-0.785, 0.785), (-1.571, 1.571), (-2.618, 2.618))  # the bundled leg's
LENGTHS = {"thigh_short": (0.07, 0.23, 0.31), "equal": (0.05, 0.20, 0.20), "thigh_long": (0.06, 0.30, 0.18)}
FLIPPED = ((0.0, 0.0, -1.0), (0.0, -1.0, 0.0), (0.0, 1.0, 0.0))
TURN = 2 * np.pi
# the same ranges a turn away (yaw, thigh) and wider than a half turn (knee): the IK turns its angles
TURNED = ((TURN - 0.785, TURN + 0.785), (-1.571 - TURN, 1.571 - TURN), (-4.0, 0.3))
MOUNTS = {  # xyz, rpy, axes, limits
    "flat": ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), None, LIMITS),
    "tilted": ((0.1, -0.05, 0.02), (0.3, -0.2, 0.7), None, LIMITS),
    "tilted_flipped": ((-0.08, 0.07, -0.01), (-0.25, 0.35, -2.2), FLIPPED, LIMITS),
    "turned": ((0.02, 0.03, 0.0), (0.1, 0.2, 0.3), None, TURNED),
}
LEGS = {f"{length}_{mount}": (length, mount) for length in LENGTHS for mount in MOUNTS}


def make_leg(key: str) -> Leg:
    length, mount = LEGS[key]
    xyz, rpy, axes, limits = MOUNTS[mount]
    leg = Leg("leg", xyz, rpy, LENGTHS[length], limits=limits)
    return replace(leg, axes=axes) if axes else leg


def interpreted(leg: Leg, targets: np.ndarray) -> tuple[np.ndarray, ...]:
    """q_up (n, 3), q_down (n, 3), reach (n,), excess (n,) from ``legs.analytic_ik`` on floats."""
    like = MultiVector.zero(preset("pga3d"))
    solved = [analytic_ik(PGA, like, leg, [float(v) for v in t]) for t in targets]
    return (np.array([s["q_up"] for s in solved], dtype=float),
            np.array([s["q_down"] for s in solved], dtype=float),
            np.array([s["reach"] for s in solved], dtype=float),
            np.array([s["excess"] for s in solved], dtype=float))


def traced(leg: Leg, targets: np.ndarray) -> tuple[np.ndarray, ...]:
    """The same from the ``<leg>_ik`` kernel's traced graph, batched (CasADi map)."""
    function = _ik_kernel(leg).trace().function.map(len(targets))
    q_up, q_down, reach, excess = (np.asarray(x, dtype=float) for x in function(targets.T))
    return q_up.T, q_down.T, reach[0], excess[0]


SOLVERS = {"interpreter": interpreted, "kernel": traced}


def wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2 * np.pi) - np.pi


def in_limits(leg: Leg, q: np.ndarray, slack: float = 1e-9) -> np.ndarray:
    lo, hi = np.array(leg.limits).T
    return ((q >= lo - slack) & (q <= hi + slack)).all(axis=1)


def expected_excess(leg: Leg, targets: np.ndarray) -> np.ndarray:
    """How far the nearest toe is from each target (numpy geometry, no IK): the yaw turns the thigh
    joint to l1 towards the target's heading or away from it, the toe then sweeps the annulus
    |l2 − l3| ≤ d ≤ l2 + l3 about the joint in the plane through the yaw axis and the target."""
    l1, l2, l3 = leg.lengths
    hip = mc.to_hip(leg, targets)
    radial = np.hypot(hip[:, 0], hip[:, 1])
    best = np.full(len(targets), np.inf)
    for along in (radial - l1, -radial - l1):
        d = np.hypot(along, hip[:, 2])
        best = np.minimum(best, np.maximum(0.0, np.maximum(d - (l2 + l3), abs(l2 - l3) - d)))
    return best


def check_in_limit_targets(leg: Leg, q: np.ndarray, solved: tuple[np.ndarray, ...]) -> None:
    """Toes of in-limit configurations q: reached by both branches; the branch of q's knee sign is in
    the limits and (away from the degenerate poses) is q itself."""
    targets = mc.toe(leg, q)
    q_up, q_down, reach, excess = solved
    for x in solved:
        assert np.isfinite(x).all()
    for name, branch in (("q_up", q_up), ("q_down", q_down)):
        error = np.linalg.norm(mc.toe(leg, branch) - targets, axis=1)
        worst = int(error.argmax())
        assert error[worst] <= TOL, (f"{name}: toe {error[worst]:.3g} m off for q = {q[worst].tolist()}, "
                                     f"reach {reach[worst]}")
    missed = np.flatnonzero(reach != 1)
    assert not len(missed), f"{len(missed)} reachable targets flagged 0, e.g. q = {q[missed[0]].tolist()}"
    assert (np.abs(excess) <= TOL).all()
    up = np.sin(np.sign(leg.axes[2][1]) * q[:, 2]) >= 0  # knee up: the knee angle about +y in [0, π]
    mine = np.where(up[:, None], q_up, q_down)
    outside = np.flatnonzero(~in_limits(leg, mine))
    assert not len(outside), (f"{len(outside)} branches outside the limits, e.g. q = "
                              f"{q[outside[0]].tolist()} solved as {mine[outside[0]].tolist()}")
    # away from the folded/straight knee and the yaw axis the solution of q's knee sign is unique
    # within these limits (the yaw range is narrower than π)
    hip = mc.to_hip(leg, targets)
    posed = (np.abs(np.sin(q[:, 2])) > 1e-3) & (np.hypot(hip[:, 0], hip[:, 1]) > 1e-3)
    assert posed.mean() > 0.9
    distance = np.abs(wrap(mine - q)).max(axis=1)
    assert (distance[posed] <= 1e-9).all(), f"largest {distance[posed].max():.2e} rad"


def test_the_issues_example_is_reached():
    """Lengths 0.07, 0.23, 0.31 and q = [−0.696672, 1.110612, 2.548724] (issue 29): the toe is behind
    the yaw axis; atan2's yaw put it inside |l2 − l3| and the IK returned reach 0, 0.0208 m off."""
    leg = make_leg("thigh_short_flat")
    q = np.array([[-0.696672, 1.110612, 2.548724]])
    hip = mc.to_hip(leg, mc.toe(leg, q))[0]
    along_heading = np.hypot(np.hypot(hip[0], hip[1]) - 0.07, hip[2])  # from the thigh joint, atan2's yaw
    assert hip[0] < 0 and 0.31 - 0.23 - along_heading > 0.02  # behind the yaw axis; in the hole
    for solve in SOLVERS.values():
        solved = solve(leg, mc.toe(leg, q))
        check_in_limit_targets(leg, q, solved)
        np.testing.assert_allclose(solved[0], q, rtol=0, atol=1e-9)


def _in_limit_round_trip(key: str, solver: str, count: int) -> None:
    leg = make_leg(key)
    q = mc.random_configurations(leg, np.random.default_rng(sum(map(ord, key)) + count), count)
    check_in_limit_targets(leg, q, SOLVERS[solver](leg, mc.toe(leg, q)))


@pytest.mark.parametrize("count", tiered([200, 1000], {200}))  # (1000 in the full tier)
@pytest.mark.parametrize("solver", list(SOLVERS))
@pytest.mark.parametrize("key", list(LEGS))
def test_toes_of_in_limit_configurations_are_reached(key, solver, count):
    _in_limit_round_trip(key, solver, count)


def any_targets(leg: Leg, rng: np.random.Generator, n: int) -> np.ndarray:
    """Targets anywhere within 1.5× the leg's reach of the hip (inside the inner radius, outside the
    outer one), plus the yaw axis and the thigh joint of either yaw."""
    l1, l2, l3 = leg.lengths
    size = 1.5 * (l1 + l2 + l3)
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    hip = direction * size * rng.uniform(0, 1, (n, 1)) ** (1 / 3)
    special = np.array([[0, 0, 0], [0, 0, -0.2], [0, 0, 0.3], [0, 0, -1.0], [l1, 0, 0], [-l1, 0, 0],
                        [0, l1, 0], [l1, 0, -abs(l2 - l3)], [-l1, 0, abs(l2 - l3) / 2]])
    return mc.from_hip(leg, np.concatenate([hip, special]))


def _any_target(key: str, solver: str, count: int) -> None:
    leg = make_leg(key)
    targets = any_targets(leg, np.random.default_rng(sum(map(ord, key)) + 7 * count), count)
    q_up, q_down, reach, excess = SOLVERS[solver](leg, targets)
    want = expected_excess(leg, targets)
    bad = np.flatnonzero(np.abs(excess - want) > TOL)
    assert not len(bad), (f"{len(bad)} of {len(targets)} targets with the wrong excess, e.g. "
                          f"{targets[bad[0]].tolist()}: {excess[bad[0]]:.4g} m, expected {want[bad[0]]:.4g}")
    np.testing.assert_array_equal(reach, (want <= 1e-9).astype(float))
    for branch in (q_up, q_down):
        assert np.isfinite(branch).all()
        off = np.linalg.norm(mc.toe(leg, branch) - targets, axis=1)
        np.testing.assert_allclose(off, want, rtol=0, atol=TOL)


@pytest.mark.parametrize("count", tiered([200, 1000], {200}))
@pytest.mark.parametrize("solver", list(SOLVERS))
@pytest.mark.parametrize("key", list(LEGS))
def test_any_target_gives_the_nearest_toe(key, solver, count):
    _any_target(key, solver, count)


NONFINITE = np.array([
    [np.nan, 0.1, -0.1], [0.1, np.nan, 0.0], [0.0, 0.0, np.nan], [np.nan] * 3, [np.inf, 0.0, 0.0],
    [-np.inf, 0.1, 0.2], [np.inf, -np.inf, np.nan], [1e308] * 3, [-1e308, 1e308, 0.0], [1e308, 0.0, 0.0],
    [0.0, 0.0, -1e200], [1e20, 0.3, -0.1], [5e9, -5e9, 1.0],
])


@pytest.mark.parametrize("solver", list(SOLVERS))
@pytest.mark.parametrize("key", ["thigh_short_tilted", "equal_flat", "thigh_long_tilted_flipped"])
def test_nonfinite_and_huge_targets_give_finite_angles_flagged_unreachable(key, solver):
    leg = make_leg(key)
    q_up, q_down, reach, excess = SOLVERS[solver](leg, NONFINITE)
    for x in (q_up, q_down, reach, excess):
        assert np.isfinite(x).all(), x
    assert (reach == 0).all()
    assert (excess >= MAX_TARGET / 2).all()  # far beyond any leg: a finite stand-in for "out of range"
    # a target just inside the range is still solved
    near = mc.from_hip(leg, np.array([[0.5 * MAX_TARGET, 0.0, 0.0]]))
    _, _, reach_near, excess_near = SOLVERS[solver](leg, near)
    assert reach_near[0] == 0 and np.isfinite(excess_near[0]) and excess_near[0] > 0.4 * MAX_TARGET


COMPILED = ("thigh_short_flat", "thigh_short_tilted", "thigh_short_tilted_flipped", "equal_tilted",
            "thigh_long_flat", "thigh_long_tilted_flipped")


def _spec_line(key: str) -> str:
    leg = make_leg(key)
    return (f"  - {{name: {key}, xyz: {list(leg.xyz)}, rpy: {list(leg.rpy)}, lengths: {list(leg.lengths)}, "
            f"axes: {[list(a) for a in leg.axes]}, limits: {[list(b) for b in leg.limits]}}}\n")


@pytest.mark.compiling
def test_compiled_ik_of_unequal_legs(tmp_path):
    """The same on the compiled C kernels (SIMD batch) of a hexapod of six such legs."""
    from gagen.apps.hexapod.gait import hexapod_module

    spec = tmp_path / "unequal.yaml"
    spec.write_text("app: hexapod\nname: unequal\nlegs:\n" + "".join(map(_spec_line, COMPILED)))
    module = hexapod_module(spec, tmp_path / "out")

    def compiled(leg: Leg, targets: np.ndarray) -> tuple[np.ndarray, ...]:
        q_up, q_down, reach, excess = getattr(module.c, f"{leg.name}_ik").batch(targets)
        return q_up, q_down, reach[:, 0], excess[:, 0]

    for i, key in enumerate(COMPILED):
        leg = replace(make_leg(key), name=key)
        q = mc.random_configurations(leg, np.random.default_rng(i), 1000)
        check_in_limit_targets(leg, q, compiled(leg, mc.toe(leg, q)))
        targets = any_targets(leg, np.random.default_rng(100 + i), 1000)
        q_up, q_down, reach, excess = compiled(leg, targets)
        want = expected_excess(leg, targets)
        np.testing.assert_allclose(excess, want, rtol=0, atol=TOL)
        np.testing.assert_array_equal(reach, (want <= 1e-9).astype(float))
        for branch in (q_up, q_down):
            np.testing.assert_allclose(np.linalg.norm(mc.toe(leg, branch) - targets, axis=1), excess,
                                       rtol=0, atol=TOL)
        for x in compiled(leg, NONFINITE):
            assert np.isfinite(x).all()
        assert (compiled(leg, NONFINITE)[2] == 0).all()



@pytest.mark.parametrize("mount", [((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
                                   ((-1e6, 0.12890625, 1e6), (-1000.0, 2.08757301477913, np.pi / 2))])
def test_the_toes_of_a_leg_mounted_far_from_the_body_origin_are_reached(mount):
    """The fuzzer's leg (tests/fuzz/test_fuzz_hexapod.py found it): mounted 1e6 m from the body origin,
    turned by rpy (−1000, 2.09, π/2), its toes at the limits' corners. The hip-frame target carries the
    mount's rounding (≈ 1e6 · 1e-16 m), so the former absolute reach tolerance of 1e-9 m called the leg's
    own FK toe unreachable; the tolerance is now relative to the leg's size 1 + max|mount| + Σ lengths."""
    xyz, rpy = mount
    leg = Leg("front_right", xyz, rpy, (0.001, 0.3333333333333333, 0.05062471461285534))
    like = MultiVector.zero(preset("pga3d"))
    size = 1 + 1e6 * (xyz[0] != 0) + sum(leg.lengths)
    lo, hi = np.array(leg.limits).T
    for q in ((lo + hi) / 2, lo, hi):
        toe = [float(v) for v in leg_kinematics(PGA, like, leg, [float(v) for v in q])["p"]]
        solved = analytic_ik(PGA, like, leg, toe)
        assert solved["reach"] == 1.0, (q, solved["excess"])
        for branch in ("q_up", "q_down"):
            reached = leg_kinematics(PGA, like, leg, [float(v) for v in solved[branch]])["p"]
            assert max(abs(a - b) for a, b in zip(reached, toe, strict=True)) <= 1e-9 * size
