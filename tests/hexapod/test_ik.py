"""The hexapod's inverse kinematics against independent references: the analytic IK (interpreter and
compiled, per leg and for the body) round-trips through the 4×4 matrix chain on random reachable
targets (1e-12 m), gives knee-up and knee-down branches and recovers the sampled configuration;
unreachable targets are clamped and flagged, with the excess computed independently; the damped
least-squares IK converges to the same solutions; a leg whose knee axis is not parallel to its thigh
axis is refused by the analytic IK and still solved by DLS."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gagen.algebra.kinds import kind_blades
from gagen.apps.hexapod.kernels import hexapod_kernels, random_pose
from gagen.apps.hexapod.legs import AnalyticIKError, analytic_ik, dls_step, leg_kinematics, planar_signs
from gagen.apps.hexapod.spec import Leg, load_hexapod
from gagen.interp import MultiVector, preset
from gagen.model.euclidean import GEOMETRIES

from . import matrix_chain as mc
from .conftest import SPEC

HEXAPOD = load_hexapod(SPEC)
PGA = GEOMETRIES["pga3d"]
TOL = 1e-12
DLS_TOL = 1e-13


def zero() -> MultiVector:
    return MultiVector.zero(preset("pga3d"))


def interpreted_ik(leg: Leg, targets: np.ndarray) -> tuple[np.ndarray, ...]:
    """q_up (n, 3), q_down (n, 3), reach (n,), excess (n,) from the interpreter."""
    like = zero()
    solved = [analytic_ik(PGA, like, leg, [float(v) for v in t]) for t in targets]
    return (np.array([s["q_up"] for s in solved]), np.array([s["q_down"] for s in solved]),
            np.array([s["reach"] for s in solved]), np.array([s["excess"] for s in solved]))


def compiled_ik(module, leg: Leg, targets: np.ndarray) -> tuple[np.ndarray, ...]:
    q_up, q_down, reach, excess = getattr(module.c, f"{leg.name}_ik").batch(targets)
    return q_up, q_down, reach[:, 0], excess[:, 0]


def wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2 * np.pi) - np.pi


def reachable(leg: Leg, seed: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """n configurations within the limits and their toes (matrix chain)."""
    q = mc.random_configurations(leg, np.random.default_rng(seed), n)
    return q, mc.toe(leg, q)


def check_round_trip(leg: Leg, q: np.ndarray, targets: np.ndarray, solved: tuple[np.ndarray, ...]) -> float:
    """Both branches reach the targets, flagged reachable; the knee signs; one branch is the sampled q
    where that is well posed. Returns the largest toe error."""
    q_up, q_down, reach, excess = solved
    worst = 0.0
    for branch in (q_up, q_down):
        error = np.abs(mc.toe(leg, branch) - targets).max()
        worst = max(worst, error)
        assert error <= TOL, f"{leg.name}: FK of the IK misses the target by {error:.2e} m"
    assert (reach == 1).all()
    assert (np.abs(excess) <= TOL).all()
    knee_up = np.sign(leg.axes[2][1])  # the knee angle about +y: positive bends the knee up
    assert (knee_up * q_up[:, 2] >= 0).all() and (knee_up * q_down[:, 2] <= 0).all()
    # away from the boundary (knee not straight or folded, toe outward of the yaw axis along the
    # sampled yaw) the sample is one of the two solutions
    heading = np.einsum("nij,j->ni", mc.rotation(leg.axes[0], q[:, 0]), [1.0, 0.0, 0.0])
    outward = np.einsum("ni,ni->n", mc.to_hip(leg, targets), heading)
    posed = (np.abs(np.sin(q[:, 2])) > 1e-3) & (outward > 1e-3)
    assert posed.mean() > 0.5
    distance = np.minimum(np.abs(wrap(q_up - q)).max(axis=1), np.abs(wrap(q_down - q)).max(axis=1))
    assert (distance[posed] <= 1e-9).all(), f"{leg.name}: largest {distance[posed].max():.2e} rad"
    return worst


@pytest.mark.parametrize("count", [pytest.param(100, id="100"), pytest.param(1000, id="1000",
                                                                             marks=pytest.mark.slow)])
def test_analytic_ik_round_trip(count):
    worst = 0.0
    for i, leg in enumerate(HEXAPOD.legs):
        q, targets = reachable(leg, 100 + i, count)
        worst = max(worst, check_round_trip(leg, q, targets, interpreted_ik(leg, targets)))
    print(f"analytic IK (interpreter), {count} targets per leg: largest toe error {worst:.2e} m")


@pytest.mark.compiling
def test_compiled_analytic_ik(hexapod_module):
    worst = 0.0
    for i, leg in enumerate(HEXAPOD.legs):
        q, targets = reachable(leg, 100 + i, 1000)
        solved = compiled_ik(hexapod_module, leg, targets)
        worst = max(worst, check_round_trip(leg, q, targets, solved))
        reference = interpreted_ik(leg, targets[:100])
        for got, want in zip(solved, reference, strict=True):
            np.testing.assert_allclose(got[:100], want, rtol=0, atol=TOL)
    print(f"analytic IK (C), 1000 targets per leg: largest toe error {worst:.2e} m")


@pytest.mark.compiling
def test_compiled_body_ik(hexapod_module):
    rng = np.random.default_rng(7)
    n = 200
    poses = np.array([random_pose(rng) for _ in range(n)])
    q = np.concatenate([mc.random_configurations(leg, rng, n) for leg in HEXAPOD.legs], axis=1)
    body = [mc.toe(leg, q[:, 3 * i:3 * i + 3]) for i, leg in enumerate(HEXAPOD.legs)]
    like = zero()
    world = np.zeros((n, 18))
    for k, pose in enumerate(poses):  # world targets: the body pose (a PGA motor) moves the toes
        motor = like.make(dict(zip(kind_blades(like.algebra, "motor"), pose, strict=True)))
        for i in range(len(HEXAPOD.legs)):
            world[k, 3 * i:3 * i + 3] = PGA.location(motor.sandwich(PGA.point(like, list(body[i][k]))))
    solved, reach, excess = hexapod_module.c.body_ik.batch(poses, world)
    branch = 0 if HEXAPOD.knee == "up" else 1
    for i, leg in enumerate(HEXAPOD.legs):
        mine = solved[:, 3 * i:3 * i + 3]
        np.testing.assert_allclose(mc.toe(leg, mine), body[i], rtol=0, atol=TOL, err_msg=leg.name)
        assert (reach[:, i] == 1).all() and (np.abs(excess[:, i]) <= TOL).all()
        per_leg = compiled_ik(hexapod_module, leg, body[i])[branch]
        np.testing.assert_allclose(mc.toe(leg, per_leg), mc.toe(leg, mine), rtol=0, atol=TOL)


# -- unreachable and degenerate targets -------------------------------------------------------------------

def awkward_targets(leg: Leg, seed: int) -> np.ndarray:
    """Reachable toes pushed out 1.5-3x from the hip, and targets on the yaw axis (at the hip, above and
    below it, far below), at the thigh joint of the zero yaw."""
    _, toes = reachable(leg, seed, 40)
    hip = np.array(leg.xyz)
    pushed = hip + (toes - hip) * np.random.default_rng(seed).uniform(1.5, 3.0, size=(len(toes), 1))
    l1 = leg.lengths[0]
    special = mc.from_hip(leg, np.array([[0, 0, 0], [0, 0, -0.2], [0, 0, 0.3], [0, 0, -0.5], [0, 0, 0.6],
                                         [l1, 0, 0]], dtype=float))
    return np.concatenate([pushed, special])


def check_awkward(leg: Leg, targets: np.ndarray, solved: tuple[np.ndarray, ...]) -> None:
    q_up, q_down, reach, excess = solved
    for x in solved:
        assert np.isfinite(x).all(), f"{leg.name}: NaN or inf"
    _, l2, l3 = leg.lengths
    l1 = leg.lengths[0]
    hip = mc.to_hip(leg, targets)
    radial = np.hypot(hip[:, 0], hip[:, 1])
    d = np.hypot(radial - l1, hip[:, 2])  # from the thigh joint, which turns towards the target
    expected = np.maximum(0.0, np.maximum(d - (l2 + l3), abs(l2 - l3) - d))
    np.testing.assert_allclose(excess, expected, rtol=0, atol=TOL, err_msg=leg.name)
    outside = expected > 1e-6
    assert outside.sum() >= 30
    assert (reach[outside] == 0).all() and (reach[expected == 0] == 1).all()
    # the yaw turns the thigh joint towards the heading, or away from it (+π) where that reaches the
    # target too and is nearer the limits; out of reach the heading is nearer (l2 = l3)
    off_axis = radial > 1e-9
    heading = np.arctan2(hip[:, 1], hip[:, 0])
    for branch in (q_up, q_down):
        turned = np.abs(wrap(branch[:, 0] - heading))
        np.testing.assert_allclose(turned[off_axis & outside], 0, rtol=0, atol=TOL)
        np.testing.assert_allclose(np.minimum(turned, np.pi - turned)[off_axis], 0, rtol=0, atol=TOL)
    for branch in (q_up, q_down):
        toes = mc.to_hip(leg, mc.toe(leg, branch))
        thigh = l1 * np.stack([np.cos(branch[:, 0]), np.sin(branch[:, 0]), np.zeros(len(branch))], axis=1)
        towards = hip - thigh
        stretched = thigh + (l2 + l3) * towards / np.linalg.norm(towards, axis=1, keepdims=True)
        np.testing.assert_allclose(toes[outside], stretched[outside], rtol=0, atol=TOL, err_msg=leg.name)
        np.testing.assert_allclose(toes[~outside], hip[~outside], rtol=0, atol=TOL, err_msg=leg.name)


def test_unreachable_targets_are_clamped_and_flagged():
    for i, leg in enumerate(HEXAPOD.legs):
        targets = awkward_targets(leg, 200 + i)
        check_awkward(leg, targets, interpreted_ik(leg, targets))


@pytest.mark.compiling
def test_compiled_unreachable_targets(hexapod_module):
    for i, leg in enumerate(HEXAPOD.legs):
        targets = awkward_targets(leg, 200 + i)
        solved = compiled_ik(hexapod_module, leg, targets)
        check_awkward(leg, targets, solved)
        # angles the target leaves free are picked by rounding residues of 1e-17 (differently in C and
        # in the interpreter): the yaw on the yaw axis, the thigh at the thigh joint (l2 = l3, folded)
        hip = mc.to_hip(leg, targets)
        free = np.zeros((len(targets), 3), dtype=bool)
        free[:, 0] = np.hypot(hip[:, 0], hip[:, 1]) < 1e-9
        free[:, 1] = np.linalg.norm(hip - [leg.lengths[0], 0, 0], axis=1) < 1e-9
        assert free.sum() == 6
        reference = interpreted_ik(leg, targets)
        for got, want in zip(solved[:2], reference[:2], strict=True):
            np.testing.assert_allclose(wrap(got - want)[~free], 0, rtol=0, atol=TOL)
        for got, want in zip(solved[2:], reference[2:], strict=True):
            np.testing.assert_allclose(got, want, rtol=0, atol=TOL)


# -- numerical IK ----------------------------------------------------------------------------------------

def standing_targets(leg: Leg, seed: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Configurations around the standing pose (thigh within ±0.8, knee bent 0.3..2.4 on the neutral's
    side, yaw within its limits) away from singularities (smallest singular value of J ≥ 0.02), and
    their toes: the region where DLS from the neutral pose converges without a restart."""
    rng = np.random.default_rng(seed)
    (ylo, yhi), _, _ = leg.limits
    q = rng.uniform([ylo, -0.8, 0.3], [yhi, 0.8, 2.4], size=(4 * n, 3))
    smallest = np.linalg.svd(mc.jacobians(leg, q)[0], compute_uv=False)[:, 2]
    q = q[smallest >= 0.02][:n]
    assert len(q) == n
    return q, mc.toe(leg, q)


def iterate(step, q0: np.ndarray, targets: np.ndarray, damping: np.ndarray,
            iterations: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """Run a batched DLS step (q, target, damping → q_next, error) until each error < 1e-13; returns
    the converged q and the iteration each converged at (−1: never)."""
    q, done = q0.copy(), np.full(len(q0), -1)
    final = q0.copy()
    for it in range(iterations):
        q_next, error = step(q, targets, damping)
        newly = (error < DLS_TOL) & (done < 0)
        done[newly], final[newly] = it, q[newly]
        if (done >= 0).all():
            break
        q = q_next
    return final, done


def interpreted_dls(leg: Leg):
    like = zero()

    def step(q, targets, damping):
        out = [dls_step(PGA, like, leg, list(qk), list(tk), float(lk))
               for qk, tk, lk in zip(q, targets, damping, strict=True)]
        return np.array([o["q_next"] for o in out]), np.array([o["error"] for o in out])

    return step


def compiled_dls(module, leg: Leg):
    kernel = getattr(module.c, f"{leg.name}_dls")

    def step(q, targets, damping):
        q_next, error = kernel.batch(q, targets, damping[:, None])
        return q_next, error[:, 0]

    return step


def check_dls(leg: Leg, step, count: int, seed: int) -> int:
    rng = np.random.default_rng(seed)
    _, targets = standing_targets(leg, seed, count)
    damping = rng.uniform(1e-3, 1e-2, count)
    neutral = np.tile(HEXAPOD.neutral, (count, 1))
    q, done = iterate(step, neutral, targets, damping)
    assert (done >= 0).all(), f"{leg.name}: DLS did not converge for {(done < 0).sum()} targets"
    np.testing.assert_allclose(mc.toe(leg, q), targets, rtol=0, atol=TOL)
    # started near an analytic solution, DLS converges to it (either branch; on up to 20 targets)
    few = slice(0, 20)
    q_up, q_down, _, _ = interpreted_ik(leg, targets[few])
    for analytic in (q_up, q_down):
        start = analytic + rng.uniform(-0.05, 0.05, analytic.shape)
        near, converged = iterate(step, start, targets[few], damping[few])
        assert (converged >= 0).all()
        np.testing.assert_allclose(near, analytic, rtol=0, atol=1e-9, err_msg=leg.name)
    return int(done.max())


@pytest.mark.parametrize("count", [pytest.param(2, id="12")])
def test_dls_converges(count):
    """DLS from the neutral pose on the interpreter (count targets per leg; the ≥ 200 targets per leg
    run on the compiled step in test_compiled_dls)."""
    for i, leg in enumerate(HEXAPOD.legs):
        check_dls(leg, interpreted_dls(leg), count, 300 + i)


@pytest.mark.compiling
def test_compiled_dls(hexapod_module):
    for i, leg in enumerate(HEXAPOD.legs):
        compiled = compiled_dls(hexapod_module, leg)
        iterations = check_dls(leg, compiled, 200, 300 + i)
        print(f"DLS (C) {leg.name}: 200 targets from the neutral pose, converged within {iterations} steps")
        rng = np.random.default_rng(i)  # one step, compiled against the interpreter
        q, targets = mc.random_configurations(leg, rng, 20), reachable(leg, 400 + i, 20)[1]
        damping = rng.uniform(1e-3, 1e-1, 20)
        reference = interpreted_dls(leg)(q, targets, damping)
        for got, want in zip(compiled(q, targets, damping), reference, strict=True):
            np.testing.assert_allclose(got, want, rtol=0, atol=TOL)


# -- a leg the analytic IK cannot solve ------------------------------------------------------------------

def skewed_leg() -> Leg:
    """The first bundled leg with its knee axis tilted 0.1 off the thigh axis."""
    return replace(HEXAPOD.legs[0], axes=((0, 0, 1), (0, 1, 0), (0.1, 0.99498743710662, 0)))


def test_non_parallel_knee_is_refused_by_the_analytic_ik():
    leg = skewed_leg()
    pattern = rf"leg {leg.name}\b.*not parallel.*numerical IK"
    with pytest.raises(AnalyticIKError, match=pattern):
        planar_signs(leg)
    with pytest.raises(AnalyticIKError, match=pattern):
        analytic_ik(PGA, zero(), leg, [0.3, 0.1, -0.1])


def test_non_parallel_knee_is_solved_by_dls():
    leg = skewed_leg()
    like = zero()
    rng = np.random.default_rng(5)
    q_samples, _ = standing_targets(leg, 5, 3)
    for sample in q_samples:
        target = leg_kinematics(PGA, like, leg, list(sample))["p"]
        q, done = iterate(interpreted_dls(leg), np.array([HEXAPOD.neutral]), np.array([target]),
                          rng.uniform(1e-3, 1e-2, 1))
        assert done[0] >= 0
        reached = leg_kinematics(PGA, like, leg, list(q[0]))["p"]
        np.testing.assert_allclose(reached, target, rtol=0, atol=TOL)


def test_kernels_of_a_hexapod_with_a_non_parallel_knee():
    hexapod = replace(HEXAPOD, legs=(skewed_leg(), *HEXAPOD.legs[1:]))
    names = {k.name for k in hexapod_kernels(hexapod)}
    bad = hexapod.legs[0].name
    assert f"{bad}_ik" not in names and "body_ik" not in names
    assert {f"{bad}_dls", f"{bad}_fk_pga", f"{bad}_fk_cga"} <= names
    assert {f"{leg.name}_ik" for leg in hexapod.legs[1:]} <= names
