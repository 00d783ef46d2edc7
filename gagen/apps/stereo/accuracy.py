"""Accuracy of the stereo symmetry-line estimate on rendered scenes with ground truth [issue 16, item 4].

For each random pose (:func:`~gagen.apps.stereo.scene.random_pose`: about 1 m away, inside both images,
the axis away from the epipolar plane) and each noise level, render the pair, detect the symmetry line
and mass centre in both images (:mod:`~gagen.apps.stereo.vision`), reconstruct the 3D axis and point,
and compare with the truth:

- **axis error**: the angle between the estimated and the true axis (unoriented lines, 0 … 90°);
- **line error**: the distance from the true centre to the estimated 3D line (how far the line misses
  the object; the distance between two nearly parallel lines is ill-conditioned, this is not);
- **point error**: the distance between the estimated reference point and the true one. The paper
  builds the reference from the two image mass centres: here they are triangulated (the midpoint of
  the closest approach of their viewing rays) and the point projected onto the estimated axis
  (``"triangulate"``), or each mass centre's viewing ray is met with the estimated axis and the two
  points averaged (``"rays"``: no disparity involved); the two agree within ~10 % in error. An image
  mass centre is not the image of a fixed body point (perspective, and the end discs show when the
  axis tilts towards a camera), so the true reference is the same construction on the true axis from
  the exact silhouette mass centres of the noise-free, unoccluded object (:func:`reference_point`);
  the **centre error** compares with the body's fixed centre
  (:attr:`~gagen.apps.stereo.scene.ObjectPose.centre`) instead, and includes that bias (~2 mm median,
  up to ~1 cm when the axis tilts 30° towards a camera);
- **failures**, per frame, with the reason (either image's "no symmetry: …", or "degenerate geometry"
  when the two viewing planes nearly coincide).

The reconstruction here is plain numpy (the plane through each camera centre and its image line,
intersected), independent of the generated CGA kernels; ``estimator`` swaps in another one.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from gagen.apps.stereo import scene, vision
from gagen.apps.stereo.calibration import Rig


@dataclass(frozen=True)
class Estimate:
    point: np.ndarray  # reference point on the axis, left camera frame (m)
    direction: np.ndarray  # unit axis direction (sign arbitrary)
    conditioning: float  # sine of the angle between the two viewing planes: 0 when they coincide


def viewing_plane(theta: float, r: float) -> np.ndarray:
    """Normal of the plane through a camera centre and the image line (θ, r), in that camera's frame:
    n · (x, y, 1) = 0 on the line, so n = (cos θ, sin θ, −r) and the plane is n · X = 0."""
    return np.array([np.cos(theta), np.sin(theta), -r])


def triangulate_axis(rig: Rig, left: tuple[float, float], right: tuple[float, float]
                     ) -> tuple[np.ndarray, np.ndarray, float]:
    """The 3D line (a point, a unit direction) in the left frame as the meet of the two viewing planes,
    and their conditioning (sine of the angle between them)."""
    R, t = rig.right_in_left.R, rig.right_in_left.t
    n1 = viewing_plane(*left)
    n2 = R @ viewing_plane(*right)  # X_r = Rᵀ(X − t): n_r · X_r = 0 ⇔ (R n_r) · X = (R n_r) · t
    d2 = float(n2 @ t)
    n1, n2, d2 = n1 / np.linalg.norm(n1), n2 / np.linalg.norm(n2), d2 / float(np.linalg.norm(n2))
    u = np.cross(n1, n2)
    s = float(np.linalg.norm(u))
    if s < 1e-12:
        return np.zeros(3), np.array([0.0, 0.0, 1.0]), 0.0
    point = d2 * np.cross(u, n1) / (s * s)  # the line's point closest to the left camera centre
    return point, u / s, s


def triangulate_point(rig: Rig, left_xy: np.ndarray, right_xy: np.ndarray) -> np.ndarray:
    """Midpoint of the closest approach of the viewing rays of two normalised image points."""
    R, t = rig.right_in_left.R, rig.right_in_left.t
    a = np.array([left_xy[0], left_xy[1], 1.0])
    b = R @ np.array([right_xy[0], right_xy[1], 1.0])
    # minimise |s a − (t + u b)|²
    m = np.array([[a @ a, -a @ b], [a @ b, -b @ b]])
    s, u = np.linalg.lstsq(m, np.array([a @ t, b @ t]), rcond=None)[0]
    midpoint: np.ndarray = (s * a + t + u * b) / 2
    return midpoint


def ray_to_axis(origin: np.ndarray, ray: np.ndarray, point: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The point of the line (point, direction) closest to the ray from ``origin`` along ``ray``."""
    w = point - origin
    m = np.array([[direction @ direction, -direction @ ray], [direction @ ray, -ray @ ray]])
    s, _ = np.linalg.lstsq(m, np.array([-w @ direction, -w @ ray]), rcond=None)[0]
    closest: np.ndarray = point + s * direction
    return closest


def axis_point(rig: Rig, left_xy: np.ndarray, right_xy: np.ndarray, point: np.ndarray,
               direction: np.ndarray, construction: str = "triangulate") -> np.ndarray:
    """The reference point on the axis (point, direction) from the two image mass centres (normalised):
    ``"triangulate"`` them and project onto the axis, or meet each one's viewing ray with the axis
    (``"rays"``) and average."""
    if construction not in ("triangulate", "rays"):
        raise ValueError(f"construction {construction!r}: expected 'triangulate' or 'rays'")
    if construction == "triangulate":
        x = triangulate_point(rig, left_xy, right_xy)
        projected: np.ndarray = point + ((x - point) @ direction) * direction
        return projected
    R, t = rig.right_in_left.R, rig.right_in_left.t
    a = ray_to_axis(np.zeros(3), np.array([left_xy[0], left_xy[1], 1.0]), point, direction)
    b = ray_to_axis(t, R @ np.array([right_xy[0], right_xy[1], 1.0]), point, direction)
    average: np.ndarray = (a + b) / 2
    return average


def numpy_estimator(rig: Rig, left: vision.Detection, right: vision.Detection,
                    construction: str = "triangulate") -> Estimate:
    point, direction, cond = triangulate_axis(rig, (left.theta, left.r), (right.theta, right.r))
    return Estimate(axis_point(rig, left.centre_xy, right.centre_xy, point, direction, construction),
                    direction, cond)


def reference_point(rig: Rig, pose: scene.ObjectPose, construction: str = "triangulate") -> np.ndarray:
    """The reference point that exact measurements give: the construction of :func:`axis_point` on the
    true axis from the exact silhouette mass centres (rasterised at 4× the resolution)."""
    cl, cr = scene.silhouette_centroids(rig, pose, scale=4)
    return axis_point(rig, rig.left.normalised(cl), rig.right.normalised(cr), pose.centre, pose.axis,
                      construction)


Estimator = Callable[[Rig, vision.Detection, vision.Detection], Estimate]


@dataclass(frozen=True)
class Level:
    name: str
    options: scene.SceneOptions


# "n px" is geometric noise: every projected mesh vertex jittered by σ = n px (the rings are ≤ 1.2 px
# apart, so the outline is perturbed about once per pixel), with photometric noise of 4n grey levels on
# top; "grey σ 10" is photometric noise alone
LEVELS = (
    Level("clean", scene.SceneOptions()),
    Level("0.5 px", scene.SceneOptions(vertex_jitter=0.5, pixel_noise=2.0)),
    Level("1 px", scene.SceneOptions(vertex_jitter=1.0, pixel_noise=4.0)),
    Level("2 px", scene.SceneOptions(vertex_jitter=2.0, pixel_noise=8.0)),
    Level("grey σ 10", scene.SceneOptions(pixel_noise=10.0)),
    Level("1 px + blur 1 + clutter", scene.SceneOptions(vertex_jitter=1.0, pixel_noise=4.0, blur=1.0,
                                                        clutter=16)),
    Level("1 px + 20 % occluded", scene.SceneOptions(vertex_jitter=1.0, pixel_noise=4.0, occlusion=0.2)),
)


@dataclass
class Row:
    level: str
    frames: int = 0
    axis_deg: list[float] = field(default_factory=list)
    line_m: list[float] = field(default_factory=list)
    point_m: list[float] = field(default_factory=list)
    centre_m: list[float] = field(default_factory=list)
    epipolar_deg: list[float] = field(default_factory=list)  # the true axis' angle to the epipolar plane
    failures: list[tuple[int, str]] = field(default_factory=list)  # (frame, reason)

    def stats(self, epipolar: tuple[float, float] = (0.0, 90.0)) -> dict[str, float]:
        """Medians and 95th percentiles (over the frames whose axis makes an angle within ``epipolar``
        degrees with the epipolar plane), frame and failure counts."""
        e = np.asarray(self.epipolar_deg)
        keep = (e >= epipolar[0]) & (e <= epipolar[1])
        out: dict[str, float] = {"frames": self.frames, "failures": len(self.failures),
                                 "estimates": int(keep.sum())}
        for key, values, unit in (("axis_deg", self.axis_deg, 1.0), ("line_mm", self.line_m, 1e3),
                                  ("point_mm", self.point_m, 1e3), ("centre_mm", self.centre_m, 1e3)):
            v = np.asarray(values)[keep] * unit
            out[f"{key}_median"] = float(np.median(v)) if len(v) else float("nan")
            out[f"{key}_p95"] = float(np.percentile(v, 95)) if len(v) else float("nan")
        return out


def errors(truth: scene.Truth, reference: np.ndarray, est: Estimate) -> tuple[float, float, float, float]:
    """Axis angle (degrees), line distance from the true centre (m), point error (m) against
    ``reference``, centre error (m) against the body's centre."""
    a = truth.axis_direction
    cosang = min(1.0, abs(float(a @ est.direction)))
    rel = truth.axis_point - est.point
    line = float(np.linalg.norm(rel - (rel @ est.direction) * est.direction))
    return (float(np.degrees(np.arccos(cosang))), line, float(np.linalg.norm(reference - est.point)),
            float(np.linalg.norm(rel)))


def epipolar_angle(rig: Rig, pose: scene.ObjectPose) -> float:
    """The angle (degrees) between the object's axis and the epipolar plane through its centre (the
    plane of the two camera centres and the centre): 0 is the degenerate case."""
    m = np.cross(rig.right_in_left.t, pose.centre)
    return float(np.degrees(np.arcsin(min(1.0, abs(m @ pose.axis) / np.linalg.norm(m)))))


def evaluate(rig: Rig, poses: int | Sequence[scene.ObjectPose] = 200, levels: Sequence[Level] = LEVELS,
             seed: int = 0, estimator: Estimator = numpy_estimator, construction: str = "triangulate",
             min_conditioning: float = 0.005, settings: vision.Settings | None = None) -> list[Row]:
    """The accuracy table: one :class:`Row` per noise level over the same poses (``poses`` random ones
    drawn from ``seed``, or the given list). ``construction`` is the reference point's (see
    :func:`axis_point`; the default estimator uses it too); ``min_conditioning`` the sine of the angle
    between the viewing planes below which a frame counts as degenerate."""
    settings = settings or vision.Settings()
    rng = np.random.default_rng(seed)
    if isinstance(poses, int):
        poses = [scene.random_pose(rig, rng) for _ in range(poses)]
    references = [reference_point(rig, pose, construction) for pose in poses]
    if estimator is numpy_estimator:
        def estimator(rig: Rig, left: vision.Detection, right: vision.Detection) -> Estimate:
            return numpy_estimator(rig, left, right, construction)
    rows = []
    for level in levels:
        row = Row(level.name)
        level_key = zlib.crc32(level.name.encode())
        for k, pose in enumerate(poses):
            # the noise of frame k at a level depends on the seed, the level's name and k only
            frame = scene.render(rig, pose, level.options, np.random.default_rng([seed, level_key, k]))
            row.frames += 1
            left, right = vision.detect_pair(frame.left, frame.right, rig, settings)
            if isinstance(left, vision.NoSymmetry) or isinstance(right, vision.NoSymmetry):
                bad = [f"{side}: {d}" for side, d in (("left", left), ("right", right))
                       if isinstance(d, vision.NoSymmetry)]
                row.failures.append((k, "; ".join(bad)))
                continue
            est = estimator(rig, left, right)
            if est.conditioning < min_conditioning:
                row.failures.append((k, f"degenerate geometry (conditioning {est.conditioning:.4f})"))
                continue
            axis, line, point, centre = errors(frame.truth, references[k], est)
            row.axis_deg.append(axis)
            row.line_m.append(line)
            row.point_m.append(point)
            row.centre_m.append(centre)
            row.epipolar_deg.append(epipolar_angle(rig, pose))
        rows.append(row)
    return rows


def table(rows: Sequence[Row], epipolar: tuple[float, float] = (0.0, 90.0)) -> str:
    """The rows as a Markdown table (statistics over the frames within ``epipolar``, see
    :meth:`Row.stats`)."""
    lines = ["| noise | frames | failures | estimates | axis ° median | axis ° p95 | line mm median "
             "| line mm p95 | point mm median | point mm p95 | centre mm median | centre mm p95 |",
             "|" + "---|" * 12]
    for row in rows:
        s = row.stats(epipolar)
        lines.append(f"| {row.level} | {s['frames']:.0f} | {s['failures']:.0f} | {s['estimates']:.0f} "
                     f"| {s['axis_deg_median']:.3f} "
                     f"| {s['axis_deg_p95']:.3f} | {s['line_mm_median']:.2f} | {s['line_mm_p95']:.2f} "
                     f"| {s['point_mm_median']:.2f} | {s['point_mm_p95']:.2f} "
                     f"| {s['centre_mm_median']:.2f} | {s['centre_mm_p95']:.2f} |")
    return "\n".join(lines)


if __name__ == "__main__":  # python -m gagen.apps.stereo.accuracy [poses]
    import sys
    from pathlib import Path

    from gagen.apps.stereo.calibration import load_rig

    bundled = load_rig(Path(__file__).parent / "robots" / "stereo_rig.yaml")
    result = evaluate(bundled, int(sys.argv[1]) if len(sys.argv) > 1 else 200)
    print(table(result))
    print("\naxis at least 45° from the epipolar plane:")
    print(table(result, (45.0, 90.0)))
    print("\naxis 20° to 45° from the epipolar plane:")
    print(table(result, (0.0, 45.0)))
    for row in result:
        for k, why in row.failures:
            print(f"{row.level}: frame {k}: {why}")
