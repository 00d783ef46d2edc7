"""A synthetic stereo scene with ground truth [SMC IV]: a textured bottle (a surface of revolution) at a
known pose, rendered by both cameras of a :class:`~gagen.apps.stereo.calibration.Rig` without a display.

- **Object** (:class:`Bottle`): a radius profile r(h) along the axis (base at h = 0, ~0.22 m tall, body
  radius 0.035 m, a shoulder, a neck and a lip), closed by two discs. Its texture depends on h only
  (horizontal rings in the rig's blue hue range, with saturation/value steps so that edges exist
  inside it), so every view is mirror-symmetric about the plane through the camera centre and the
  axis, whatever the roll about the axis.
- **Centre**: :attr:`ObjectPose.centre` is the axis point at :attr:`Bottle.centre_height`, the centroid
  of the axial cross-section (the region x² ≤ r(h)², a side-on silhouette), which is the 3D point that
  an image mass centre sees when the axis is parallel to the image plane (orthographic limit). The
  solid's mass centre (:attr:`Bottle.mass_centre_height`) sits lower (the neck holds little volume);
  an image mass centre cannot see it, so it is not the reference.
- **Rendering** (:func:`render`): the mesh (quads between profile rings, the two end discs) projected
  with each camera's intrinsics, back faces and faces behind the near plane culled, flat Lambert
  shading with the light at the camera centre (a headlight keeps the image symmetric, up to the
  48-facet tessellation), drawn far to near (painter's algorithm) with ``cv2.fillConvexPoly`` at
  ``supersample`` times the resolution and averaged down (anti-aliased edges).
- **Perturbations** (:class:`SceneOptions`): ``vertex_jitter`` is *geometric* noise, Gaussian noise of
  σ pixels on every projected mesh vertex (shared by the faces around it; the rings are ≤ 2 mm, i.e.
  ≤ 1.2 px at 1 m apart, so the outline is perturbed by about σ px about once per pixel: the "1 px
  noise" of the accuracy targets); ``pixel_noise`` is *photometric* noise,
  Gaussian noise of σ grey levels on every pixel and channel; ``blur`` a Gaussian blur of σ px;
  ``clutter`` random shapes of other hues (and a few small ones of the object's hue, kept off the
  object) behind it; ``occlusion`` a grey box over that fraction of the object's image from one side;
  ``present = False`` leaves the object out, ``blank = True`` gives uniform grey images.
- **Ground truth** (:class:`Truth`): the axis in the left frame, the centre, and per camera the true
  image line (θ, r) of the axis in normalised coordinates (x cos θ + y sin θ = r) and the image of the
  centre; :func:`silhouette_centroids` gives the exact image mass centres (a finely rasterised mask).

Coordinates: camera frames follow OpenCV (x right, y down, z forward), the left camera's frame is the
scene's frame, ``rig.right_in_left`` maps right-camera coordinates to left ones. Everything random
comes from one ``numpy.random.Generator``: the same seed gives the same images.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from gagen.apps.stereo.calibration import Camera, Pose, Rig, canonical_line

NEAR = 0.05  # m: faces with a vertex closer to a camera's image plane are culled
AMBIENT = 0.35  # shading floor, so that the darkest rim stays inside the segmentation's value range
BACKGROUND_BGR = (118, 124, 128)  # a grey table (saturation ≈ 20, far from the object's range)
OCCLUDER_BGR = (96, 96, 96)


# the outline: (height, radius) corners in m; between them the radius is constant or (shoulder) a cosine
BASE, BODY, SHOULDER, NECK, LIP, TOP = 0.006, 0.125, 0.173, 0.2035, 0.2045, 0.22
R_BASE, R_BODY, R_NECK, R_LIP = 0.031, 0.035, 0.0125, 0.0145


def bottle_radius(h: np.ndarray) -> np.ndarray:
    """The bottle's radius (m) at heights h (m) above its base."""
    h = np.asarray(h, dtype=float)
    s = ((h - BODY) / (SHOULDER - BODY)).clip(0, 1)
    return np.select([h <= BASE, h <= BODY, h <= SHOULDER, h <= NECK],
                     [R_BASE + (R_BODY - R_BASE) * np.sin(h / BASE * np.pi / 2), np.full_like(h, R_BODY),
                      R_NECK + (R_BODY - R_NECK) * 0.5 * (1 + np.cos(np.pi * s)), np.full_like(h, R_NECK)],
                     R_LIP)


def _profile(step: float = 0.002) -> tuple[np.ndarray, np.ndarray]:
    """Heights and radii (m) of the outline, base to lip, rings at most ``step`` apart (2 mm: ≤ 1.2 px
    at 1 m, so that vertex jitter perturbs the outline every pixel or so)."""
    corners = [0.0, BASE, BODY, SHOULDER, NECK, LIP, TOP]
    h = np.unique(np.concatenate([np.linspace(a, b, max(2, int(np.ceil((b - a) / step)) + 1))
                                  for a, b in itertools.pairwise(corners)]))
    return h, bottle_radius(h)


# texture rings: (top height of the band in m, OpenCV HSV colour), base to lip; all inside hue 100-130,
# saturation ≥ 120 and value ≥ 150 (×AMBIENT ≥ 52 > the rig's value floor 40)
BANDS = ((0.012, (112, 230, 170)), (0.030, (106, 250, 235)), (0.045, (118, 150, 200)),
         (0.085, (110, 200, 250)), (0.100, (122, 255, 160)), (0.118, (110, 200, 250)),
         (0.150, (104, 180, 215)), (0.178, (116, 230, 180)), (0.205, (108, 140, 240)),
         (1.000, (120, 255, 175)))


@dataclass(frozen=True)
class Bottle:
    heights: np.ndarray  # profile samples along the axis from the base (m)
    radii: np.ndarray  # radius at each height (m)
    segments: int = 48  # faces around the axis

    @property
    def height(self) -> float:
        return float(self.heights[-1])

    @property
    def centre_height(self) -> float:
        """Height of the reference centre: the centroid of the axial cross-section, ∫h r dh / ∫r dh."""
        return _trapezoid(self.heights * self.radii, self.heights) / _trapezoid(self.radii, self.heights)

    @property
    def mass_centre_height(self) -> float:
        """Height of the solid's mass centre, ∫h r² dh / ∫r² dh (for information)."""
        r2 = self.radii ** 2
        return _trapezoid(self.heights * r2, self.heights) / _trapezoid(r2, self.heights)

    @property
    def bounding_radius(self) -> float:
        """Radius of a sphere about the centre that holds the whole bottle."""
        c = self.centre_height
        return float(np.max(np.hypot(self.heights - c, self.radii)))


def _trapezoid(y: np.ndarray, x: np.ndarray) -> float:
    return float(np.sum((y[1:] + y[:-1]) * np.diff(x)) / 2)


def default_bottle() -> Bottle:
    h, r = _profile()
    return Bottle(h, r)


@dataclass(frozen=True)
class ObjectPose:
    """The bottle in the left camera's frame: its centre (m) and the unit axis from base to neck."""

    centre: np.ndarray
    axis: np.ndarray

    def __post_init__(self) -> None:
        a = np.asarray(self.axis, dtype=float)
        object.__setattr__(self, "axis", a / np.linalg.norm(a))
        object.__setattr__(self, "centre", np.asarray(self.centre, dtype=float))


@dataclass(frozen=True)
class SceneOptions:
    vertex_jitter: float = 0.0  # σ (px) of Gaussian noise on every projected vertex: geometric noise
    pixel_noise: float = 0.0  # σ (grey levels) of Gaussian noise on every pixel and channel
    blur: float = 0.0  # σ (px) of a Gaussian blur
    clutter: int = 0  # number of background shapes (a quarter of them small and of the object's hue)
    occlusion: float = 0.0  # fraction of the object's image covered by a grey box from one side
    present: bool = True  # False: the object is left out
    blank: bool = False  # True: uniform grey images (noise still applies)
    supersample: int = 2  # rasterise at this many times the resolution, then average down


@dataclass(frozen=True)
class ViewTruth:
    line: tuple[float, float]  # (θ, r) of the axis' image, normalised coordinates, θ ∈ (−π/2, π/2]
    centre_xy: np.ndarray  # normalised image coordinates of the 3D centre
    centre_px: np.ndarray  # the same in pixels


@dataclass(frozen=True)
class Truth:
    pose: ObjectPose  # left camera frame
    left: ViewTruth
    right: ViewTruth

    @property
    def axis_point(self) -> np.ndarray:
        return self.pose.centre

    @property
    def axis_direction(self) -> np.ndarray:
        return self.pose.axis


@dataclass(frozen=True)
class StereoFrame:
    left: np.ndarray  # (H, W, 3) uint8 BGR
    right: np.ndarray
    truth: Truth  # of the pose rendered (also when the object is absent or the images blank)
    present: bool = True  # whether the object is visible at all
    info: dict[str, Any] = field(default_factory=dict)


# ----------------------------------------------------------------------------------------- geometry

def axis_frame(axis: np.ndarray) -> np.ndarray:
    """A rotation whose third column is ``axis`` (the roll about it is arbitrary but fixed)."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(helper, a)
    u /= np.linalg.norm(u)
    return np.column_stack([u, np.cross(a, u), a])


def left_to_camera(rig: Rig, which: str) -> Pose:
    """The map from left-frame coordinates to the named camera's frame."""
    return Pose(np.eye(3), np.zeros(3)) if which == "left" else rig.right_in_left.inverse()


def image_line(point: np.ndarray, direction: np.ndarray) -> tuple[float, float]:
    """(θ, r), θ ∈ (−π/2, π/2], of the image of the 3D line through ``point`` along ``direction`` (camera
    frame): the plane through the camera centre and the line has normal n = p × d, and the image line is
    n · (x, y, 1) = 0."""
    n = np.cross(point, direction)
    return canonical_line(float(np.arctan2(n[1], n[0])), float(-n[2] / np.hypot(n[0], n[1])))


def truth(rig: Rig, pose: ObjectPose) -> Truth:
    views = {}
    for which, camera in (("left", rig.left), ("right", rig.right)):
        to_cam = left_to_camera(rig, which)
        c = to_cam.apply(pose.centre)
        d = to_cam.R @ pose.axis
        xy = c[:2] / c[2]
        views[which] = ViewTruth(image_line(c, d), xy, camera.pixels(xy))
    return Truth(pose, views["left"], views["right"])


@dataclass(frozen=True)
class _Mesh:
    vertices: np.ndarray  # (V, 3) object frame: axis along z, the centre at the origin
    quads: np.ndarray  # (Q, 4) vertex indices of the side faces
    faces: list[np.ndarray]  # vertex indices: the side quads, then the bottom and top discs' rims
    normals: np.ndarray  # (F, 3) outward unit normals, object frame
    colour: np.ndarray  # (F, 3) BGR albedo in 0…255


def _band_bgr(h: np.ndarray) -> np.ndarray:
    tops = np.array([top for top, _ in BANDS])
    hsv = np.array([[c for _, c in BANDS]], dtype=np.uint8)
    bgr = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0].astype(float)
    colours: np.ndarray = bgr[np.searchsorted(tops, h, side="right").clip(0, len(BANDS) - 1)]
    return colours


def _mesh(bottle: Bottle) -> _Mesh:
    n, m = len(bottle.heights), bottle.segments
    phi = 2 * np.pi * np.arange(m) / m
    z = bottle.heights - bottle.centre_height
    verts = np.stack([bottle.radii[:, None] * np.cos(phi)[None, :],
                      bottle.radii[:, None] * np.sin(phi)[None, :],
                      np.broadcast_to(z[:, None], (n, m))], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(m), indexing="ij")
    jn = (j + 1) % m
    # counter-clockwise seen from outside: around the axis (+φ), then up
    quads = np.stack([i * m + j, i * m + jn, (i + 1) * m + jn, (i + 1) * m + j], axis=-1).reshape(-1, 4)
    q = verts[quads]
    normals = np.cross(q[:, 2] - q[:, 0], q[:, 3] - q[:, 1])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    mid_h = (bottle.heights[:-1] + bottle.heights[1:]) / 2
    colour = np.repeat(_band_bgr(mid_h), m, axis=0)
    faces = [*quads, np.arange(m), (n - 1) * m + np.arange(m)]
    normals = np.vstack([normals, [0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])
    colour = np.vstack([colour, _band_bgr(np.array([0.0, bottle.height]))])
    return _Mesh(verts, quads, faces, normals, colour)


_MESHES: dict[tuple[bytes, bytes, int], _Mesh] = {}


def _cached_mesh(bottle: Bottle) -> _Mesh:
    key = (bottle.heights.tobytes(), bottle.radii.tobytes(), bottle.segments)
    if key not in _MESHES:
        _MESHES[key] = _mesh(bottle)
    return _MESHES[key]


# ---------------------------------------------------------------------------------------- rendering

def _draw_object(img: np.ndarray, camera: Camera, mesh: _Mesh, R: np.ndarray, t: np.ndarray,
                 jitter: float, scale: int, rng: np.random.Generator, flat: bool = False) -> None:
    """Paint the mesh posed by (R, t) in the camera's frame into ``img`` (``scale`` times the camera's
    resolution); ``flat`` paints every face white (a mask)."""
    verts = mesh.vertices @ R.T + t
    centres = np.array([verts[f].mean(axis=0) for f in mesh.faces[-2:]])
    centres = np.vstack([verts[mesh.quads].mean(axis=1), centres])
    normals = mesh.normals @ R.T
    dist = np.linalg.norm(centres, axis=1)
    facing = -np.einsum("ij,ij->i", normals, centres) / dist  # cos of the angle to the headlight
    front = verts[:, 2] > NEAR
    px = camera.project(np.where(front[:, None], verts, 1.0))
    if jitter > 0:
        px = px + rng.normal(0.0, jitter, px.shape)
    shift = 4  # sub-pixel vertex positions, 1/16 px
    ipx = np.round(((px + 0.5) * scale - 0.5) * (1 << shift)).astype(np.int32)
    shade = AMBIENT + (1 - AMBIENT) * facing.clip(0, 1)
    nq, quads = len(mesh.quads), mesh.quads
    visible = (facing > 0) & np.concatenate([front[quads].all(axis=1),
                                              [front[f].all() for f in mesh.faces[nq:]]])
    colours = np.full((len(facing), 3), 255.0) if flat else mesh.colour * shade[:, None]
    order = np.argsort(-dist)  # far to near
    order = order[visible[order]].tolist()
    quad_px = ipx[quads]
    colour_list = colours.tolist()
    for k in order:
        points = quad_px[k] if k < nq else ipx[mesh.faces[k]]
        cv2.fillConvexPoly(img, points, colour_list[k], cv2.LINE_8, shift)


_RAMPS: dict[tuple[int, int], np.ndarray] = {}


def _table(w: int, h: int) -> np.ndarray:
    """The empty table: grey with a gentle brightness ramp (cached per size)."""
    if (w, h) not in _RAMPS:
        ramp = np.linspace(-10, 10, w, dtype=np.float32)[None, :] \
            + np.linspace(-6, 6, h, dtype=np.float32)[:, None]
        _RAMPS[(w, h)] = np.stack([np.clip(base + ramp, 0, 255).astype(np.uint8) for base in BACKGROUND_BGR],
                                  axis=-1)
    return _RAMPS[(w, h)].copy()


def _background(camera: Camera, scale: int, options: SceneOptions, rng: np.random.Generator,
                avoid: tuple[float, ...] | None, hsv_low: tuple[int, int, int],
                hsv_high: tuple[int, int, int]) -> np.ndarray:
    """The table with the clutter (at ``scale`` times the resolution); decoys of the object's hue keep
    clear of the ``avoid`` box (the object's pixel bounds)."""
    w, h = camera.width * scale, camera.height * scale
    img = _table(w, h)
    if options.blank:
        img[:] = BACKGROUND_BGR
        return img
    for k in range(options.clutter):
        own_hue = k % 4 == 3
        if own_hue:  # small blobs of the object's colour, never touching it
            hue = rng.integers(hsv_low[0], hsv_high[0] + 1)
            size = rng.uniform(3, 7) * scale
        else:  # other hues: outside the object's range
            hue = (rng.integers(hsv_high[0] + 8, hsv_low[0] + 172) % 180)
            size = rng.uniform(8, 45) * scale
        colour_hsv = np.array([[[hue, rng.integers(120, 256), rng.integers(90, 256)]]], np.uint8)
        colour = tuple(int(c) for c in cv2.cvtColor(colour_hsv, cv2.COLOR_HSV2BGR)[0, 0])
        for _ in range(20):
            cu, cv = rng.uniform(0, w), rng.uniform(0, h)
            if not own_hue or avoid is None or not (avoid[0] - 2 * size < cu < avoid[2] + 2 * size
                                                    and avoid[1] - 2 * size < cv < avoid[3] + 2 * size):
                break
        else:
            continue
        a, b, ang = size, size * rng.uniform(0.4, 1.0), rng.uniform(0, 180)
        if rng.random() < 0.5:
            cv2.ellipse(img, (int(cu), int(cv)), (int(a), int(b)), ang, 0, 360, colour, -1)
        else:
            box = cv2.boxPoints(((cu, cv), (2 * a, 2 * b), ang)).astype(np.int32)
            cv2.fillConvexPoly(img, box, colour)
    return img


def _object_box(camera: Camera, mesh: _Mesh, R: np.ndarray, t: np.ndarray) -> tuple[float, ...]:
    verts = mesh.vertices @ R.T + t
    verts = verts[verts[:, 2] > NEAR]
    if len(verts) == 0:
        return (0.0, 0.0, 0.0, 0.0)
    px = camera.project(verts)
    return (float(px[:, 0].min()), float(px[:, 1].min()), float(px[:, 0].max()), float(px[:, 1].max()))


def _occluder_corners(box: tuple[float, ...], side: int, fraction: float, pad: float
                      ) -> tuple[tuple[int, int], tuple[int, int]]:
    """A box over ``fraction`` of the object's bounding box from one side (0 left, 1 top, 2 right,
    3 bottom), reaching ``pad`` beyond the object on the other three sides."""
    lo, hi = np.array(box[:2]), np.array(box[2:])
    a, b = lo - pad, hi + pad
    k = side % 2  # 0: along x, 1: along y
    if side < 2:
        b[k] = lo[k] + fraction * (hi[k] - lo[k])
    else:
        a[k] = hi[k] - fraction * (hi[k] - lo[k])
    return (int(a[0]), int(a[1])), (int(b[0]), int(b[1]))


def render_view(rig: Rig, which: str, pose: ObjectPose, options: SceneOptions, rng: np.random.Generator,
                bottle: Bottle | None = None, occluder: tuple[int, float] | None = None) -> np.ndarray:
    """One camera's image (BGR uint8). ``occluder`` is (side 0-3: left, top, right, bottom; fraction)."""
    bottle = bottle or default_bottle()
    camera = rig.left if which == "left" else rig.right
    scale = max(1, int(options.supersample))
    mesh = _cached_mesh(bottle)
    to_cam = left_to_camera(rig, which)
    R = to_cam.R @ axis_frame(pose.axis)
    t = to_cam.apply(pose.centre)
    box = _object_box(camera, mesh, R, t)
    sbox = tuple(((v + 0.5) * scale - 0.5) for v in box)
    img = _background(camera, scale, options, rng, sbox, rig.hsv_low, rig.hsv_high)
    if options.present and not options.blank:
        _draw_object(img, camera, mesh, R, t, options.vertex_jitter, scale, rng)
        if occluder is not None and occluder[1] > 0:
            cv2.rectangle(img, *_occluder_corners(sbox, *occluder, pad=6 * scale), OCCLUDER_BGR, -1)
    if scale > 1:
        img = cv2.resize(img, (camera.width, camera.height), interpolation=cv2.INTER_AREA)
    if options.blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), options.blur)
    if options.pixel_noise > 0:
        noisy = rng.standard_normal(img.shape, dtype=np.float32)
        noisy *= np.float32(options.pixel_noise)
        noisy += img
        np.clip(noisy, 0, 255, out=noisy)
        noisy += 0.5
        img = noisy.astype(np.uint8)
    return img


def render(rig: Rig, pose: ObjectPose, options: SceneOptions | None = None,
           rng: np.random.Generator | int | None = 0, bottle: Bottle | None = None) -> StereoFrame:
    """Both cameras' images of the bottle at ``pose`` (left frame) and the ground truth."""
    options = options or SceneOptions()
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    occluder = (int(rng.integers(0, 4)), float(options.occlusion)) if options.occlusion > 0 else None
    left = render_view(rig, "left", pose, options, rng, bottle, occluder)
    right = render_view(rig, "right", pose, options, rng, bottle, occluder)
    return StereoFrame(left, right, truth(rig, pose), options.present and not options.blank,
                       {"occluder": occluder})


# ------------------------------------------------------------------------------------ ground truth

def silhouette_mask(rig: Rig, which: str, pose: ObjectPose, bottle: Bottle | None = None,
                    scale: int = 1) -> np.ndarray:
    """The bottle's silhouette (uint8 0/255) at ``scale`` times the camera's resolution, no noise."""
    bottle = bottle or default_bottle()
    camera = rig.left if which == "left" else rig.right
    mesh = _cached_mesh(bottle)
    to_cam = left_to_camera(rig, which)
    R = to_cam.R @ axis_frame(pose.axis)
    t = to_cam.apply(pose.centre)
    img = np.zeros((camera.height * scale, camera.width * scale, 3), np.uint8)
    _draw_object(img, camera, mesh, R, t, 0.0, scale, np.random.default_rng(0), flat=True)
    return img[..., 0]


def silhouette_centroids(rig: Rig, pose: ObjectPose, bottle: Bottle | None = None,
                         scale: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """The exact image mass centres (pixels) of the bottle's silhouette in the left and right images,
    from a mask rasterised at ``scale`` times the resolution."""
    out = []
    for which in ("left", "right"):
        m = cv2.moments(silhouette_mask(rig, which, pose, bottle, scale), binaryImage=True)
        if m["m00"] == 0:
            out.append(np.full(2, np.nan))
            continue
        c = np.array([m["m10"], m["m01"]]) / m["m00"]
        out.append((c + 0.5) / scale - 0.5)
    return out[0], out[1]


def random_pose(rig: Rig, rng: np.random.Generator, bottle: Bottle | None = None,
                depth: tuple[float, float] = (0.9, 1.1), max_tilt: float = np.radians(30),
                min_epipolar: float = np.radians(20), margin: float = 10.0) -> ObjectPose:
    """A random pose about 1 m in front of the rig with the whole bottle inside both images: the axis
    at most ``max_tilt`` out of the left image plane and at least ``min_epipolar`` away from the
    epipolar plane through the centre (where the two viewing planes coincide)."""
    bottle = bottle or default_bottle()
    mesh = _cached_mesh(bottle)
    baseline = rig.right_in_left.t / np.linalg.norm(rig.right_in_left.t)
    for _ in range(10000):
        z = rng.uniform(*depth)
        x = rng.uniform(-0.35, 0.35) * z
        y = rng.uniform(-0.25, 0.25) * z
        centre = np.array([x, y, z])
        tilt = np.arcsin(rng.uniform(-np.sin(max_tilt), np.sin(max_tilt)))
        spin = rng.uniform(0, 2 * np.pi)
        axis = np.array([np.cos(tilt) * np.cos(spin), np.cos(tilt) * np.sin(spin), np.sin(tilt)])
        m = np.cross(baseline, centre)
        if abs(np.arcsin(abs(np.dot(m / np.linalg.norm(m), axis)))) < min_epipolar:
            continue
        pose = ObjectPose(centre, axis)
        inside = True
        for which, camera in (("left", rig.left), ("right", rig.right)):
            to_cam = left_to_camera(rig, which)
            R = to_cam.R @ axis_frame(axis)
            x0, y0, x1, y1 = _object_box(camera, mesh, R, to_cam.apply(centre))
            inside &= x0 >= margin and y0 >= margin and x1 <= camera.width - 1 - margin \
                and y1 <= camera.height - 1 - margin
        if inside:
            return pose
    raise RuntimeError("no pose inside both images; widen the depth range")
