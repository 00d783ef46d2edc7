"""The stereo front end [SMC IV-A], per image: HSV colour segmentation, the segment's edge, its
reflectional-symmetry line (θ, r) in normalised image coordinates, and its mass centre.

1. **Segmentation** (:func:`segment`): ``cv2.inRange`` on the rig's HSV range, a morphological opening
   (speckle) and closing (gaps between texture bands), the largest connected component, holes filled.
   Too few pixels → "no symmetry".
2. **Edges**: the segment's outer contour (``cv2.findContours``, every boundary pixel), lightly
   smoothed, with its normals: the edge image of the segmentation, as the paper does.
3. **Coarse symmetry: pair voting** (:func:`vote`), after Loy & Eklundh's mirrored-feature voting and
   Li, Zhang & Kleeman's fast reflectional symmetry detection: every pair of (subsampled) edge points
   votes for its perpendicular bisector (θ, r), weighted by how well the reflection about that line
   maps one point's edge normal onto the other's and by how squarely the normals face along the pair
   (two points of one straight side agree about their bisector too). The three highest peaks of the
   smoothed (θ, r) histogram, at least 20° apart, and the segment's two principal axes through its mass
   centre are the candidates (a bottle's body alone is nearly symmetric across its axis, and noisy
   normals spread the votes); a three-step fine fit of each, the one whose symmetry explains most of
   the edge goes on. Accurate to about a bin (1°, 2 px).
4. **Fine symmetry: harmonic homology** (:func:`refine`). Under perspective the image of a surface of
   revolution is not mirror-symmetric in the Euclidean sense: the 3D reflection in the plane through
   the camera centre and the axis, whose normal is n = (cos θ, sin θ, −r) in the camera frame, maps the
   object onto itself and fixes the camera centre, so it maps the image onto itself by the 3×3 matrix
   H = I − 2 n nᵀ / nᵀn acting on homogeneous normalised coordinates (x, y, 1) (a harmonic homology
   whose axis is the image line (θ, r) and whose vertex is n; a Euclidean reflection only when r = 0).
   Gauss-Newton over (θ, r) minimises the distances of the H-mapped edge points to the edge (point-to-
   tangent residuals, correspondences refreshed every iteration, Tukey weights with a MAD scale), so the
   estimate is the image of the axis itself, not the silhouette's Euclidean midline (off by 0.1° to
   0.2° and ~0.2 px for a bottle near the image corners at 1 m, which stereo magnifies to 1° to 2° in
   3D; ``model="euclidean"`` fits that midline instead, to measure the bias). On clean renders the
   homology fit is within ~0.02° (median, 0.08° worst) and ~0.02 px of the true axis image.
5. **Score**: the fraction of edge points that the fitted symmetry maps to within ``inlier_px`` of the
   edge; below ``min_score`` → "no symmetry".
6. **Mass centre**: ``cv2.moments`` of the filled segment, in pixels and normalised coordinates.

:func:`detect` returns a :class:`Detection` or a :class:`NoSymmetry` with the reason; never a NaN.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import cv2
import numpy as np

from gagen.apps.stereo.calibration import Camera, Rig, canonical_line


@dataclass(frozen=True)
class Settings:
    min_area: int = 300  # pixels of the largest segment below which there is no object
    min_score: float = 0.6  # fraction of the edge the symmetry must explain
    inlier_px: float = 2.0  # distance (px) within which a mirrored edge point counts as explained
    open_px: int = 3  # kernel sizes of the morphological opening and closing
    close_px: int = 7
    vote_points: int = 160  # edge points paired in the vote (M² / 2 pairs)
    theta_bins: int = 180  # over [0, π): 1°
    r_bin_px: float = 2.0
    fit_points: int = 600  # edge points used by the fine fit
    iterations: int = 20
    tukey: float = 4.685  # Tukey's biweight constant, in robust residual scales (95 % efficiency)


@dataclass(frozen=True)
class Detection:
    theta: float  # the symmetry line x cos θ + y sin θ = r in normalised coordinates, θ ∈ (−π/2, π/2]
    r: float
    centre_xy: np.ndarray  # the segment's mass centre, normalised coordinates
    centre_px: np.ndarray  # the same in pixels
    area: float  # pixels in the segment
    score: float  # fraction of the edge the symmetry explains, 0 … 1
    line_px: tuple[float, float]  # the line as u cos φ + v sin φ = ρ in pixels (for drawing)
    residual_px: float  # robust RMS of the mirror residuals (px)


@dataclass(frozen=True)
class NoSymmetry:
    reason: str

    def __str__(self) -> str:
        return f"no symmetry: {self.reason}"


# ------------------------------------------------------------------------------------------- lines

def pixel_to_normalised(camera: Camera, phi: float, rho: float) -> tuple[float, float]:
    """u cos φ + v sin φ = ρ (pixels) → x cos θ + y sin θ = r (normalised)."""
    a, b = camera.fx * np.cos(phi), camera.fy * np.sin(phi)
    c = rho - camera.cx * np.cos(phi) - camera.cy * np.sin(phi)
    n = np.hypot(a, b)
    return canonical_line(float(np.arctan2(b, a)), float(c / n))


def normalised_to_pixel(camera: Camera, theta: float, r: float) -> tuple[float, float]:
    """x cos θ + y sin θ = r (normalised) → u cos φ + v sin φ = ρ (pixels)."""
    a, b = np.cos(theta) / camera.fx, np.sin(theta) / camera.fy
    c = r + camera.cx * a + camera.cy * b
    n = np.hypot(a, b)
    return canonical_line(float(np.arctan2(b, a)), float(c / n))


def homology(theta: float, r: float) -> np.ndarray:
    """The image of the reflection in the plane through the camera centre and the image line (θ, r):
    H = I − 2 n nᵀ / nᵀn with n = (cos θ, sin θ, −r), on homogeneous normalised coordinates."""
    n = np.array([np.cos(theta), np.sin(theta), -r])
    h: np.ndarray = np.eye(3) - 2 * np.outer(n, n) / (n @ n)
    return h


# ------------------------------------------------------------------------------------ segmentation

def segment(image: np.ndarray, hsv_low: tuple[int, int, int], hsv_high: tuple[int, int, int],
            settings: Settings = Settings()) -> np.ndarray:
    """The object's mask (uint8 0/255): the largest connected component in the HSV range, its holes
    filled; all zeros when nothing is in range."""
    hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
    mask = cv2.inRange(hsv, np.array(hsv_low, np.uint8), np.array(hsv_high, np.uint8))
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN,
                            cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (settings.open_px,) * 2))
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE,
                            cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (settings.close_px,) * 2))
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if count <= 1:
        return np.zeros_like(mask)
    biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    mask = np.where(labels == biggest, 255, 0).astype(np.uint8)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    filled = np.zeros_like(mask)
    cv2.drawContours(filled, contours, -1, 255, thickness=cv2.FILLED)
    return filled


@dataclass(frozen=True)
class Edge:
    """The segment's outline: ordered boundary pixels, smoothed points and unit normals (pixels)."""

    pixels: np.ndarray  # (N, 2) int, u, v
    points: np.ndarray  # (N, 2) float, smoothed
    normals: np.ndarray  # (N, 2) unit, all on the same side (outwards for OpenCV's outer contours)


def edge(mask: np.ndarray) -> Edge | None:
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None
    c = max(contours, key=len)[:, 0, :]
    if len(c) < 16:
        return None
    pts = c.astype(float)
    k = 2  # a 5-point circular moving average takes out the pixel staircase
    # (sum's start 0 types it ndarray | int; five rolled arrays make an array)
    smooth = cast(np.ndarray, sum(np.roll(pts, s, axis=0) for s in range(-k, k + 1))) / (2 * k + 1)
    tangent = np.roll(smooth, -k, axis=0) - np.roll(smooth, k, axis=0)
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    return Edge(c, smooth, normal)


# ------------------------------------------------------------------------------------------ voting

def _spread(n: int, most: int) -> np.ndarray:
    """At most ``most`` indices spread evenly over range(n)."""
    return np.arange(n) if n <= most else np.linspace(0, n, most, endpoint=False).astype(np.int64)


def vote(e: Edge, camera: Camera, settings: Settings = Settings(), peaks: int = 3
         ) -> list[tuple[float, float, float]]:
    """Coarse symmetry lines (φ, ρ) in pixels with their vote shares, best first (up to ``peaks``
    separated maxima): mirrored edge-pair voting."""
    pick = _spread(len(e.points), settings.vote_points)
    p = e.points[pick] - np.array([camera.cx, camera.cy])  # about the principal point: small ρ
    n = e.normals[pick]
    i, j = np.triu_indices(len(p), 1)
    d = p[j] - p[i]
    length = np.hypot(d[:, 0], d[:, 1])
    keep = length > 3.0
    i, j, d, length = i[keep], j[keep], d[keep], length[keep]
    u = d / length[:, None]  # the bisector's normal
    rho = np.einsum("ij,ij->i", u, (p[i] + p[j]) / 2)
    ni_u = np.einsum("ij,ij->i", n[i], u)
    mirrored = n[i] - 2 * ni_u[:, None] * u
    # mirrored normals agree, and they face along the pair (two points on one straight side agree too,
    # about their bisector, but their normals are across the pair: such pairs vote for nothing real)
    weight = np.clip(np.einsum("ij,ij->i", mirrored, n[j]), 0, None) ** 4 * np.abs(ni_u)
    phi = np.arctan2(u[:, 1], u[:, 0])
    flip = phi < 0
    phi = np.where(flip, phi + np.pi, phi)
    rho = np.where(flip, -rho, rho)
    rmax = float(np.hypot(camera.width, camera.height))
    nt, nr = settings.theta_bins, 2 * int(np.ceil(rmax / settings.r_bin_px))
    ti = np.minimum((phi * (nt / np.pi)).astype(np.int64), nt - 1)
    ri = ((rho + rmax) * (nr / (2 * rmax))).astype(np.int64).clip(0, nr - 1)
    hist = np.bincount(ti * nr + ri, weights=weight, minlength=nt * nr).reshape(nt, nr)
    pad = 4  # θ wraps at π with ρ → −ρ: pad with the flipped rows before smoothing
    padded = np.vstack([hist[-pad:, ::-1], hist, hist[:pad, ::-1]]).astype(np.float32)
    smooth = cv2.GaussianBlur(padded, (0, 0), 1.0)[pad:-pad]
    total = max(float(smooth.sum()), 1e-12)
    out: list[tuple[float, float, float]] = []
    for _ in range(peaks):
        t, r = np.unravel_index(int(np.argmax(smooth)), smooth.shape)
        if smooth[t, r] <= 0:
            break
        phi0 = (t + 0.5) * np.pi / nt
        rho0 = -rmax + (r + 0.5) * 2 * rmax / nr
        # back to absolute pixels: u' = u − cx
        rho_abs = rho0 + camera.cx * np.cos(phi0) + camera.cy * np.sin(phi0)
        out.append((phi0, rho_abs, float(smooth[t, r] / total)))
        # suppress every line within ±20° of it: the next peak is another family of orientations
        dt = nt // 9
        smooth[np.arange(t - dt, t + dt + 1) % nt] = 0
    return out


# ------------------------------------------------------------------------------------- fine fitting

class Nearest:
    """The nearest edge point of any pixel near the edge: a labelled distance transform of the outline
    over its bounding box and a margin (pixels beyond it are too far to be explained anyway)."""

    def __init__(self, e: Edge, margin: int = 24) -> None:
        self.origin = e.pixels.min(axis=0) - margin
        size = e.pixels.max(axis=0) + margin + 1 - self.origin
        src = np.full((size[1], size[0]), 255, np.uint8)
        local = e.pixels - self.origin
        src[local[:, 1], local[:, 0]] = 0
        _, self.labels = cv2.distanceTransformWithLabels(src, cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL)
        self.index = np.zeros(int(self.labels.max()) + 1, np.int64)
        self.index[self.labels[local[:, 1], local[:, 0]]] = np.arange(len(e.pixels))
        self.shape = src.shape

    def __call__(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Indices of the nearest edge points of pixels q (…, 2) and whether q lies in the box."""
        q = np.nan_to_num(q, nan=-1e9, posinf=-1e9, neginf=-1e9).clip(-1e9, 1e9)  # mapped to infinity
        u = np.round(q[:, 0] - self.origin[0]).astype(np.int64)
        v = np.round(q[:, 1] - self.origin[1]).astype(np.int64)
        inside = (u >= 0) & (v >= 0) & (u < self.shape[1]) & (v < self.shape[0])
        u, v = u.clip(0, self.shape[1] - 1), v.clip(0, self.shape[0] - 1)
        return self.index[self.labels[v, u]], inside


def _mirror(camera: Camera, params: np.ndarray, xy: np.ndarray, model: str
            ) -> tuple[np.ndarray, np.ndarray]:
    """Edge points (normalised) mapped by the symmetry with parameters (θ, r), in pixels, and the
    derivatives of those pixels by θ and r, (N, 2, 2)."""
    theta, r = params
    if model != "homology":  # Euclidean reflection in pixels about the line's pixel form, numerically
        def reflect(t: float, rr: float) -> np.ndarray:
            phi, rho = normalised_to_pixel(camera, t, rr)
            u = np.array([np.cos(phi), np.sin(phi)])
            p = camera.pixels(xy)
            mirrored: np.ndarray = p - 2 * ((p @ u) - rho)[:, None] * u
            return mirrored
        eps = 1e-6
        jac = np.stack([(reflect(theta + eps, r) - reflect(theta - eps, r)) / (2 * eps),
                        (reflect(theta, r + eps) - reflect(theta, r - eps)) / (2 * eps)], axis=-1)
        return reflect(theta, r), jac
    # h = x̃ − 2 g k n, g = 1 / (1 + r²), k = n·x̃, n = (cos θ, sin θ, −r), x̃ = (x, y, 1); q = (h₀, h₁) / h₂
    c, s = np.cos(theta), np.sin(theta)
    x, y = xy[:, 0], xy[:, 1]
    g = 1.0 / (1.0 + r * r)
    k = c * x + s * y - r
    gk2 = 2 * g * k
    h2 = 1 + gk2 * r
    with np.errstate(divide="ignore", invalid="ignore"):  # a point sent to infinity: no correspondence
        inv = 1.0 / h2
        q = np.empty((len(xy), 2))
        q[:, 0] = (x - gk2 * c) * inv
        q[:, 1] = (y - gk2 * s) * inv
        dk_t = -s * x + c * y  # dk/dθ
        # dh/dθ = −2g (dk/dθ n + k dn/dθ), dn/dθ = (−s, c, 0)
        t0, t1, t2 = -2 * g * (dk_t * c - k * s), -2 * g * (dk_t * s + k * c), 2 * g * dk_t * r
        # dh/dr = −2 (g (dk/dr n + k dn/dr) + dg/dr k n), dk/dr = −1, dn/dr = (0, 0, −1), dg/dr = −2 r g²
        w = 2 * g + 4 * r * g * g * k
        r0, r1, r2 = w * c, w * s, -2 * g * (r - k) - 4 * r * r * g * g * k
        jac = np.empty((len(xy), 2, 2))
        jac[:, 0, 0] = (t0 - q[:, 0] * t2) * inv * camera.fx
        jac[:, 1, 0] = (t1 - q[:, 1] * t2) * inv * camera.fy
        jac[:, 0, 1] = (r0 - q[:, 0] * r2) * inv * camera.fx
        jac[:, 1, 1] = (r1 - q[:, 1] * r2) * inv * camera.fy
    return camera.pixels(q), jac


def refine(e: Edge, camera: Camera, theta: float, r: float, settings: Settings = Settings(),
           model: str = "homology", nearest: Nearest | None = None, iterations: int | None = None
           ) -> tuple[float, float, float, float]:
    """Gauss-Newton fit of the symmetry (θ, r) (normalised) from a start; returns θ, r, the score and
    the robust RMS residual (px)."""
    nearest = nearest or Nearest(e)
    src = camera.normalised(e.points[_spread(len(e.points), settings.fit_points)])
    params = np.array([theta, r], dtype=float)
    scale = 4.0
    for it in range(settings.iterations if iterations is None else iterations):
        q, dq = _mirror(camera, params, src, model)
        idx, inside = nearest(q)
        c, n = e.points[idx], e.normals[idx]
        diff = q - c
        res = n[:, 0] * diff[:, 0] + n[:, 1] * diff[:, 1]
        jac = n[:, 0, None] * dq[:, 0, :] + n[:, 1, None] * dq[:, 1, :]
        dist = np.hypot(diff[:, 0], diff[:, 1])
        if it >= 2 and inside.any():  # a MAD scale once the vote's bin error is gone
            scale = max(0.5, 1.4826 * float(np.median(np.abs(res[inside]))))
        c_tukey = settings.tukey * scale
        w = np.where(inside & (dist < 2 * c_tukey), (1 - (res / c_tukey) ** 2).clip(0, None) ** 2, 0.0)
        jac = np.where(w[:, None] > 0, jac, 0.0)
        a = jac.T @ (w[:, None] * jac)
        if w.sum() < 10 or np.linalg.det(a) <= 1e-12 * np.trace(a) ** 2:
            break
        delta = -np.linalg.solve(a, jac.T @ (w * np.where(w > 0, res, 0.0)))
        params += delta
        if abs(delta[0]) < 1e-6 and abs(delta[1]) < 1e-6 and it >= 2:  # 1e-6 rad, 6e-4 px
            break
    q, _ = _mirror(camera, params, src, model)
    idx, inside = nearest(q)
    diff = q - e.points[idx]
    dist = np.where(inside, np.hypot(diff[:, 0], diff[:, 1]), np.inf)
    res = np.einsum("ij,ij->i", e.normals[idx], diff)
    score = float(np.mean(dist < settings.inlier_px))
    good = inside & (np.abs(res) < 3 * max(scale, 0.5))
    rms = float(np.sqrt(np.mean(res[good] ** 2))) if good.any() else float("inf")
    theta, r = canonical_line(float(params[0]), float(params[1]))
    return theta, r, score, rms


# ------------------------------------------------------------------------------------------ detect

def detect(image: np.ndarray, camera: Camera, hsv_low: tuple[int, int, int], hsv_high: tuple[int, int, int],
           settings: Settings = Settings(),
           model: str = "homology") -> Detection | NoSymmetry:
    """The symmetry line and mass centre of the object in one image, or why there is none."""
    if image is None or image.ndim != 3 or image.shape[2] != 3:
        return NoSymmetry("expected a BGR image")
    mask = segment(image, hsv_low, hsv_high, settings)
    moments = cv2.moments(mask, binaryImage=True)
    area = float(moments["m00"])
    if area < settings.min_area:
        return NoSymmetry(f"too few object pixels ({area:.0f} < {settings.min_area})")
    e = edge(mask)
    if e is None:
        return NoSymmetry("no outline")
    nearest = Nearest(e)
    centre_px = np.array([moments["m10"], moments["m01"]]) / area
    # candidates: the vote's peaks and the segment's principal axes (a bottle's body alone is nearly
    # symmetric across its axis too, and noise spreads the votes); a short fit each, the best goes on
    major = 0.5 * np.arctan2(2 * moments["mu11"], moments["mu20"] - moments["mu02"])
    starts = [(phi, rho) for phi, rho, _ in vote(e, camera, settings)]
    starts += [(phi, float(centre_px @ [np.cos(phi), np.sin(phi)])) for phi in (major + np.pi / 2, major)]
    best = None
    tried: list[tuple[float, float]] = []
    for phi, rho in starts:
        if any(abs(np.sin(phi - p)) < 0.05 and abs(rho - np.cos(phi - p) * q) < 5 for p, q in tried):
            continue  # the same line as one already fitted (within ~3° and 5 px)
        tried.append((phi, rho))
        theta0, r0 = pixel_to_normalised(camera, phi, rho)
        fit = refine(e, camera, theta0, r0, settings, model, nearest, iterations=3)
        if best is None or (fit[2], -fit[3]) > (best[2], -best[3]):
            best = fit
    if best is None:
        return NoSymmetry("no mirrored edge pairs")
    theta, r, score, rms = refine(e, camera, best[0], best[1], settings, model, nearest)
    if not (np.isfinite(theta) and np.isfinite(r)):
        return NoSymmetry("the fit diverged")
    if score < settings.min_score:
        return NoSymmetry(f"symmetry score {score:.2f} < {settings.min_score}")
    return Detection(theta, r, camera.normalised(centre_px), centre_px, area, score,
                     normalised_to_pixel(camera, theta, r), rms)


def detect_pair(left: np.ndarray, right: np.ndarray, rig: Rig, settings: Settings = Settings()
                ) -> tuple[Detection | NoSymmetry, Detection | NoSymmetry]:
    """:func:`detect` in both images of the rig."""
    return (detect(left, rig.left, rig.hsv_low, rig.hsv_high, settings),
            detect(right, rig.right, rig.hsv_low, rig.hsv_high, settings))
