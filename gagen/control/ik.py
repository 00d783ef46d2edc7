"""Inverse kinematics of a cooperative system on its task error [COOP Section 3.7, Eq. 43-47].

The problem is q* = argmin ‖e(q)‖² with e(q) = log(V_Sc(q)~ V_Sd) [Eq. 43-44], the 7 similarity
bivector coefficients between the current and the desired cooperative primitive, and J_Be = ∂e/∂q
[Eq. 47]; both come from the generated ``task`` kernel. The paper's Gauss-Newton step
q ← q − α (J_Beᵀ J_Be)⁻¹ J_Beᵀ e [Eq. 45-46] cannot be taken literally: J_Be has 7 rows and m ≥ 7
columns, so J_Beᵀ J_Be (m × m) is singular, and J_Be itself only has the rank of the primitive's
controllable bivectors (Table 1). ``solve_ik`` therefore takes the Levenberg-Marquardt step

    Δq = −(J_Beᵀ J_Be + λ I)⁻¹ J_Beᵀ e = −V diag(s / (s² + λ)) Uᵀ e      (J_Be = U diag(s) Vᵀ),

the minimum-norm Gauss-Newton step as λ → 0, with a backtracking (Armijo) line search on ‖e‖²
for α and λ adapted from the ratio of actual to predicted decrease. Joint limits are enforced by
clipping every iterate into the box, and the step is taken on the joints that are free to move: a
joint at a limit whose step would leave the box is held there and the step recomputed without it
(``_bounded_step``). Clipping the unconstrained step instead throws away its component along the
held joint and leaves only linear convergence (‖e‖ × 0.72 per iteration for the LEAP hand at a
thumb limit in Fig. 17, 50 iterations short of 1e-10).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.control.differential import RCOND
from gagen.model.similarity import DEGENERATE_BELOW

Task = Callable[[NDArray[np.float64], NDArray[np.float64]], tuple[ArrayLike, ArrayLike]]
"""task(q, V_Sd) -> (e, J_Be), e.g. ``load(folder).c.task`` (any callable returning arrays)."""

ARMIJO = 1e-4  # sufficient decrease: ‖e_new‖² <= ‖e‖² + ARMIJO · α · ∂‖e‖²/∂α
MAX_BACKTRACKS = 30
DAMPING_MIN, DAMPING_MAX = 1e-12, 1e8


@dataclass(frozen=True)
class IKResult:
    """Outcome of ``solve_ik``.

    ``q``: the last accepted iterate; ``error_norm``: ‖e(q)‖; ``iterations``: accepted steps;
    ``converged``: ‖e(q)‖ <= tol; ``history``: ‖e‖ at q0 and after every accepted step;
    ``evaluations``: calls of ``task`` (one per iteration plus one per line-search trial);
    ``status``: why the solve stopped, one of ``STATUSES``; ``message``: the same in a sentence.
    """

    q: NDArray[np.float64]
    error_norm: float
    iterations: int
    converged: bool
    history: NDArray[np.float64]
    evaluations: int = 0
    status: str = "converged"
    message: str = ""


STATUSES = {
    "converged": "‖e‖ <= tol",
    "max_iterations": "max_iterations steps taken with ‖e‖ > tol",
    "degenerate_primitive": "the spanning points are degenerate (coincident, collinear, coplanar: "
                            "conditioning 0), so V_Sc is the identity and J_Be = 0: no direction decreases "
                            "‖e‖; start from a configuration with positive conditioning",
    "stationary": "Jᵀe = 0 with ‖e‖ > tol: a stationary point of ‖e‖², e.g. an unreachable V_Sd or a "
                  "singular configuration",
    "line_search_failed": "no step length decreased ‖e‖² even with the largest damping (the "
                          "floating-point floor above a very small tol, or joint limits blocking every step)",
    "non_finite": "the task kernel returned NaN or inf",
}
"""``IKResult.status`` values and what each means."""


def _limits(limits: tuple[ArrayLike, ArrayLike] | None,
            m: int) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    if limits is None:
        return None
    lower, upper = (np.broadcast_to(np.asarray(b, dtype=float), (m,)).copy() for b in limits)
    if np.any(lower > upper):
        raise ValueError("joint limits need lower <= upper")
    return lower, upper


def _step(J: NDArray[np.float64], e: NDArray[np.float64], damping: float) -> NDArray[np.float64]:
    """Δq = −(Jᵀ J + λ I)⁻¹ Jᵀ e through the SVD of the (7 × m) J; directions with s <= RCOND · s_max
    are left out, so λ → 0 gives the minimum-norm least-squares (Gauss-Newton) step −J⁺ e."""
    u, s, vt = np.linalg.svd(J, full_matrices=False)
    keep = s > RCOND * s[0] if s.size and s[0] > 0 else np.zeros(s.shape, dtype=bool)
    filtered = np.zeros_like(s)
    filtered[keep] = s[keep] / (s[keep] ** 2 + damping)
    step: NDArray[np.float64] = -(vt.T * filtered) @ (u.T @ e)  # (numpy types svd's factors as Any arrays)
    return step


def _bounded_step(J: NDArray[np.float64], e: NDArray[np.float64], damping: float, q: NDArray[np.float64],
                  bounds: tuple[NDArray[np.float64], NDArray[np.float64]] | None) -> NDArray[np.float64]:
    """``_step`` on the free joints: a joint at a limit (q is clipped, so exactly on it) whose step
    points out of the box is held (its column of J left out) and the step recomputed, until no
    held joint would leave; at most m rounds, the held set only grows. The Gauss-Newton step then
    solves the problem the box leaves, so convergence stays quadratic at an active limit."""
    delta = _step(J, e, damping)
    if bounds is None:
        return delta
    lower, upper = bounds
    free = np.ones(q.size, dtype=bool)
    while True:
        leaving = free & (((q <= lower) & (delta < 0)) | ((q >= upper) & (delta > 0)))
        if not leaving.any():
            return delta
        free &= ~leaving
        delta = np.zeros_like(q)
        if free.any():
            delta[free] = _step(J[:, free], e, damping)


def solve_ik(task: Task, q0: ArrayLike, V_Sd: ArrayLike, *, tol: float = 1e-12, max_iterations: int = 100,
             damping: float = 1e-6, limits: tuple[ArrayLike, ArrayLike] | None = None,
             conditioning: Callable[[NDArray[np.float64]], float] | None = None) -> IKResult:
    """Solve q* = argmin ‖log(V_Sc(q)~ V_Sd)‖² [COOP Eq. 43-44] from ``q0`` by damped Gauss-Newton.

    ``task(q, V_Sd) -> (e, J_Be)`` is the generated task kernel [Eq. 44, 47] (C or CasADi on numbers);
    ``V_Sd`` holds the 12 coefficients of the desired similarity versor in the kernel's V_Sd row order.
    Each iteration takes the Levenberg-Marquardt step Δq = −(J_Beᵀ J_Be + λ I)⁻¹ J_Beᵀ e, the damped
    form of the Gauss-Newton step of Eq. 45-46 (J_Beᵀ J_Be alone is singular, J_Be being 7 × m of
    rank < 7), and q ← clip(q + α Δq) with α = 1, ½, ¼, … the first that satisfies the Armijo
    condition on ‖e‖². The damping λ starts at ``damping`` and adapts: divided by 10 after a full
    step whose decrease matches the linear model well, multiplied by 4 after a poor one and by 10
    when the line search had to shorten the step; if no step length decreases ‖e‖², λ grows by 100
    and the step is recomputed, and the solve stops once λ passes 1e8 (a stationary point of ‖e‖²
    with ‖e‖ > 0, e.g. an unreachable V_Sd, or the floating-point floor above a very small ``tol``).

    ``limits`` = (lower, upper) joint bounds (arrays of m, or scalars); q0 and every iterate are
    clipped into them, and a joint at a bound is held there while the step would leave the box.
    ``conditioning(q)``: optional, e.g. ``lambda q: module.c.similarity(q)[1]``, to tell a degenerate
    primitive from another stationary point where J_Be is not exactly zero.
    Returns an ``IKResult``; ``converged`` means ‖e‖ <= ``tol``, and ``status`` /
    ``message`` say why the solve stopped (``STATUSES``): e.g. ``degenerate_primitive`` when J_Be
    is zero at a stop because the spanning points are degenerate there. Non-finite q0, V_Sd, tol or
    damping are a ValueError.
    """
    if not all(isinstance(v, (int, float)) and math.isfinite(v) and v >= 0 for v in (tol, damping)):
        raise ValueError(f"tol and damping must be finite numbers >= 0, got {tol!r} and {damping!r}")
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, (int, np.integer)) \
            or max_iterations < 0:
        raise ValueError(f"max_iterations must be an integer >= 0, got {max_iterations!r}")
    q = np.array(q0, dtype=float).ravel()
    target = np.ascontiguousarray(V_Sd, dtype=float).ravel()
    if not np.all(np.isfinite(q)):
        raise ValueError(f"q0 must be finite, got {q}")
    if not np.all(np.isfinite(target)):
        raise ValueError(f"V_Sd must be finite, got {target}")
    bounds = _limits(limits, q.size)

    def clip(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return x if bounds is None else np.clip(x, *bounds)

    def evaluate(x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        e, J = task(x, target)
        return np.array(e, dtype=float).ravel(), np.array(J, dtype=float)  # copies (a bound kernel reuses)

    q = clip(q)
    e, J = evaluate(q)
    evaluations = 1
    if J.shape != (e.size, q.size):
        raise ValueError(f"task returned J_Be of shape {J.shape}, expected {(e.size, q.size)}")
    f = float(e @ e)
    history = [np.sqrt(f)]
    lam = max(damping, DAMPING_MIN)
    iterations = 0
    stalled = "stationary"  # why λ last had to grow
    finite = bool(np.all(np.isfinite(e)) and np.all(np.isfinite(J)))
    while finite and iterations < max_iterations and np.sqrt(f) > tol and lam <= DAMPING_MAX:
        delta = _bounded_step(J, e, lam, q, bounds)
        slope = 2.0 * float(e @ (J @ delta))  # d‖e(q + αΔ)‖²/dα at α = 0 (<= 0)
        if not slope < 0 and bounds is not None:  # nothing left on the free joints: the clipped full step
            delta = _step(J, e, lam)
            slope = 2.0 * float(e @ (J @ delta))
        if not slope < 0:  # Jᵀ e = 0 numerically: stationary
            lam *= 100.0
            stalled = "stationary"
            continue
        alpha, accepted = 1.0, None
        for _ in range(MAX_BACKTRACKS):
            trial = clip(q + alpha * delta)
            e_trial, J_trial = evaluate(trial)
            evaluations += 1
            f_trial = float(e_trial @ e_trial)
            moved = trial - q
            # Armijo on the step actually taken (clipping may shorten or bend it)
            if (np.isfinite(f_trial) and np.all(np.isfinite(J_trial))
                    and f_trial <= f + ARMIJO * 2.0 * float(e @ (J @ moved))):
                accepted = trial, e_trial, J_trial, f_trial, moved
                break
            alpha *= 0.5
        if accepted is None:
            lam *= 100.0
            stalled = "line_search_failed"
            continue
        trial, e_trial, J_trial, f_trial, moved = accepted
        if alpha == 1.0:
            residual = e + J @ moved
            predicted = f - float(residual @ residual)
            ratio = (f - f_trial) / predicted if predicted > 0 else 0.0
            if ratio > 0.75:
                lam = max(lam / 10.0, DAMPING_MIN)
            elif ratio < 0.25:
                lam = min(lam * 4.0, DAMPING_MAX)
        else:
            lam = min(lam * 10.0, DAMPING_MAX)
        q, e, J, f = trial, e_trial, J_trial, f_trial
        iterations += 1
        history.append(np.sqrt(f))
    error = float(np.sqrt(f))
    if not finite:
        status = "non_finite"
    elif error <= tol:
        status = "converged"
    elif lam <= DAMPING_MAX:
        status = "max_iterations"
    elif not np.any(J) or (conditioning is not None
                           and float(np.asarray(conditioning(q)).ravel()[0]) <= DEGENERATE_BELOW):
        status = "degenerate_primitive"  # the kernels' J_Be is exactly 0 where the primitive is degenerate
    else:
        status = stalled
    message = (f"{status} after {iterations} iterations, ‖e‖ = {error:.3g} (tol {tol:g}): "
               f"{STATUSES[status]}")
    return IKResult(q=q, error_norm=error, iterations=iterations, converged=error <= tol,
                    history=np.array(history), evaluations=evaluations, status=status, message=message)
