"""The Lie-algebra Newton solver of a planar linkage [LINK 3.3-3.4], on its generated kernels.

At a driver value θ (a crank angle, or a slider's displacement s) the moving bodies' motors R solve
F(R, θ) = 0: Newton on se(2), J ΔB = −F (least squares, by SVD, when the constraints are redundant),
R_b ← T(Δt) C(Δθ) R_b (``retract``; C the Cayley rotor, the turn by 2 atan(Δθ/2)). The driver is
advanced step by step and each solve starts from the previous configuration (continuation), which
keeps the mechanism on its assembly branch. Every step reports its Newton iterations, the final
residual (max |F|), and the conditioning of J (its smallest singular value and σ_max/σ_min): near a
singular configuration (a dead point of the four-bar, a branch point) the crank step is halved, up
to ``max_halvings`` times, so Newton does not jump to the other branch; a step that still fails is
reported, never silently replaced.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from gagen.apps.linkage.kernels import identity_motors, linkage_kernels, point_labels
from gagen.apps.linkage.spec import GROUND, Linkage, Prismatic, slot_coordinate

TOLERANCE = 1e-12  # max |F| (m) at convergence
MAX_ITERATIONS = 30


@dataclass
class Solve:
    motors: np.ndarray
    iterations: int
    residuals: list[float]  # max |F| before each iteration, then the final one
    sigma_min: float  # smallest singular value of J at the solution
    condition: float  # σ_max / σ_min

    @property
    def residual(self) -> float:
        return self.residuals[-1]

    @property
    def converged(self) -> bool:
        return self.residual < TOLERANCE


@dataclass
class Trajectory:
    angles: np.ndarray  # the driver's values: crank angles (rad) or slider displacements (m)
    motors: np.ndarray  # (steps, 4 × moving bodies)
    points: np.ndarray  # (steps, 2 × named body points), ``point_labels`` order
    iterations: np.ndarray
    residuals: np.ndarray
    sigma_min: np.ndarray
    condition: np.ndarray
    halvings: np.ndarray
    failures: list[str] = field(default_factory=list)
    rank: int = 0  # of J at the assembled initial configuration (3 × moving bodies when well posed)
    unknowns: int = 0
    limits: list[str] = field(default_factory=list)  # prismatic joints outside their travel
    phases: np.ndarray | None = None  # the driver's cycle phase (rad; the crank angle for a crank)

    @property
    def phase(self) -> np.ndarray:
        return self.angles if self.phases is None else self.phases


class Kernels:
    """The kernels the solver calls, as ``(R, θ) -> (F, J)``, ``(R, ΔB) -> R``, ``(R, θ) -> P`` and,
    where the module has it, ``(R, θ) -> (R_next, max |F|)`` (the whole Newton step in one kernel):
    the compiled module's (``kernels(linkage)``) or any equivalent."""

    def __init__(self, constraints: Callable[..., Any], retract: Callable[..., Any],
                 positions: Callable[..., Any], newton_step: Callable[..., Any] | None = None) -> None:
        self.constraints, self.retract, self.positions = constraints, retract, positions
        self.newton_step = newton_step


def kernels(linkage: Linkage, module: Any | None = None) -> Kernels:
    """The linkage's kernels compiled (``gagen.compile``'s cache, once per content) or from a loaded
    generated module's C namespace."""
    if module is None:
        from gagen.build import compile_kernels

        module = compile_kernels(linkage_kernels(linkage), name=linkage.name)
    return Kernels(module.constraints, module.retract, module.positions, getattr(module, "newton_step", None))


Value = float | np.ndarray  # a driver's value, or k drivers' values


def driver_values(value: Value) -> np.ndarray:
    """The kernels' driver input: [θ] for one driver, the k values for k."""
    return np.atleast_1d(np.asarray(value, dtype=float)).reshape(-1)


def newton(k: Kernels, motors: np.ndarray, angle: Value, *, tolerance: float = TOLERANCE,
           max_iterations: int = MAX_ITERATIONS) -> Solve:
    """Newton on se(2) from ``motors`` at the driver's value ``angle`` (k drivers: a vector of k)."""
    R = np.array(motors, dtype=float)
    theta = driver_values(angle)
    residuals = []
    if k.newton_step is not None:  # one kernel call per iteration; J only for the conditioning
        for iteration in range(max_iterations + 1):
            R_next, residual = k.newton_step(R, theta)
            residuals.append(float(np.asarray(residual).reshape(-1)[0]))
            if residuals[-1] < tolerance or iteration == max_iterations:
                break
            R = np.asarray(R_next).reshape(-1)
        return _conditioned(k, R, theta, iteration, residuals)
    for iteration in range(max_iterations + 1):
        F, J = k.constraints(R, theta)
        F, J = np.asarray(F).reshape(-1), np.asarray(J)
        residuals.append(float(np.max(np.abs(F))) if F.size else 0.0)
        if residuals[-1] < tolerance or iteration == max_iterations:
            break
        U, s, Vt = np.linalg.svd(J, full_matrices=False)
        keep = s > s[0] * 1e-13 if s.size else s
        step = -(Vt[keep].T @ ((U[:, keep].T @ F) / s[keep]))  # least squares, minimum norm
        R = np.asarray(k.retract(R, step)).reshape(-1)
    return _conditioned(k, R, theta, iteration, residuals)


def _conditioned(k: Kernels, R: np.ndarray, theta: np.ndarray, iterations: int,
                 residuals: list[float]) -> Solve:
    """The solve, with the singular values of J at its configuration."""
    s = np.linalg.svd(np.asarray(k.constraints(R, theta)[1]), compute_uv=False)
    sigma_min = float(s[-1]) if s.size else 0.0
    return Solve(R, iterations, residuals, sigma_min, float(s[0] / sigma_min) if sigma_min > 0 else np.inf)


def _driver_motion(linkage: Linkage, a: Value, b: Value) -> float:
    """How far a driven body's farthest point moves when the driver(s) go from a to b (the input
    motion): the crank's radius times the turn, or the slider's displacement; the most of k drivers."""
    out = 0.0
    for driver, x, y in zip(linkage.drivers, driver_values(a), driver_values(b), strict=True):
        if driver.pivot is None:
            out = max(out, abs(y - x))
            continue
        pivot = np.array(linkage.ground[driver.pivot])
        radius = max(np.hypot(*(np.array(p) - pivot)) for p in linkage.bodies[driver.body].values())
        out = max(out, float(radius * abs(y - x)))
    return out


def driven_pose(linkage: Linkage, value: Value, index: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(rotation matrix, translation) of a driven body (the ``index``-th driver's) at the drivers'
    value(s)."""
    driver, value = linkage.drivers[index], float(driver_values(value)[index])
    slide = driver.slide
    if slide is not None:
        sign = 1.0 if slide.on == GROUND else -1.0
        return np.eye(2), sign * value * np.array(slide.direction)
    assert driver.pivot is not None  # a driver without a slide is a crank, turning about its pivot
    pivot = np.array(linkage.ground[driver.pivot])
    c, s = np.cos(value), np.sin(value)
    rotation = np.array([[c, -s], [s, c]])
    return rotation, pivot - rotation @ pivot


def _advance(k: Kernels, linkage: Linkage, R: np.ndarray, points: np.ndarray, start: Value, target: Value,
             halvings: int, tolerance: float = TOLERANCE) -> tuple[Solve, float]:
    """Solve at ``target`` from ``start`` in 2^halvings equal crank steps; the last solve and the
    largest point displacement of a sub-step over the crank's own motion in it."""
    parts, ratio = 2 ** halvings, 0.0
    for part in range(1, parts + 1):
        a, b = start + (target - start) * (part - 1) / parts, start + (target - start) * part / parts
        solve = newton(k, R, b, tolerance=tolerance)
        if solve.residual >= tolerance:
            return solve, np.inf
        moved = np.asarray(k.positions(solve.motors, driver_values(b))).reshape(-1)
        ratio = max(ratio, float(np.max(np.abs(moved - points))) / max(_driver_motion(linkage, a, b), 1e-300))
        R, points = solve.motors, moved
    return solve, ratio


def simulate(k: Kernels, linkage: Linkage, angles: ArrayLike, *, max_halvings: int = 8,
             jump: float = 20.0, progress: Callable[[str], None] = lambda _: None,
             phases: ArrayLike | None = None, tolerance: float = TOLERANCE) -> Trajectory:
    """Follow the driver through ``angles`` (crank angles in rad, or slider displacements, from the
    initial configuration; k drivers: steps × k values; ``phases`` their cycle phase, for the plots),
    continuing each solve from
    the previous one; the first solve assembles the initial guess (identity motors).

    A step is cut into 2, 4, … equal parts (at most 2^max_halvings) while Newton fails or some body
    point moves more than ``jump`` times as far as the crank's farthest point in a part: near a
    singular configuration the output races ahead of the input, and a large step there could land
    on the other assembly branch. A step that still fails is reported in ``failures``, and the
    configuration stays at the last solved one. ``tolerance``: max |F| at convergence (the default
    1e-12 leaves points within about 1e-12 / σ_min(J) of the exact ones)."""
    values = np.asarray(angles, dtype=float)
    if values.ndim != (1 if len(linkage.drivers) == 1 else 2) or (values.ndim == 2 and
                                                                    values.shape[1] != len(linkage.drivers)):
        raise ValueError(f"{linkage.name}: driver values of shape {values.shape}; expected (steps,) for one "
                         f"driver, (steps, k) for k drivers (k = {len(linkage.drivers)})")
    first = newton(k, identity_motors(linkage), values[0], tolerance=tolerance)
    R, previous = first.motors, values[0]
    points = np.asarray(k.positions(R, driver_values(previous))).reshape(-1)
    rows: dict[str, list[Any]] = {key: [] for key in ("motors", "points", "iterations", "residuals",
                                                      "sigma_min", "condition", "halvings")}
    failures: list[str] = [] if first.residual < tolerance else [
        f"assembly at {linkage.at(previous)}: max |F| = {first.residual:.2e}; the initial "
        f"points do not close the loop"]
    rank, unknowns = initial_rank(k, R, previous)
    if rank < unknowns:
        failures.append(f"the constraint Jacobian has rank {rank} for {unknowns} unknowns at the initial "
                        f"configuration: the mechanism is under-constrained there (or at a singular pose), "
                        f"though Grübler–Kutzbach counts {linkage.mobility()} degree(s) of freedom")
    elif rank < linkage.constraint_rows:
        failures.append(f"the constraint Jacobian has rank {rank} for {linkage.constraint_rows} constraint "
                        f"rows: {linkage.constraint_rows - rank} redundant (over-constrained) at the initial "
                        f"configuration")
    for index, target in enumerate(values):
        for halvings in range(max_halvings + 1):
            solve, ratio = _advance(k, linkage, R, points, previous, target, halvings, tolerance)
            if solve.residual < tolerance and ratio <= jump:
                break
        if solve.residual >= tolerance:
            failures.append(f"step {index} ({linkage.at(target)}): Newton stopped at max |F| = "
                            f"{solve.residual:.2e} after {solve.iterations} iterations, {halvings} halvings "
                            f"(σ_min of J {solve.sigma_min:.2e}): a singular or unreachable configuration")
        else:
            R, previous = solve.motors, target
            points = np.asarray(k.positions(R, driver_values(previous))).reshape(-1)
        rows["motors"].append(R.copy())
        rows["points"].append(points)
        rows["iterations"].append(solve.iterations)
        rows["residuals"].append(solve.residual)
        rows["sigma_min"].append(solve.sigma_min)
        rows["condition"].append(solve.condition)
        rows["halvings"].append(halvings)
        if index % 100 == 0:
            progress(f"  step {index}/{len(values)}: {linkage.at(target)}, {solve.iterations} "
                     f"iterations, max |F| {solve.residual:.1e}")
    trajectory = Trajectory(values, np.array(rows["motors"]), np.array(rows["points"]),
                            np.array(rows["iterations"]), np.array(rows["residuals"]),
                            np.array(rows["sigma_min"]), np.array(rows["condition"]),
                            np.array(rows["halvings"]), failures, rank, unknowns,
                            phases=None if phases is None else np.asarray(phases, dtype=float))
    trajectory.limits = travel_limits(linkage, trajectory)
    return trajectory


TRAVEL_TOLERANCE = 1e-9  # a slider this far beyond its travel still counts as within it


def _pose(motor: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """(rotation matrix, translation) of an SE(2) motor T(t) R(φ) on 1, e12, e1∞, e2∞."""
    c, s = motor[0], -motor[1]  # cos(φ/2), sin(φ/2)
    rotation = np.array([[c * c - s * s, -2 * s * c], [2 * s * c, c * c - s * s]])
    # (m_e1∞, m_e2∞) = −½ R(φ/2)ᵀ t, so t = −2 R(φ/2) (m_e1∞, m_e2∞)
    return rotation, -2 * np.array([[c, -s], [s, c]]) @ np.array([motor[2], motor[3]])


def travel_limits(linkage: Linkage, trajectory: Trajectory) -> list[str]:
    """Every prismatic joint whose point leaves its travel, with the driver's values where it does: the
    point's coordinate (x − through)·direction along the slot, in the frame of the body (or ground)
    that carries the slot."""
    out = []
    for number, joint in enumerate(linkage.joints):
        if not isinstance(joint, Prismatic) or joint.travel is None:
            continue
        fixed = joint.point[0] == GROUND
        column = 0 if fixed else point_index(linkage, *joint.point)
        along = []
        frames = zip(trajectory.angles, trajectory.motors, trajectory.points, strict=True)
        for angle, motors, points in frames:
            x = np.array(linkage.point(joint.point)) if fixed else points[column:column + 2]
            if joint.on != GROUND:
                if joint.on in linkage.driven:
                    rotation, shift = driven_pose(linkage, angle, linkage.driven.index(joint.on))
                else:
                    i = linkage.unknown.index(joint.on)
                    rotation, shift = _pose(motors[4 * i:4 * i + 4])
                x = rotation.T @ (x - shift)  # into the carrying body's frame
            along.append(slot_coordinate(joint, x))
        along_ = np.array(along)
        lo, hi = joint.travel
        outside = (along_ < lo - TRAVEL_TOLERANCE) | (along_ > hi + TRAVEL_TOLERANCE)
        if outside.any():
            values = trajectory.angles[outside]
            out.append(f"joint {number} ({joint.point[0]}.{joint.point[1]} in a slot of {joint.on}) leaves "
                       f"its travel [{lo:g}, {hi:g}] at {outside.sum()} step(s), "
                       f"{linkage.at(values.min())} … {linkage.at(values.max())} (from {along_.min():.4g} "
                       f"to {along_.max():.4g})")
    return out


def initial_rank(k: Kernels, motors: np.ndarray, angle: Value, relative: float = 1e-9) -> tuple[int, int]:
    """The numerical rank of J (singular values above ``relative`` × the largest) and the number of
    unknowns, at a configuration: the mobility as the constraints see it, beside Grübler–Kutzbach's count."""
    J = np.asarray(k.constraints(np.asarray(motors, dtype=float), driver_values(angle))[1])
    s = np.linalg.svd(J, compute_uv=False)
    return int(np.count_nonzero(s > relative * s[0])) if s.size else 0, J.shape[1]


def point_index(linkage: Linkage, body: str, name: str) -> int:
    """The column of a body point's x in ``Trajectory.points`` (y follows)."""
    return point_labels(linkage).index(f"{body}_{name}_x")
