"""Singular configurations of a linkage along its driven cycle, from the constraint Jacobian [LINK 4].

At a configuration R and driver value θ the constraints F(R, θ) = 0 have two Jacobians: J_q = ∂F/∂ε
with respect to the passive bodies (the solver's J, square for a mechanism without redundant joints),
and the full one [J_q | ∂F/∂θ] with the driver's column besides. Along the solution curve:

- σ_min(J_q) → 0 with the full Jacobian regular is a **dead centre**: a fold of the curve where the
  driver's value reaches a limit of its range (a double-rocker's input where coupler and output
  align; a crank-rocker driven by its rocker where crank and coupler align). The driver cannot go
  further; the curve goes on, back, on the other assembly branch.
- σ_min of the full Jacobian → 0 too is a **branch point** (a bifurcation): two branches of the curve
  cross there (a Grashof change-point linkage, s + l = p + q, folded flat). The driver passes it, and
  may go on along either branch.

:func:`analyse` follows the driver in equal steps from the initial configuration. The test function
τ = sign(det J_q) σ_min(J_q) changes sign across a branch point: the crossing is bracketed between
two steps and located by bisection on the driver's value (each value solved by Newton from a tangent
predictor, so it stays on the branch being followed). A dead centre shows as the first value Newton
cannot solve; it is bracketed between the last solved value and that one and located by bisection on
solvability. Both stop when the bracket is 1e-12 (relative) wide. With ``switch`` the analysis goes on
past each singular point on the other branch: at a dead centre it turns the driver back along the
other assembly branch (so a double-rocker's whole closed cycle is followed), at a branch point it
takes the other branch forward. The other branch is found by Newton from the configuration pushed
along J_q's null vector (by ±√δ at a fold, ±δ at a crossing, δ the driver's step from the singular
value), accepting only a solution distinct from the branch followed so far.

∂F/∂θ is a five-point central difference of F (step 1e-3, error about 1e-13); it is used only to
classify (σ_min of the full Jacobian) and to predict, never in the residuals that locate the points.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gagen.apps.linkage.kernels import identity_motors
from gagen.apps.linkage.solver import Kernels, _driver_motion, newton
from gagen.apps.linkage.spec import Linkage

LOCATE_TOLERANCE = 1e-12  # the bracket's width at the end, relative to max(1, |θ|)
BRANCH_RATIO = 1e-6  # σ_min(full) / σ_max(full) below this at a located point: a branch point
SOLVE_TOLERANCE = 1e-13  # max |F| for the solves along the path and in the brackets
SOLVE_ITERATIONS = 100  # Newton converges only linearly at a fold: room for it
DIFFERENCE = 1e-3  # the step of ∂F/∂θ's five-point central difference (error ~h⁴ and 1e-16/h: ~1e-13)
BRANCH_WINDOW = 1e-4  # a branch point's final bracket half-width and sampling step (driver units)
DEAD_CENTRE, BRANCH_POINT = "dead centre", "branch point"


@dataclass
class _At:
    """The last solved point of a bisection: its motors, driver value and tangent."""

    motors: np.ndarray
    value: float
    tangent: np.ndarray


@dataclass
class Singularity:
    kind: str  # DEAD_CENTRE or BRANCH_POINT
    value: float  # the driver's value there (rad for a crank, m for a slider)
    index: int  # its point on the followed path
    sigma_passive: float  # σ_min(J_q) at the located configuration
    sigma_full: float  # σ_min([J_q | ∂F/∂θ]) there
    motors: np.ndarray
    switched: bool = False  # whether the analysis went on along the other branch


@dataclass
class Analysis:
    values: np.ndarray  # the driver's value at each point of the followed path
    motors: np.ndarray  # (points, 4 × moving bodies)
    points: np.ndarray  # (points, 2 × named body points)
    tau: np.ndarray  # sign(det J_q) σ_min(J_q) per point (σ_min alone where J_q is not square)
    sigma_full: np.ndarray  # σ_min of the full Jacobian per point
    residuals: np.ndarray
    singularities: list[Singularity] = field(default_factory=list)
    closed: bool = False  # the path came back to its first configuration
    failures: list[str] = field(default_factory=list)


def jacobians(k: Kernels, motors: np.ndarray, value: float) -> tuple[np.ndarray, np.ndarray]:
    """(J_q, ∂F/∂θ) at a configuration: the passive Jacobian and the driver's column."""
    J = np.asarray(k.constraints(motors, np.array([value]))[1], dtype=float)
    h = DIFFERENCE
    F = [np.asarray(k.constraints(motors, np.array([value + s * h]))[0], dtype=float).reshape(-1)
         for s in (-2, -1, 1, 2)]
    return J.reshape(len(F[0]), -1), (F[0] - 8 * F[1] + 8 * F[2] - F[3]) / (12 * h)


def measures(k: Kernels, motors: np.ndarray, value: float) -> tuple[float, float, np.ndarray, np.ndarray]:
    """τ = sign(det J_q) σ_min(J_q), σ_min of the full Jacobian, J_q's null vector (its last right
    singular vector) and the tangent dε/dθ = −J_q⁺ ∂F/∂θ (least squares)."""
    Jq, Jt = jacobians(k, motors, value)
    _, s, Vt = np.linalg.svd(Jq)
    sign = float(np.sign(np.linalg.det(Jq))) if Jq.shape[0] == Jq.shape[1] else 1.0
    full = np.linalg.svd(np.column_stack([Jq, Jt]), compute_uv=False)
    tangent = -np.linalg.lstsq(Jq, Jt, rcond=1e-13)[0]
    return sign * float(s[-1]), float(full[-1]), Vt[-1], tangent


def _newton(k: Kernels, motors: np.ndarray, value: float) -> np.ndarray | None:
    """Newton to SOLVE_TOLERANCE, or None (not converged, or diverged to non-finite motors)."""
    if not np.all(np.isfinite(motors)):
        return None
    try:
        solve = newton(k, motors, value, tolerance=SOLVE_TOLERANCE, max_iterations=SOLVE_ITERATIONS)
    except np.linalg.LinAlgError:  # non-finite J after a divergent iteration
        return None
    ok = solve.residual < SOLVE_TOLERANCE and np.all(np.isfinite(solve.motors))
    return solve.motors if ok else None


def _size(linkage: Linkage) -> float:
    xy = np.array([p for points in linkage.bodies.values() for p in points.values()], dtype=float)
    return float(np.ptp(xy, axis=0).max()) or 1.0


class _Follower:
    """Solves along one branch: Newton from a predictor, accepted only close to where it started."""

    def __init__(self, k: Kernels, linkage: Linkage, jump: float = 20.0):
        self.k, self.linkage, self.jump = k, linkage, jump
        self.size = _size(linkage)

    def positions(self, motors: np.ndarray, value: float) -> np.ndarray:
        return np.asarray(self.k.positions(motors, np.array([value]))).reshape(-1)

    def solve(self, motors: np.ndarray, value: float, target: float,
              tangent: np.ndarray | None = None, fold: bool = True) -> np.ndarray | None:
        """The configuration at ``target`` continuing from (motors, value), or None: Newton from the
        tangent's prediction, accepted if it converges and no point moves more than ``jump`` times the
        driver's motion (plus, with ``fold``, a fold's √ growth)."""
        predicted = None if tangent is None else (target - value) * tangent
        if predicted is not None and np.abs(predicted).max() > 0.1:  # near a fold the tangent blows up
            predicted = None
        start = motors if predicted is None else np.asarray(self.k.retract(motors, predicted))
        solved = _newton(self.k, np.asarray(start).reshape(-1), target)
        if solved is None:
            return None
        moved = float(np.abs(self.positions(solved, target) - self.positions(motors, value)).max())
        motion = _driver_motion(self.linkage, value, target)
        if moved > self.jump * motion + (self.size * np.sqrt(abs(target - value)) if fold else 0.0):
            return None
        return solved

    def other(self, motors: np.ndarray, value: float, null: np.ndarray, scale: float,
              base: np.ndarray | None = None) -> np.ndarray | None:
        """A solution at ``value`` distinct from ``motors`` (a solution there), found by Newton from
        ``base`` (default ``motors``) pushed by ±c·scale along ``null`` (J_q's null vector at the
        singular point)."""
        here = self.positions(motors, value)
        base = motors if base is None else base
        for c in (1.0, 2.0, 0.5, 4.0, 0.25, 8.0):
            for sign in (1.0, -1.0):
                start = np.asarray(self.k.retract(base, sign * c * scale * null)).reshape(-1)
                solved = _newton(self.k, start, value)
                if solved is None:
                    continue
                apart = float(np.abs(self.positions(solved, value) - here).max())
                if 1e-6 * self.size < apart < 20 * c * scale * self.size + 1e-3 * self.size:
                    return solved
        return None


def _bisect(lo: float, hi: float, good: Callable[[float], bool]) -> tuple[float, float]:
    """Shrink [lo, hi] (good(lo), not good(hi); either order) to LOCATE_TOLERANCE."""
    while abs(hi - lo) > LOCATE_TOLERANCE * max(1.0, abs(lo)):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if good(mid):
            lo = mid
        else:
            hi = mid
    return lo, hi


def analyse(k: Kernels, linkage: Linkage, steps: int = 360, *, span: float | None = None,
            switch: bool = False, max_steps: int | None = None,
            progress: Callable[[str], None] = lambda _: None) -> Analysis:
    """Follow the driver from the initial configuration in ``steps`` equal steps per ``span`` (a crank:
    2π; a slider: its stroke's length), locating every singular configuration on the way (module
    docstring). Without ``switch`` the path ends at the first dead centre; with it, it turns back
    there along the other branch, and takes the other branch at a branch point. The path ends where
    it closes (back at its first configuration), after ``max_steps`` steps (default 2 × steps), or,
    for a slider, at the end of its stroke."""
    if len(linkage.drivers) != 1:
        raise ValueError(f"{linkage.name}: the singularity analysis follows one driver; this mechanism has "
                         f"{len(linkage.drivers)} (mobility {linkage.mobility()})")
    slider = linkage.driver.slide is not None
    bounds = linkage.stroke() if slider else (-np.inf, np.inf)
    span = span if span is not None else (bounds[1] - bounds[0] if slider else 2 * np.pi)
    h = np.copysign(span / steps, linkage.driver.rate)
    limit = max_steps if max_steps is not None else 2 * steps
    follow = _Follower(k, linkage)
    assembled = _newton(k, identity_motors(linkage), 0.0)
    if assembled is None:
        raise ValueError(f"{linkage.name}: the initial configuration does not assemble to max |F| < "
                         f"{SOLVE_TOLERANCE:g}")
    found: list[Singularity] = []
    failures: list[str] = []
    closed = False
    rows: dict[str, list[object]] = {key: [] for key in ("values", "motors", "points", "tau", "sigma_full",
                                                        "residuals")}

    def record(motors: np.ndarray, value: float) -> tuple[float, np.ndarray, np.ndarray]:
        tau, full, null, tangent = measures(k, motors, value)
        F = np.asarray(k.constraints(motors, np.array([value]))[0]).reshape(-1)
        for key, item in (("values", value), ("motors", motors.copy()),
                          ("points", follow.positions(motors, value)), ("tau", tau), ("sigma_full", full),
                          ("residuals", float(np.abs(F).max()))):
            rows[key].append(item)
        return tau, null, tangent

    R, value = assembled, 0.0
    tau, null, tangent = record(R, value)
    start = follow.positions(R, value)
    direction = 1.0
    for step in range(limit):
        target = value + direction * h
        if slider and not bounds[0] - 1e-12 <= target <= bounds[1] + 1e-12:
            break
        if len(rows["values"]) > 1 and value * target <= 0 < abs(target):  # passing the start value
            at_start = follow.solve(R, value, 0.0, tangent, fold=False)
            if at_start is not None and float(np.abs(follow.positions(at_start, 0.0) - start).max()) < \
                    1e-9 * follow.size:
                record(at_start, 0.0)
                closed = True
                break
        moved = follow.solve(R, value, target, tangent)
        if moved is None:  # no solution ahead on this branch: a dead centre between value and target
            singular, null = _dead_centre(k, follow, R, value, target, tangent)
            singular.index = len(rows["values"])
            record(singular.motors, singular.value)  # the path point at the singular configuration
            found.append(singular)
            progress(f"  {singular.kind} at {linkage.at(singular.value)} (σ_min(J_q) "
                     f"{singular.sigma_passive:.1e}, full {singular.sigma_full:.1e})")
            if not switch:
                break
            back = singular.value - direction * 0.5 * abs(h)  # half a step back, on the other branch
            near = follow.solve(R, value, back, tangent)  # the branch followed so far, there
            reach = _fold_reach(k, singular.motors, singular.value, back)
            other = None if near is None or reach is None else \
                follow.other(near, back, null, reach, base=singular.motors)
            if other is None:
                failures.append(f"no other branch found at the dead centre {linkage.at(singular.value)}")
                break
            singular.switched = True
            direction = -direction
            R, value = other, back
            tau, null, tangent = record(R, value)
            continue
        new_tau = measures(k, moved, target)[0]
        if np.sign(new_tau) != np.sign(tau) and tau != 0:
            singular = _branch_point(k, follow, R, value, target, tangent, tau)
            singular.index = len(rows["values"])
            record(singular.motors, singular.value)
            found.append(singular)
            progress(f"  {singular.kind} at {linkage.at(singular.value)} (σ_min(J_q) "
                     f"{singular.sigma_passive:.1e}, full {singular.sigma_full:.1e})")
            if switch and singular.kind == BRANCH_POINT:
                _, _, sing_null, _ = measures(k, singular.motors, singular.value)
                other = follow.other(moved, target, sing_null, abs(target - singular.value))
                if other is None:
                    failures.append(f"no other branch found at the branch point "
                                        f"{linkage.at(singular.value)}")
                else:
                    singular.switched = True
                    moved = other
        R, value = moved, target
        tau, null, tangent = record(R, value)
        if float(np.abs(follow.positions(R, value) - start).max()) < 1e-9 * follow.size:
            closed = True  # a crank's whole turn: back at the start value and configuration
            break
        if step % 100 == 0:
            progress(f"  step {step}: {linkage.at(value)}, σ_min(J_q) {abs(tau):.3e}")
    return Analysis(np.array(rows["values"], dtype=float), np.array(rows["motors"]), np.array(rows["points"]),
                    np.array(rows["tau"], dtype=float), np.array(rows["sigma_full"], dtype=float),
                    np.array(rows["residuals"], dtype=float), found, closed, failures)


def _classify(k: Kernels, motors: np.ndarray, value: float) -> Singularity:
    Jq, Jt = jacobians(k, motors, value)
    passive = np.linalg.svd(Jq, compute_uv=False)
    full = np.linalg.svd(np.column_stack([Jq, Jt]), compute_uv=False)
    kind = BRANCH_POINT if full[-1] < BRANCH_RATIO * full[0] else DEAD_CENTRE
    return Singularity(kind, value, -1, float(passive[-1]), float(full[-1]), motors.copy())


def _dead_centre(k: Kernels, follow: _Follower, R: np.ndarray, value: float, target: float,
                 tangent: np.ndarray) -> tuple[Singularity, np.ndarray]:
    """The last solvable driver value between ``value`` (solved: R) and ``target`` (not), by bisection
    on solvability, each trial continued from the last solvable one; the singularity there and J_q's
    null vector."""
    state = _At(R, value, tangent)

    def solvable(x: float) -> bool:
        moved = follow.solve(state.motors, state.value, x, state.tangent)
        if moved is None:
            return False
        state.motors, state.value, state.tangent = moved, x, measures(k, moved, x)[3]
        return True

    _bisect(value, target, solvable)
    singular = _classify(k, state.motors, state.value)
    return singular, measures(k, state.motors, state.value)[2]


def _fold_reach(k: Kernels, motors: np.ndarray, value: float, back: float) -> float | None:
    """How far along J_q's null vector v the two branches lie from a fold (motors, value) at the
    driver value ``back``: with φ the left null vector, φ·F(q* + s v, θ) ≈ ½ κ s² + β (θ − θ*),
    κ = φ·∂²F[v, v] (a difference of F along v) and β = φ·∂F/∂θ, so s = √(−2 β (back − θ*) / κ)."""
    Jq, Jt = jacobians(k, motors, value)
    U, _, Vt = np.linalg.svd(Jq)
    phi, v, eps = U[:, -1], Vt[-1], 1e-3
    bent = [float(phi @ np.asarray(k.constraints(np.asarray(k.retract(motors, s * v)).reshape(-1),
                                                  np.array([value]))[0]).reshape(-1)) for s in (eps, -eps)]
    kappa = (bent[0] + bent[1]) / eps ** 2  # the second difference (φ·F(q*) ≈ 0 cancels)
    square = -2 * float(phi @ Jt) * (back - value) / kappa if kappa != 0 else -1.0
    return float(np.sqrt(square)) if square > 0 else None


def _polish(k: Kernels, motors: np.ndarray, value: float) -> np.ndarray:
    """A few more Newton iterations, to rounding: near a branch point a residual of 1e-13 leaves the
    configuration off by 1e-13 / σ_min(J_q) along the null vector, which would blur τ."""
    solve = newton(k, motors, value, tolerance=0.0, max_iterations=4)
    return solve.motors if np.all(np.isfinite(solve.motors)) else motors


def _branch_point(k: Kernels, follow: _Follower, R: np.ndarray, value: float, target: float,
                  tangent: np.ndarray, tau: float) -> Singularity:
    """Where τ changes sign between ``value`` (τ there) and ``target``: bisection on the driver's value
    (each trial solved from the bracket's near end along its tangent) down to a bracket of
    ``2 w`` (w = BRANCH_WINDOW), then the root of the degree-5 polynomial through det J_q at six values
    c ± (1, 2, 3) w about its centre c, solved in order along the branch and polished to rounding.
    Closer to the crossing than w the configuration itself is determined only to √(rounding) (two
    branches meet), so τ there is noise; det J_q at ≥ w from it is accurate and smooth."""
    state = _At(R, value, tangent)

    def same_sign(x: float) -> bool:
        moved = follow.solve(state.motors, state.value, x, state.tangent)
        if moved is None:
            return False
        t, _, _, tangent_x = measures(k, moved, x)
        if np.sign(t) == np.sign(tau):
            state.motors, state.value, state.tangent = moved, x, tangent_x
            return True
        return False

    lo, hi = value, target
    while abs(hi - lo) > 2 * BRANCH_WINDOW:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if same_sign(mid) else (lo, mid)
    centre, sign = 0.5 * (lo + hi), np.sign(target - value)
    offsets = sign * BRANCH_WINDOW * np.array([-3.0, -2.0, -1.0, 1.0, 2.0, 3.0])
    Rx, x0, dets = state.motors, state.value, []
    for offset in offsets:
        t = measures(k, Rx, x0)[3]
        moved = follow.solve(Rx, x0, centre + offset, t)
        if moved is None:
            break
        Rx, x0 = _polish(k, moved, centre + offset), centre + offset
        dets.append(float(np.linalg.det(jacobians(k, Rx, x0)[0])))
    at = centre
    if len(dets) == len(offsets):
        roots = np.roots(np.polyfit(offsets / BRANCH_WINDOW, dets, len(offsets) - 1))
        real = roots[np.abs(roots.imag) < 1e-9].real
        real = real[np.abs(real) <= 1.5]
        if real.size:
            at = centre + BRANCH_WINDOW * float(real[np.argmin(np.abs(real))])
    moved = follow.solve(state.motors, state.value, at, state.tangent)
    return _classify(k, moved if moved is not None else state.motors, at if moved is not None else lo)


def table(linkage: Linkage, analysis: Analysis) -> str:
    """The singular points found, one line each."""
    unit = "°" if linkage.driver.slide is None else ""
    scale = 180 / np.pi if linkage.driver.slide is None else 1.0
    lines = [f"{'kind':<13} {'driver ' + linkage.driver.input:>18} {'σ_min(J_q)':>11} {'σ_min(full)':>12} "
             f"{'path point':>10}  branch"]
    for s in analysis.singularities:
        lines.append(f"{s.kind:<13} {s.value * scale:>17.12f}{unit or ' '} {s.sigma_passive:>11.2e} "
                     f"{s.sigma_full:>12.2e} {s.index:>10}  {'switched' if s.switched else 'kept'}")
    if not analysis.singularities:
        lines.append("(none: J_q stays regular along the path)")
    return "\n".join(lines)


def four_bar_text(name: str, ground: float, crank: float, coupler: float, rocker: float, angle: float,
                  driver: str = "crank", side: int = 1) -> str:
    """A four-bar spec (pivots A = (0, 0), D = (ground, 0); crank A–B at ``angle`` rad, coupler B–C,
    rocker C–D; C left (side 1) or right (−1) of B → D), driven by its ``crank`` (about A) or its
    ``rocker`` (about D): the Grashof cases of the tests and docs."""
    from gagen.apps.linkage.assemble import intersect

    A, D = np.zeros(2), np.array([ground, 0.0])
    B = crank * np.array([np.cos(angle), np.sin(angle)])
    C = intersect(B, coupler, D, rocker, side)
    if not np.all(np.isfinite(C)):
        raise ValueError(f"four_bar_text: the loop does not close at the crank angle {angle!r}")

    def xy(p: np.ndarray) -> str:
        return f"[{float(p[0])!r}, {float(p[1])!r}]"

    pivot = "A" if driver == "crank" else "D"
    return (f"app: linkage\nname: {name}\nground: {{A: {xy(A)}, D: {xy(D)}}}\nbodies:\n"
            f"  crank: {{A: {xy(A)}, B: {xy(B)}}}\n  coupler: {{B: {xy(B)}, C: {xy(C)}}}\n"
            f"  rocker: {{C: {xy(C)}, D: {xy(D)}}}\njoints:\n  - {{revolute: [crank.A, ground.A]}}\n"
            f"  - {{revolute: [crank.B, coupler.B]}}\n  - {{revolute: [coupler.C, rocker.C]}}\n"
            f"  - {{revolute: [rocker.D, ground.D]}}\ndriver: {{body: {driver}, pivot: ground.{pivot}}}\n"
            f"trace: coupler.C\n")


def plot(linkage: Linkage, analysis: Analysis, path: str | Path) -> Path:
    """σ_min(J_q) and σ_min of the full Jacobian (log) over the followed path, and the driver's value,
    the singular points marked (a dead centre ▲, a branch point ◆) and labelled with their value."""
    from gagen.apps.linkage.plots import _figure

    fig = _figure((9, 6))
    drive, sigma = fig.add_subplot(2, 1, 1), fig.add_subplot(2, 1, 2)
    crank = linkage.driver.slide is None
    scale, unit = (180 / np.pi, "°") if crank else (1.0, "")
    n = np.arange(len(analysis.values))
    drive.plot(n, analysis.values * scale, ".-", ms=2, lw=0.8, color="C0")
    drive.set_ylabel(f"driver {linkage.driver.input} [{unit or 'm'}]")
    floor = 1e-16
    sigma.semilogy(n, np.maximum(np.abs(analysis.tau), floor), color="C2", label="σ_min(J_q) (passive)")
    sigma.semilogy(n, np.maximum(analysis.sigma_full, floor), color="C1", label="σ_min([J_q | ∂F/∂θ]) (full)")
    for s in analysis.singularities:
        marker, colour = ("^", "C3") if s.kind == DEAD_CENTRE else ("D", "C4")
        x = s.index
        sigma.semilogy([x], [max(s.sigma_passive, floor)], marker, color=colour, ms=8,
                       label=f"{s.kind} {s.value * scale:.6f}{unit}")
        drive.plot([x], [s.value * scale], marker, color=colour, ms=8)
        for ax in (drive, sigma):
            ax.axvline(x, color=colour, ls=":", lw=0.8)
    sigma.set_xlabel("point along the followed path (driver steps; past a dead centre the driver turns back)")
    sigma.set_ylabel("smallest singular value")
    sigma.legend(fontsize=8, loc="lower right")
    for ax in (drive, sigma):
        ax.grid(alpha=0.3)
        ax.set_xlim(0, max(len(n) - 1, 1))
    closed = "closed" if analysis.closed else "open"
    fig.suptitle(f"{linkage.name}: singular configurations along the driven cycle ({len(n)} points, {closed} "
                 f"path)", fontsize=11)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=90)
    return out
