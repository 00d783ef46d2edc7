"""A pinhole camera for the viewer: where it stands, what it looks at, and where points land in the image.

Conventions are viser's (OpenCV): the camera frame has +z forward, +y down and +x right, its
orientation ``wxyz`` is the rotation camera → world, and ``fov`` is the vertical field of view. A
point at camera coordinates (x, y, z), z > 0, lands at pixel (u, v) = (f x / z + W / 2, f y / z + H / 2)
with f = (H / 2) / tan(fov / 2), u to the right and v down from the top-left corner: the same
projection the browser's three.js camera makes for a render of W × H pixels, so tests can say where
a drawn object must appear.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gagen.viewer.geometry import quaternion

Array = NDArray[np.float64]
UP = (0.0, 0.0, 1.0)  # the robots' world frames have z up


@dataclass(frozen=True)
class Camera:
    position: tuple[float, float, float]
    look_at: tuple[float, float, float]
    fov: float = math.radians(50.0)
    up: tuple[float, float, float] = UP

    def rotation(self) -> Array:
        """3 × 3, camera → world: columns right, down, forward."""
        forward = np.subtract(self.look_at, self.position, dtype=float)
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, self.up)
        if np.linalg.norm(right) < 1e-9:
            raise ValueError(f"camera looks along its up direction {self.up}: the image's roll is undefined")
        right /= np.linalg.norm(right)
        return np.column_stack([right, np.cross(forward, right), forward])

    def wxyz(self) -> Array:
        return quaternion(self.rotation())

    def project(self, points: Array, width: int, height: int) -> Array:
        """(n, 2) pixel coordinates (u right, v down) of world points (n, 3); NaN behind the camera."""
        c = (np.atleast_2d(points) - np.asarray(self.position)) @ self.rotation()
        f = (height / 2.0) / math.tan(self.fov / 2.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = np.column_stack([f * c[:, 0] / c[:, 2] + width / 2.0, f * c[:, 1] / c[:, 2] + height / 2.0])
        uv[c[:, 2] <= 0.0] = np.nan
        return uv


def framing(points: Array, *, azimuth: float = math.radians(-60.0), elevation: float = math.radians(30.0),
            fov: float = math.radians(50.0), aspect: float = 4.0 / 3.0, fill: float = 0.85) -> Camera:
    """A camera looking at the centre of ``points``' bounding box from the direction (azimuth about z
    from +x, elevation above the xy plane), at the distance where the points fill ``fill`` of the image
    (the larger of their horizontal and vertical extent, measured from the centre)."""
    p = np.atleast_2d(np.asarray(points, dtype=float))
    centre = 0.5 * (p.min(axis=0) + p.max(axis=0))
    radius = max(0.05, float(np.max(np.linalg.norm(p - centre, axis=1))))
    direction = np.array([math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
                          math.sin(elevation)])

    def camera(distance: float) -> Camera:
        eye = centre + distance * direction
        return Camera((float(eye[0]), float(eye[1]), float(eye[2])),
                      (float(centre[0]), float(centre[1]), float(centre[2])), fov)

    def extent(distance: float) -> float:  # the points' largest offset from the image centre, in half-sizes
        uv = camera(distance).project(p, 2000, round(2000 / aspect)) / [1000.0, 1000.0 / aspect] - 1.0
        return float(np.max(np.abs(uv))) if np.all(np.isfinite(uv)) else math.inf

    def fit() -> float:
        near = 1.01 * radius
        far = near / math.sin(min(fov, 2.0 * math.atan(aspect * math.tan(fov / 2))) / 2)
        if extent(near) <= fill:  # even from just outside the bounding sphere the points are small
            return near
        for _ in range(50):  # bisection: the extent decreases with the distance beyond the bounding sphere
            middle = 0.5 * (near + far)
            near, far = (middle, far) if extent(middle) > fill else (near, middle)
        return far

    for _ in range(2):  # centre the points' image: move the look-at point across the view, then refit
        distance = fit()
        view = camera(distance)
        uv = view.project(p, 2000, round(2000 / aspect))
        offset = 0.5 * (uv.min(axis=0) + uv.max(axis=0)) - [1000.0, 1000.0 / aspect]
        f = (1000.0 / aspect) / math.tan(fov / 2.0)
        centre = centre + view.rotation()[:, :2] @ offset * distance / f
    return camera(fit())
