"""The tripod gait (``gagen.apps.hexapod.gait``) and ``gagen walk``: the body pose as a PGA motor
against the interpreter, the drawing chain against the reference FK, footholds and swing arcs; with the
generated module, the stance slip, ground contact, swing heights, reachability and limit margins
computed by the generated FK from the IK's joint angles, on flat and sloped ground; impossible walks
reported by leg and time without NaN; the plots and the GIF."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gagen.apps.hexapod import gait
from gagen.apps.hexapod.kernels import _motor, random_q, toe_position
from gagen.cli import main
from gagen.model.euclidean import PROJECTIVE

SLOPES = (0.0, 10.0)


# -- pure numpy (fast) -----------------------------------------------------------------------------------

def test_motor_is_the_pose_on_the_interpreter() -> None:
    """M = T(c) R from a rotation matrix acts on points as x -> R x + c (interpreter sandwich)."""
    rng = np.random.default_rng(3)
    for _ in range(30):
        axis = rng.normal(size=3)
        r = gait.rotation(axis / np.linalg.norm(axis), rng.uniform(-math.pi, math.pi))
        c = rng.normal(size=3)
        m = _motor("pga3d", gait.motor(r[None], c[None])[0])
        p = rng.normal(size=3)
        moved = np.array(PROJECTIVE.location(m.sandwich(PROJECTIVE.point(m, list(p)))))
        assert np.abs(moved - (r @ p + c)).max() < 1e-14
        assert abs((m * ~m)["1"] - 1) < 1e-14


def test_tripods_alternate_around_the_body(hexapod) -> None:
    a, b = gait.tripods(hexapod)
    names = [{hexapod.legs[i].name for i in s} for s in (a, b)]
    assert names == [{"front_left", "rear_left", "middle_right"},
                     {"front_right", "rear_right", "middle_left"}]


def test_joint_points_end_at_the_reference_toe(hexapod) -> None:
    rng = np.random.default_rng(4)
    q = np.array([random_q(hexapod, rng) for _ in range(5)])
    points = gait.joint_points(hexapod, q)
    for n in range(len(q)):
        for i, leg in enumerate(hexapod.legs):
            assert np.abs(points[n, i, 3] - toe_position(leg, q[n, 3 * i:3 * i + 3])).max() < 1e-14
            assert np.allclose(np.linalg.norm(np.diff(points[n, i], axis=0), axis=1), leg.lengths)


@pytest.mark.parametrize("slope", SLOPES)
def test_targets_stand_on_the_ground_and_swing_above_it(hexapod, slope: float) -> None:
    params = gait.GaitParameters()
    ground = gait.Ground(math.radians(slope), math.radians(30))
    t = params.times()
    body = gait.body_trajectory(params, ground, t)
    assert np.abs(ground.distance(body.position) - params.height).max() < 1e-12
    assert np.abs(body.rotation[:, :, 2] - ground.normal).max() < 1e-12  # tilted with the slope
    targets, phase, swing = gait.toe_targets(hexapod, params, ground, t, gait.tripods(hexapod))
    height = ground.distance(targets)
    assert np.abs(height[~swing]).max() < 1e-12
    assert height[swing].min() > -1e-12
    assert abs(height[swing].max() - params.step_height) < 1e-12
    for i in range(len(hexapod.legs)):  # a stance toe holds still; both tripods start and end on neutral
        for a, b in gait._runs(~swing[:, i]):
            assert np.abs(targets[a:b + 1, i] - targets[a, i]).max() == 0.0
    ends = body.to_world(gait.neutral_toes(hexapod)[None].repeat(len(t), 0))[[0, -1]]
    assert np.abs(ground.project(ends) - targets[[0, -1]]).max() < 1e-12
    assert phase[-1] == params.phases - 1 and swing.sum(axis=1).tolist() == [3] * len(t)


def test_bad_parameters_are_refused() -> None:
    for bad in ({"height": 0.0}, {"stride": float("nan")}, {"straight": 0.0, "turn": 0.0}, {"rate": 4.0}):
        with pytest.raises(ValueError):
            gait.GaitParameters(**bad)


# -- with the generated module ------------------------------------------------------------------------------

@pytest.mark.compiling
@pytest.mark.parametrize("slope", SLOPES)
def test_walk_stance_slip_contact_and_margins(hexapod_module, hexapod, slope: float) -> None:
    params = gait.GaitParameters()
    ground = gait.Ground(math.radians(slope), 0.0)
    r = gait.walk(hexapod_module, hexapod, params, ground)
    # the FK toes (generated body_fk_pga, carried by the rotation matrix, not the IK's motor)
    assert r.slip_max < 1e-9
    assert r.tracking_max < 1e-9
    independent = ground.distance(r.toes)
    assert np.abs(independent[r.stance]).max() < 1e-9
    assert np.abs(r.distance - independent).max() < 1e-12  # body_contact_pga agrees with n·x
    assert independent[r.swing].min() > -1e-9
    assert abs(independent[r.swing].max() - params.step_height) < 1e-9
    assert (r.reach == 1).all() and not r.unreachable and not r.past_limits and r.ok
    assert r.margin.min() > 0.05
    assert r.q.shape == (len(r.t), 18) and np.isfinite(r.q).all()


@pytest.mark.compiling
@pytest.mark.parametrize("change", [{"height": 0.5}, {"stride": 0.4}])
def test_impossible_walks_name_leg_and_time(hexapod_module, hexapod, change: dict) -> None:
    r = gait.walk(hexapod_module, hexapod, gait.GaitParameters(**change), gait.Ground(math.radians(10), 0.0))
    assert (r.reach == 0).any() and not r.ok
    for array in (r.q, r.toes, r.slip, r.margin, r.distance, r.excess):
        assert np.isfinite(array).all()
    covered = np.zeros_like(r.reach, dtype=bool)
    for run in r.unreachable:
        i = [leg.name for leg in hexapod.legs].index(run.leg)
        covered[(r.t >= run.start) & (r.t <= run.end), i] = True
        assert run.message().startswith(f"leg {run.leg} unreachable at t = {run.start:.2f}")
        assert run.worst > 0
    assert (covered == (r.reach == 0)).all()  # every unreachable sample is in a reported run
    assert "unreachable" in gait.summary(r)


@pytest.mark.compiling
def test_walk_command(hexapod_module, tmp_path, capsys) -> None:
    out = tmp_path / "walk"
    args = ["walk", "--module", str(hexapod_module.folder), "--out", str(out), "--no-animation"]
    assert main([*args, "--slope", "10"]) == 0
    text = capsys.readouterr().out
    assert "max stance slip" in text and "every leg reachable" in text
    assert (out / "joint_angles.png").stat().st_size > 10_000 and (out / "toe_paths.png").is_file()
    assert main([*args, "--height", "0.5"]) == 1
    err = capsys.readouterr().err
    assert "error: the walk is not feasible" in err and "unreachable at t = " in err


@pytest.mark.compiling
@pytest.mark.slow
def test_animation(hexapod_module, hexapod, tmp_path) -> None:
    from PIL import Image

    from gagen.apps.hexapod.plots import animate

    r = gait.walk(hexapod_module, hexapod)
    path = animate(r, tmp_path / "walk.gif", frames=24)
    assert 20_000 < path.stat().st_size < 5_000_000
    with Image.open(path) as gif:
        assert gif.n_frames == 24
        frames = []
        for k in (0, 12, 23):
            gif.seek(k)
            frames.append(np.asarray(gif.convert("RGB"), dtype=float))
    assert np.abs(frames[0] - frames[1]).mean() > 0.1 and np.abs(frames[1] - frames[2]).mean() > 0.1
