"""Statics of a body standing on point feet [HEX 9.2]: the static stability margin of the support
polygon, friction cones and their linearised pyramids, and the foot forces that hold the body (a QP
solved by ProxQP).

- **Margin** (:func:`stability_margin`): the support plane is the plane through the stance feet (the
  least-squares plane when more than three are not quite coplanar); the centre of mass is projected
  onto it **along gravity** (on a slope that point lies downhill of the foot of the perpendicular, by
  h tan θ for a CoM h above the plane); the support polygon is the convex hull of the feet in that
  plane; the margin is the signed distance from the projected CoM to the polygon's nearest edge,
  positive inside, negative outside (minus the distance to the polygon). Fewer than three feet, feet
  in a line, or gravity parallel to the support plane raise :class:`DegenerateSupport`.
- **Cones**: a foot force f is inside the cone of friction coefficient μ about the ground normal n
  when f·n ≥ 0 and |f − (f·n) n| ≤ μ f·n. The QP uses the *inscribed* pyramid of ``facets`` planes
  (rows a_j = cos φ_j t1 + sin φ_j t2 − μ cos(π/m) n, φ_j = (2j+1)π/m, a_j·f ≤ 0), so every force it
  returns is inside the true cone; the pyramid's edges lie on the cone, one of them along t1, the
  tangent nearest the world x axis (uphill on a slope rising towards +x).
- **Force distribution** (:func:`distribute_forces`): minimise Σ f_iᵀ W_i f_i with W_i = n nᵀ +
  w_t (I − n nᵀ) (w_t = 1: Σ|f_i|², the minimum-norm distribution, which adds no internal squeeze
  between the feet; w_t > 1 leans less on friction) subject to Σ f_i + m g = 0, Σ (p_i − c) × f_i = 0
  (force and moment balance about the CoM), the pyramids and f_i·n ≥ f_min. ProxQP (proxsuite), a
  primal-dual proximal augmented-Lagrangian QP solver, rather than an ADMM one such as OSQP: it
  reaches residuals of 1e-12 on these problems where ADMM stalls around 1e-4 … 1e-6 unless polished
  (``benchmarks/hexapod_qp.py`` measures both). The balance residuals are recomputed here and the
  solution refused above ``BALANCE_TOL``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

GRAVITY = np.array([0.0, 0.0, -9.81])  # m/s², world z up
BALANCE_TOL = 1e-9  # N and N·m: the largest balance residual a returned distribution may have
COLLINEAR_TOL = 1e-9  # the support's second principal spread over its first below which it is a line


class DegenerateSupport(ValueError):
    """The stance has no area: fewer than three feet, feet in a line, or gravity along the support plane."""


class InfeasibleForces(ValueError):
    """No foot forces inside the friction pyramids hold the body on this stance."""


# -- the stability margin -------------------------------------------------------------------------

def _vectors(name: str, value: ArrayLike, shape: tuple[int, ...]) -> Array:
    a = np.asarray(value, dtype=float)
    if a.ndim != len(shape) or any(s != -1 and s != d for s, d in zip(shape, a.shape, strict=True)):
        want = "×".join("k" if s == -1 else str(s) for s in shape)
        raise ValueError(f"{name}: expected an array of shape {want}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected finite numbers")
    return a


def _unit(name: str, v: ArrayLike) -> Array:
    a = _vectors(name, v, (3,))
    norm = float(np.linalg.norm(a))
    if not norm > 0:
        raise ValueError(f"{name}: expected a non-zero vector, got {a}")
    return a / norm


def _hull(points: Array) -> Array:
    """The convex hull's vertices (counter-clockwise, no collinear ones) of 2-D points, Andrew's
    monotone chain."""
    pts = sorted({(float(x), float(y)) for x, y in points})

    def half(seq: list[tuple[float, float]]) -> list[tuple[float, float]]:
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _segment_distance(p: Array, a: Array, b: Array) -> float:
    ab = b - a
    s = float(np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0))
    return float(np.linalg.norm(p - a - s * ab))


@dataclass(frozen=True)
class Support:
    """A stance in its support plane: the plane's unit normal (against gravity) and origin (the feet's
    mean), an in-plane basis (e1, e2, normal right-handed), the hull (h×2, counter-clockwise, in that
    basis) and the CoM projected along gravity (2,)."""

    normal: Array
    origin: Array
    basis: Array  # 2×3: e1, e2
    hull: Array
    com: Array

    def margin(self) -> float:
        hull, c = self.hull, self.com
        edges = np.roll(hull, -1, axis=0) - hull
        inward = np.column_stack([-edges[:, 1], edges[:, 0]]) / np.linalg.norm(edges, axis=1)[:, None]
        signed = ((c - hull) * inward).sum(axis=1)
        if signed.min() >= 0:  # inside a convex polygon: the nearest edge line is the nearest edge
            return float(signed.min())
        return -min(_segment_distance(c, hull[i], hull[(i + 1) % len(hull)]) for i in range(len(hull)))

    def to_world(self, xy: Array) -> Array:
        """In-plane points (…×2) in the world."""
        world: Array = self.origin + np.asarray(xy) @ self.basis
        return world


def support(feet: ArrayLike, com: ArrayLike, gravity: ArrayLike = GRAVITY) -> Support:
    """The support plane, polygon and projected CoM of a stance (see the module docstring)."""
    p = _vectors("feet", feet, (-1, 3))
    c = _vectors("com", com, (3,))
    g = _unit("gravity", gravity)
    if len(p) < 3:
        raise DegenerateSupport(f"the stance has {len(p)} feet: a support polygon needs at least 3")
    origin = p.mean(axis=0)
    _, s, vt = np.linalg.svd(p - origin)
    if not s[1] > COLLINEAR_TOL * s[0]:
        raise DegenerateSupport(f"the {len(p)} stance feet are in a line (spread {s[1]:.3g} m across "
                                f"{s[0]:.3g} m along): no support polygon")
    n = vt[2] if vt[2] @ g < 0 else -vt[2]
    along = float(n @ g)
    if not abs(along) > COLLINEAR_TOL:
        raise DegenerateSupport("gravity lies in the support plane: the CoM has no projection onto it")
    e1 = vt[0]
    basis = np.stack([e1, np.cross(n, e1)])
    projected = c + (n @ (origin - c)) / along * g
    hull = _hull((p - origin) @ basis.T)
    return Support(n, origin, basis, hull, basis @ (projected - origin))


def stability_margin(feet: np.ndarray, com: np.ndarray, gravity: np.ndarray) -> float:
    """The static stability margin (m) of the stance ``feet`` (k×3, world) for the centre of mass
    ``com`` (3,) under ``gravity`` (3,, any length): the CoM projected along gravity onto the feet's
    plane, its signed distance to the nearest edge of their convex hull, positive inside.
    :class:`DegenerateSupport` (a ValueError) for fewer than three feet or feet in a line."""
    return support(feet, com, gravity).margin()


# -- friction cones ---------------------------------------------------------------------------------

def _split(force: ArrayLike, normal: ArrayLike) -> tuple[Array, Array]:
    f = np.asarray(force, dtype=float)
    if f.shape[-1:] != (3,) or not np.all(np.isfinite(f)):
        raise ValueError(f"force: expected finite 3-vectors (…×3), got shape {f.shape}")
    n = np.asarray(normal, dtype=float)
    if n.shape[-1:] != (3,) or not np.all(np.isfinite(n)) or not np.all(np.linalg.norm(n, axis=-1) > 0):
        raise ValueError(f"normal: expected finite non-zero 3-vectors (…×3), got shape {n.shape}")
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    fn = (f * n).sum(axis=-1)
    ft = np.linalg.norm(f - fn[..., None] * n, axis=-1)
    return fn, ft


def inside_friction_cone(force: ArrayLike, normal: ArrayLike, mu: float, atol: float = 0.0) -> Any:
    """Whether each force (3, or …×3) is inside the cone of friction coefficient ``mu`` about the
    (not necessarily unit) ``normal``: f·n ≥ −atol and |f_t| ≤ μ f·n + atol. A bool, or an array."""
    if not (math.isfinite(mu) and mu >= 0):
        raise ValueError(f"mu: expected a finite friction coefficient >= 0, got {mu!r}")
    fn, ft = _split(force, normal)
    inside = (fn >= -atol) & (ft <= mu * fn + atol)
    return bool(inside) if inside.ndim == 0 else inside


def friction_ratio(force: ArrayLike, normal: ArrayLike) -> Any:
    """|f_t| / f_n of each force (a float, or an array); inf where f_n ≤ 0 (pulling or no contact)."""
    fn, ft = _split(force, normal)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(fn > 0, ft / np.where(fn > 0, fn, 1.0), np.inf)
    return float(ratio) if ratio.ndim == 0 else ratio


def tangent_basis(normal: ArrayLike) -> Array:
    """Unit tangents t1, t2 (2×3) with (t1, t2, n) right-handed; t1 is the world x axis (y when n is
    nearly along x) projected onto the tangent plane."""
    n = _unit("normal", normal)
    axis = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0.0, 1, 0])
    t1 = axis - (axis @ n) * n
    t1 /= np.linalg.norm(t1)
    return np.stack([t1, np.cross(n, t1)])


def friction_pyramid(normal: ArrayLike, mu: float, facets: int = 8) -> Array:
    """The inscribed linearised cone: rows a_j (facets×3) with a_j·f ≤ 0 for the forces inside it
    (every such force with f·n ≥ 0 is inside the true cone; its edges are on it, one along t1)."""
    if not (math.isfinite(mu) and mu >= 0):
        raise ValueError(f"mu: expected a finite friction coefficient >= 0, got {mu!r}")
    if facets < 3:
        raise ValueError(f"facets: a friction pyramid needs at least 3, got {facets}")
    n = _unit("normal", normal)
    t = tangent_basis(n)
    phi = (2 * np.arange(facets) + 1) * math.pi / facets
    rows: Array = np.cos(phi)[:, None] * t[0] + np.sin(phi)[:, None] * t[1] \
        - mu * math.cos(math.pi / facets) * n
    return rows


# -- force distribution ------------------------------------------------------------------------------

def _skew(r: Array) -> Array:
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


@dataclass(frozen=True)
class ForceDistribution:
    """Foot forces (k×3, N, world, exerted by the ground on the feet) and how well they balance:
    the residuals of Σ f + m g (N) and Σ (p − c) × f (N·m), recomputed here; the solver's
    iterations and time (s)."""

    forces: Array
    normals: Array  # k×3, unit
    mu: float
    residual_force: float
    residual_moment: float
    iterations: int
    solve_time: float
    duals: tuple[Array, Array]  # ProxQP's multipliers of the balance (6) and the inequalities

    @property
    def normal_forces(self) -> Array:
        fn: Array = (self.forces * self.normals).sum(axis=1)
        return fn

    @property
    def ratios(self) -> Array:
        """|f_t| / f_n of each foot."""
        ratio: Array = friction_ratio(self.forces, self.normals)
        return ratio


def balance_matrix(feet: Array, com: Array) -> Array:
    """A (6×3k): A f = (Σ f_i, Σ (p_i − c) × f_i) for forces f stacked foot by foot."""
    k = len(feet)
    a = np.zeros((6, 3 * k))
    for i in range(k):
        a[:3, 3 * i:3 * i + 3] = np.eye(3)
        a[3:, 3 * i:3 * i + 3] = _skew(feet[i] - com)
    return a


def force_problem(feet: ArrayLike, com: ArrayLike, mass: float, gravity: ArrayLike = GRAVITY,
                  normals: ArrayLike = (0.0, 0.0, 1.0), mu: float = 0.5, facets: int = 8,
                  f_min: float = 0.0, tangential_weight: float = 1.0) -> dict[str, Array]:
    """The QP's matrices: minimise ½ xᵀ H x subject to A x = b, l ≤ C x ≤ u (x: the forces stacked foot
    by foot; ±1e20 for no bound). Also the unit ``normals`` (k×3)."""
    p = _vectors("feet", feet, (-1, 3))
    c = _vectors("com", com, (3,))
    g = _vectors("gravity", gravity, (3,))
    k = len(p)
    if k == 0:
        raise DegenerateSupport("no stance feet: nothing can hold the body")
    if not (math.isfinite(mass) and mass > 0):
        raise ValueError(f"mass: expected a finite number > 0 (kg), got {mass!r}")
    if not (math.isfinite(f_min) and f_min >= 0):
        raise ValueError(f"f_min: expected a finite normal force >= 0 (N), got {f_min!r}")
    if not (math.isfinite(tangential_weight) and tangential_weight > 0):
        raise ValueError(f"tangential_weight: expected a finite number > 0, got {tangential_weight!r}")
    n = np.asarray(normals, dtype=float)
    n = np.broadcast_to(n, (k, 3)) if n.shape == (3,) else n
    n = np.stack([_unit(f"normals[{i}]", v) for i, v in enumerate(_vectors("normals", n, (k, 3)))])
    h = np.zeros((3 * k, 3 * k))
    rows = []
    for i in range(k):
        nn = np.outer(n[i], n[i])
        h[3 * i:3 * i + 3, 3 * i:3 * i + 3] = 2 * (nn + tangential_weight * (np.eye(3) - nn))
        block = np.zeros((facets + 1, 3 * k))
        block[:facets, 3 * i:3 * i + 3] = friction_pyramid(n[i], mu, facets)
        block[facets, 3 * i:3 * i + 3] = n[i]
        rows.append(block)
    big = 1e20
    lower = np.tile(np.r_[np.full(facets, -big), f_min], k)
    upper = np.tile(np.r_[np.zeros(facets), big], k)
    return {"H": h, "A": balance_matrix(p, c), "b": np.r_[-mass * g, np.zeros(3)], "C": np.vstack(rows),
            "l": lower, "u": upper, "normals": n}


def distribute_forces(feet: ArrayLike, com: ArrayLike, mass: float, gravity: ArrayLike = GRAVITY,
                      normals: ArrayLike = (0.0, 0.0, 1.0), mu: float = 0.5, facets: int = 8,
                      f_min: float = 0.0, tangential_weight: float = 1.0, eps_abs: float = 1e-12,
                      max_iter: int = 100) -> ForceDistribution:
    """The foot forces (k×3, world) that hold a body of ``mass`` kg with its CoM at ``com`` on the
    stance ``feet`` (k×3) under ``gravity``; ``normals`` the ground normal (3,) or one per foot (k×3);
    see the module docstring. :class:`InfeasibleForces` (a ValueError) when none exist: ProxQP's
    infeasibility certificate, or no solution that balances to ``BALANCE_TOL`` within ``max_iter`` outer
    iterations (feasible stances take 5-20; ProxQP does not detect every infeasible one, e.g. an f_min
    above the weight's share, and would iterate on)."""
    from gagen.extras import require

    proxqp = require("proxsuite", "gagen.apps.hexapod.statics.distribute_forces").proxqp
    m = force_problem(feet, com, mass, gravity, normals, mu, facets, f_min, tangential_weight)
    k = len(m["normals"])
    qp = proxqp.dense.QP(3 * k, 6, len(m["C"]))
    qp.settings.eps_abs = eps_abs
    qp.settings.eps_rel = 0.0
    qp.settings.max_iter = max_iter
    qp.settings.verbose = False
    qp.init(m["H"], np.zeros(3 * k), m["A"], m["b"], m["C"], m["l"], m["u"])
    qp.solve()
    info = qp.results.info
    x = np.array(qp.results.x)
    residual = m["A"] @ x - m["b"]
    violation = float(np.maximum(np.maximum(m["C"] @ x - m["u"], m["l"] - m["C"] @ x), 0.0).max())
    where = f"{k} feet, mass {mass:g} kg, mu = {mu:g} ({facets}-facet pyramids), f_min = {f_min:g} N"
    status = info.status
    if status == proxqp.QPSolverOutput.PROXQP_PRIMAL_INFEASIBLE:
        raise InfeasibleForces(f"no foot forces hold the body ({where}): ProxQP proved the balance and "
                               f"friction constraints infeasible after {info.iter} iterations")
    worst = max(float(np.abs(residual).max()), violation)
    if status != proxqp.QPSolverOutput.PROXQP_SOLVED or not np.all(np.isfinite(x)) or worst > BALANCE_TOL:
        raise InfeasibleForces(f"no foot forces hold the body ({where}): ProxQP ended with {status.name} "
                               f"after {info.iter} iterations, balance/cone residual {worst:.2e} "
                               f"(> {BALANCE_TOL:g})")
    return ForceDistribution(x.reshape(k, 3), m["normals"], mu, float(np.abs(residual[:3]).max()),
                             float(np.abs(residual[3:]).max()), int(info.iter), float(info.solve_time) * 1e-6,
                             (np.array(qp.results.y), np.array(qp.results.z)))


__all__ = ["BALANCE_TOL", "GRAVITY", "DegenerateSupport", "ForceDistribution", "InfeasibleForces", "Support",
           "balance_matrix", "distribute_forces", "force_problem", "friction_pyramid", "friction_ratio",
           "inside_friction_cone", "stability_margin", "support", "tangent_basis"]
