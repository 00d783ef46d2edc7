"""Optimal control for reaching a cooperative primitive [COOP Section 3.9, Eq. 53-57].

The problem, for a system of m joints and a desired similarity versor V_Sd:

    min_{u_0..u_{N-1}}  Σ_k u_kᵀ R u_k  +  ‖e(q_N)‖²_Q,   e(q) = log(V_Sc(q)~ V_Sd)       [Eq. 53, 56, 57]
    s.t.  x_{k+1} = A x_k + B u_k,  x = [q; q̇],  u = q̈                                   [Eq. 54, 55]
          x_0 given,  q_lower <= q_k <= q_upper,  (optionally) q̇_N = 0

with the exact (zero-order-hold) discretisation of the double integrator over a step Δt = T/N:
A = [[I, Δt I], [0, I]], B = [[½Δt² I], [Δt I]]. The terminal error e and its derivatives come from
the generated ``task`` CasADi Function, embedded in the NLP (``expand=True`` flattens the whole NLP,
kernel included, into one SX graph; IPOPT gets the exact Hessian by CasADi's AD).

Shooting form: **multiple shooting** (states and controls are both decision variables, interleaved
u_0, x_1, u_1, x_2, …, x_N; the dynamics are 2mN linear equality constraints). Why not the condensed
(single-shooting) form, where q_N is an explicit linear function of all the u_k? Because there the
terminal cost couples every control with every other: its Hessian block is dense (mN × mN, 2100² for
the three-Panda circle at N = 100), and joint limits on q_k become dense general inequalities. In the
multiple-shooting form the terminal cost touches only the m variables of q_N (an m × m Hessian
block), the running cost is diagonal, the constraint Jacobian is constant and banded, and joint
limits are plain variable bounds, so IPOPT's sparse KKT factorisation is cheap (with linear dynamics
both forms take the same Newton steps; only the cost of a step differs).

Exactness: the paper's terminal cost is a penalty, so its optimum keeps a residual ‖e(q_N)‖ that is
proportional to R/Q (the effort of the last bit of motion balances its terminal cost): ≈ 1e-3 for
R/Q = 1e-4 and ≈ 1e-7-1e-6 for R/Q = 1e-8 (three-Panda circle, N = 20-100). Pushing R/Q lower to
reach 1e-9 makes the NLP badly scaled: IPOPT then stops on its dual tolerance before the effort (the
nullspace motion) is minimised, or crawls for hundreds of iterations. ``exact=True`` (the default)
keeps R/Q moderate (R = 1e-6 I per step, Q = I) and removes the residual instead by the method of
multipliers: the terminal cost becomes ‖e(q_N) − s‖²_Q, and the shift s ← s − e(q_N) after each
(warm-started) solve, which shrinks ‖e‖ by the same factor ~1e-4 per update: one or two updates reach
‖e(q_N)‖ <= 1e-9. The result is the Q/R → ∞ limit of the paper's problem: the least-effort motion
that reaches V_Sd exactly. ``exact=False`` solves the paper's penalty problem as it stands.

Solvers (``solver``): ``"ipopt"`` (general sparse interior point, MUMPS on the whole KKT system) or
``"fatrop"`` (CasADi's FATROP plugin: an interior point whose linear algebra is a Riccati recursion over
the stages, dense BLASFEO blocks per stage). The NLP is the same for both: its variables are already
stage-wise (stage 0: u_0 only, since x_0 is a parameter; stage k = 1 … N−1: x_k then u_k; stage N:
x_N), its constraints are the gap-closing rows x_{k+1} − (A x_k + B u_k) = 0 in stage order, joint
limits and the rest condition are bounds on x_k. FATROP gets that structure stated (``structure_detection``
"manual": nx = (0, 2m, …, 2m), nu = (m, …, m, 0), no path constraints) rather than detected. FATROP
takes no dual start: its warm start is the primal point only. Measured (benchmarks/ocp.py --solvers),
FATROP is slower than IPOPT here, not faster: its Riccati recursion factorises dense (3m)² stage blocks
(A and B are treated as dense 2m × 3m matrices), while MUMPS sees that the double integrator decouples
joint by joint (A, B are diagonal in blocks) and that only q_N carries a dense m × m block; the pip
wheel's BLASFEO is moreover its generic C build (an AVX2 build made FATROP 2-3× faster, still not
faster than IPOPT). It also takes more iterations (a monotone barrier update, where IPOPT runs the
adaptive one) and, from the same start, may end in another local optimum of this redundant problem
than IPOPT (both reach V_Sd exactly).

Hessians (``hessian``): ``"exact"`` (CasADi's AD of the Lagrangian, second derivatives of e included)
or ``"gauss-newton"`` (IPOPT only): the dynamics are linear, so the Lagrangian's Hessian is that of the
cost, and its Gauss-Newton part is block diagonal: 2R on every u_k and 2 J_Beᵀ Q J_Be on q_N, with J_Be
= ∂e/∂q the ``task`` kernel's own Jacobian output; the term 2 Σᵢ (Q(e − s))ᵢ ∇²eᵢ is dropped. It is
handed to IPOPT as its ``hess_lag`` Function (the nlp_hess_l signature: x, p, lam_f, lam_g → the upper
triangle), so no second derivatives of e are formed at all; the gradient stays exact, so the KKT points
are the same (with the multiplier updates the dropped term does not vanish at the solution: there
e − s = −s carries the multiplier of e(q_N) = 0, so Gauss-Newton converges only linearly in the
nullspace directions, and a PSD model may settle in another local optimum than the exact Hessian's
path). Cheaper iterations, sometimes more of them: see benchmarks/ocp.py --solvers. Why not a lifted
residual r = e(q_N) − s with ‖r‖²_Q? Its constraint's multiplier brings λᵀ∇²e back into the exact
Hessian: not Gauss-Newton. The FATROP plugin builds its own Hessian Function (it has no ``hess_lag``
option), hence exact only.

The plotted "bivector command" (``bivector_command``) is the similarity twist of the primitive along
the trajectory, B_k = J_G,Sc(q_k) q̇_k (rows e12 e13 e23 e0∞ e1∞ e2∞ e3∞, w.r.t. V_Sc): the task-space
command that the differential kinematics q̇ = J_G⁺ B of Eq. 48 turns back into the optimal joint
velocities (up to nullspace motion), as in the paper's teleoperation section; it starts and ends at
zero for a rest-to-rest motion. ``task_errors`` gives the remaining error e(q_k) for comparison.
"""

from __future__ import annotations

import math
import time
from collections.abc import Hashable, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Any, TypeVar

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.control.reaching import (
    BLADES,  # noqa: F401 (re-exported: callers import it from here)
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

if TYPE_CHECKING:
    from gagen.algebra.protocol import Multivector
    from gagen.algebra.signature import Algebra
    from gagen.interp import MultiVector

IPOPT_OPTIONS: dict[str, Any] = {
    "ipopt.print_level": 0,
    "ipopt.sb": "yes",
    "ipopt.tol": 1e-10,
    "ipopt.acceptable_tol": 1e-8,
    "ipopt.max_iter": 500,
    "ipopt.mu_strategy": "adaptive",
    "print_time": False,
}
FATROP_OPTIONS: dict[str, Any] = {
    "fatrop.print_level": 0,
    "fatrop.tolerance": 1e-10,
    "fatrop.max_iter": 500,
    "print_time": False,
}
FATROP_WARM_OPTIONS: dict[str, Any] = {
    # FATROP takes the previous primal point only (no multipliers): a small initial barrier keeps the
    # iterate near it (the default 0.1 walks away and, on the circle, stalls with return flag 1)
    "fatrop.mu_init": 1e-8,
}
GAUSS_NEWTON_OPTIONS: dict[str, Any] = {
    # the constraints are linear, so second-order corrections have nothing to correct; with the
    # Gauss-Newton model they only waste the line search (the plane stops in Error_In_Step_Computation)
    "ipopt.max_soc": 0,
}
SOLVERS = ("ipopt", "fatrop")
HESSIANS = ("exact", "gauss-newton")
WARM_OPTIONS: dict[str, Any] = {
    "ipopt.warm_start_init_point": "yes",
    "ipopt.warm_start_bound_push": 1e-9,
    "ipopt.warm_start_slack_bound_push": 1e-9,
    "ipopt.warm_start_mult_bound_push": 1e-9,
    "ipopt.mu_init": 1e-8,
}


Symbolic = TypeVar("Symbolic", ca.SX, ca.MX)


class ReachingOCP:
    """The NLP of Eq. 53-57 for one system, horizon and weights, built once and solved many times.

    q0, q̇0 and V_Sd are NLP parameters and joint limits are variable bounds, so one instance serves
    every start, target and box (and warm starts from its own previous solutions).

    ``task``: a CasADi Function (q[m], V_Sd[12]) -> (e[7], …), usually ``module.casadi.task`` (or any
    residual e[r] as the terminal cost ‖e‖²_Q, e.g. ``gagen.control.objectives.Objective.task``);
    ``expand``: nlpsol's option (True: the NLP, kernel included, becomes one flat SX graph);
    ``rest``: constrain the final velocity q̇_N to zero; ``solver``: "ipopt" or "fatrop";
    ``hessian``: "exact" or "gauss-newton" (IPOPT only; see the module docstring); ``options``: nlpsol
    options on top of ``IPOPT_OPTIONS`` / ``FATROP_OPTIONS``.
    """

    def __init__(self, task: ca.Function, m: int, *, N: int = DEFAULT_N, horizon: float = DEFAULT_HORIZON,
                 R: ArrayLike = DEFAULT_R, Q: ArrayLike = DEFAULT_Q, rest: bool = True, expand: bool = True,
                 options: dict[str, Any] | None = None, solver: str = "ipopt",
                 hessian: str = "exact") -> None:
        check_horizon(N, horizon)
        if solver not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}")
        if hessian not in HESSIANS:
            raise ValueError(f"hessian must be one of {HESSIANS}, got {hessian!r}")
        if solver == "fatrop" and hessian != "exact":
            raise ValueError("the Gauss-Newton Hessian needs solver='ipopt': CasADi's FATROP plugin builds "
                             "its own Hessian of the Lagrangian (it takes no hess_lag Function)")
        self.task, self.m, self.N, self.horizon, self.rest = task, m, N, float(horizon), rest
        self.solver, self.hessian = solver, hessian
        self.dt = self.horizon / N
        # e may have any length: the 7 rows of log(V_Sc~ V_Sd), or a stacked objective residual
        # (gagen.control.objectives) as the terminal cost
        self.rows = int(task.numel_out(0))
        self.R, self.Q = weight(R, m, "R"), weight(Q, self.rows, "Q")
        self.A, self.B = double_integrator(m, self.dt)
        self.expand = expand
        if solver == "fatrop":  # the stage structure, stated: stage 0 holds u_0 only (x_0 is a parameter)
            structure = {"structure_detection": "manual", "N": N, "nx": [0] + [2 * m] * N,
                         "nu": [m] * N + [0], "ng": [0] * (N + 1)}
            self._options = {**FATROP_OPTIONS, "expand": expand, **structure, **(options or {})}
        else:
            extra = GAUSS_NEWTON_OPTIONS if hessian == "gauss-newton" else {}
            self._options = {**IPOPT_OPTIONS, "expand": expand, **extra, **(options or {})}
        self._solvers: dict[bool, ca.Function] = {}
        started = time.perf_counter()
        self._nlp = self._build()
        if hessian == "gauss-newton":
            self._options["hess_lag"] = self._gauss_newton_hessian()
        self._built = time.perf_counter() - started
        self._solver(warm=False)
        self.build_time = self._built

    # -- the NLP ------------------------------------------------------------------------------------------
    def _build(self) -> dict[str, ca.MX]:
        """The NLP as an MX graph of two calls: the linear-quadratic part (dynamics residuals and
        running cost, one flat SX Function) and the ``task`` kernel on q_N. With ``expand`` nlpsol
        flattens both into one SX graph; without it only the kernel's own form (SX, MX, external)
        decides how its derivatives are evaluated."""
        m, N = self.m, self.N
        n_w, n_p = N * 3 * m, 2 * m + 12 + self.rows
        w_sx, p_sx = ca.SX.sym("w", n_w), ca.SX.sym("p", n_p)
        A, B, R = ca.DM(self.A), ca.DM(self.B), ca.DM(self.R)
        x = p_sx[: 2 * m]
        gaps: list[ca.SX] = []
        effort: ca.SX | int = 0
        for k in range(N):  # w = u_0, x_1, u_1, x_2, …, u_{N-1}, x_N
            u, x_next = w_sx[3 * m * k: 3 * m * k + m], w_sx[3 * m * k + m: 3 * m * (k + 1)]
            gaps.append(x_next - (A @ x + B @ u))
            effort += ca.bilin(R, u, u)
            x = x_next
        stage = ca.Function("stage", [w_sx, p_sx], [ca.vertcat(*gaps), effort])
        w, p = ca.MX.sym("w", n_w), ca.MX.sym("p", n_p)  # p = q0, q̇0, V_Sd, shift s of the terminal error
        g, running = stage(w, p)
        e = self.task(w[n_w - 2 * m: n_w - m], p[2 * m: 2 * m + 12])
        e = (e[0] if isinstance(e, (list, tuple)) else e) - p[2 * m + 12:]
        return {"x": w, "p": p, "f": running + ca.bilin(ca.DM(self.Q), e, e), "g": g}

    def _terminal_error(self, q: Any, V_Sd: Any) -> tuple[Any, Any]:
        """(e, J_Be = ∂e/∂q) at q: the kernel's own Jacobian output where it has one, else CasADi's AD."""
        out = self.task(q, V_Sd)
        if isinstance(out, (list, tuple)) and len(out) > 1 and self.task.name_out(1) == "J_Be":
            return out[0], out[1]
        e = out[0] if isinstance(out, (list, tuple)) else out
        return e, ca.jacobian(e, q)

    def _gauss_newton_hessian(self) -> ca.Function:
        """IPOPT's ``hess_lag``: lam_f × the Gauss-Newton Hessian of the cost (upper triangle), block
        diagonal over w = u_0, x_1, …, u_{N-1}, x_N: 2R on each u_k, 2 J_Beᵀ Q J_Be on q_N, nothing on
        the constraints (linear)."""
        if self.task.is_a("SXFunction"):
            return self._gauss_newton_hessian_in(ca.SX)
        return self._gauss_newton_hessian_in(ca.MX)

    def _gauss_newton_hessian_in(self, sym: type[Symbolic]) -> ca.Function:
        """``_gauss_newton_hessian`` in the task's own symbolic type (SX, else MX)."""
        m, N = self.m, self.N
        n_w, n_p = N * 3 * m, 2 * m + 12 + self.rows
        w, p = sym.sym("w", n_w), sym.sym("p", n_p)
        lam_f, lam_g = sym.sym("lam_f"), sym.sym("lam_g", 2 * m * N)
        _, J = self._terminal_error(w[n_w - 2 * m: n_w - m], p[2 * m: 2 * m + 12])
        control = sym(ca.sparsify(ca.DM(np.triu(2.0 * self.R))))
        terminal = ca.triu(2.0 * (J.T @ ca.DM(self.Q) @ J))
        blocks = [block for _ in range(N - 1) for block in (control, sym(2 * m, 2 * m))]
        H = lam_f * ca.diagcat(*blocks, control, terminal, sym(m, m))
        return ca.Function("hess_gauss_newton", [w, p, lam_f, lam_g], [H], ["x", "p", "lam_f", "lam_g"],
                           ["triu_hess_gamma_x_x"])

    def _solver(self, warm: bool) -> ca.Function:
        """The nlpsol for cold starts, or for warm starts (IPOPT: warm_start_init_point; FATROP: a small
        initial barrier at the previous primal point, as it takes no multipliers). Built on first use:
        the time goes to the ``build_time`` of the result that needed it."""
        if warm not in self._solvers:
            started = time.perf_counter()
            warm_options = WARM_OPTIONS if self.solver == "ipopt" else FATROP_WARM_OPTIONS
            options = {**self._options, **(warm_options if warm else {})}
            self._solvers[warm] = ca.nlpsol("reach", self.solver, self._nlp, options)
            self._built += time.perf_counter() - started
        return self._solvers[warm]

    def _layout(self, w: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(u (N, m), x (N, 2m)) from the stacked decision vector."""
        blocks = w.reshape(self.N, 3 * self.m)
        return blocks[:, : self.m], blocks[:, self.m:]

    def _stack(self, u: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.hstack([u, x]).ravel()

    # -- solving ------------------------------------------------------------------------------------------
    def solve(self, q0: ArrayLike, V_Sd: ArrayLike, *, qdot0: ArrayLike | None = None,
              limits: tuple[ArrayLike, ArrayLike] | None = None,
              velocity_limits: tuple[ArrayLike, ArrayLike] | None = None,
              warm_start: OCPResult | None = None, exact: bool = True, tol: float = DEFAULT_TOL,
              max_updates: int = 5) -> OCPResult:
        """Solve from (q0, q̇0 = 0 by default) towards V_Sd (12 coefficients, the ``V_Sd`` rows).

        ``limits`` = (lower, upper) joint bounds on q_1 … q_N (arrays of m or scalars; q0 must lie
        inside); ``velocity_limits`` likewise on q̇_1 … q̇_N. ``warm_start``: a previous ``OCPResult`` of
        an OCP of the same size (e.g. the last MPC solve): its primal-dual solution is the initial
        point (IPOPT's warm_start_init_point), and its shift the first shift; without it the start is
        x_k = x_0, u_k = 0 and s = 0.

        ``exact`` = False solves the paper's penalty problem once; its optimum keeps a residual
        ‖e(q_N)‖ ∝ R/Q. ``exact`` = True (default) then removes that residual by the method of
        multipliers: the terminal cost becomes ‖e(q_N) − s‖²_Q with the shift s ← s − e(q_N) after
        each solve (warm-started), until ‖e(q_N)‖ <= ``tol`` or ``max_updates`` shifts. The limit is
        the penalty problem's Q/R → ∞ limit: the least-effort motion that reaches V_Sd exactly
        (s is then −λ/2 Q⁻¹ for the multiplier λ of the constraint e(q_N) = 0).
        """
        m, N = self.m, self.N
        q0, qdot0, V_Sd = start_and_target(q0, qdot0, V_Sd, m)
        if not (isinstance(tol, (int, float)) and math.isfinite(tol) and tol >= 0):
            raise ValueError(f"tol must be a finite number >= 0, got {tol!r}")
        inf = np.full(m, np.inf)
        lower_q, upper_q = (-inf, inf) if limits is None else box(limits, m, "limits")
        if np.any(q0 < lower_q - 1e-12) or np.any(q0 > upper_q + 1e-12):
            raise ValueError("q0 lies outside the joint limits")
        lower_v, upper_v = (-inf, inf) if velocity_limits is None else box(velocity_limits, m,
                                                                             "velocity_limits")
        lbx_x = np.tile(np.concatenate([lower_q, lower_v]), (N, 1))
        ubx_x = np.tile(np.concatenate([upper_q, upper_v]), (N, 1))
        if self.rest:
            lbx_x[-1, m:] = ubx_x[-1, m:] = 0.0
        free = np.full((N, m), np.inf)
        args: dict[str, Any] = {"lbx": self._stack(-free, lbx_x), "ubx": self._stack(free, ubx_x),
                                "lbg": 0.0, "ubg": 0.0}
        if warm_start is not None:
            if warm_start.w.size != N * 3 * m:
                raise ValueError("warm_start comes from an OCP of another size")
            start: tuple[NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.float64] | None] = (
                warm_start.w, warm_start.lam_x, warm_start.lam_g)
            shift = warm_start.shift.copy() if exact else np.zeros(self.rows)
        else:
            shift = np.zeros(self.rows)
            x_guess = np.tile(np.concatenate([np.clip(q0, lower_q, upper_q), np.zeros(m)]), (N, 1))
            start = (self._stack(np.zeros((N, m)), x_guess), None, None)
        iterations, wall, functions, updates = 0, 0.0, 0.0, 0
        self._built = 0.0
        while True:
            w, lam_x, lam_g = start
            solver = self._solver(warm=lam_x is not None)
            call = {**args, "p": np.concatenate([q0, qdot0, V_Sd, shift]), "x0": w}
            if lam_x is not None:
                call.update(lam_x0=lam_x, lam_g0=lam_g)
            started = time.perf_counter()
            solution = solver(**call)
            wall += time.perf_counter() - started
            stats = solver.stats()
            status = _status(self.solver, stats)
            iterations += int(stats["iter_count"])
            functions += sum(v for k, v in stats.items() if k.startswith("t_wall_nlp_"))
            w = np.array(solution["x"]).ravel()
            lam_x, lam_g = np.array(solution["lam_x"]).ravel(), np.array(solution["lam_g"]).ravel()
            start = (w, lam_x, lam_g)
            e = self._error(w[-2 * m: -m], V_Sd)  # q_N
            if (not exact or status not in IPOPT_SUCCESS or np.linalg.norm(e) <= tol
                    or updates >= max_updates):
                break
            shift = shift - e
            updates += 1
        u, x = self._layout(w)
        success, message = _verdict(status, float(np.linalg.norm(e)), exact, tol, updates, max_updates,
                                    self.solver.upper())
        return OCPResult(q=np.vstack([q0, x[:, :m]]), qdot=np.vstack([qdot0, x[:, m:]]), u=u, dt=self.dt,
                         V_Sd=V_Sd, error=e, error_norm=float(np.linalg.norm(e)), shift=shift,
                         updates=updates, objective=float(solution["f"]), iterations=iterations,
                         wall_time=wall, function_time=functions, build_time=self._built, success=success,
                         status=status, w=w, lam_x=lam_x, lam_g=lam_g, message=message,
                         solver=self.solver)

    def _error(self, q: NDArray[np.float64], V_Sd: NDArray[np.float64]) -> NDArray[np.float64]:
        out = self.task(q, V_Sd)
        return np.array(out[0] if isinstance(out, (list, tuple)) else out).ravel()


IPOPT_SUCCESS = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
"""IPOPT return statuses that count as solved (CasADi's own ``success`` flag also accepts e.g.
Feasible_Point_Found, which is no optimum)."""


def _status(solver: str, stats: dict[str, Any]) -> str:
    """IPOPT's return status; FATROP's integer return flag as "Solve_Succeeded" (0) or "FATROP flag n"."""
    if solver == "fatrop":
        flag = int(stats["return_status"])
        return "Solve_Succeeded" if flag == 0 and stats["success"] else f"FATROP flag {flag}"
    return str(stats["return_status"])


def _verdict(status: str, error: float, exact: bool, tol: float, updates: int,
             max_updates: int, name: str = "IPOPT") -> tuple[bool, str]:
    """(success, message) from the solver's return status and the final terminal error."""
    if status not in IPOPT_SUCCESS:
        return False, f"{name} stopped with {status}; final ‖e(q_N)‖ = {error:.3g}"
    if not exact:
        return True, (f"{name} {status}; the penalty problem (exact=False) keeps a residual ‖e(q_N)‖ = "
                      f"{error:.3g}, not held to tol")
    if error > tol:
        return False, (f"{name} {status}, but ‖e(q_N)‖ = {error:.3g} > tol {tol:g} after {updates} of at "
                       f"most {max_updates} multiplier updates: the target is not reached (out of reach "
                       f"within the joint limits and horizon, or tol below what the solver attains)")
    return True, f"{name} {status}; ‖e(q_N)‖ = {error:.3g} <= tol {tol:g} after {updates} multiplier updates"


_CACHE: dict[tuple[Hashable, ...], ReachingOCP] = {}
_CACHE_SIZE = 8


def _key(value: ArrayLike) -> tuple[tuple[int, ...], bytes]:
    a = np.asarray(value, dtype=float)
    return (a.shape, a.tobytes())


def reach(module: Any, q0: ArrayLike, V_Sd: ArrayLike, *, N: int = DEFAULT_N,
          horizon: float = DEFAULT_HORIZON, R: ArrayLike = DEFAULT_R, Q: ArrayLike = DEFAULT_Q,
          limits: tuple[ArrayLike, ArrayLike] | None = None,
          warm_start: OCPResult | None = None, qdot0: ArrayLike | None = None,
          velocity_limits: tuple[ArrayLike, ArrayLike] | None = None, rest: bool = True,
          exact: bool = True, tol: float = DEFAULT_TOL, task: ca.Function | None = None, expand: bool = True,
          options: dict[str, Any] | None = None, solver: str = "ipopt", hessian: str = "exact") -> OCPResult:
    """Solve the reaching OCP of Eq. 53-57 for a generated ``module`` (``gagen.runtime.load``) with IPOPT
    (or ``solver`` = "fatrop"; ``hessian`` = "gauss-newton": see ``ReachingOCP``; or ``solver`` = "ilqr":
    the structured iLQR of ``gagen.control.ilqr`` on the C ``task`` kernel, diagonal R only, no velocity
    limits, ``exact`` always).

    From rest at ``q0`` (or with velocity ``qdot0``) to the primitive of the desired similarity
    versor ``V_Sd`` (12 coefficients in the ``task`` kernel's V_Sd rows; see ``target_from``) in
    ``horizon`` seconds and ``N`` steps; ``R``: running-cost weight on u_k (scalar, m weights or an
    m × m matrix); ``Q``: terminal weight on e(q_N) (scalar, 7 weights or 7 × 7); ``limits``:
    (lower, upper) joint bounds; ``rest``: q̇_N = 0; ``warm_start``: a previous result of the same
    N and m; ``exact``, ``tol``: see ``ReachingOCP.solve``. The NLP (multiple shooting, see the module
    docstring) is built once per task Function, N, horizon, weights and options and cached (the
    last 8): ``build_time`` is non-zero only when something had to be built.
    ``task`` replaces ``module.casadi.task`` (e.g. a wrapped or external Function, for benchmarks).
    """
    check_horizon(N, horizon)
    m = int(module.manifest["dof"])
    if solver == "ilqr":
        from gagen.control.ilqr import ILQR, Task

        if velocity_limits is not None or hessian != "exact" or not exact:
            raise ValueError("solver='ilqr' takes no velocity limits, always uses the Gauss-Newton model "
                             "(hessian='exact' is its default) and always reaches the target exactly")
        # a Function called on arrays returns its outputs as a tuple; CasADi's stubs say one DM
        kernel: Task = module.c.task if task is None else task  # type: ignore[assignment]
        return ILQR(kernel, m, N=N, horizon=horizon, R=R, Q=Q,
                    rest=rest).solve(q0, V_Sd, qdot0=qdot0, limits=limits, warm_start=warm_start, tol=tol)
    task = module.casadi.task if task is None else task
    key = (id(task), m, N, float(horizon), _key(R), _key(Q), rest, expand, solver, hessian,
           repr(sorted((options or {}).items())))
    ocp = _CACHE.get(key)
    built = 0.0
    if ocp is None or ocp.task is not task:
        ocp = ReachingOCP(task, m, N=N, horizon=horizon, R=R, Q=Q, rest=rest, expand=expand, options=options,
                          solver=solver, hessian=hessian)
        built = ocp.build_time
        if len(_CACHE) >= _CACHE_SIZE:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = ocp
    result = ocp.solve(q0, V_Sd, qdot0=qdot0, limits=limits, velocity_limits=velocity_limits,
                       warm_start=warm_start, exact=exact, tol=tol)
    return replace(result, build_time=built + result.build_time)


# -- along the trajectory --------------------------------------------------------------------------------
def bivector_command(module: Any, result: OCPResult) -> NDArray[np.float64]:
    """(N+1, 7): the similarity twist B_k = J_G,Sc(q_k) q̇_k of the primitive (rows ``BLADES``), the
    task-space bivector command that q̇ = J_G⁺ B [Eq. 48] maps to the optimal joint velocities."""
    similarity = module.c.similarity
    return np.array([np.array(similarity(q)[2]) @ v for q, v in zip(result.q, result.qdot, strict=True)])


def task_errors(module: Any, result: OCPResult) -> NDArray[np.float64]:
    """(N+1, 7): e(q_k) = log(V_Sc(q_k)~ V_Sd) along the trajectory."""
    task = module.c.task
    return np.array([np.array(task(q, result.V_Sd)[0]) for q in result.q])


# -- targets ---------------------------------------------------------------------------------------------
def _algebra() -> Algebra:
    from gagen.algebra.signature import cga3d

    return cga3d()


def multivector(rows: Sequence[str], values: ArrayLike) -> MultiVector:
    """An interpreter MultiVector from a kernel port's row labels and values."""
    from gagen.interp import MultiVector

    return MultiVector.from_blades(_algebra(), dict(zip(rows, np.asarray(values, dtype=float).ravel(),
                                                        strict=True)))


def coefficients(x: Any, rows: Sequence[str]) -> NDArray[np.float64]:
    """The coefficients of multivector x on ``rows``."""
    return np.array([x[r] for r in rows])


def target_from(V_Sc0: ArrayLike, translation: ArrayLike = (0.0, 0.0, 0.0),
                rotation_axis_angle: tuple[ArrayLike, float] | None = None, dilation: float = 1.0, *,
                kind: str | None = None) -> NDArray[np.float64]:
    """A desired similarity V_Sd: the primitive of V_Sc0 moved by a chosen similarity.

    With c the primitive's reference point (the image of the origin under V_Sc0: the centre of a
    round, a point of a flat), the primitive X_c0 = V_Sc0 X_u V_Sc0~ is dilated by ``dilation`` about
    c, rotated by ``rotation_axis_angle`` = (world axis, angle in rad) about the axis through c, then
    translated by ``translation``: S = T(t) T(c) R D T(c)~, X_d = S X_c0 S~. Dilation does not change a
    flat. With ``kind`` (the primitive kind) the result is the canonical V_S(X_u, X_d) that the
    ``similarity`` kernel builds for X_d [COOP Eq. 28], so e(q) = 0 exactly when X_c(q) ∝ X_d; without
    it, the raw composition S V_Sc0 (the same primitive, but e = 0 is only reachable if it happens to
    be canonical: a rotation about a circle's own axis, say, is not). Returns 12 coefficients in the
    V_Sd row order.
    """
    from gagen.model.conformal import SIMILARITY, e0, location, vector
    from gagen.model.primitives import unit_primitive
    from gagen.model.similarity import similarity
    from gagen.model.versors import dilator, rotor, translator

    v0: Multivector = multivector(SIMILARITY, V_Sc0)
    c = location(v0.sandwich(e0(v0)))
    s = dilator(v0, float(dilation))
    if rotation_axis_angle is not None:
        axis, angle = rotation_axis_angle
        a = np.asarray(axis, dtype=float)
        s = rotor(vector(v0, list(a / np.linalg.norm(a))), float(angle)) * s
    t = vector(v0, list(np.asarray(translation, dtype=float)))
    s = translator(t) * translator(c) * s * translator(-c)
    v = s * v0
    if kind is not None:
        x_u = unit_primitive(kind, v0)
        v = similarity(kind, x_u, v.sandwich(x_u)).versor
    return coefficients(v, SIMILARITY)


def target_primitive(module: Any, V_Sd: ArrayLike) -> NDArray[np.float64]:
    """X_d = V_Sd X_u V_Sd~ in the ``primitive`` kernel's X_c row order, to compare with X_c(q)."""
    from gagen.model.conformal import SIMILARITY
    from gagen.model.primitives import unit_primitive

    v: Multivector = multivector(SIMILARITY, V_Sd)
    x_d = v.sandwich(unit_primitive(module.manifest["primitive"], v))
    return coefficients(x_d, _rows(module, "primitive", "X_c"))


def _rows(module: Any, kernel: str, port: str) -> list[str]:
    entry = next(k for k in module.manifest["kernels"] if k["name"] == kernel)
    return next(p["rows"] for p in entry["outputs"] + entry["inputs"] if p["name"] == port)
