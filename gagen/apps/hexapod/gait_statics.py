"""The tripod gait checked against statics [HEX 9.2], and planned to keep a chosen stability margin.

- :func:`check_walk`: at every sample of a walk (``gait.walk``), the robot's centre of mass
  (``mass.py``'s model at the IK's joint angles and the body pose), the stability margin of the
  standing tripod (its FK toes, ``statics.stability_margin``, gravity along −z) and the foot forces of
  the force-distribution QP (``statics.distribute_forces``, friction pyramids about the ground normal).
- :func:`keep_margin`: the largest stride (at most the requested one) whose walk keeps a margin
  ≥ M. Why the stride: in a tripod gait each tripod stands for one step, during which the body moves
  half a stride over it, from a quarter stride behind its mid-stance pose to a quarter stride ahead;
  the margin is largest at mid-stance (the footholds are placed for it) and falls off with the CoM's
  excursion, so the walk's minimum margin falls roughly linearly from the standing margin (stride 0)
  as the stride grows. Shortening the stride is the one change that keeps the gait, the path and the
  footholds' placement and moves the margin monotonically. The stride is found by regula falsi on
  min margin(stride) − M between stride 0 (the standing margin, both tripods at the neutral pose) and
  the requested stride, each evaluation a walk. A margin at or above the standing one, or one that
  needs a stride below ``MIN_STRIDE_FRACTION`` of the request, is refused with one line: no stride
  keeps it (on a slope, the CoM's projection moves downhill by its height × tan θ, which the lean
  wins back).
- :func:`balanced_lean`: on a slope the CoM's projection along gravity falls h tan θ downhill of its
  foot on the plane (h its height along the normal), so the downhill tripod edge loses that much
  margin. Leaning the body uphill by L (``GaitParameters.lean``, the footholds unmoved) brings it
  back; as the legs' links move with the body only in part, L is more than h tan θ: the L at which the
  standing CoM's projection along gravity lands on the unleaned CoM's foot (where flat ground puts it,
  relative to the feet), along the uphill direction, is found by the secant method from L = h tan θ,
  each step the standing pose's IK. With it the standing margin on the slope is the flat ground's
  (to a few µm where the uphill direction is askew to the body: the legs' IK then moves the CoM a
  little across it too).
- :func:`margin_plot`: the margin and the largest friction ratio over the walk.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.apps.hexapod import gait
from gagen.apps.hexapod.mass import MassModel, default_mass_model, total_mass
from gagen.apps.hexapod.spec import Hexapod
from gagen.apps.hexapod.statics import GRAVITY, InfeasibleForces, distribute_forces, stability_margin

Array = NDArray[np.float64]

MIN_STRIDE_FRACTION = 1 / 64  # keep_margin refuses a stride shorter than this fraction of the request
CONE_TOL = 1e-9  # |f_t| / f_n may pass mu by this much (the QP's forces sit on the pyramids' edges)


def centre_of_mass_along(hexapod: Hexapod, mass: MassModel, body: gait.BodyTrajectory, q: Array) -> Array:
    """The robot's centre of mass (n×3, world) at each sample: ``mass.centre_of_mass``'s sum, batched
    over the samples (link centres from ``gait.joint_points``)."""
    points = gait.joint_points(hexapod, q)  # n × legs × (hip, thigh joint, knee, toe) × 3
    centres = (points[:, :, :-1] + points[:, :, 1:]) / 2
    masses = np.array(mass.link_masses)
    local = (np.einsum("lj,nljk->nk", masses, centres) + mass.body_mass * np.array(mass.body_centre)) \
        / total_mass(mass)
    com: Array = np.einsum("nij,nj->ni", body.rotation, local) + body.position
    return com


def margins_along(result: gait.GaitResult, com: Array) -> Array:
    """The standing feet's stability margin (n, m) at each sample (FK toes, gravity along −z)."""
    stance = result.stance
    return np.array([stability_margin(result.toes[k, stance[k]], com[k], GRAVITY)
                     for k in range(len(result.t))])


@dataclass
class WalkStatics:
    """A walk's statics: per sample the CoM (n×3), the margin (n), the foot forces (n×legs×3, N, zero
    for swinging legs), their |f_t|/f_n (n×legs, 0 for swinging legs) and whether the QP found forces
    (n); the balance residuals' maxima and the QP's total time."""

    result: gait.GaitResult
    mass: float
    mu: float
    com: Array
    margin: Array
    forces: Array
    ratio: Array
    feasible: NDArray[np.bool_]
    residual_force: float
    residual_moment: float
    qp_time: float
    first_infeasible: str = ""

    def margin_min(self) -> tuple[float, float]:
        """(margin m, time s) of the smallest margin."""
        k = int(np.argmin(self.margin))
        return float(self.margin[k]), float(self.result.t[k])

    def ratio_max(self) -> tuple[float, str, float]:
        """(|f_t|/f_n, leg, time s) of the largest friction ratio where the QP found forces."""
        ratio = np.where(self.feasible[:, None], self.ratio, 0.0)
        k, i = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
        return float(ratio[k, i]), self.result.hexapod.legs[i].name, float(self.result.t[k])

    @property
    def inside_cones(self) -> bool:
        normal = (self.forces * self.result.ground.normal).sum(axis=2)
        stance = self.result.stance
        return bool(self.feasible.all() and (normal[stance] > 0).all()
                    and (self.ratio <= self.mu + CONE_TOL).all())

    @property
    def ok(self) -> bool:
        return bool(self.margin.min() > 0 and self.inside_cones)

    def lines(self) -> list[str]:
        value, when = self.margin_min()
        ratio, leg, at = self.ratio_max()
        normal = (self.forces * self.result.ground.normal).sum(axis=2)[self.result.stance]
        lines = [f"statics: mass {self.mass:.3g} kg, gravity −z, mu = {self.mu:g}; margin of the standing "
                 f"tripod, foot forces by ProxQP (min Σ|f|², force and moment balance, friction pyramids)",
                 f"min stability margin             {value:.4f} m (t = {when:.2f} s)",
                 f"max |f_t|/f_n                    {ratio:.4f} (mu = {self.mu:g}; {leg} at t = {at:.2f} s)",
                 f"normal forces                    {normal.min():.3f} … {normal.max():.3f} N",
                 f"max balance residual             {self.residual_force:.1e} N, "
                 f"{self.residual_moment:.1e} N·m ({len(self.result.t)} QPs in {self.qp_time:.2f} s)"]
        bad = int((~self.feasible).sum())
        if bad:
            lines.append(f"  no foot forces inside the cones at {bad} sample(s); "
                         f"first: {self.first_infeasible}")
        return lines


def check_walk(result: gait.GaitResult, mass: MassModel | None = None, mu: float = 0.5, facets: int = 8,
               f_min: float = 0.0, progress: Callable[[str], None] = lambda _: None) -> WalkStatics:
    """The walk's margins and foot forces (see the module docstring)."""
    import time

    model = mass or default_mass_model(result.hexapod)
    m = total_mass(model)
    com = centre_of_mass_along(result.hexapod, model, result.body, result.q)
    margin = margins_along(result, com)
    n, legs = result.stance.shape
    progress(f"statics: {n} force-distribution QPs (ProxQP), mu = {mu:g}")
    forces, ratio = np.zeros((n, legs, 3)), np.zeros((n, legs))
    feasible = np.ones(n, dtype=bool)
    res_f = res_m = 0.0
    first = ""
    start = time.perf_counter()
    for k in range(n):
        stance = np.flatnonzero(result.stance[k])
        try:
            d = distribute_forces(result.toes[k, stance], com[k], m, GRAVITY, result.ground.normal, mu,
                                  facets, f_min)
        except InfeasibleForces as e:
            feasible[k] = False
            first = first or f"t = {result.t[k]:.2f} s: {e}"
            continue
        forces[k, stance] = d.forces
        ratio[k, stance] = d.ratios
        res_f, res_m = max(res_f, d.residual_force), max(res_m, d.residual_moment)
    return WalkStatics(result, m, mu, com, margin, forces, ratio, feasible, res_f, res_m,
                       time.perf_counter() - start, first)


# -- keeping a margin -------------------------------------------------------------------------------

def standing(module: Any, hexapod: Hexapod, ground: gait.Ground, params: gait.GaitParameters,
             mass: MassModel | None = None) -> tuple[Array, Array]:
    """(CoM (3,), feet (6×3)) with the body standing at the walk's start (leaned by ``params.lean``)
    and every leg on its neutral foothold (placed from the unleaned body), the joints by the IK."""
    model = mass or default_mass_model(hexapod)
    body = gait.body_trajectory(params, ground, np.zeros(1))
    unleaned = gait.body_trajectory(params, ground, np.zeros(1), lean=False)
    feet = ground.project(unleaned.to_world(gait.neutral_toes(hexapod)[None]))[0]
    q, reach, _ = module.c.body_ik.batch(body.motor, feet.reshape(1, -1))
    if np.min(reach) < 0.5:
        raise ValueError(f"the standing pose (lean {params.lean:g} m) puts a foot out of its leg's reach")
    return centre_of_mass_along(hexapod, model, body, np.asarray(q))[0], feet


def standing_margin(module: Any, hexapod: Hexapod, ground: gait.Ground, params: gait.GaitParameters,
                    mass: MassModel | None = None) -> float:
    """The margin of the weaker tripod standing at the walk's start (:func:`standing`): the limit of the
    walk's minimum margin as the stride goes to 0."""
    com, feet = standing(module, hexapod, ground, params, mass)
    return min(stability_margin(feet[list(s)], com, GRAVITY) for s in gait.tripods(hexapod))


def gravity_foot(ground: gait.Ground, point: Array) -> Array:
    """Where the vertical line through ``point`` meets the ground plane."""
    n = ground.normal
    foot: Array = point - (ground.distance(point) / n[2]) * np.array([0.0, 0.0, 1.0])
    return foot


def balanced_lean(module: Any, hexapod: Hexapod, params: gait.GaitParameters, ground: gait.Ground,
                  mass: MassModel | None = None, tolerance: float = 1e-12) -> float:
    """The lean (m uphill) at which the standing CoM's projection along gravity is the unleaned CoM's
    foot on the plane (module docstring); 0 on flat ground."""
    if ground.slope == 0.0:
        return 0.0
    uphill = ground.uphill_direction
    com0, _ = standing(module, hexapod, ground, replace(params, lean=0.0), mass)
    target = ground.project(com0)

    def offset(lean: float) -> float:
        com, _ = standing(module, hexapod, ground, replace(params, lean=lean), mass)
        return float((gravity_foot(ground, com) - target) @ uphill)

    a, fa = 0.0, offset(0.0)
    b = float(ground.distance(com0)) * math.tan(ground.slope)  # the whole body's share: a first guess
    fb = offset(b)
    for _ in range(30):
        if abs(fb) <= tolerance or fb == fa:
            break
        a, fa, b = b, fb, b - fb * (b - a) / (fb - fa)
        fb = offset(b)
    if not abs(fb) <= 1e3 * tolerance:
        raise ValueError(f"no lean balances the stance on a {math.degrees(ground.slope):g}° slope "
                         f"(offset {fb:.3g} m left)")
    return b


@dataclass(frozen=True)
class MarginPlan:
    """What :func:`keep_margin` chose: the parameters, their walk, its minimum margin (m), and the
    strides tried with their minimum margins."""

    params: gait.GaitParameters
    result: gait.GaitResult
    margin: float
    tries: tuple[tuple[float, float], ...]


def keep_margin(module: Any, hexapod: Hexapod, params: gait.GaitParameters, ground: gait.Ground,
                margin: float, mass: MassModel | None = None, tolerance: float = 0.02,
                progress: Callable[[str], None] = lambda _: None) -> MarginPlan:
    """The walk with the largest stride ≤ ``params.stride`` (to ``tolerance`` × the stride) whose minimum
    stability margin is ≥ ``margin`` m; ValueError (one line) when no stride keeps it. See the module
    docstring for the method."""
    if not math.isfinite(margin):
        raise ValueError(f"--margin: expected a finite margin in m, got {margin!r}")
    model = mass or default_mass_model(hexapod)
    tries: list[tuple[float, float]] = []

    def attempt(stride: float) -> tuple[float, gait.GaitResult, gait.GaitParameters]:
        p = replace(params, stride=stride)
        result = gait.walk(module, hexapod, p, ground)
        com = centre_of_mass_along(hexapod, model, result.body, result.q)
        value = float(margins_along(result, com).min())
        tries.append((stride, value))
        progress(f"  stride {stride:.4f} m: min margin {value:.4f} m ({len(result.t)} samples)")
        return value, result, p

    hi = params.stride
    m_hi, result, p = attempt(hi)
    if m_hi >= margin:
        return MarginPlan(p, result, m_hi, tuple(tries))
    m_lo = standing_margin(module, hexapod, ground, params, model)
    if m_lo <= margin:
        hint = ("; on a slope, --lean auto wins back its downhill shift" if ground.slope and not params.lean
                else "")
        raise ValueError(f"a stability margin of {margin:g} m cannot be kept: standing on either tripod "
                         f"gives at most {m_lo:.4f} m (the requested stride {hi:g} m gives {m_hi:.4f} m)"
                         + hint)
    lo, best = 0.0, None
    floor = MIN_STRIDE_FRACTION * params.stride
    while hi - lo > tolerance * params.stride:
        # regula falsi on min margin(stride) − margin, the margin falling roughly linearly with the stride
        s = hi - (m_hi - margin) * (hi - lo) / (m_hi - m_lo)
        s = min(max(s, lo + 0.1 * (hi - lo)), hi - 0.1 * (hi - lo))  # safeguard: shrink the bracket
        if s < floor:
            break
        value, r, p2 = attempt(s)
        if value >= margin:
            lo, m_lo, best = s, value, (p2, r, value)
        else:
            hi, m_hi = s, value
    if best is None:
        raise ValueError(f"a stability margin of {margin:g} m cannot be kept: it needs a stride below "
                         f"{max(hi, floor):.4g} m ({MIN_STRIDE_FRACTION:.3g} of the requested "
                         f"{params.stride:g} m)")
    return MarginPlan(best[0], best[1], best[2], tuple(tries))


# -- the plot -----------------------------------------------------------------------------------------

def margin_plot(statics: WalkStatics, path: str | Path, keep: float | None = None) -> Path:
    """The stability margin over the walk (swing of tripod B shaded) and the largest |f_t|/f_n against
    mu; the kept margin dashed when given."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    result = statics.result
    fig = Figure(figsize=(8, 4.6))
    FigureCanvasAgg(fig)
    top, bottom = fig.add_subplot(2, 1, 1), fig.add_subplot(2, 1, 2, sharex=None)
    t = result.t
    for ax in (top, bottom):
        b_swings = result.swing[:, result.tripods[1][0]].astype(float)
        ax.fill_between(t, 0, 1, where=b_swings > 0, transform=ax.get_xaxis_transform(), color="0.92",
                        zorder=0, lw=0)
        ax.grid(alpha=0.3)
    top.plot(t, 100 * statics.margin, color="C0", label="margin (standing tripod)")
    top.axhline(0, color="k", lw=0.8)
    if keep is not None:
        top.axhline(100 * keep, color="C3", ls="--", lw=1, label=f"kept ≥ {100 * keep:g} cm")
    top.set_ylabel("margin [cm]")
    top.legend(fontsize=8, loc="lower right")
    bottom.plot(t, np.where(statics.feasible, statics.ratio.max(axis=1), np.nan), color="C1",
                label="max |f_t| / f_n (QP)")
    bottom.axhline(statics.mu, color="C3", ls="--", lw=1, label=f"mu = {statics.mu:g}")
    bottom.set_ylim(0, 1.15 * max(statics.mu, float(statics.ratio.max())))
    bottom.set_xlabel("t [s]  (shaded: tripod A stands)")
    bottom.set_ylabel("friction ratio")
    bottom.legend(fontsize=8, loc="lower right")
    g = result.ground
    fig.suptitle(f"Static stability over the walk: slope {math.degrees(g.slope):g}°, "
                 f"stride {result.params.stride:.3g} m", fontsize=10)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=90)
    return out


__all__ = ["MarginPlan", "WalkStatics", "balanced_lean", "centre_of_mass_along", "check_walk", "gravity_foot",
           "keep_margin", "margin_plot", "margins_along", "standing", "standing_margin"]
