"""A stereo rig's hostile calibrations (issue 29): a rig whose check scene cannot be generated (a
baseline of a fraction of a millimetre made ``random_scene``, the sampler of every kernel and so of
``gagen build --check``, loop forever) is refused by the loader naming the field, ``random_scene``
itself gives up after a bounded number of tries with a clear error, and the image size is bounded by
``gagen.limits`` (``image_pixels``, raised through the environment)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from conftest import deadline

from gagen.apps.stereo.calibration import MIN_BASELINE, Pose, load_rig
from gagen.apps.stereo.kernels import SceneError, random_scene
from gagen.errors import SpecError

RIG = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "stereo" / "robots" / "stereo_rig.yaml"
TEXT = RIG.read_text()


def _refusal(tmp_path: Path, text: str) -> SpecError:
    path = tmp_path / "rig.yaml"
    path.write_text(text)
    with deadline(10), pytest.raises(SpecError) as e:
        load_rig(path)
    assert e.value.file == str(path) and "\n" not in str(e.value), str(e.value)
    return e.value


@pytest.mark.parametrize("xyz", ["[1.0e-5, 0, 0]", "[0.0001, 0, 0]", "[0, 0.002, 0]", "[0.005, 0.005, 0]"])
def test_a_baseline_too_short_for_the_scene_is_refused(tmp_path, xyz):
    e = _refusal(tmp_path, TEXT.replace("xyz: [0.25, 0, 0]", f"xyz: {xyz}", 1))
    assert e.field.startswith("right_in_left.xyz (line"), e.field
    assert "baseline" in e.message and f"at least {MIN_BASELINE:g} m" in e.message, e.message


def test_a_baseline_along_the_viewing_direction_is_refused(tmp_path):
    """1.5 cm, but along the optical axis: almost every axis ahead is seen in two coinciding planes."""
    e = _refusal(tmp_path, TEXT.replace("xyz: [0.25, 0, 0]", "xyz: [0, 0, 0.015]", 1))
    assert e.field.startswith("right_in_left (line") and "viewing direction" in e.message, e


def test_the_shortest_accepted_baseline_gives_scenes(tmp_path):
    path = tmp_path / "rig.yaml"
    path.write_text(TEXT.replace("xyz: [0.25, 0, 0]", f"xyz: [{MIN_BASELINE}, 0, 0]", 1))
    rig = load_rig(path)
    rng = np.random.default_rng(3)
    with deadline(10):
        for _ in range(50):
            assert np.all(np.isfinite(random_scene(rig, rng).lines))


def test_random_scene_gives_up_with_a_clear_error():
    """A rig the loader would refuse (built directly): bounded tries, then a one-line error naming the
    baseline, not a hang."""
    rig = dataclasses.replace(load_rig(RIG), right_in_left=Pose(np.eye(3), np.array([1e-6, 0.0, 0.0])))
    with deadline(10), pytest.raises(SceneError) as e:
        random_scene(rig, np.random.default_rng(0))
    assert "baseline" in str(e.value) and "\n" not in str(e.value)


def test_an_image_over_the_pixel_limit_is_refused_in_one_line(tmp_path):
    e = _refusal(tmp_path, TEXT.replace("width: 640", "width: 20000", 1))
    assert e.field.startswith("cameras.left.width (line"), e.field
    assert "20000 pixels along an image side, over the limit of 16384" in e.message
    assert "GAGEN_LIMIT_IMAGE_PIXELS" in e.message


def test_the_environment_raises_the_pixel_limit(tmp_path, monkeypatch):
    monkeypatch.setenv("GAGEN_LIMIT_IMAGE_PIXELS", "32768")
    path = tmp_path / "rig.yaml"
    path.write_text(TEXT.replace("width: 640", "width: 20000", 1))
    assert load_rig(path).left.width == 20000
