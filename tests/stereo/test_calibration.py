"""The stereo rig's calibration file: the bundled rig's numbers, its poses against their meaning, and
every malformed field named with the file and what was expected."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gagen.apps.stereo.calibration import load_rig, rpy_matrix
from gagen.errors import SpecError

RIG = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "stereo" / "robots" / "stereo_rig.yaml"


def test_bundled_rig_sees_the_reference_path_from_one_metre_above():
    """The paper's reference path (x = −0.3 ± 0.1, y = 0.15, z = 0.25 in the base) is 1 m in front of
    the left camera, inside both images, and the baseline is 0.25 m along camera x = base x."""
    rig = load_rig(RIG)
    assert rig.baseline == pytest.approx(0.25, abs=1e-15)
    to_left = rig.left_in_base.inverse()
    for x in (-0.4, -0.3, -0.2):
        p_left = to_left.apply(np.array([x, 0.15, 0.25]))
        assert p_left[2] == pytest.approx(1.0, abs=1e-12)
        p_right = rig.right_in_left.inverse().apply(p_left)
        for camera, p in ((rig.left, p_left), (rig.right, p_right)):
            u, v = camera.project(p)
            assert 0 <= u < camera.width and 0 <= v < camera.height
    # camera x along base x, camera z (forward) down
    np.testing.assert_allclose(rig.left_in_base.R[:, 0], [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(rig.left_in_base.R[:, 2], [0, 0, -1], atol=1e-15)


def test_rpy_is_the_urdf_convention():
    """Rz(yaw) Ry(pitch) Rx(roll) against the product of the three elementary rotations."""
    rng = np.random.default_rng(2)
    for _ in range(10):
        r, p, y = rng.uniform(-np.pi, np.pi, 3)
        rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
        ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
        rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
        np.testing.assert_allclose(rpy_matrix((r, p, y)), rz @ ry @ rx, atol=1e-15)


def test_pixels_and_normalised_coordinates_invert_each_other():
    camera = load_rig(RIG).left
    pixels = np.array([[0.0, 0.0], [639.0, 479.0], [319.5, 239.5], [100.25, 400.75]])
    np.testing.assert_allclose(camera.pixels(camera.normalised(pixels)), pixels, atol=1e-12)
    np.testing.assert_allclose(camera.normalised([[319.5, 239.5]]), [[0.0, 0.0]], atol=0)


@pytest.mark.parametrize(("old", "new", "field", "message"), [
    ("app: stereo", "app: stereoo", "app", "a stereo rig says app: stereo"),
    ("fx: 600, fy: 600, cx: 319.5, cy: 239.5, width: 640, height: 480}\n  right",
     "fx: -600, fy: 600, cx: 319.5, cy: 239.5, width: 640, height: 480}\n  right", "cameras.left.fx",
     "positive"),
    ("width: 640, height: 480}\nright", "width: 640.5, height: 480}\nright", "cameras.right.width", "whole"),
    ("cy: 239.5, width: 640, height: 480}\n  right", "cy: 239.5, width: 640}\n  right", "cameras.left.height",
     "missing"),
    ("right_in_left: {xyz: [0.25, 0, 0]", "right_in_left: {xyz: [0, 0, 0]", "right_in_left.xyz",
     "zero baseline"),
    ("right_in_left: {xyz: [0.25, 0, 0]", "right_in_left: {xyz: [0.25, 0, .nan]", "right_in_left.xyz",
     "three finite numbers"),
    ("rpy: [3.141592653589793, 0, 0]", "rpy: [3.14, 0]", "left_in_base.rpy", "three finite numbers"),
    ("hue: [100, 130]", "hue: [100, 190]", "segmentation.hue", "≤ 179"),
    ("hue: [100, 130]", "hue: [130, 100]", "segmentation.hue", "lo ≤ hi"),
    ("segmentation:", "segmentaton:", "segmentaton", "did you mean 'segmentation'"),
    ("name: stereo_rig", 'name: "rig */ evil"', "name", "letter"),
])
def test_malformed_rig_names_file_field_and_expectation(tmp_path, old, new, field, message):
    text = RIG.read_text()
    assert old in text, old
    path = tmp_path / "rig.yaml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(SpecError) as e:
        load_rig(path)
    assert e.value.file == str(path)
    assert e.value.field.startswith(field) and message in e.value.message, (e.value.field, e.value.message)
