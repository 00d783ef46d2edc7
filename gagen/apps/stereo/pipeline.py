"""One stereo frame to the controller's reference [SMC IV]: the symmetry line and mass centre in each
image (``vision``), the generated ``estimate`` kernel (the 3D symmetry axis as the meet of the two
back-projected planes, the mass centre triangulated and dropped onto the axis), and the result in
the robot's base frame as the sliding-mode controller's x_ref = [position; unit direction].

A frame gives a pose or a :class:`Failure` naming why (no symmetry in an image, the two planes too
close to each other: the axis near the epipolar plane), never a NaN.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from gagen.apps.stereo import vision
from gagen.apps.stereo.calibration import Rig
from gagen.apps.stereo.kernels import stereo_kernels

# below this sine of the angle between the two back-projected planes (≈ 2.9°) the axis is not trusted:
# its error grows as 1/conditioning
MIN_CONDITIONING = 0.05
BASE_ORIENTATION = (0.0, 1.0, 0.0)  # the reference direction of [SMC Eq. 43]: an axis's sign is unknown
# to a symmetry line, so the base-frame direction is turned to agree with it


@dataclass(frozen=True)
class FrameEstimate:
    reference: np.ndarray  # the position reference: the mass centre's foot on the axis (left frame, m)
    direction: np.ndarray  # the axis' unit direction (left frame)
    point: np.ndarray  # the axis' point nearest the left camera centre
    centre: np.ndarray  # the triangulated mass centre
    conditioning: float  # sine of the angle between the two planes (0: degenerate)
    gap: float  # length of the common perpendicular of the two viewing lines (m)
    left: vision.Detection
    right: vision.Detection

    def in_base(self, rig: Rig, orientation: tuple[float, float, float] = BASE_ORIENTATION) -> np.ndarray:
        """x_ref = [position; direction] in the robot's base frame, the direction turned to agree with
        ``orientation``."""
        pose = rig.left_in_base
        direction = pose.R @ self.direction
        if direction @ np.asarray(orientation) < 0:
            direction = -direction
        return np.concatenate([pose.apply(self.reference), direction])


@dataclass(frozen=True)
class Failure:
    reason: str

    def __str__(self) -> str:
        return self.reason


class Estimator:
    """A rig's per-frame estimator: its ``estimate`` kernel compiled (``gagen.compile``'s cache, once
    per content) or taken from a loaded module's C namespace."""

    def __init__(self, rig: Rig, module: Any | None = None, settings: vision.Settings | None = None) -> None:
        if module is None:
            from gagen.build import compile_kernels

            module = compile_kernels(stereo_kernels(rig), name=rig.name)
        self.rig, self.kernel = rig, module.estimate
        self.settings = settings or vision.Settings()

    def observe(self, left: vision.Detection, right: vision.Detection) -> FrameEstimate | Failure:
        obs = np.array([left.theta, left.r, right.theta, right.r, *left.centre_xy, *right.centre_xy])
        point, direction, conditioning, centre, reference, gap = (np.asarray(v).reshape(-1)
                                                                  for v in self.kernel(obs))
        if conditioning[0] < MIN_CONDITIONING:
            angle, least = (np.degrees(np.arcsin(min(c, 1.0))) for c in (conditioning[0], MIN_CONDITIONING))
            return Failure(f"degenerate geometry: the two symmetry planes meet at {angle:.2f}° "
                           f"(< {least:.1f}°): the axis lies near the epipolar plane")
        return FrameEstimate(reference, direction, point, centre, float(conditioning[0]), float(gap[0]), left,
                             right)

    def for_accuracy(self) -> Any:
        """The kernel as ``accuracy.evaluate``'s estimator: (rig, left, right) → its Estimate."""
        from gagen.apps.stereo.accuracy import Estimate

        def estimate(rig: Rig, left: vision.Detection, right: vision.Detection) -> Estimate:
            obs = np.array([left.theta, left.r, right.theta, right.r, *left.centre_xy, *right.centre_xy])
            outputs = [np.asarray(v).reshape(-1) for v in self.kernel(obs)]
            direction, conditioning, reference = outputs[1], outputs[2], outputs[4]
            return Estimate(reference, direction, float(conditioning[0]))

        return estimate

    def __call__(self, left_image: np.ndarray, right_image: np.ndarray) -> FrameEstimate | Failure:
        left, right = vision.detect_pair(left_image, right_image, self.rig, self.settings)
        if isinstance(left, vision.NoSymmetry):
            return Failure(f"left image: {left}")
        if isinstance(right, vision.NoSymmetry):
            return Failure(f"right image: {right}")
        return self.observe(left, right)
