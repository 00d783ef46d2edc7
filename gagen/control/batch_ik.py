"""Many cooperative IK problems at once, on the CPU or the GPU: Levenberg-Marquardt on the generated
``task`` kernel (e = log(V_Sc(q)~ V_Sd) and J_Be [COOP Eq. 43-47]) for every (target, seed) pair of a
batch, vectorised over the samples with the array module that holds them (numpy with the C kernels'
column batch, CuPy with the CUDA kernels: the whole solve then stays on the device).

Per sample and iteration: the step Δq = −J_Beᵀ (J_Be J_Beᵀ + λ I)⁻¹ e (the damped least-squares step
of ``gagen.control.ik`` in its k × k form, k = 7 rows, one batched solve), clipped into the joint box;
accepted when it lowers ‖e‖², and λ shrinks (× 0.3), else it is rejected and λ grows (× 10). A target
is solved when one of its seeds reaches ‖e‖ ≤ ``tol``; ``success`` and the errors are reported per
target, as GPU IK libraries report them (cuRobo: success rate over targets, seeds per target).

Standalone on purpose (numpy or CuPy only, no other gagen import): a GPU machine runs it through the
CUDA kernels without CasADi (benchmarks/cuda_gpu.py).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

Task = Callable[[Any, Any], tuple[Any, Any]]
"""task(q (m, n), V_Sd (12, n)) -> (e (k, n), J_Be (k, m, n)) in the column layout:
``module.cuda.task`` on the device, ``module.c.task.batch_columns`` on the CPU."""

DAMPING = 1e-3  # the first λ, relative to ‖J‖² ~ 1 on the bundled arms
DAMPING_MIN, DAMPING_MAX = 1e-12, 1e8


@dataclass(frozen=True)
class BatchIK:
    """Outcome per (target, seed) sample, in the solve's array module: ``q`` (m, n), ``error`` ‖e‖ (n,);
    per target (T): ``best`` the seed with the least error, ``best_error`` its error, ``success`` its
    error ≤ tol; ``iterations`` taken."""

    q: Any
    error: Any
    best: Any
    best_error: Any
    success: Any
    iterations: int

    @property
    def success_rate(self) -> float:
        return float(self.success.astype(float).mean())


def solve_batch(task: Task, targets: Any, seeds: Any, lower: Any, upper: Any, *, iterations: int = 30,
                tol: float = 1e-9, compact_every: int = 5, xp: Any = None) -> BatchIK:
    """Solve every target (V_Sd, shape (12, T)) from every seed (q, shape (m, S)): n = T·S samples, the
    target index running slowest. ``lower``/``upper``: the joint box (m,). ``xp``: the array module
    (default: that of ``targets``). Every ``compact_every`` iterations the samples of the targets solved
    by then are set aside, so that the work shrinks as targets are solved (0: never)."""
    if xp is None:
        xp = _array_module(targets)
    _check(xp, targets, seeds, lower, upper, iterations, tol)
    T, S = targets.shape[1], seeds.shape[1]
    n = T * S
    lower, upper = xp.asarray(lower)[:, None], xp.asarray(upper)[:, None]
    alive = xp.arange(n)  # the samples still iterated, sample t·S + s
    V = xp.repeat(targets, S, axis=1)
    q = xp.clip(xp.tile(seeds, (1, T)), lower, upper)
    e, J = task(q, V)
    cost = (e * e).sum(axis=0)
    damping = xp.full(cost.shape, DAMPING)
    final_q, final_cost = q.copy(), cost.copy()
    eye = xp.eye(e.shape[0])[None]
    for iteration in range(1, iterations + 1):
        Jn = xp.moveaxis(J, -1, 0)  # (n, k, m)
        A = Jn @ xp.swapaxes(Jn, 1, 2) + damping[:, None, None] * eye
        y = xp.linalg.solve(A, xp.moveaxis(e, -1, 0)[:, :, None])  # (n, k, 1)
        step = -(xp.swapaxes(Jn, 1, 2) @ y)[:, :, 0].T  # (m, n)
        trial = xp.clip(q + step, lower, upper)
        e_new, J_new = task(xp.ascontiguousarray(trial), V)
        cost_new = (e_new * e_new).sum(axis=0)
        better = cost_new < cost  # NaN never is: a degenerate trial is rejected
        q = xp.where(better[None], trial, q)
        e = xp.where(better[None], e_new, e)
        J = xp.where(better[None, None], J_new, J)
        cost = xp.where(better, cost_new, cost)
        damping = xp.clip(xp.where(better, damping * 0.3, damping * 10.0), DAMPING_MIN, DAMPING_MAX)
        if compact_every and iteration % compact_every == 0 and iteration < iterations:
            final_q[:, alive], final_cost[alive] = q, cost
            solved = (final_cost.reshape(T, S) <= tol * tol).any(axis=1)
            keep = ~solved[alive // S]
            if not bool(keep.all()):
                alive, V, q, e, J = alive[keep], V[:, keep], q[:, keep], e[:, keep], J[:, :, keep]
                cost, damping = cost[keep], damping[keep]
                if alive.size == 0:
                    break
    final_q[:, alive], final_cost[alive] = q, cost
    error = xp.sqrt(final_cost)
    per_target = error.reshape(T, S)
    best = per_target.argmin(axis=1)
    best_error = per_target.min(axis=1)
    return BatchIK(final_q, error, best, best_error, best_error <= tol, iterations)


def _check(xp: Any, targets: Any, seeds: Any, lower: Any, upper: Any, iterations: int, tol: float) -> None:
    """One-line ValueErrors for what the solve cannot take (a NaN target only fails its own target)."""
    if getattr(targets, "ndim", 0) != 2 or targets.shape[0] != 12 or targets.shape[1] < 1:
        raise ValueError(f"targets must be V_Sd columns of shape (12, T), T >= 1; got shape "
                         f"{getattr(targets, 'shape', None)}")
    m = getattr(seeds, "shape", (0, 0))[0]
    if getattr(seeds, "ndim", 0) != 2 or seeds.shape[1] < 1 or not bool(xp.isfinite(seeds).all()):
        raise ValueError(f"seeds must be finite joint columns of shape (m, S), S >= 1; got shape "
                         f"{getattr(seeds, 'shape', None)}")
    low, high = xp.asarray(lower), xp.asarray(upper)
    if low.shape != (m,) or high.shape != (m,) or not bool(xp.all(low <= high)) or \
            bool(xp.isnan(low).any() | xp.isnan(high).any()):
        raise ValueError(f"lower and upper must be ({m},) joint bounds with lower <= upper; got shapes "
                         f"{low.shape} and {high.shape}")
    if not (isinstance(iterations, int) and iterations >= 1) or not (tol > 0 and tol < float("inf")):
        raise ValueError(f"iterations must be a positive int and tol a positive number; got {iterations!r}, "
                         f"{tol!r}")


def _array_module(a: Any) -> Any:
    if type(a).__module__.startswith("cupy"):
        import cupy

        return cupy
    import numpy

    return numpy
