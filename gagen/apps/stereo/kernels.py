"""The kernel catalogue of a stereo rig, as front-end kernels over cga3d (``gagen.kernel``); the rig's
stereo motor M (right camera → left camera) is an exact constant of each. Everything 3D is in the left
camera's frame; image quantities are in normalised image coordinates (``gagen.apps.stereo.geometry``).

- ``image_line``: θ, r → L, the image line on z = 1 as a CGA line (Eq. 21);
- ``planes``: lines (θ_l, r_l, θ_r, r_r) → line_l, line_r = M L M~ (Eq. 22-23), centre_l = e0,
  centre_r = M e0 M~ (Eq. 24-25), plane_l, plane_r = c ∧ L (Eq. 26-27);
- ``axis``: lines → axis (π_l ∨ π_r, Eq. 28, normalised and oriented), point (closest to the left
  camera centre), direction (unit, signed by ``AXIS_REFERENCE``), conditioning (sine of the angle
  between the planes, 0 in the degenerate epipolar case);
- ``reproject``: a 3D line → hesse_l, hesse_r ((θ, r) of its perspective images), image_l, image_r (those
  images as CGA lines on z = 1) and ortho_l, ortho_r (Eq. 30-31's (L·Π)Π⁻¹), in each camera's frame;
- ``viewing_lines``: centres (x_l, y_l, x_r, y_r) → view_l, view_r (Eq. 29);
- ``triangulate``: centres → point (midpoint of the viewing lines' common perpendicular), gap (its length);
- ``estimate``: obs (θ_l, r_l, θ_r, r_r, x_l, y_l, x_r, y_r) → point, direction, conditioning, centre (the
  3D mass centre), reference (the centre's foot on the axis: the position reference), gap. The
  per-frame kernel.

``stereo_source(path)`` makes the module of a rig file (``app: stereo``), named after the rig.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from gagen.apps.stereo import geometry as geo
from gagen.apps.stereo.calibration import (
    SCENE_CONDITIONING,
    SCENE_HIGH,
    SCENE_LOW,
    Rig,
    load_rig,
    scene_accepts,
)
from gagen.build import check_identifier
from gagen.codegen.ir import ModuleSource
from gagen.errors import read_input
from gagen.frontend import KernelFunction, scalars, source_of

XYZ = ("x", "y", "z")
HESSE = ("theta", "r")
LINES = ("theta_l", "r_l", "theta_r", "r_r")
CENTRES = ("x_l", "y_l", "x_r", "y_r")
SAMPLE_NOISE = 2e-3  # normalised image units: 1.2 px at f = 600 px
KERNELS = ("image_line", "planes", "axis", "reproject", "viewing_lines", "triangulate", "estimate")
MAX_SCENE_TRIES = 10_000  # the loader refuses rigs accepting under 0.5 % of the tries (calibration)


class SceneError(ValueError):
    """No well-conditioned scene in MAX_SCENE_TRIES tries: a rig the loader would refuse."""


# -- well-conditioned samples for --check: a random axis about 1 m in front of both cameras ---------------

@dataclasses.dataclass(frozen=True)
class Scene:
    """A 3D axis (point, unit direction) and a mass centre near it, in the left camera's frame, with
    their images: lines (θ_l, r_l, θ_r, r_r) and centres (x_l, y_l, x_r, y_r)."""

    point: np.ndarray
    direction: np.ndarray
    centre: np.ndarray
    lines: np.ndarray
    centres: np.ndarray


def hesse_of(point: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """(θ, r) of the image of a 3D line (in the camera's frame): the plane through the centre and the
    line has the normal n = p × d, and meets z = 1 in n1 x + n2 y + n3 = 0."""
    n = np.cross(point, direction)
    return np.array([np.arctan2(n[1], n[0]), -n[2] / np.hypot(n[0], n[1])])


def random_scene(rig: Rig, rng: np.random.Generator, min_conditioning: float = SCENE_CONDITIONING,
                 noise: float = 0.0) -> Scene:
    """An axis through a point 0.8-1.2 m deep, within ±0.15 m of the rig's middle across, with a random
    direction such that both planes meet at a sine of at least ``min_conditioning`` (≈ baseline / depth
    at best: 0.25 for the bundled rig at 1 m) and neither image line runs near infinity; the mass
    centre within 5 cm of the axis' point; ``noise``: the standard deviation of N(0, noise²) added to
    the image centres (normalised units), so that their viewing lines miss each other by a measurable
    gap. Raises SceneError after MAX_SCENE_TRIES tries (a rig whose baseline is too short for it)."""
    R, t = rig.right_in_left.R, rig.right_in_left.t
    for _ in range(MAX_SCENE_TRIES):
        p = np.array([t[0] / 2, t[1] / 2, 0.0]) + rng.uniform(SCENE_LOW, SCENE_HIGH)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        if scene_accepts(p, d, rig.right_in_left, min_conditioning):
            break
    else:
        raise SceneError(f"{rig.name}: no axis 0.8-1.2 m in front of the cameras is seen well conditioned "
                         f"(viewing planes meeting at a sine ≥ {min_conditioning:g}) in {MAX_SCENE_TRIES} "
                         f"tries: the baseline of {rig.baseline:g} m is too short for it")
    centre = p + rng.uniform(-0.05, 0.05) * d + rng.normal(scale=0.01, size=3)
    centre_r = R.T @ (centre - t)
    lines = np.concatenate([hesse_of(p, d), hesse_of(R.T @ (p - t), R.T @ d)])
    centres = np.concatenate([centre[:2] / centre[2], centre_r[:2] / centre_r[2]])
    centres = centres + rng.normal(scale=noise, size=4)
    return Scene(p, d, centre, lines, centres)


def axis_line(point: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The CGA line through ``point`` along ``direction`` (e0∧d∧e∞ + (p × d)* ∧ e∞), on the line kind's
    blades e01∞, e02∞, e12∞, e03∞, e13∞, e23∞."""
    m = np.cross(point, direction)
    return np.array([direction[0], direction[1], m[2], direction[2], -m[1], m[0]])


# -- the kernels -----------------------------------------------------------------------------------------

def _kernel(fn: Callable[..., Any], name: str, inputs: dict[str, Any], outputs: dict[str, Any], doc: str,
            sample: Callable[[np.random.Generator], list[np.ndarray]]) -> KernelFunction:
    return KernelFunction(fn, algebra="cga3d", inputs={**inputs, "ga": "algebra"}, outputs=outputs, name=name,
                          doc=doc, sample=sample)


def stereo_kernels(rig: Rig, reference: tuple[float, float, float] = geo.AXIS_REFERENCE
                   ) -> list[KernelFunction]:
    """Every kernel of a rig's module, in a stable order (``KERNELS``)."""
    pose = rig.right_in_left

    def scene(rng: np.random.Generator) -> Scene:
        # (the centres about a pixel off: a consistent pair's gap is rounding noise at the check's floor)
        return random_scene(rig, rng, noise=SAMPLE_NOISE)

    def image_line(theta: Any, r: Any, ga: Any) -> dict[str, Any]:
        return {"L": geo.image_line(ga, theta, r)}

    def planes(lines: Any, ga: Any) -> dict[str, Any]:
        p = geo.back_projection(ga, geo.stereo_motor(ga, pose), lines[0:2], lines[2:4])
        return {"line_l": p.line_l, "line_r": p.line_r, "centre_l": p.centre_l, "centre_r": p.centre_r,
                "plane_l": p.plane_l, "plane_r": p.plane_r}

    def axis(lines: Any, ga: Any) -> dict[str, Any]:
        a = geo.symmetry_axis(ga, geo.stereo_motor(ga, pose), lines[0:2], lines[2:4], reference)
        return {"axis": a.line, "point": a.point, "direction": a.direction, "conditioning": a.conditioning}

    def reproject(line: Any, ga: Any) -> dict[str, Any]:
        r = geo.reproject(ga, geo.stereo_motor(ga, pose), line)
        return {"hesse_l": list(r.hesse_l), "hesse_r": list(r.hesse_r), "image_l": r.image_l,
                "image_r": r.image_r, "ortho_l": r.ortho_l, "ortho_r": r.ortho_r}

    def viewing_lines(centres: Any, ga: Any) -> dict[str, Any]:
        view_l, view_r = geo.viewing_lines(ga, geo.stereo_motor(ga, pose), centres[0:2], centres[2:4])
        return {"view_l": view_l, "view_r": view_r}

    def triangulate(centres: Any, ga: Any) -> dict[str, Any]:
        point, gap = geo.triangulate(ga, geo.stereo_motor(ga, pose), centres[0:2], centres[2:4])
        return {"point": point, "gap": gap}

    def estimate(obs: Any, ga: Any) -> dict[str, Any]:
        e = geo.estimate(ga, geo.stereo_motor(ga, pose), obs[0:4], obs[4:8], reference)
        return {"point": e.axis.point, "direction": e.axis.direction, "conditioning": e.axis.conditioning,
                "centre": e.centre, "reference": e.reference, "gap": e.gap}

    xyz, lines, centres = scalars(3, XYZ), scalars(4, LINES), scalars(4, CENTRES)
    ref = ", ".join(f"{v:g}" for v in reference)
    return [
        _kernel(image_line, "image_line", {"theta": "scalar", "r": "scalar"}, {"L": "line"},
                "an image line x cos θ + y sin θ = r (normalised) as the CGA line on z = 1 (Eq. 21)",
                lambda rng: list(np.split(scene(rng).lines[0:2], 2))),
        _kernel(planes, "planes", {"lines": lines},
                {"line_l": "line", "line_r": "line", "centre_l": "point", "centre_r": "point",
                 "plane_l": "plane", "plane_r": "plane"},
                "both image lines and camera centres in the left frame and their planes c ∧ L (Eq. 22-27)",
                lambda rng: [scene(rng).lines]),
        _kernel(axis, "axis", {"lines": lines},
                {"axis": "line", "point": xyz, "direction": xyz, "conditioning": "scalar"},
                f"the 3D symmetry axis π_l ∨ π_r (Eq. 28): unit line, point nearest the left centre, "
                f"direction (· ({ref}) ≥ 0), conditioning",
                lambda rng: [scene(rng).lines]),
        _kernel(reproject, "reproject", {"line": "line"},
                {"hesse_l": scalars(2, HESSE), "hesse_r": scalars(2, HESSE), "image_l": "line",
                 "image_r": "line", "ortho_l": "line", "ortho_r": "line"},
                "a 3D line's perspective images per camera as (θ, r) and lines on z = 1, and Eq. 30-31's "
                "(L·Π)Π⁻¹",
                lambda rng: [axis_line(*dataclasses.astuple(scene(rng))[:2])]),
        _kernel(viewing_lines, "viewing_lines", {"centres": centres}, {"view_l": "line", "view_r": "line"},
                "the viewing lines X ∧ c ∧ e∞ of two image points, in the left frame (Eq. 29)",
                lambda rng: [scene(rng).centres]),
        _kernel(triangulate, "triangulate", {"centres": centres}, {"point": xyz, "gap": "scalar"},
                "the 3D point of two image points: midpoint and length of the viewing lines' common "
                "perpendicular",
                lambda rng: [scene(rng).centres]),
        _kernel(estimate, "estimate", {"obs": scalars(8, LINES + CENTRES)},
                {"point": xyz, "direction": xyz, "conditioning": "scalar", "centre": xyz, "reference": xyz,
                 "gap": "scalar"},
                "one frame: symmetry axis (point, direction, conditioning), 3D mass centre, its foot on the "
                "axis, viewing-line gap",
                lambda rng: [np.concatenate(dataclasses.astuple(scene(rng))[3:])]),
    ]


def stereo_source(spec: str | Path) -> ModuleSource:
    """The module of a stereo rig file, named after the rig. A malformed file raises ``SpecError``."""
    path = Path(spec)
    rig = load_rig(path)
    check_identifier(rig.name, "rig name", path)
    source = source_of(stereo_kernels(rig), rig.name, path.name, read_input(path, "spec"),
                       f"gagen build {path.name}")
    meta = {**source.meta, "app": "stereo", "axis_reference": list(geo.AXIS_REFERENCE),
            "baseline": rig.baseline}
    title = f"kernels of {rig.name}, a stereo rig ({rig.baseline:g} m baseline): symmetry axis in CGA"
    return dataclasses.replace(source, title=title, meta=meta)
