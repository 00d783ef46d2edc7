"""A tripod gait for a hexapod [HEX 9]: a body trajectory over flat or sloped ground, footholds, swing
arcs, joint trajectories from the generated analytic IK, and checks computed independently of it.

The walk, step by step:

- **Ground** (:class:`Ground`): the plane n·x = 0 through the origin, rising at ``slope`` towards the
  world heading ``uphill`` (flat for slope 0).
- **Body** (:func:`body_trajectory`): a path in the world xy plane (a straight line, then an arc) run
  with a smooth speed profile (cosine ramps of one step time at both ends), lifted vertically onto
  the ground plane; the body's origin keeps ``height`` above the ground **along the plane normal**,
  and the body is **tilted with the slope** (its z axis is the ground normal, its x axis the path
  heading turned by the minimal rotation taking the world z to the normal). Its pose is the PGA motor
  M = T(c) R (body → world) that the generated ``body_ik`` kernel takes. On a slope the body may
  **lean** uphill: its origin moves ``lean`` m along the ground's uphill direction while the footholds
  stay where the unleaned body puts them, so the centre of mass, whose projection along gravity falls
  h tan θ downhill of its foot on the plane, comes back over the feet
  (``gait_statics.balanced_lean`` finds the lean that undoes it exactly).
- **Tripods** (:func:`tripods`): the legs ordered by their hips' azimuth on the body, alternately; the
  tripod A is the one holding the leg with the smallest non-negative azimuth (front left on the
  bundled hexapod: A = {front_left, rear_left, middle_right}, B = {front_right, rear_right,
  middle_left}).
- **Steps**: the time is cut into phases of ``step_time``; A swings in the even phases, B in the odd
  ones, the other tripod stands. A stance toe is a fixed world point on the ground. A swinging toe
  goes from its lift-off point to its next foothold: the neutral toe (``hexapod.neutral`` through
  the leg FK, body frame) placed at the body pose of the middle of its next stance phase and
  projected onto the ground plane. On the way it moves along the chord with the minimum-jerk blend
  10τ³ − 15τ⁴ + 6τ⁵ and lifts along the plane normal by ``step_height`` · sin²(πτ) (zero vertical
  speed at lift-off and touch-down). The walk starts and ends standing on the neutral footholds.
- **Joints** (:func:`walk`): all samples at once through ``body_ik.batch`` (knee branch of the spec).
- **Checks**, independent of the IK: the toes by the generated FK (``body_fk_pga``) carried to the
  world by the body's rotation matrix and position (not by the motor the IK read); the stance slip
  (how far a stance toe moves from where its stance began), the stance toes' signed distance from
  the ground (``body_contact_pga``), the joint-limit margins, and the IK's reachability flags grouped
  into runs "leg X unreachable at t = … s (excess … m)". The IK clamps an unreachable target to the
  nearest pose, so nothing is ever NaN.

The module is the hexapod's generated module (:func:`hexapod_module`: the committed
``generated/<name>`` for the bundled spec, else built once per spec file into the gagen cache; both
built on first use, ``gagen.modules``).
Plots and the animation are in ``gagen.apps.hexapod.plots``; ``gagen walk`` runs it all.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.apps.hexapod.bundled import SPEC
from gagen.apps.hexapod.kernels import toe_position
from gagen.apps.hexapod.spec import Hexapod, Leg, load_hexapod

Array = NDArray[np.float64]


# -- the module -----------------------------------------------------------------------------------------

def hexapod_module(spec: str | Path = SPEC, folder: str | Path | None = None,
                   progress: Callable[[str], None] | None = None) -> Any:
    """The generated module of a hexapod spec, loaded (``gagen.runtime.GeneratedModule``).

    ``folder``: build into it (``gagen.build.build``, a no-op when up to date) and load it. Without
    it, where ``gagen.modules.module_folder`` puts it: the checkout's committed ``generated/<name>``
    for the bundled spec (rebuilt on first use in a fresh clone, which has no CasADi files), else
    the gagen cache (``gagen.build.cache_root()/<name>-<key>``), built once per spec file.
    """
    from gagen.modules import module_folder
    from gagen.runtime import load

    spec = Path(spec)
    hexapod = load_hexapod(spec)
    return _checked(load(module_folder(spec, folder, progress=progress)), hexapod)


def _checked(module: Any, hexapod: Hexapod) -> Any:
    legs = module.manifest.get("legs")
    if legs != [leg.name for leg in hexapod.legs] or "body_ik" not in module.kernel_names:
        raise ValueError(f"the module {module} is not the walking module of the hexapod {hexapod.name} "
                         f"(its legs: {legs}; body_ik needed)")
    return module


# -- ground and body ------------------------------------------------------------------------------------

def rotation(axis: Array, angle: float | Array) -> Array:
    """Rotation matrices (Rodrigues) about the unit ``axis`` by ``angle`` (a number, or an array of n:
    then n×3×3)."""
    u = np.asarray(axis, dtype=float)
    k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    a = np.asarray(angle, dtype=float)[..., None, None]
    matrices: Array = np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * (k @ k)
    return matrices


@dataclass(frozen=True)
class Ground:
    """The plane n·x = 0 through the origin, rising at ``slope`` (rad) towards the world heading
    ``uphill`` (rad, from +x towards +y)."""

    slope: float = 0.0
    uphill: float = 0.0

    @property
    def normal(self) -> Array:
        s, c = math.sin(self.slope), math.cos(self.slope)
        return np.array([-s * math.cos(self.uphill), -s * math.sin(self.uphill), c])

    @property
    def uphill_direction(self) -> Array:
        """The unit vector in the plane pointing straight uphill (along ``uphill`` on flat ground)."""
        s, c = math.sin(self.slope), math.cos(self.slope)
        return np.array([c * math.cos(self.uphill), c * math.sin(self.uphill), s])

    @property
    def plane(self) -> Array:
        """The PGA plane's coefficients in kind order (e0, e1, e2, e3): n1 e1 + n2 e2 + n3 e3 − 0 e0."""
        return np.array([0.0, *self.normal])

    @property
    def tilt(self) -> Array:
        """The minimal rotation taking the world z to the normal."""
        n = self.normal
        axis = np.cross([0.0, 0.0, 1.0], n)
        s = np.linalg.norm(axis)
        return np.eye(3) if s < 1e-15 else rotation(axis / s, math.atan2(s, n[2]))

    def lift(self, xy: Array) -> Array:
        """Points (n×3) of the plane vertically above or below ``xy`` (n×2)."""
        n = self.normal
        return np.column_stack([xy, -(xy @ n[:2]) / n[2]])

    def distance(self, p: Array) -> Array:
        """Signed distances of points (…×3) above the plane."""
        return p @ self.normal

    def project(self, p: Array) -> Array:
        """The feet of the perpendiculars from points (…×3) on the plane (euclidean.py's project)."""
        return p - self.distance(p)[..., None] * self.normal


@dataclass(frozen=True)
class GaitParameters:
    """A walk: the path (``straight`` m, then an arc of ``turn`` rad, + to the left, of ``radius`` m),
    the body's ``height`` above the ground (m), the ``stride`` (body travel per gait cycle of two
    steps, m; each toe steps this far), ``step_time`` (s per swing), ``step_height`` (m), the
    sampling ``rate`` (Hz) and the body's ``lean`` (m along the ground's uphill direction, the
    footholds unmoved; module docstring)."""

    straight: float = 0.3
    turn: float = math.radians(60)
    radius: float = 0.3
    height: float = 0.15
    stride: float = 0.10
    step_time: float = 0.5
    step_height: float = 0.05
    rate: float = 100.0
    lean: float = 0.0

    def __post_init__(self) -> None:
        for name in ("radius", "height", "stride", "step_time", "rate"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"gait parameter {name} must be a finite number > 0, got {value!r}")
        for name in ("straight", "turn", "step_height", "lean"):
            value = getattr(self, name)
            if not math.isfinite(value) or (name not in ("turn", "lean") and value < 0):
                raise ValueError(f"gait parameter {name} must be a finite number >= 0, got {value!r}")
        if self.length <= 0:
            raise ValueError("the path is empty: give a straight part or a turn")
        if self.step_time * self.rate < 4:
            raise ValueError(f"{self.rate:g} Hz gives fewer than 4 samples per step of {self.step_time:g} s")

    @property
    def length(self) -> float:
        return self.straight + self.radius * abs(self.turn)

    @property
    def speed(self) -> float:
        return self.stride / (2 * self.step_time)

    @property
    def ramp(self) -> float:
        """Seconds to speed up (and to slow down): one step, or less on a short path."""
        return min(self.step_time, self.length / self.speed)

    @property
    def moving(self) -> float:
        """Seconds the body moves: the cruise plus half of each ramp."""
        return self.length / self.speed + self.ramp

    @property
    def phases(self) -> int:
        """Steps: while the body moves, and one more to bring the last tripod to its neutral stand."""
        return math.ceil(self.moving / self.step_time - 1e-9) + 1

    @property
    def duration(self) -> float:
        return self.phases * self.step_time

    def times(self) -> Array:
        return np.arange(round(self.duration * self.rate) + 1) / self.rate


def arclength(params: GaitParameters, t: Array) -> Array:
    """Distance along the path at times ``t``: speed v with cosine ramps (1 − cos)/2 of ``ramp`` s."""
    v, a, T = params.speed, params.ramp, params.moving
    t = np.clip(np.asarray(t, dtype=float), 0.0, T)

    def up(u: Array) -> Array:  # the distance covered after u s of speeding up (u ≤ a)
        return v * (u / 2 - a / (2 * math.pi) * np.sin(math.pi * u / a))

    return np.where(t < a, up(np.minimum(t, a)),
                    np.where(t > T - a, params.length - up(np.clip(T - t, 0, a)), v * a / 2 + v * (t - a)))


def path(params: GaitParameters, s: Array) -> tuple[Array, Array]:
    """The path's points (n×2) and headings (n) at distances ``s``: along +x, then the arc."""
    s = np.asarray(s, dtype=float)
    along = np.minimum(s, params.straight)
    phi = np.sign(params.turn) * np.maximum(s - params.straight, 0.0) / params.radius
    r = params.radius * np.sign(params.turn)
    xy = np.column_stack([along + np.abs(r) * np.sin(np.abs(phi)), r * (1 - np.cos(phi))])
    return xy, phi


@dataclass(frozen=True)
class BodyTrajectory:
    """The body's pose at times ``t``: position (n×3), rotation (n×3×3, body → world) and the same as
    a PGA motor (n×8, coefficients in kind order 1, e01, e02, e12, e03, e13, e23, e0123)."""

    t: Array
    position: Array
    rotation: Array
    motor: Array

    def to_world(self, p: Array) -> Array:
        """Body-frame points (n×k×3, one set per time) in the world."""
        world: Array = np.einsum("nij,nkj->nki", self.rotation, p) + self.position[:, None, :]
        return world


def quaternion(r: Array) -> Array:
    """Unit quaternions (w, x, y, z) of rotation matrices (n×3×3), by the largest-diagonal method."""
    r = np.asarray(r, dtype=float).reshape(-1, 3, 3)
    tr = np.trace(r, axis1=1, axis2=2)
    cand = np.stack([1 + tr, 1 + 2 * r[:, 0, 0] - tr, 1 + 2 * r[:, 1, 1] - tr, 1 + 2 * r[:, 2, 2] - tr], 1)
    k = np.argmax(cand, axis=1)
    out = np.empty((len(r), 4))
    for i, (m, j) in enumerate(zip(r, k, strict=True)):
        s = 2 * math.sqrt(cand[i, j])  # 4 |component j|
        off = {0: (m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]),
               1: (m[2, 1] - m[1, 2], m[0, 1] + m[1, 0], m[0, 2] + m[2, 0]),
               2: (m[0, 2] - m[2, 0], m[0, 1] + m[1, 0], m[1, 2] + m[2, 1]),
               3: (m[1, 0] - m[0, 1], m[0, 2] + m[2, 0], m[1, 2] + m[2, 1])}[int(j)]
        q = np.empty(4)
        q[j] = s / 4
        q[[i2 for i2 in range(4) if i2 != j]] = np.array(off) / s
        out[i] = q
    return out


def motor(r: Array, c: Array) -> Array:
    """PGA motors M = T(c) R (n×8, kind order) of rotations (n×3×3) and translations (n×3).

    The rotor of the quaternion (w, x, y, z) is w − x e23 + y e13 − z e12 (``Geometry.rotation_generator``:
    cos(θ/2) − sin(θ/2) (u3 e12 − u2 e13 + u1 e23)); T(c) = 1 − ½ e0 c, so M = R − ½ e0 (c R) with
    c R = (w c + a(c1 e2 − c2 e1) + b(c1 e3 − c3 e1) + g(c2 e3 − c3 e2)) + (g c1 − b c2 + a c3) e123 in
    G(3) for R = w + a e12 + b e13 + g e23."""
    q = quaternion(r)
    w, a, b, g = q[:, 0], -q[:, 3], q[:, 2], -q[:, 1]
    c1, c2, c3 = np.asarray(c, dtype=float).T
    v1 = w * c1 - a * c2 - b * c3
    v2 = w * c2 + a * c1 - g * c3
    v3 = w * c3 + b * c1 + g * c2
    tri = g * c1 - b * c2 + a * c3
    return np.column_stack([w, -v1 / 2, -v2 / 2, a, -v3 / 2, b, g, -tri / 2])


def body_trajectory(params: GaitParameters, ground: Ground, t: ArrayLike | None = None,
                    lean: bool = True) -> BodyTrajectory:
    """The body's poses at ``t`` (default: the walk's samples), see the module docstring; ``lean=False``
    gives the unleaned poses the footholds are placed from."""
    t = params.times() if t is None else np.asarray(t, dtype=float)
    xy, heading = path(params, arclength(params, t))
    r = ground.tilt @ rotation(np.array([0.0, 0.0, 1.0]), heading)
    c = ground.lift(xy) + params.height * ground.normal
    if lean and params.lean:
        c = c + params.lean * ground.uphill_direction
    return BodyTrajectory(t, c, r, motor(r, c))


# -- legs ---------------------------------------------------------------------------------------------

def tripods(hexapod: Hexapod) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The two tripods (leg indices, spec order): the legs alternately around the body by their hips'
    azimuth; A holds the leg with the smallest non-negative azimuth (front left when x is forward)."""
    azimuth = [math.atan2(leg.xyz[1], leg.xyz[0]) for leg in hexapod.legs]
    order = sorted(range(len(azimuth)), key=lambda i: azimuth[i])
    sets = (tuple(sorted(order[0::2])), tuple(sorted(order[1::2])))
    first = min((i for i in range(len(azimuth)) if azimuth[i] >= 0), key=lambda i: azimuth[i])
    return sets if first in sets[0] else (sets[1], sets[0])


def neutral_toes(hexapod: Hexapod) -> Array:
    """The toes (6×3, body frame) at the neutral configuration."""
    return np.array([toe_position(leg, hexapod.neutral) for leg in hexapod.legs])


def _mount(leg: Leg) -> tuple[Array, Array]:
    roll, pitch, yaw = leg.rpy
    r = rotation(np.array([0.0, 0, 1]), yaw) @ rotation(np.array([0.0, 1, 0]), pitch) \
        @ rotation(np.array([1.0, 0, 0]), roll)
    return r, np.array(leg.xyz)


def joint_points(hexapod: Hexapod, q: Array) -> Array:
    """Each leg's hip, thigh joint, knee and toe in the body frame (n×6×4×3), by a matrix chain (for
    drawing; the checks use the generated FK, which this chain matches)."""
    q = np.atleast_2d(q)
    out = np.empty((len(q), len(hexapod.legs), 4, 3))
    for i, leg in enumerate(hexapod.legs):
        mr, mc = _mount(leg)
        r = np.broadcast_to(np.eye(3), (len(q), 3, 3))
        c = np.zeros((len(q), 3))  # the chain so far as x -> r x + c (hip frame)
        points = [*leg.centres[1:], leg.toe]
        out[:, i, 0] = mc
        for j, (u, centre) in enumerate(zip(leg.axes, leg.centres, strict=True)):
            rj = rotation(np.array(u), q[:, 3 * i + j])
            cj = np.array(centre) - rj @ np.array(centre)  # turn about the line through the centre
            c = c + np.einsum("nij,nj->ni", r, cj)
            r = r @ rj
            out[:, i, j + 1] = (np.einsum("nij,j->ni", r, np.array(points[j])) + c) @ mr.T + mc
    return out


# -- the walk -----------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Run:
    """A run of samples where a leg is unreachable (``reach`` = 0) or past a joint limit."""

    leg: str
    start: float  # s
    end: float  # s
    samples: int
    worst: float  # m outside the reach, or rad past the limit
    stance: bool  # whether the leg was standing in any of them
    joint: str = ""

    def message(self) -> str:
        when = f"t = {self.start:.2f} s" if self.samples == 1 else f"t = {self.start:.2f} … {self.end:.2f} s"
        where = "in stance" if self.stance else "in swing"
        if self.joint:
            return f"joint {self.joint} past its limit at {when} (by up to {self.worst:.4f} rad, {where})"
        return f"leg {self.leg} unreachable at {when} (excess up to {self.worst:.4f} m, {where})"


@dataclass
class GaitResult:
    """A walk and its checks. Arrays over n samples at times ``t``; legs in spec order."""

    hexapod: Hexapod
    params: GaitParameters
    ground: Ground
    tripods: tuple[tuple[int, ...], tuple[int, ...]]
    t: Array  # n
    body: BodyTrajectory  # poses: position n×3, rotation n×3×3, motor n×8
    phase: NDArray[np.int64]  # n: the step each sample is in (A swings in even steps)
    swing: NDArray[np.bool_]  # n×6: the leg is in the swinging tripod
    targets: Array  # n×6×3: commanded toes (world)
    q: Array  # n×18: the IK's joint angles
    reach: Array  # n×6: 1 reachable, 0 clamped
    excess: Array  # n×6: m outside the reach
    toes: Array  # n×6×3: the toes by the generated FK, carried to the world by the body pose
    distance: Array  # n×6: the toes' signed distance from the ground (body_contact_pga)
    slip: Array  # n×6: how far a standing toe is from where its stance began (0 in swing)
    margin: Array  # n×18: distance to the nearer joint limit (rad; negative: past it)
    unreachable: list[Run] = field(default_factory=list)
    past_limits: list[Run] = field(default_factory=list)

    @property
    def stance(self) -> NDArray[np.bool_]:
        return ~self.swing

    @property
    def slip_max(self) -> float:
        return float(self.slip.max())

    @property
    def tracking_max(self) -> float:
        """The largest distance of an FK toe from its target where the leg is reachable."""
        ok = self.reach > 0.5
        err = np.linalg.norm(self.toes - self.targets, axis=2)
        return float(err[ok].max()) if ok.any() else 0.0

    @property
    def stance_distance_max(self) -> float:
        return float(np.abs(self.distance[self.stance]).max())

    @property
    def swing_height(self) -> float:
        return float(self.distance[self.swing].max()) if self.swing.any() else 0.0

    def min_margin(self) -> tuple[float, str, float]:
        """(margin rad, joint name, time s) of the smallest joint-limit margin."""
        k, j = np.unravel_index(int(np.argmin(self.margin)), self.margin.shape)
        return float(self.margin[k, j]), self.hexapod.joint_names[j], float(self.t[k])

    @property
    def ok(self) -> bool:
        return not self.unreachable and not self.past_limits

    def flags(self) -> list[str]:
        return [r.message() for r in (*self.unreachable, *self.past_limits)]

    def table(self) -> str:
        """A concise per-leg summary."""
        names = [leg.name for leg in self.hexapod.legs]
        width = max(map(len, names)) + 2
        lines = [f"{'leg':<{width}}{'tripod':>7}{'slip [m]':>11}{'|dist| stance [m]':>19}"
                 f"{'swing max [m]':>15}{'min margin [rad]':>18}{'unreachable':>13}"]
        for i, name in enumerate(names):
            stance, swing = self.stance[:, i], self.swing[:, i]
            lines.append(f"{name:<{width}}{'A' if i in self.tripods[0] else 'B':>7}"
                         f"{self.slip[:, i].max():>11.2e}{np.abs(self.distance[stance, i]).max():>19.2e}"
                         f"{(self.distance[swing, i].max() if swing.any() else 0.0):>15.4f}"
                         f"{self.margin[:, 3 * i:3 * i + 3].min():>18.3f}"
                         f"{int((self.reach[:, i] < 0.5).sum()):>13d}")
        return "\n".join(lines)


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """[start, end] index pairs of the runs of True."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1, strict=True))


def footholds(hexapod: Hexapod, params: GaitParameters, ground: Ground,
              sets: tuple[tuple[int, ...], tuple[int, ...]]) -> Array:
    """Each leg's foothold during each step (phases×6×3, world): where the toe stands, or, for a
    swinging leg, where it lands at the end of the step."""
    neutral = neutral_toes(hexapod)
    k = params.phases
    # a leg swinging in step j lands on its neutral toe at the body pose of the middle of step j + 1
    poses = body_trajectory(params, ground, (np.arange(k + 1) + 0.5) * params.step_time, lean=False)
    start = body_trajectory(params, ground, np.zeros(1), lean=False)
    placed = ground.project(poses.to_world(np.broadcast_to(neutral, (k + 1, *neutral.shape))))
    current = ground.project(start.to_world(neutral[None]))[0]
    out = np.empty((k, len(hexapod.legs), 3))
    for j in range(k):
        for i in sets[j % 2]:
            current[i] = placed[j, i]
        out[j] = current
    return out


def toe_targets(hexapod: Hexapod, params: GaitParameters, ground: Ground, t: Array,
                sets: tuple[tuple[int, ...], tuple[int, ...]]
                ) -> tuple[Array, NDArray[np.int64], NDArray[np.bool_]]:
    """The commanded toes (n×6×3, world), each sample's step and the swing mask (n×6)."""
    k = params.phases
    holds = footholds(hexapod, params, ground, sets)
    before = np.concatenate([ground.project(body_trajectory(params, ground, np.zeros(1), lean=False)
                                            .to_world(neutral_toes(hexapod)[None])), holds[:-1]])
    phase = np.minimum((t / params.step_time + 1e-9).astype(np.int64), k - 1)
    tau = np.clip(t / params.step_time - phase, 0.0, 1.0)
    swing = np.zeros((len(t), len(hexapod.legs)), dtype=bool)
    for j, legs in enumerate(sets):
        swing[np.ix_(phase % 2 == j, legs)] = True
    blend = tau * tau * tau * (10 - 15 * tau + 6 * tau * tau)
    lift = params.step_height * np.sin(math.pi * tau) ** 2
    swinging = before[phase] + blend[:, None, None] * (holds[phase] - before[phase]) \
        + lift[:, None, None] * ground.normal
    targets = np.where(swing[:, :, None], swinging, holds[phase])
    return targets, phase, swing


def walk(module: Any, hexapod: Hexapod, params: GaitParameters | None = None, ground: Ground | None = None,
         progress: Callable[[str], None] = lambda _: None) -> GaitResult:
    """Walk ``hexapod`` with the generated ``module`` (its ``body_ik``, ``body_fk_pga`` and
    ``body_contact_pga`` kernels, batched over all samples) and check the result."""
    params = params or GaitParameters()
    ground = ground or Ground()
    sets = tripods(hexapod)
    t = params.times()
    body = body_trajectory(params, ground, t)
    targets, phase, swing = toe_targets(hexapod, params, ground, t, sets)
    n, legs = len(t), len(hexapod.legs)
    progress(f"{n} samples over {params.duration:.2f} s ({params.phases} steps): IK, FK and contact, batched")
    q, reach, excess = module.c.body_ik.batch(body.motor, targets.reshape(n, 3 * legs))
    p_body = module.c.body_fk_pga.batch(q)[0].reshape(n, legs, 3)
    toes = body.to_world(p_body)
    distance = module.c.body_contact_pga.batch(body.motor, q, np.broadcast_to(ground.plane, (n, 4)))[0]
    slip = np.zeros((n, legs))
    for i in range(legs):
        for a, b in _runs(~swing[:, i]):
            slip[a:b + 1, i] = np.linalg.norm(toes[a:b + 1, i] - toes[a, i], axis=1)
    lo = np.array([lim[0] for leg in hexapod.legs for lim in leg.limits])
    hi = np.array([lim[1] for leg in hexapod.legs for lim in leg.limits])
    margin = np.minimum(q - lo, hi - q)
    unreachable = [Run(hexapod.legs[i].name, float(t[a]), float(t[b]), int(b - a + 1),
                       float(excess[a:b + 1, i].max()), bool((~swing[a:b + 1, i]).any()))
                   for i in range(legs) for a, b in _runs(reach[:, i] < 0.5)]
    past = [Run(hexapod.legs[j // 3].name, float(t[a]), float(t[b]), int(b - a + 1),
                float(-margin[a:b + 1, j].min()), bool((~swing[a:b + 1, j // 3]).any()),
                hexapod.joint_names[j])
            for j in range(3 * legs) for a, b in _runs(margin[:, j] < 0)]
    return GaitResult(hexapod, params, ground, sets, t, body, phase, swing, targets, q, reach, excess, toes,
                      distance, slip, margin, unreachable, past)


def summary(result: GaitResult) -> str:
    """The walk's report: parameters, per-leg table, the worst numbers and every flag."""
    p, g = result.params, result.ground
    value, joint, when = result.min_margin()
    names = {0: "A", 1: "B"}
    sets = "; ".join(f"{names[k]} = {{{', '.join(result.hexapod.legs[i].name for i in s)}}}"
                     for k, s in enumerate(result.tripods))
    lines = [f"tripod gait of {result.hexapod.name}: {p.straight:g} m straight, then "
             f"{math.degrees(p.turn):g}° on a {p.radius:g} m arc; height {p.height:g} m, stride "
             f"{p.stride:g} m, step {p.step_time:g} s × {p.phases}, step height {p.step_height:g} m, "
             f"{p.rate:g} Hz ({len(result.t)} samples)" + (f"; lean {p.lean:.4g} m uphill" if p.lean else ""),
             f"ground: slope {math.degrees(g.slope):g}° rising towards {math.degrees(g.uphill):g}°; "
             f"tripods {sets}",
             "", result.table(), "",
             f"max stance slip (FK, world)      {result.slip_max:.2e} m",
             f"max |FK toe − target| (reached)  {result.tracking_max:.2e} m",
             f"max |stance toe distance|        {result.stance_distance_max:.2e} m",
             f"max swing toe height             {result.swing_height:.4f} m",
             f"min joint-limit margin           {value:.4f} rad ({joint} at t = {when:.2f} s)"]
    flags = result.flags()
    lines += [f"reachability: every leg reachable at all {len(result.t)} samples" if not result.unreachable
              else f"reachability: {len(result.unreachable)} unreachable run(s)"]
    lines += [f"  {f}" for f in flags]
    return "\n".join(lines)


__all__ = ["SPEC", "BodyTrajectory", "GaitParameters", "GaitResult", "Ground", "Run", "body_trajectory",
           "footholds", "hexapod_module", "joint_points", "motor", "neutral_toes", "quaternion", "rotation",
           "summary", "toe_targets", "tripods", "walk"]
