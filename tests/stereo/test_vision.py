"""The vision front end: the homology against 3D reflections, line conversions, detection on rendered
scenes against their ground truth (clean: tight; noisy: the issue's targets), the Euclidean midline's
perspective bias, and "no symmetry" for blank, absent and asymmetric inputs — never a NaN."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest

from gagen.apps.stereo import accuracy, scene, vision
from gagen.apps.stereo.calibration import Pose, canonical_line, load_rig

RIG = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "stereo" / "robots" / "stereo_rig.yaml"
OFF_CENTRE = (scene.ObjectPose([0.25, 0.18, 0.95], [0.4, -1.0, 0.3]),
              scene.ObjectPose([0.28, -0.15, 1.0], [0.1, 1.0, -0.3]))


@pytest.fixture(scope="module")
def rig():
    return load_rig(RIG)


def _line_errors(detection: vision.Detection, view: scene.ViewTruth, fx: float) -> tuple[float, float]:
    """Angle between the detected and the true image line (degrees) and the detected line's distance
    from the true centre's image (pixels)."""
    theta, _ = view.line
    angle = abs((detection.theta - theta + np.pi / 2) % np.pi - np.pi / 2)
    c = view.centre_xy
    offset = abs(c @ [np.cos(detection.theta), np.sin(detection.theta)] - detection.r) * fx
    return float(np.degrees(angle)), float(offset)


def test_homology_maps_images_of_points_to_images_of_their_mirror_points():
    """H(θ, r) is the image of the reflection in the plane through the camera centre and the line: it
    maps the projection of any 3D point to the projection of its mirror point, fixes the line and is an
    involution."""
    rng = np.random.default_rng(0)
    for _ in range(5):
        theta, r = rng.uniform(-np.pi, np.pi), rng.uniform(-0.5, 0.5)
        n = np.array([np.cos(theta), np.sin(theta), -r])
        n /= np.linalg.norm(n)
        points = rng.uniform([-0.5, -0.5, 0.8], [0.5, 0.5, 1.2], (10, 3))
        mirrored = points - 2 * np.outer(points @ n, n)
        h = vision.homology(theta, r)
        image = np.column_stack([points[:, :2] / points[:, 2:], np.ones(10)]) @ h.T
        np.testing.assert_allclose(image[:, :2] / image[:, 2:], mirrored[:, :2] / mirrored[:, 2:], atol=1e-12)
        np.testing.assert_allclose(h @ h, np.eye(3), atol=1e-12)
        on_line = np.array([r * np.cos(theta) - 0.3 * np.sin(theta),
                            r * np.sin(theta) + 0.3 * np.cos(theta), 1.0])
        fixed = h @ on_line
        np.testing.assert_allclose(fixed / fixed[2], on_line, atol=1e-12)


def test_pixel_and_normalised_lines_are_the_same_line(rig):
    camera = rig.left
    rng = np.random.default_rng(1)
    for _ in range(10):
        theta, r = canonical_line(rng.uniform(-np.pi, np.pi), rng.uniform(-0.4, 0.4))
        phi, rho = vision.normalised_to_pixel(camera, theta, r)
        back = vision.pixel_to_normalised(camera, phi, rho)
        np.testing.assert_allclose(back, (theta, r), atol=1e-12)
        foot = np.array([r * np.cos(theta), r * np.sin(theta)])
        xy = foot + np.outer([-0.2, 0.3], [-np.sin(theta), np.cos(theta)])
        np.testing.assert_allclose(camera.pixels(xy) @ [np.cos(phi), np.sin(phi)], rho, atol=1e-9)
        assert -np.pi / 2 < theta <= np.pi / 2 and -np.pi / 2 < phi <= np.pi / 2


def test_clean_renders_give_the_true_lines_and_mass_centres(rig):
    """Eight random poses, no noise: the detected image lines are within 0.12° and 0.15 px (at the
    object) of the true image of the axis, and the mass centres within 0.3 px of the exact silhouette
    mass centres."""
    rng = np.random.default_rng(11)
    for k in range(8):
        pose = scene.random_pose(rig, rng)
        frame = scene.render(rig, pose, scene.SceneOptions(), k)
        exact = scene.silhouette_centroids(rig, pose, scale=2)
        views = ((frame.left, rig.left, frame.truth.left, exact[0]),
                 (frame.right, rig.right, frame.truth.right, exact[1]))
        for image, camera, view, centre in views:
            d = vision.detect(image, camera, rig.hsv_low, rig.hsv_high)
            assert isinstance(d, vision.Detection), str(d)
            angle, offset = _line_errors(d, view, camera.fx)
            assert angle < 0.12 and offset < 0.15
            assert np.linalg.norm(d.centre_px - centre) < 0.3
            np.testing.assert_allclose(d.centre_xy, camera.normalised(d.centre_px), atol=1e-15)
            assert d.score > 0.95 and 0 < d.residual_px < 0.5 and d.area > 1000


def test_euclidean_midline_is_biased_off_centre_and_the_homology_is_not(rig):
    """Off the image centre the silhouette's Euclidean mirror line misses the axis image by about 0.1°
    to 0.2° (which stereo magnifies tenfold); the homology fit stays within 0.03°. (The poses were
    placed for cameras 12 cm apart: the rig here has that baseline.)"""
    rig = dataclasses.replace(rig, right_in_left=Pose(np.eye(3), np.array([0.12, 0.0, 0.0])))
    for pose in OFF_CENTRE:
        frame = scene.render(rig, pose, scene.SceneOptions(), 0)
        for image, camera, view in ((frame.left, rig.left, frame.truth.left),
                                    (frame.right, rig.right, frame.truth.right)):
            fitted = vision.detect(image, camera, rig.hsv_low, rig.hsv_high)
            midline = vision.detect(image, camera, rig.hsv_low, rig.hsv_high, model="euclidean")
            assert _line_errors(fitted, view, camera.fx)[0] < 0.03
            assert _line_errors(midline, view, camera.fx)[0] > 0.08


def test_noisy_renders_on_a_fixed_seed_set(rig):
    """16 random poses at 1 px noise (vertex jitter σ = 1 px, grey noise σ = 4): no failures; image lines
    within 0.15° and 0.1 px of the truth (medians; 0.08° and 0.04 px over 160 images); the 3D point
    under the issue's 5 mm (median, against the body's centre) and the line within 3 mm of it. The 3D
    axis error is the image lines' error magnified by depth / baseline (4× for the bundled rig's 0.25 m
    at 1 m), and its median over a set this small scatters (the 200-pose median is 0.47°): the issue's
    "< 1°" is held on 100 poses by the slow test; here a bound of 1.5°."""
    level = next(lv for lv in accuracy.LEVELS if lv.name == "1 px")
    rng = np.random.default_rng(0)
    angles, offsets, axis, line, point = [], [], [], [], []
    for k in range(16):
        pose = scene.random_pose(rig, rng)
        frame = scene.render(rig, pose, level.options, np.random.default_rng([0, 2, k]))
        left, right = vision.detect_pair(frame.left, frame.right, rig)
        assert isinstance(left, vision.Detection) and isinstance(right, vision.Detection)
        for d, view in ((left, frame.truth.left), (right, frame.truth.right)):
            angle, offset = _line_errors(d, view, rig.left.fx)
            angles.append(angle)
            offsets.append(offset)
        est = accuracy.numpy_estimator(rig, left, right)
        a, li, p, _ = accuracy.errors(frame.truth, pose.centre, est)
        axis.append(a)
        line.append(li)
        point.append(p)
    assert np.median(angles) < 0.15 and np.median(offsets) < 0.1
    assert np.median(point) < 5e-3 and np.median(line) < 3e-3
    assert np.median(axis) < 1.5


def test_blank_and_absent_scenes_have_no_symmetry(rig):
    pose = OFF_CENTRE[0]
    for options in (scene.SceneOptions(blank=True), scene.SceneOptions(blank=True, pixel_noise=10.0),
                    scene.SceneOptions(present=False, clutter=24, pixel_noise=4.0)):
        frame = scene.render(rig, pose, options, 3)
        for image, camera in ((frame.left, rig.left), (frame.right, rig.right)):
            d = vision.detect(image, camera, rig.hsv_low, rig.hsv_high)
            assert isinstance(d, vision.NoSymmetry)
            assert str(d).startswith("no symmetry: too few object pixels")
    black = np.zeros((480, 640, 3), np.uint8)
    assert isinstance(vision.detect(black, rig.left, rig.hsv_low, rig.hsv_high), vision.NoSymmetry)
    speckle = np.random.default_rng(0).integers(0, 256, (480, 640, 3), dtype=np.uint8)
    assert isinstance(vision.detect(speckle, rig.left, rig.hsv_low, rig.hsv_high), vision.NoSymmetry)


def _blue_shape(points: np.ndarray) -> np.ndarray:
    image = np.full((480, 640, 3), 120, np.uint8)
    cv2.fillPoly(image, [np.round(points).astype(np.int32)], (220, 110, 30))  # BGR: hue ≈ 107
    return image


def test_an_asymmetric_blob_has_no_symmetry_and_a_kite_has_its_axis(rig):
    """A blue L-shaped blob gets "symmetry score … < …"; a kite through the principal point (where the
    homology is a plain reflection), its axis turned 30° from the image's vertical (so the line's
    normal is at −30°), gets its axis to 0.1°; neither gives a NaN."""
    ell = np.array([[200, 150], [260, 150], [260, 300], [420, 300], [420, 350], [200, 350]], float)
    d = vision.detect(_blue_shape(ell), rig.left, rig.hsv_low, rig.hsv_high)
    assert isinstance(d, vision.NoSymmetry) and "symmetry score" in d.reason
    tilt = np.radians(30)
    along, across = np.array([np.sin(tilt), np.cos(tilt)]), np.array([np.cos(tilt), -np.sin(tilt)])
    centre = np.array([rig.left.cx, rig.left.cy])
    kite = np.array([centre - 120 * along, centre + 30 * along + 50 * across, centre + 100 * along,
                     centre + 30 * along - 50 * across])
    d = vision.detect(_blue_shape(kite), rig.left, rig.hsv_low, rig.hsv_high)
    assert isinstance(d, vision.Detection)
    assert np.isfinite([d.theta, d.r, *d.centre_xy, d.area, d.score]).all()
    assert abs((d.theta + tilt + np.pi / 2) % np.pi - np.pi / 2) < np.radians(0.1)
    assert abs(d.r) * rig.left.fx < 0.3


@pytest.mark.slow
def test_accuracy_over_100_poses(rig):
    """The issue's accuracy evaluation on the first 100 of the docs' 200 random poses (``python -m
    gagen.apps.stereo.accuracy 200`` makes the table; 100 measured 0.155° / 0.41° / 0.32° / 0.55° for
    the medians bounded below) at four noise levels (clean, 1 px, grey noise, 1 px with blur and
    clutter), no failures. Point error (median) under the issue's 5 mm everywhere
    (1 px: 1.5 mm); axis error (median) under the issue's 1° everywhere (clean 0.15°, 1 px 0.47°, 1 px
    with blur and clutter 0.55°; with the axis at least 45° from the epipolar plane, 1 px: 0.39°). A
    12 cm baseline put the 1 px median at 1.04° (the axis error scales as depth / baseline)."""
    names = ("clean", "1 px", "grey σ 10", "1 px + blur 1 + clutter")
    levels = [lv for lv in accuracy.LEVELS if lv.name in names]
    rows = {row.level: row for row in accuracy.evaluate(rig, 100, levels, seed=0)}
    clean = rows["clean"].stats()
    assert clean["axis_deg_median"] < 0.2 and clean["point_mm_median"] < 0.5
    one = rows["1 px"].stats()
    assert one["axis_deg_median"] < 0.6 and one["point_mm_median"] < 2.0
    assert rows["1 px"].stats(epipolar=(45.0, 90.0))["axis_deg_median"] < 0.5
    for row in rows.values():
        s = row.stats()
        assert not row.failures and s["point_mm_median"] < 5.0 and s["axis_deg_median"] < 1.0


def test_numpy_reconstruction_recovers_the_true_axis_and_flags_the_degenerate_case(rig):
    """The accuracy module's plain-numpy reconstruction: the true image lines give back the true axis
    (direction and a point on it) and the true centre images the true centre; an axis in the epipolar
    plane gives conditioning ~0 and finite numbers."""
    rng = np.random.default_rng(5)
    for _ in range(5):
        pose = scene.random_pose(rig, rng)
        t = scene.truth(rig, pose)
        point, direction, cond = accuracy.triangulate_axis(rig, t.left.line, t.right.line)
        assert abs(abs(direction @ pose.axis) - 1) < 1e-12 and cond > 0.02
        rel = point - pose.centre
        assert np.linalg.norm(rel - (rel @ pose.axis) * pose.axis) < 1e-12
        np.testing.assert_allclose(accuracy.triangulate_point(rig, t.left.centre_xy, t.right.centre_xy),
                                   pose.centre, atol=1e-12)
        for construction in ("triangulate", "rays"):
            np.testing.assert_allclose(accuracy.axis_point(rig, t.left.centre_xy, t.right.centre_xy, point,
                                                           direction, construction), pose.centre, atol=1e-12)
    centre = np.array([0.05, 0.02, 1.0])
    flat = scene.truth(rig, scene.ObjectPose(centre, [1.0, 0.0, 0.0]))  # along the baseline: degenerate
    point, direction, cond = accuracy.triangulate_axis(rig, flat.left.line, flat.right.line)
    assert cond < 1e-9 and np.isfinite([*point, *direction]).all()
