"""The cooperative reaching problem that every solver of it shares [COOP Eq. 53-57]: the double integrator
q̈ = u discretised exactly, weights, checks of the start, the target and the horizon, and the result.
``ocp`` solves it with IPOPT or FATROP, ``ilqr`` with the structured iLQR."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

BLADES = ("e12", "e13", "e23", "e0inf", "e1inf", "e2inf", "e3inf")
"""Rows of e, J_Be and J_G,Sc: the similarity bivector coefficients."""

DEFAULT_HORIZON = 2.5  # s, the paper's planning horizon
DEFAULT_N = 100
DEFAULT_TOL = 1e-9  # on ‖e(q_N)‖, for exact=True
DEFAULT_R = 1e-6
DEFAULT_Q = 1.0


def double_integrator(m: int, dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Exact discretisation of q̈ = u over a step dt with u held constant [Eq. 54-55]: (A, B)."""
    eye = np.eye(m)
    A = np.block([[eye, dt * eye], [np.zeros((m, m)), eye]])
    B = np.vstack([0.5 * dt * dt * eye, dt * eye])
    return A, B


def weight(value: ArrayLike, size: int, name: str) -> NDArray[np.float64]:
    """A scalar (× I), a diagonal (vector) or a full symmetric matrix, as a size × size matrix."""
    w = np.asarray(value, dtype=float)
    if w.ndim == 0:
        w = float(w) * np.eye(size)
    elif w.ndim == 1:
        if w.size != size:
            raise ValueError(f"{name}: a diagonal of {size} weights, got {w.size}")
        w = np.diag(w)
    if w.shape != (size, size):
        raise ValueError(f"{name}: expected a scalar, {size} weights or a {size}×{size} matrix, "
                         f"got {w.shape}")
    if not np.allclose(w, w.T) or np.linalg.eigvalsh(w).min() < -1e-12 * max(1.0, np.abs(w).max()):
        raise ValueError(f"{name} must be symmetric positive semidefinite")
    return w


@dataclass(frozen=True)
class OCPResult:
    """Outcome of ``reach`` / ``ReachingOCP.solve``.

    ``q``, ``qdot``: (N+1, m) joint positions and velocities at t_k = k Δt (row 0 is the start);
    ``u``: (N, m) accelerations; ``error``: e(q_N) (7 coefficients, rows ``BLADES``) and
    ``error_norm`` its norm; ``shift``, ``updates``: the final shift s of the terminal error and the
    number of multiplier updates (0 for the plain penalty problem); ``iterations``: IPOPT iterations
    and ``wall_time``: seconds in the solver calls, both summed over the updates (``function_time``:
    the part of it spent evaluating the NLP's CasADi Functions, the rest is IPOPT's own; ``build_time``:
    building the NLP and IPOPT's derivative functions, 0 when the NLP came from the cache);
    ``success``: IPOPT's return status (``status``, of the last solve) is one of ``IPOPT_SUCCESS``
    (FATROP's return flag 0 reads "Solve_Succeeded") and, for ``exact``, ‖e(q_N)‖ <= tol; ``message``:
    why it succeeded or not, in a sentence; ``w``, ``lam_x``, ``lam_g``: the raw primal-dual solution
    (warm starts); ``solver``: which solver produced it ("ipopt", "fatrop", …).
    """

    q: NDArray[np.float64]
    qdot: NDArray[np.float64]
    u: NDArray[np.float64]
    dt: float
    V_Sd: NDArray[np.float64]
    error: NDArray[np.float64]
    error_norm: float
    shift: NDArray[np.float64]
    updates: int
    objective: float
    iterations: int
    wall_time: float
    function_time: float
    build_time: float
    success: bool
    status: str
    w: NDArray[np.float64] = field(repr=False)
    lam_x: NDArray[np.float64] = field(repr=False)
    lam_g: NDArray[np.float64] = field(repr=False)
    message: str = ""
    solver: str = "ipopt"

    @property
    def N(self) -> int:
        return len(self.u)  # (N, m)

    @property
    def t(self) -> NDArray[np.float64]:
        """Times of the N + 1 states."""
        return np.arange(self.N + 1, dtype=np.float64) * self.dt

    def dynamics_residual(self) -> float:
        """max |x_{k+1} − A x_k − B u_k| over the trajectory (IPOPT's primal infeasibility)."""
        m = self.q.shape[1]
        A, B = double_integrator(m, self.dt)
        x = np.hstack([self.q, self.qdot])
        return float(np.abs(x[1:] - x[:-1] @ A.T - self.u @ B.T).max())


def check_horizon(N: int, horizon: float) -> None:
    """ValueError unless N is an integer >= 1 and the horizon a finite number > 0 (seconds)."""
    if isinstance(N, bool) or not isinstance(N, (int, np.integer)) or N < 1:
        raise ValueError(f"N must be an integer >= 1 (time steps), got {N!r}")
    if isinstance(horizon, bool) or not isinstance(horizon, (int, float, np.floating)) \
            or not math.isfinite(horizon) or horizon <= 0:
        raise ValueError(f"horizon must be a finite number of seconds > 0, got {horizon!r}")


def start_and_target(q0: ArrayLike, qdot0: ArrayLike | None, V_Sd: ArrayLike,
                     m: int) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(q0, q̇0 (zeros when None), V_Sd) as flat float arrays; ValueError unless m, m and 12 finite values."""
    q0 = np.asarray(q0, dtype=float).ravel()
    qdot0 = np.zeros(m) if qdot0 is None else np.asarray(qdot0, dtype=float).ravel()
    V_Sd = np.asarray(V_Sd, dtype=float).ravel()
    if q0.size != m or qdot0.size != m or V_Sd.size != 12:
        raise ValueError(f"need q0 and qdot0 of {m} values and V_Sd of 12, got {q0.size}, {qdot0.size}, "
                         f"{V_Sd.size}")
    for name, value in (("q0", q0), ("qdot0", qdot0), ("V_Sd", V_Sd)):
        if not np.all(np.isfinite(value)):
            raise ValueError(f"{name} must be finite, got {value}")
    return q0, qdot0, V_Sd


def box(bounds: tuple[ArrayLike, ArrayLike], m: int,
        name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    lower, upper = (np.broadcast_to(np.asarray(b, dtype=float), (m,)).copy() for b in bounds)
    if np.any(lower > upper):
        raise ValueError(f"{name} need lower <= upper")
    return lower, upper
