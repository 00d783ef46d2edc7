"""Fuzz tier (issue 29): stereo rig calibrations. A mutated copy of the bundled rig, and a rig built
from random baselines (tiny, zero, negative, along the viewing direction), poses, focal lengths,
principal points and image sizes, is refused in one line naming the file and a field, or loaded and
used: the check scene of every stereo kernel (``random_scene``, the sampler of ``gagen build --check``)
generated within the case's deadline, the symmetry axis and the mass centre estimated from it on the
interpreter (no C compiler), and its image points mapped to pixels, all finite."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from gagen.apps.stereo import geometry as geo
from gagen.apps.stereo.calibration import MAX_DISTANCE, MIN_BASELINE, load_rig
from gagen.apps.stereo.kernels import random_scene
from gagen.interp import MultiVector, cga3d
from gagen.limits import limit

from .harness import all_finite, examples, mutated_file, run_case, run_document

RIG = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "stereo" / "robots" / "stereo_rig.yaml"
TEXT = RIG.read_text()
GA = MultiVector.zero(cga3d())


def estimate(path: Path) -> dict[str, Any]:
    """Load the rig, generate three check scenes and estimate each one's axis and centre."""
    rig = load_rig(path)
    motor = geo.stereo_motor(GA, rig.right_in_left)
    rng = np.random.default_rng(0)
    out: dict[str, Any] = {}
    for k in range(3):
        scene = random_scene(rig, rng, noise=2e-3)
        e = geo.estimate(GA, motor, scene.lines, scene.centres)
        out[f"scene {k}"] = [e.axis.point, e.axis.direction, e.axis.conditioning, e.centre, e.reference,
                             e.gap, rig.left.pixels(scene.centres[:2]), rig.right.pixels(scene.centres[2:])]
    return out


def check(outputs: dict[str, Any]) -> None:
    assert all_finite(outputs), f"non-finite estimates: {outputs}"


@examples(fast=40, full=250)
@given(st.data())
def test_mutated_bundled_rig(data):
    with tempfile.TemporaryDirectory() as folder:
        what, path = mutated_file(data.draw, TEXT, Path(folder), RIG.name)
        run_case("stereo", (path,), lambda: estimate(path), check, what=what)


# -- schema level ------------------------------------------------------------------------------------------

# ordinary values, and per field the hostile ones: a case changes one field (or none) to a hostile value
BASELINE = st.tuples(st.floats(-0.5, 0.5), st.floats(-0.1, 0.1), st.floats(-0.1, 0.1))
HOSTILE_BASELINES = [(0, 0, 0), (1e-300, 0, 0), (1e-5, 0, 0), (0.0099, 0, 0), (0.01, 0, 0), (-0.01, 0, 0),
                     (0.02, 0, 0), (0, 0.03, 0), (0, 0, 0.015), (0, 0, 0.25), (0, 0, -0.5), (1e3, 0, 0),
                     (1001, 0, 0), (float("nan"), 0, 0), (0, float("inf"), 0)]
HOSTILE_ANGLES = [math.pi, -math.pi, 1.5, 4 * math.pi, 13.0, float("nan")]
HOSTILE_PIXELS = [0, -1, 1e-9, 1, 16384, 16385, 20000, 10 ** 12, 640.5, float("nan"), float("inf"), True]


def _valid(value: Any, low: float, high: float) -> bool:
    """A finite real number (not a bool) in (low, high]."""
    return (isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
            and low < value <= high)


@st.composite
def rig_schema(draw) -> tuple[str, dict[str, Any], bool]:
    """(description, rig, certainly invalid): random cameras and poses, one field hostile or none."""
    cameras = {}
    for which in ("left", "right"):
        width, height = draw(st.integers(32, 4096)), draw(st.integers(32, 4096))
        cameras[which] = {"fx": draw(st.floats(50, 5000)), "fy": draw(st.floats(50, 5000)),
                          "cx": width * draw(st.floats(0.3, 0.7)), "cy": height * draw(st.floats(0.3, 0.7)),
                          "width": width, "height": height}
    xyz: list[Any] = list(draw(BASELINE))
    rpy: list[Any] = [draw(st.floats(-0.3, 0.3)) for _ in range(3)]
    hostile = draw(st.sampled_from(["none", "none", "baseline", "baseline", "angle", "pixels"]))
    invalid, what = False, "none"
    if hostile == "baseline":
        xyz = list(draw(st.sampled_from(HOSTILE_BASELINES)))
        invalid = not all(_valid(abs(v), -1, MAX_DISTANCE) for v in xyz) or math.hypot(*xyz) < MIN_BASELINE
        what = f"right_in_left.xyz {xyz}"
    elif hostile == "angle":
        i = draw(st.integers(0, 2))
        rpy[i] = draw(st.sampled_from(HOSTILE_ANGLES))
        invalid = not _valid(abs(rpy[i]), -1, 4 * math.pi)
        what = f"right_in_left.rpy {rpy}"
    elif hostile == "pixels":
        which, key = draw(st.sampled_from(["left", "right"])), draw(st.sampled_from(list(cameras["left"])))
        value = cameras[which][key] = draw(st.sampled_from(HOSTILE_PIXELS))
        whole = key not in ("width", "height") or (_valid(value, 0, math.inf) and value == int(value))
        invalid = not _valid(value, 0, limit("image_pixels")) or not whole
        what = f"cameras.{which}.{key} {value}"
    rig = {"app": "stereo", "name": "fuzzed", "cameras": cameras, "right_in_left": {"xyz": xyz, "rpy": rpy},
           "left_in_base": {"xyz": [-0.425, 0.15, 1.25], "rpy": [math.pi, 0, 0]},
           "segmentation": {"hue": [100, 130], "saturation": [80, 255], "value": [40, 255]}}
    return f"{what} (baseline {xyz})", rig, invalid


@examples(fast=40, full=250)
@given(st.data())
def test_random_rig_schema(data):
    what, rig, invalid = data.draw(rig_schema())
    run_document("stereo schema", "rig.yaml", rig, estimate, check, must_refuse=invalid, what=what)
