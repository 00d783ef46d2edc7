"""Numerical IK of a leg: damped least squares iterated on the generated step kernel ``<leg>_dls``
(or on the formula on the interpreter), for legs the analytic IK does not cover and as its check."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

DLSStep = Callable[[np.ndarray, np.ndarray, np.ndarray], tuple[Any, Any]]


@dataclass(frozen=True)
class DLSResult:
    q: np.ndarray
    iterations: int
    error: float  # |target − p(q)| at the returned q (m)
    converged: bool


def solve_dls(step: DLSStep, q0: Sequence[float], target: Sequence[float], *, damping: float = 1e-2,
              tolerance: float = 1e-13, max_iterations: int = 200) -> DLSResult:
    """Iterate q ← q + Jᵀ(J Jᵀ + λ² I)⁻¹ (target − p(q)) from ``q0`` until |target − p| < tolerance.

    ``step(q, target, [λ]) -> (q_next, error)`` is the compiled ``<leg>_dls`` kernel (its error is the
    one at q, before the step). Not converging within ``max_iterations`` (an unreachable target: DLS
    then settles at the nearest pose) is reported by ``converged`` = False, never by a NaN."""
    q = np.array(q0, dtype=float)
    goal = np.array(target, dtype=float)
    if q.shape != (3,) or goal.shape != (3,):
        raise ValueError(f"solve_dls: expected q0 and target of 3 numbers, got shapes {q.shape} and "
                         f"{goal.shape}")
    if not np.all(np.isfinite(q)) or not np.all(np.isfinite(goal)):
        raise ValueError("solve_dls: q0 and target must be finite")
    if not damping > 0:
        raise ValueError(f"solve_dls: damping must be > 0, got {damping}")
    lam = np.array([damping])
    error = np.inf
    for iteration in range(max_iterations + 1):
        q_next, err = step(q, goal, lam)
        error = float(np.asarray(err).reshape(-1)[0])
        if error < tolerance or iteration == max_iterations:
            return DLSResult(q, iteration, error, error < tolerance)
        q = np.asarray(q_next, dtype=float).reshape(3)
    raise AssertionError("unreachable")
