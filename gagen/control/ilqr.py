"""iLQR for cooperative reaching [COOP Sections 3.9, 4.2, Eq. 53-57], exploiting the problem's structure.

The problem is ``gagen.control.ocp``'s: x = [q; q̇], u = q̈, the exact double integrator
x_{k+1} = A x_k + B u_k over Δt = T/N, running cost Σ u_kᵀ R u_k, terminal cost ‖e(q_N) − s‖²_Q with
e(q) = log(V_Sc(q)~ V_Sd) from the generated ``task`` kernel, joint limits, q̇_N = 0 (``rest``).

**iLQR on this problem.** Each iLQR iteration linearises the dynamics (already linear) and takes the
Gauss-Newton model of the terminal cost, gradient 2 J_Beᵀ Q (e − s) and Hessian 2 J_Beᵀ Q J_Be (no
second derivatives of e), then solves that linear-quadratic problem exactly by the Riccati recursion
and moves along the new controls with a line search on the true cost. Here the recursion has a
closed form, and that is the structure exploited:

- with R diagonal (r_j per joint) the m joints are m decoupled scalar double integrators until the
  terminal cost couples them, so the Riccati matrices are 2 × 2 blocks per joint plus the terminal
  term;
- the least-effort controls that take joint j from (q0_j, q̇0_j) to a terminal state x_N,j are known:
  u_k = Γ_kᵀ W_j⁻¹ d_j / r_j with Γ_k = A^{N−1−k} B = (Δt²(N − k − ½), Δt), the reachability Gramian
  W_j = Σ_k Γ_k Γ_kᵀ / r_j (2 × 2) and d_j = x_N,j − A^N x_0,j; their effort is d_jᵀ W_j⁻¹ d_j.
  So the value function of the Riccati recursion at the start, as a function of the terminal state,
  is that quadratic, and the LQ subproblem of every iLQR iteration is a problem in q_N alone
  (q̇_N = 0, or optimised out without ``rest``):

      min_{q_N}  Σ_j a_j (q_N,j − c_j)² + ‖e(q_N) − s‖²_Q                       (a_j > 0, c_j below)

  whose Gauss-Newton step is one m × m solve with the diagonal-plus-rank-7 matrix
  diag(a) + J_Beᵀ Q J_Be (done here by Woodbury: a 7 × 7 solve). The iterates are those of the
  textbook iLQR with the full Riccati pass (``dense_ilqr_step``, used by the tests).

**Joint limits** are a box on q_N by projection (projected Gauss-Newton: the joints at a bound with
the gradient pushing outward are fixed, the step is clipped, the line search runs on the clipped
point). From rest (q̇_0 = 0) the least-effort trajectory of each joint runs monotonically from q0_j to
q_N,j, so a q_N inside the box keeps every q_k inside it; with q̇_0 ≠ 0 the trajectory is checked and
an excursion is reported (``status = "limits_violated"``).

**In C.** With ``backend="c"`` (the default when ``task`` is a compiled kernel of a generated module and
a C compiler is found) the whole loop — Gauss-Newton steps, line search, multiplier updates — runs in
``ilqr_loop.c``, which calls the kernel's C function directly (``CKernel.address``); Python only sets up
the problem and rebuilds the trajectory from q_N. The library is compiled on first use into gagen's
cache (``$GAGEN_CACHE``, else ~/.cache/gagen). ``backend="python"`` runs the same algorithm in numpy.

**Exactness** as in ``ocp``: the method of multipliers shifts the terminal error (s ← s − e(q_N))
until ‖e(q_N)‖ ≤ tol, giving the least-effort motion that reaches V_Sd exactly (the IPOPT path's
``exact=True`` solution). ``warm_start`` takes a previous result's q_N and shift.
"""

from __future__ import annotations

import ctypes
import hashlib
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.control.reaching import (
    BLADES,
    DEFAULT_HORIZON,
    DEFAULT_N,
    DEFAULT_Q,
    DEFAULT_R,
    DEFAULT_TOL,
    OCPResult,
    box,
    check_horizon,
    double_integrator,
    start_and_target,
    weight,
)

Array = NDArray[np.float64]
Task = Callable[[Array, Array], tuple[Array, Array]]
STATUSES = ("converged", "max_iterations", "line_search_failed", "limits_violated", "non_finite")
C_STATUSES = {0: "converged", 1: "max_iterations", 2: "line_search_failed", 4: "non_finite"}
LOOP_SOURCE = Path(__file__).with_name("ilqr_loop.c")
MAX_C_DOF = 128  # GAGEN_ILQR_MAX_DOF of ilqr_loop.c
ARMIJO = 1e-4  # sufficient decrease of the line search
MIN_STEP = 1e-10  # the smallest step length tried
STALL = 1e-9  # an iteration that lowers the cost by less than this fraction ends the inner iterations


@dataclass(frozen=True)
class Gramian:
    """Per joint, the least-effort map from a terminal displacement to the controls (see the module
    docstring): ``gamma`` (N, 2) the columns Γ_k, ``inverse`` (m, 2, 2) W_j⁻¹, ``r`` (m)."""

    gamma: NDArray[np.float64]
    inverse: NDArray[np.float64]
    r: NDArray[np.float64]


def gramian(N: int, dt: float, r: NDArray[np.float64]) -> Gramian:
    k = np.arange(N)
    gamma = np.column_stack([dt * dt * (N - k - 0.5), np.full(N, dt)])
    base = gamma.T @ gamma  # Σ Γ_k Γ_kᵀ
    inverse = np.linalg.inv(base)[None, :, :] * r[:, None, None]  # W_j⁻¹ = r_j (Σ Γ Γᵀ)⁻¹
    return Gramian(gamma, inverse, r)


_LOOP_LOCK = threading.Lock()
_LOOP: ctypes.CDLL | None = None


def loop_library() -> ctypes.CDLL:
    """ilqr_loop.c compiled with gagen's flags into the cache (once per content), loaded."""
    global _LOOP
    with _LOOP_LOCK:
        if _LOOP is None:
            from gagen.build import cache_root
            from gagen.codegen.compiler import FLAGS, compile_shared, library_name

            source = LOOP_SOURCE.read_bytes()
            tag = hashlib.sha256(source + " ".join(FLAGS).encode()).hexdigest()[:12]
            folder = cache_root() / "ilqr"
            library = folder / library_name(f"gagen_ilqr_{tag}")
            if not library.exists():
                folder.mkdir(parents=True, exist_ok=True)
                copy = folder / f"gagen_ilqr_{tag}.c"
                copy.write_bytes(source)
                compile_shared(copy, library)
            loaded = ctypes.CDLL(str(library))
            double_p, int_p = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int)
            loaded.gagen_ilqr_solve.argtypes = [ctypes.c_void_p, ctypes.c_int, *[double_p] * 7,
                                                *[ctypes.c_double] * 5, ctypes.c_int, ctypes.c_int,
                                                double_p, double_p, double_p, int_p]
            loaded.gagen_ilqr_solve.restype = ctypes.c_int
            _LOOP = loaded
        return _LOOP


def _pointer(array: Array) -> ctypes._Pointer[ctypes.c_double]:
    return array.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


class ILQR:
    """The reaching OCP of one system, horizon and weights, solved by structured iLQR.

    ``task``: the generated kernel (q, V_Sd) -> (e, J_Be), usually ``module.c.task``; ``R`` a scalar or
    one weight per joint (the structure needs it diagonal); ``Q`` a scalar, 7 weights or a 7 × 7 matrix.
    """

    def __init__(self, task: Task, m: int, *, N: int = DEFAULT_N, horizon: float = DEFAULT_HORIZON,
                 R: ArrayLike = DEFAULT_R, Q: ArrayLike = DEFAULT_Q, rest: bool = True,
                 backend: str = "auto") -> None:
        check_horizon(N, horizon)
        if backend not in ("auto", "c", "python"):
            raise ValueError(f"backend must be 'auto', 'c' or 'python', got {backend!r}")
        address = int(getattr(task, "address", 0) or 0)
        if backend == "c" and (not address or m > MAX_C_DOF):
            raise ValueError("backend='c' needs a compiled kernel of a generated module (module.c.task) and "
                             f"at most {MAX_C_DOF} joints")
        if backend == "auto":
            backend = "c" if address and m <= MAX_C_DOF and _compiler_found() else "python"
        self.backend, self._address = backend, address
        R_matrix = weight(R, m, "R")
        if np.any(R_matrix != np.diag(np.diag(R_matrix))) or np.any(np.diag(R_matrix) <= 0):
            raise ValueError("R must be diagonal and positive for the structured iLQR (one weight per joint)")
        self.task, self.m, self.N, self.horizon, self.rest = task, m, N, float(horizon), rest
        self.dt = self.horizon / N
        self.R, self.Q = R_matrix, weight(Q, len(BLADES), "Q")
        self._Q_inverse = np.linalg.pinv(self.Q)  # on Q's range, for the Woodbury solve
        self.gramian = gramian(N, self.dt, np.diag(R_matrix).copy())
        self.A, self.B = double_integrator(m, self.dt)

    # -- the problem in q_N ------------------------------------------------------------------------------
    def _terminal_quadratic(self, q0: Array, qdot0: Array) -> tuple[Array, Array]:
        """(a, c): the least effort to end at q_N is Σ a_j (q_N,j − c_j)² plus a constant."""
        w = self.gramian.inverse  # (m, 2, 2)
        free = q0 + self.N * self.dt * qdot0  # where each joint coasts to without control
        if self.rest:  # d = (q_N − free, −q̇0): complete the square in q_N
            a = w[:, 0, 0]
            c = free + w[:, 0, 1] / a * qdot0
        else:  # q̇_N free: minimised out, leaving the Schur complement 1 / W_11
            a = cast(Array, 1.0 / np.linalg.inv(w)[:, 0, 0])  # (numpy types inv's result as any float)
            c = free
        return a, c

    def trajectory(self, q0: Array, qdot0: Array, qN: Array) -> tuple[Array, Array, Array]:
        """(q (N+1, m), q̇ (N+1, m), u (N, m)): the least-effort motion from (q0, q̇0) to q_N (at rest
        with ``rest``, else at the optimal q̇_N)."""
        N, dt, g = self.N, self.dt, self.gramian
        free_q, free_v = q0 + N * dt * qdot0, qdot0
        if self.rest:
            vN = np.zeros_like(qN)
        else:  # the optimal q̇_N given q_N: d2 minimises dᵀ W⁻¹ d for fixed d1
            w = g.inverse
            vN = free_v - w[:, 0, 1] / w[:, 1, 1] * (qN - free_q)
        d = np.stack([qN - free_q, vN - free_v], axis=1)  # (m, 2)
        coefficients = np.einsum("jab,jb->ja", g.inverse, d) / g.r[:, None]  # W_j⁻¹ d_j / r_j
        u = g.gamma @ coefficients.T  # (N, m): u_k,j = Γ_kᵀ W_j⁻¹ d_j / r_j
        # the exact double integrator, summed: v_k = v_0 + Δt Σ_{i<k} u_i, q_{k+1} = q_k + Δt v_k + ½Δt² u_k
        v = np.vstack([qdot0, qdot0 + dt * np.cumsum(u, axis=0)])
        q = np.vstack([q0, q0 + np.cumsum(dt * v[:-1] + 0.5 * dt * dt * u, axis=0)])
        return q, v, u

    def cost(self, qN: Array, a: Array, c: Array, V_Sd: Array, shift: Array
             ) -> tuple[float, Array, Array]:
        """(cost, e, J_Be) at q_N (the effort part without its constant)."""
        e, J = self.task(qN, V_Sd)
        e = np.asarray(e, dtype=float).ravel()
        r = e - shift
        J = np.asarray(J, dtype=float).reshape(len(BLADES), -1)
        return float(a @ (qN - c) ** 2 + r @ self.Q @ r), e, J

    def gauss_newton_step(self, qN: Array, a: Array, c: Array, e: Array, J: Array,
                          shift: Array, fixed: NDArray[np.bool_]) -> Array:
        """The Gauss-Newton step of the terminal problem on the free joints: (D + JᵀQJ) δ = −g with
        D = diag(a), g = D (q_N − c) + Jᵀ Q (e − s) (halved gradient and Hessian), by Woodbury:
        (D + JᵀQJ)⁻¹ = D⁻¹ − D⁻¹Jᵀ (Q⁻¹ + J D⁻¹ Jᵀ)⁻¹ J D⁻¹, with Q⁻¹ taken on Q's range (a 7 × 7 solve)."""
        free = ~fixed
        Jf, af = J[:, free], a[free]
        gradient = af * (qN - c)[free] + Jf.T @ (self.Q @ (e - shift))
        scaled = Jf / af  # J D⁻¹
        inner = self._Q_inverse + scaled @ Jf.T
        step = -(gradient / af - scaled.T @ np.linalg.solve(inner, scaled @ gradient))
        out = np.zeros(self.m)
        out[free] = step
        return out

    def _solve_c(self, qN: Array, shift: Array, a: Array, c: Array, V_Sd: Array, lower: Array,
                 upper: Array, tol: float, inner_tol: float, max_iterations: int,
                 max_updates: int) -> tuple[Array, Array, Array, int, int, str]:
        """The loop in C (ilqr_loop.c): (q_N, shift, e, iterations, updates, status)."""
        arrays = [np.ascontiguousarray(x, dtype=float) for x in (a, c, self.Q.T, self._Q_inverse.T, V_Sd,
                                                                  lower, upper)]
        qN, shift, e = qN.astype(float).copy(), shift.astype(float).copy(), np.zeros(len(BLADES))
        stats = (ctypes.c_int * 3)()
        loop_library().gagen_ilqr_solve(self._address, self.m, *map(_pointer, arrays), tol, inner_tol, STALL,
                                        ARMIJO, MIN_STEP, max_iterations, max_updates, _pointer(qN),
                                        _pointer(shift), _pointer(e), stats)
        return qN, shift, e, stats[0], stats[1], C_STATUSES.get(stats[2], "non_finite")

    # -- solving -----------------------------------------------------------------------------------------
    def solve(self, q0: ArrayLike, V_Sd: ArrayLike, *, qdot0: ArrayLike | None = None,
              limits: tuple[ArrayLike, ArrayLike] | None = None, warm_start: OCPResult | None = None,
              tol: float = DEFAULT_TOL, max_iterations: int = 200, max_updates: int = 30,
              inner_tol: float = 1e-12) -> OCPResult:
        """From (q0, q̇0 = 0) to V_Sd (12 coefficients): iLQR (Gauss-Newton on q_N, exact LQ subproblems)
        with a line search, to a stationary point of the shifted problem, then multiplier updates of
        the shift until ‖e(q_N)‖ ≤ ``tol``. ``limits``: (lower, upper) on q_1 … q_N."""
        started = time.perf_counter()
        m = self.m
        q0, qdot0, V_Sd = start_and_target(q0, qdot0, V_Sd, m)
        inf = np.full(m, np.inf)
        lower, upper = (-inf, inf) if limits is None else box(limits, m, "limits")
        if np.any(q0 < lower - 1e-12) or np.any(q0 > upper + 1e-12):
            raise ValueError("q0 lies outside the joint limits")
        a, c = self._terminal_quadratic(q0, qdot0)
        if warm_start is not None:
            qN, shift = np.clip(warm_start.q[-1], lower, upper), warm_start.shift.copy()
        else:
            qN, shift = np.clip(q0, lower, upper), np.zeros(len(BLADES))
        if self.backend == "c":
            solved = self._solve_c(qN, shift, a, c, V_Sd, lower, upper, tol, inner_tol, max_iterations,
                                   max_updates)
            return self._result(q0, qdot0, V_Sd, lower, upper, tol, started, *solved)
        iterations, updates, status = 0, 0, "converged"
        cost, e, J = self.cost(qN, a, c, V_Sd, shift)
        while True:
            while iterations < max_iterations:  # iLQR iterations on the shifted problem
                gradient = a * (qN - c) + J.T @ (self.Q @ (e - shift))
                fixed = ((qN <= lower) & (gradient > 0)) | ((qN >= upper) & (gradient < 0))
                step = self.gauss_newton_step(qN, a, c, e, J, shift, fixed)
                if not np.all(np.isfinite(step)):
                    status = "non_finite"
                    break
                iterations += 1
                length, accepted = 1.0, False
                while length >= MIN_STEP:  # Armijo on the clipped point
                    trial = np.clip(qN + length * step, lower, upper)
                    trial_cost, trial_e, trial_J = self.cost(trial, a, c, V_Sd, shift)
                    if np.isfinite(trial_cost) and trial_cost <= cost + ARMIJO * 2 * gradient @ (trial - qN):
                        accepted = True
                        break
                    length *= 0.5
                if not accepted:
                    status = "line_search_failed" if np.linalg.norm(gradient[~fixed]) > inner_tol else status
                    break
                moved = float(np.abs(trial - qN).max())
                decrease = cost - trial_cost
                qN, cost, e, J = trial, trial_cost, trial_e, trial_J
                # stationary: the step or the cost's relative decrease vanishes (Gauss-Newton converges
                # linearly on the shifted problem's residual; the next multiplier update goes on from here)
                if moved <= inner_tol * max(1.0, float(np.abs(qN).max())) or decrease <= STALL * cost:
                    break
            else:
                status = "max_iterations"
            if status != "converged" or np.linalg.norm(e) <= tol or updates >= max_updates:
                break
            shift = shift - e
            updates += 1
            cost, e, J = self.cost(qN, a, c, V_Sd, shift)
        return self._result(q0, qdot0, V_Sd, lower, upper, tol, started, qN, shift, e, iterations, updates,
                            status)

    def _result(self, q0: Array, qdot0: Array, V_Sd: Array, lower: Array, upper: Array, tol: float,
                started: float, qN: Array, shift: Array, e: Array, iterations: int, updates: int,
                status: str) -> OCPResult:
        q, qdot, u = self.trajectory(q0, qdot0, qN)
        if status == "converged" and (np.any(q < lower - 1e-9) or np.any(q > upper + 1e-9)):
            status = "limits_violated"
        error_norm = float(np.linalg.norm(e))
        success = status == "converged" and error_norm <= tol
        message = (f"reached ‖e(q_N)‖ = {error_norm:.2g} in {iterations} iLQR iterations and {updates} "
                   f"multiplier updates" if success else
                   f"iLQR stopped ({status}) with ‖e(q_N)‖ = {error_norm:.3g}")
        residual = e - shift
        objective = float(np.einsum("kj,j,kj->", u, self.gramian.r, u) + residual @ self.Q @ residual)
        return OCPResult(q=q, qdot=qdot, u=u, dt=self.dt, V_Sd=V_Sd, error=e, error_norm=error_norm,
                         shift=shift, updates=updates, objective=objective, iterations=iterations,
                         wall_time=time.perf_counter() - started, function_time=0.0, build_time=0.0,
                         success=success, status=status, w=np.zeros(0), lam_x=np.zeros(0), lam_g=np.zeros(0),
                         message=message, solver="ilqr")


def _compiler_found() -> bool:
    from gagen.codegen.compiler import CompilerNotFound, find_compiler

    try:
        find_compiler()
    except CompilerNotFound:
        return False
    return True


def dense_ilqr_step(A: Array, B: Array, R: Array, x0: Array, u: Array, terminal_gradient: Array,
                    terminal_hessian: Array) -> Array:
    """The textbook iLQR step (a full Riccati backward pass over 2m × 2m matrices, no structure) for linear
    dynamics, running cost Σ uᵀRu and a quadratic model of the terminal cost about the rollout of ``u``
    (its gradient and Hessian in x_N): the new controls u + δu of the exact LQ minimiser. The reference the
    structured solver is tested against."""
    N = u.shape[0]
    x = [x0]
    for k in range(N):
        x.append(A @ x[-1] + B @ u[k])
    P, p = terminal_hessian.copy(), terminal_gradient.copy()
    gains = []
    for k in reversed(range(N)):  # value V_{k+1}(x + δx) ≈ const + pᵀδx + ½ δxᵀ P δx
        Quu = 2 * R + B.T @ P @ B
        Qux = B.T @ P @ A
        Qu = 2 * R @ u[k] + B.T @ p
        K = -np.linalg.solve(Quu, Qux)
        kff = -np.linalg.solve(Quu, Qu)
        gains.append((K, kff))
        p = A.T @ p + Qux.T @ kff  # (K = −Quu⁻¹Qux makes the cross terms cancel)
        P = A.T @ P @ A + Qux.T @ K
    gains.reverse()
    new_u, dx = np.empty_like(u), np.zeros_like(x0)
    for k, (K, kff) in enumerate(gains):
        new_u[k] = u[k] + kff + K @ dx
        dx = A @ dx + B @ (new_u[k] - u[k])
    return new_u
