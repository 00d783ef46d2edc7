"""A calibrated stereo rig (YAML, ``app: stereo``): two pinhole cameras, the right camera's pose in the
left camera's frame, the left camera's pose in the robot's base frame, and the object's colour.

    app: stereo
    name: stereo_rig
    cameras:                                   # pinhole intrinsics in pixels (no distortion)
      left:  {fx: 600, fy: 600, cx: 319.5, cy: 239.5, width: 640, height: 480}
      right: {fx: 600, fy: 600, cx: 319.5, cy: 239.5, width: 640, height: 480}
    right_in_left: {xyz: [0.25, 0, 0], rpy: [0, 0, 0]}   # X_left = R X_right + t (m, rad)
    left_in_base: {xyz: [-0.425, 0.15, 1.25], rpy: [3.1416, 0, 0]}  # X_base = R X_left + t
    segmentation: {hue: [100, 130], saturation: [80, 255], value: [40, 255]}   # OpenCV HSV ranges
    head: {pan_behind: 0.08, tilt_offset: [0, 0.04, 0.03], pan_limit: 2.6, tilt_limit: 1.2}  # optional

``head`` (optional; these are its defaults) is the pan-tilt unit carrying the rig (``gagen track-head``,
:mod:`gagen.apps.stereo.pantilt`): the pan axis runs along the left camera's −y (image up) through the
rig's middle, ``pan_behind`` m behind the cameras; the tilt axis along the pan link's x, ``tilt_offset``
(m, in the pan link) from the pan axis; the joint limits in rad.
Camera frames follow OpenCV: x right, y down, z forward (the optical axis); a pixel (u, v) has the
normalised image coordinates x = (u − cx)/fx, y = (v − cy)/fy, the point (x, y, 1) of the image plane
z = 1. ``rpy`` is the URDF convention, R = Rz(yaw) Ry(pitch) Rx(roll). Errors name the file, the field
with its line and what was expected (``gagen.yaml_document``). The image size is bounded by the limit
``image_pixels`` (``gagen.limits``), and the cameras' relative pose must leave the kernels' check scene
(``kernels.random_scene``: axes about 1 m in front, seen from two different directions) to be found:
a baseline of at least ``MIN_BASELINE``, not along the viewing direction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gagen.limits import limit, over_limit
from gagen.yaml_document import Document, identifier, known_keys, number, require, show

TOP_KEYS = ("app", "name", "cameras", "right_in_left", "left_in_base", "segmentation", "head")
HEAD_KEYS = ("pan_behind", "tilt_offset", "pan_limit", "tilt_limit")
CAMERA_KEYS = ("fx", "fy", "cx", "cy", "width", "height")
POSE_KEYS = ("xyz", "rpy")
SEGMENTATION_KEYS = ("hue", "saturation", "value")
HSV_LIMITS = {"hue": 179, "saturation": 255, "value": 255}  # OpenCV's 8-bit HSV
MAX_DISTANCE = 1e3  # m
# The check scene (``kernels.random_scene``, the sampler of every kernel, so of ``gagen build --check``):
# an axis through a point in this box (left frame, m; centred across on the rig's middle) whose two
# viewing planes meet at a sine of at least SCENE_CONDITIONING (about baseline / depth at best) and
# whose images are not near infinity. A rig must leave enough such axes for the sampler to find one.
SCENE_LOW, SCENE_HIGH = (-0.15, -0.15, 0.8), (0.15, 0.15, 1.2)
SCENE_CONDITIONING = 0.03
MIN_BASELINE = 0.01  # m: shorter, the sampler's axes thin out (at 0.01 mm it found none in 200 000 tries)
# the share of random axes a rig must accept: the sampler's 10 000 tries then fail with p < e⁻³⁰
MIN_SCENE_RATE = 0.005


@dataclass(frozen=True)
class Camera:
    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def normalised(self, pixels: np.ndarray) -> np.ndarray:
        """Pixels (…, 2) → normalised image coordinates (…, 2)."""
        p = np.asarray(pixels, dtype=float)
        return np.stack([(p[..., 0] - self.cx) / self.fx, (p[..., 1] - self.cy) / self.fy], axis=-1)

    def pixels(self, normalised: np.ndarray) -> np.ndarray:
        """Normalised image coordinates (…, 2) → pixels (…, 2)."""
        x = np.asarray(normalised, dtype=float)
        return np.stack([x[..., 0] * self.fx + self.cx, x[..., 1] * self.fy + self.cy], axis=-1)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Points (…, 3) in this camera's frame → pixels (…, 2)."""
        p = np.asarray(points, dtype=float)
        return self.pixels(p[..., :2] / p[..., 2:3])


@dataclass(frozen=True)
class Pose:
    """A rigid transformation x ↦ R x + t."""

    R: np.ndarray
    t: np.ndarray

    @property
    def matrix(self) -> np.ndarray:
        out = np.eye(4)
        out[:3, :3], out[:3, 3] = self.R, self.t
        return out

    def apply(self, points: np.ndarray) -> np.ndarray:
        moved: np.ndarray = np.asarray(points, dtype=float) @ self.R.T + self.t
        return moved

    def inverse(self) -> Pose:
        return Pose(self.R.T, -self.R.T @ self.t)


@dataclass(frozen=True)
class Head:
    """The pan-tilt unit carrying the rig (module docstring): offsets in m, limits in rad."""
    pan_behind: float = 0.08
    tilt_offset: tuple[float, float, float] = (0.0, 0.04, 0.03)
    pan_limit: float = 2.6
    tilt_limit: float = 1.2


@dataclass(frozen=True)
class Rig:
    name: str
    left: Camera
    right: Camera
    right_in_left: Pose  # X_left = R X_right + t
    left_in_base: Pose  # X_base = R X_left + t
    hsv_low: tuple[int, int, int]  # inclusive OpenCV HSV range of the object's colour
    hsv_high: tuple[int, int, int]
    head: Head = Head()

    @property
    def baseline(self) -> float:
        return float(np.linalg.norm(self.right_in_left.t))


def canonical_line(theta: float, r: float) -> tuple[float, float]:
    """An image line x cos θ + y sin θ = r with θ ∈ (−π/2, π/2] ((θ, r) and (θ + π, −r) are one line)."""
    theta = math.atan2(math.sin(theta), math.cos(theta))
    if theta > math.pi / 2:
        return theta - math.pi, -r
    if theta <= -math.pi / 2:
        return theta + math.pi, -r
    return theta, r


def scene_accepts(p: np.ndarray, d: np.ndarray, right_in_left: Pose,
                  min_conditioning: float = SCENE_CONDITIONING) -> np.ndarray:
    """Whether axes through points ``p`` along unit directions ``d`` (…, 3; left frame) make a
    well-conditioned check scene: the planes through each camera centre and the axis meet at a sine of
    at least ``min_conditioning``, and neither image line runs near infinity (its plane's normal at
    least 0.2 off the camera's optical axis)."""
    R, t = right_in_left.R, right_in_left.t
    n_l, n_r = np.cross(p, d), np.cross(p - t, d)
    with np.errstate(invalid="ignore", divide="ignore"):  # an axis through a centre: nan, refused
        sine = np.linalg.norm(np.cross(n_l, n_r), axis=-1) / (np.linalg.norm(n_l, axis=-1)
                                                              * np.linalg.norm(n_r, axis=-1))
        flat = np.minimum(*(np.hypot(n[..., 0], n[..., 1]) / np.linalg.norm(n, axis=-1)
                            for n in (n_l, n_r @ R)))  # n_r @ R = Rᵀ n_r, the right camera's frame
    accepted: np.ndarray = (sine >= min_conditioning) & (flat > 0.2)
    return accepted


def scene_rate(right_in_left: Pose, samples: int = 4000, seed: int = 0) -> float:
    """The share of random axes (``kernels.random_scene``'s distribution) that make a check scene."""
    rng = np.random.default_rng(seed)
    middle = np.array([right_in_left.t[0] / 2, right_in_left.t[1] / 2, 0.0])
    p = middle + rng.uniform(SCENE_LOW, SCENE_HIGH, (samples, 3))
    d = rng.normal(size=(samples, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return float(np.mean(scene_accepts(p, d, right_in_left)))


def rpy_matrix(rpy: tuple[float, float, float]) -> np.ndarray:
    """URDF roll-pitch-yaw: Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _camera(spec: Document, value: Any, field: str) -> Camera:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {show(value)}; expected {{fx, fy, cx, cy, width, height}} in pixels")
    known_keys(spec, value, field, CAMERA_KEYS)
    numbers = {}
    bound = limit("image_pixels")  # read per load: GAGEN_LIMIT_IMAGE_PIXELS raises it
    for key in CAMERA_KEYS:
        v = require(spec, value, key, f"{field}.{key}", (int, float), "a number of pixels")
        side = key in ("width", "height")
        if side and isinstance(v, int) and v > 0:  # the image size: refused by the limit, which names
            problem = over_limit("image_pixels", v)  # the variable that raises it
            if problem:
                raise spec.error(f"{field}.{key}", problem)
        if not number(v, bound) or v <= 0 or (side and v != int(v)):
            raise spec.error(f"{field}.{key}", f"got {show(v)}; expected a positive "
                                               f"{'whole ' if side else ''}number of pixels up to {bound}")
        numbers[key] = v
    return Camera(float(numbers["fx"]), float(numbers["fy"]), float(numbers["cx"]), float(numbers["cy"]),
                  int(numbers["width"]), int(numbers["height"]))


def _triple(spec: Document, value: Any, field: str, bound: float) -> tuple[float, float, float]:
    if not isinstance(value, list) or len(value) != 3 or not all(number(v, bound) for v in value):
        raise spec.error(field, f"got {show(value)}; expected three finite numbers within ±{bound:g}")
    return float(value[0]), float(value[1]), float(value[2])


def _pose(spec: Document, value: Any, field: str) -> Pose:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {show(value)}; expected {{xyz: [x, y, z], rpy: [roll, pitch, yaw]}}")
    known_keys(spec, value, field, POSE_KEYS)
    xyz = _triple(spec, require(spec, value, "xyz", f"{field}.xyz", list, "[x, y, z] in m"), f"{field}.xyz",
                  MAX_DISTANCE)
    rpy = _triple(spec, value.get("rpy", [0, 0, 0]), f"{field}.rpy", 4 * math.pi)
    return Pose(rpy_matrix(rpy), np.array(xyz))


def _segmentation(spec: Document, value: Any) -> tuple[tuple[int, int, int], tuple[int, int, int]]:
    if not isinstance(value, dict):
        raise spec.error("segmentation", f"got {show(value)}; expected {{hue: [lo, hi], saturation: "
                                         f"[lo, hi], value: [lo, hi]}} (OpenCV 8-bit HSV)")
    known_keys(spec, value, "segmentation", SEGMENTATION_KEYS)
    low, high = [], []
    for key in SEGMENTATION_KEYS:
        field = f"segmentation.{key}"
        pair = require(spec, value, key, field, list, f"[lo, hi] within 0 … {HSV_LIMITS[key]}")
        if len(pair) != 2 or not all(isinstance(v, int) and not isinstance(v, bool) for v in pair) \
                or not 0 <= pair[0] <= pair[1] <= HSV_LIMITS[key]:
            raise spec.error(field, f"got {show(pair)}; expected [lo, hi], whole numbers with "
                                    f"0 ≤ lo ≤ hi ≤ {HSV_LIMITS[key]}")
        low.append(pair[0])
        high.append(pair[1])
    return (low[0], low[1], low[2]), (high[0], high[1], high[2])


def _head(spec: Document, value: Any) -> Head:
    if not isinstance(value, dict):
        raise spec.error("head", f"got {show(value)}; expected {{pan_behind: m, tilt_offset: [x, y, z], "
                                 f"pan_limit: rad, tilt_limit: rad}}")
    known_keys(spec, value, "head", HEAD_KEYS)
    default = Head()
    behind = value.get("pan_behind", default.pan_behind)
    if not number(behind, MAX_DISTANCE):
        raise spec.error("head.pan_behind", f"got {show(behind)}; expected a finite number of m within "
                                            f"±{MAX_DISTANCE:g}")
    offset = _triple(spec, value.get("tilt_offset", list(default.tilt_offset)), "head.tilt_offset",
                     MAX_DISTANCE)
    limits = []
    for key in ("pan_limit", "tilt_limit"):
        v = value.get(key, getattr(default, key))
        if not (number(v, math.pi) and v > 0):
            raise spec.error(f"head.{key}", f"got {show(v)}; expected a number of rad in (0, π]")
        limits.append(float(v))
    return Head(float(behind), offset, limits[0], limits[1])


def load_rig(path: str | Path) -> Rig:
    """The stereo rig of a calibration file."""
    spec = Document(Path(path), "a mapping with app: stereo, name, cameras, right_in_left, left_in_base and "
                                "segmentation")
    data = spec.data
    known_keys(spec, data, "", TOP_KEYS)
    if data.get("app") != "stereo":
        raise spec.error("app", f"got {show(data.get('app'))}; a stereo rig says app: stereo")
    name = identifier(spec, require(spec, data, "name", "name", str, "the rig's name"), "name",
                      "the rig's name")
    cameras = require(spec, data, "cameras", "cameras", dict, "{left: {...}, right: {...}}")
    known_keys(spec, cameras, "cameras", ("left", "right"))
    left = _camera(spec, require(spec, cameras, "left", "cameras.left", dict, "the left camera"),
                   "cameras.left")
    right = _camera(spec, require(spec, cameras, "right", "cameras.right", dict, "the right camera"),
                    "cameras.right")
    listed = require(spec, data, "right_in_left", "right_in_left", dict,
                     "the right camera's pose in the left camera's frame")
    right_in_left = _pose(spec, listed, "right_in_left")
    baseline = float(np.linalg.norm(right_in_left.t))
    if baseline < MIN_BASELINE:
        raise spec.error("right_in_left.xyz", f"got a {'zero' if baseline == 0 else f'{baseline:g} m'} "
                                              f"baseline; expected the right camera's centre at least "
                                              f"{MIN_BASELINE:g} m from the left one's (the axis' "
                                              f"conditioning is about baseline / depth)")
    rate = scene_rate(right_in_left)
    if rate < MIN_SCENE_RATE:  # e.g. a short baseline along the viewing direction: no scene to check with
        raise spec.error("right_in_left", f"{rate:.2%} of random axes 0.8-1.2 m in front of the left camera "
                                          f"are seen well conditioned (viewing planes meeting at a sine "
                                          f"≥ {SCENE_CONDITIONING:g}); expected at least "
                                          f"{MIN_SCENE_RATE:.1%}: the right camera's centre apart from "
                                          f"the left one's across their viewing direction, not along it")
    left_in_base = _pose(spec, data.get("left_in_base", {"xyz": [0, 0, 0]}), "left_in_base")
    low, high = _segmentation(spec, require(spec, data, "segmentation", "segmentation", dict,
                                            "the object's HSV colour range"))
    head = _head(spec, data["head"]) if "head" in data else Head()
    return Rig(name, left, right, right_in_left, left_in_base, low, high, head)
