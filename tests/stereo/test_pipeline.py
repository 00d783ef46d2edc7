"""One frame to the controller's reference (``pipeline``) and the closed loop (``track``): blank and
empty images and degenerate geometry reported as failures, never a NaN; the base-frame reference
against the rig's pose; a rendered frame's estimate against its ground truth; the held reference
between frames; the whole loop tracking the true path."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gagen.apps.stereo import scene, track, vision
from gagen.apps.stereo.calibration import load_rig
from gagen.apps.stereo.pipeline import Estimator, Failure, FrameEstimate

RIG = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "stereo" / "robots" / "stereo_rig.yaml"


@pytest.fixture(scope="module")
def rig():
    return load_rig(RIG)


@pytest.fixture(scope="module")
def estimator(rig):
    return Estimator(rig)


def _detection(theta: float, r: float, centre: tuple[float, float]) -> vision.Detection:
    return vision.Detection(theta, r, np.array(centre), np.zeros(2), 1000.0, 1.0, (0.0, 0.0), 0.0)


def test_in_base_moves_the_estimate_with_the_rig_pose_and_orients_the_axis(rig):
    """x_ref = [R p + t; ±R d], the sign making the direction agree with the base's y [SMC Eq. 43]."""
    d = np.array([0.6, -0.8, 0.0])
    dummy = _detection(0.0, 0.0, (0.0, 0.0))
    estimate = FrameEstimate(np.array([0.1, 0.2, 1.0]), d, np.zeros(3), np.zeros(3), 0.1, 0.0, dummy, dummy)
    x = estimate.in_base(rig)
    np.testing.assert_allclose(x[:3], rig.left_in_base.R @ [0.1, 0.2, 1.0] + rig.left_in_base.t, atol=1e-15)
    expected = rig.left_in_base.R @ d
    np.testing.assert_allclose(x[3:], expected if expected[1] >= 0 else -expected, atol=1e-15)
    assert x[4] >= 0
    flipped = FrameEstimate(estimate.reference, -d, np.zeros(3), np.zeros(3), 0.1, 0.0, dummy, dummy)
    np.testing.assert_allclose(flipped.in_base(rig), x, atol=1e-15)  # the sign of d does not matter


@pytest.mark.compiling
@pytest.mark.parametrize("options", [scene.SceneOptions(blank=True), scene.SceneOptions(present=False)],
                         ids=["blank", "absent"])
def test_blank_or_empty_images_report_no_symmetry(rig, estimator, options):
    frame = scene.render(rig, track.object_pose(rig, 0.0), options, 1)
    result = estimator(frame.left, frame.right)
    assert isinstance(result, Failure) and "no symmetry" in str(result), result


@pytest.mark.compiling
def test_coincident_planes_are_degenerate_geometry_not_a_pose(rig, estimator):
    """Both image lines from one 3D line lying in the epipolar plane (the plane of the baseline and
    the axis: here y = 0, through both camera centres): the two back-projected planes coincide."""
    point, direction = np.array([0.05, 0.0, 1.0]), np.array([0.3, 0.0, 1.0]) / np.hypot(0.3, 1.0)
    lines = []
    for pose in (None, rig.right_in_left.inverse()):
        p = point if pose is None else pose.apply(point)
        d = direction if pose is None else pose.R @ direction
        a, b = p[:2] / p[2], (p + d)[:2] / (p + d)[2]  # two image points of the line
        n = np.array([a[1] - b[1], b[0] - a[0]])
        n /= np.linalg.norm(n)
        lines.append((float(np.arctan2(n[1], n[0])), float(n @ a)))
    result = estimator.observe(_detection(*lines[0], (0.05, 0.0)), _detection(*lines[1], (-0.07, 0.0)))
    assert isinstance(result, Failure) and "degenerate geometry" in str(result), result


@pytest.mark.compiling
def test_rendered_frames_are_estimated_within_the_targets(rig, estimator):
    """Nine frames along the reference path, 1 px of vertex noise: the median axis error within 1°
    and the median position error within 5 mm of the rendered bottle's centre (the issue's targets),
    every frame within 3° and 1 cm."""
    angles, distances = [], []
    for k, t in enumerate(np.linspace(0.0, 3.0, 9)):
        pose = track.object_pose(rig, float(t))
        frame = scene.render(rig, pose, scene.SceneOptions(vertex_jitter=1.0, pixel_noise=2.0), k)
        result = estimator(frame.left, frame.right)
        assert isinstance(result, FrameEstimate), result
        angles.append(np.degrees(np.arccos(min(1.0, abs(result.direction @ pose.axis)))))
        distances.append(np.linalg.norm(result.reference - pose.centre))
        # ≈ baseline / depth for an axis across the baseline: 2 × 0.125 / (1 + 0.125²) = 0.246 on the path
        assert 0.23 < result.conditioning < 0.26
    assert np.median(angles) < 1.0 and max(angles) < 3.0, angles
    assert np.median(distances) < 5e-3 and max(distances) < 1e-2, distances


@pytest.mark.compiling
def test_the_kernel_agrees_with_the_independent_numpy_reconstruction(rig, estimator):
    """On the detections of rendered frames (1 px noise, random poses): the generated ``estimate``
    kernel's axis, conditioning and position reference equal ``accuracy``'s plain-numpy meet of the two
    viewing planes and its triangulated mass centre dropped onto the axis."""
    from gagen.apps.stereo import accuracy

    kernel = estimator.for_accuracy()
    rng = np.random.default_rng(8)
    for k in range(6):
        pose = scene.random_pose(rig, rng)
        frame = scene.render(rig, pose, scene.SceneOptions(vertex_jitter=1.0, pixel_noise=4.0), k)
        left, right = vision.detect_pair(frame.left, frame.right, rig)
        ours, theirs = kernel(rig, left, right), accuracy.numpy_estimator(rig, left, right, "triangulate")
        assert abs(abs(ours.direction @ theirs.direction) - 1) < 1e-12
        assert ours.conditioning == pytest.approx(theirs.conditioning, rel=1e-9)
        np.testing.assert_allclose(ours.point, theirs.point, atol=1e-9)


class _Every:
    """A stand-in estimator: fails on every ``period``-th frame, else returns the true pose moved off
    by a known offset (so the held reference can be told apart)."""

    def __init__(self, rig, period: int) -> None:
        self.rig, self.period, self.calls = rig, period, 0

    def __call__(self, left, right):
        self.calls += 1
        if self.calls % self.period == 0:
            return Failure("stand-in failure")
        t = (self.calls - 1) / track.FPS
        truth = track.true_reference(t)
        to_left = self.rig.left_in_base.inverse()
        dummy = _detection(0.0, 0.0, (0.0, 0.0))
        return FrameEstimate(to_left.apply(truth[:3] + 0.001), to_left.R @ truth[3:], np.zeros(3),
                             np.zeros(3), 0.1, 0.0, dummy, dummy)


def test_a_failed_frame_holds_the_previous_reference(rig):
    run = track.estimate_path(rig, 6 / track.FPS, estimator=_Every(rig, 3))
    assert len(run.frame_times) == 6 and run.estimates_ok.tolist() == [True, True, False, True, True, False]
    assert [f.split(":")[0] for f in run.failures] == ["frame 2 (t = 0.067 s)", "frame 5 (t = 0.167 s)"]
    np.testing.assert_allclose(run.estimates[2], run.estimates[1], atol=0)
    np.testing.assert_allclose(run.estimates[5], run.estimates[4], atol=0)
    for k in (0, 1, 3, 4):
        np.testing.assert_allclose(run.estimates[k, :3], run.truth[k, :3] + 0.001, atol=1e-12)
        np.testing.assert_allclose(run.estimates[k, 3:], [0, 1, 0], atol=1e-12)


@pytest.mark.slow
@pytest.mark.compiling
def test_the_closed_loop_tracks_the_true_path(rig):
    """1.5 s: 45 frames estimated, the Panda's end point within 1 cm of the true path after 0.5 s (the
    held reference lags the path by up to one frame: 0.2 m/s × 33 ms = 6.7 mm) and its tool line
    within 0.1 of the true axis; every frame's estimate within the issue's targets."""
    run = track.close_loop(rig, 1.5, seed=5)
    assert not run.failures
    e = track.tracking_errors(run)
    assert e["position_vs_truth"] < 0.01 and e["direction_vs_truth"] < 0.1, e
    assert e["estimate_axis_median_deg"] < 1.0 and e["estimate_position_median"] < 5e-3, e


@pytest.mark.slow
@pytest.mark.compiling
def test_gagen_stereo_writes_the_plots(tmp_path):
    out = tmp_path / "stereo"
    command = [sys.executable, "-m", "gagen.cli", "stereo", "--duration", "0.4", "--out", str(out)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "frames: 12, failed 0" in done.stdout, done.stdout
    for name in ("pose.png", "error.png", "joint_velocities.png", "joint_positions.png",
                 "estimation_error.png", "frame.png", "stereo_smc_log.csv"):
        assert (out / name).stat().st_size > 1000, name


def test_gagen_stereo_refuses_a_bad_rig(tmp_path):
    bad = tmp_path / "rig.yaml"
    bad.write_text(RIG.read_text().replace("fx: 600", "fx: -600", 1))
    done = subprocess.run([sys.executable, "-m", "gagen.cli", "stereo", "--rig", str(bad)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "cameras.left.fx" in done.stderr, done.stderr


@pytest.mark.parametrize(("flag", "value", "message"), [("--noise", "-1", "≥ 0"), ("--clutter", "-2", "≥ 0"),
                                                        ("--duration", "0", "> 0"), ("--blur", "nan", "≥ 0")])
def test_gagen_stereo_refuses_bad_options(flag, value, message):
    done = subprocess.run([sys.executable, "-m", "gagen.cli", "stereo", flag, value], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 2 and flag in done.stderr and message in done.stderr, done.stderr
