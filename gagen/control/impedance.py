"""Impedance control in the cooperative similarity task space [COOP Section 3.8, Eq. 49-52].

    B_S,e = log(V_Sc(q)~ V_Sd),  Ḃ_S,e = −V_S                                    (Eq. 49)
    V̇_Sd = K B_S,e + D Ḃ_S,e                                                      (Eq. 50)
    W_Sd = M_Sc V̇_Sd + C_Sc + g_Sc                                                (Eq. 51)
    τ = J_G,Scᵀ W_Sd + Nᵀ (g + M (k_n (q_rest − q) − d_n q̇))                      (Eq. 52 + posture)

**Ḃ_S,e.** The paper writes Ḃ_S,e = −½ V_Sc in gafro's conventions. With gagen's (J_G = −2 V~ ∂V/∂q
and its similarity logarithm) the exact rate of the error at B_S,e = 0 is −V_S: the ``task`` kernel's
J_Be equals −J_G there (tested). So Eq. 49 reads Ḃ_S,e = −V_S here, and the closed loop of the
similarity is exactly V̇_S = K B_S,e − D V_S (the task-space dynamics cancel; tested with Pinocchio's
ABA): the damped oscillator B̈ = −K B − D Ḃ to first order in B.

**The posture term.** Eq. 52 alone leaves the joint motions that do not move the primitive (15 of the
three iiwas' 21) to gravity: g_Sc compensates only the part of g that accelerates the similarity.
Like every redundant operational-space controller, this one adds a joint-space posture spring and
damper toward ``q_rest`` plus the full gravity, through the dynamically consistent nullspace
projector Nᵀ = I − J_Gᵀ J̄ᵀ, which cannot accelerate the similarity (J_G M⁻¹ Nᵀ = 0): the task
closed loop above is unchanged. The posture gains act on accelerations (scaled by M): a torque-level
damper of a few N·m·s/rad on the iiwa's wrist (inertia ≈ 2e-3 kg·m²) would be unstable when held
over a 1 ms step. ``posture_stiffness = posture_damping = 0`` and ``gravity_nullspace
= False`` give Eq. 52 alone.

**Simulation.** ``simulate`` runs the controller at a fixed rate (the torque is held over each step, as
a 1 kHz torque loop does) and integrates M q̈ + C q̇ + g = τ with Pinocchio's ABA by classical RK4
(four ABA calls per step).

**Passivity.** With V_Sd fixed, E = ½ V_Sᵀ V_S + ½ B_S,eᵀ K B_S,e is the closed loop's energy
(``Run.energy``): Ė = −V_Sᵀ D V_S + B_S,eᵀ K (Ḃ_S,e + V_S), the last term third order (the
logarithm's curvature: Ḃ_S,e = −V_S only at B_S,e = 0). In the continuous-time loop (``hold=False``)
E never increases (tested); a torque held over each step adds O(dt³) per step, a relative 1e-8 in
the first millisecond from rest, where V_S = 0 and D dissipates nothing yet.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.dynamics.rigid_body import DynamicsError, SystemDynamics
from gagen.dynamics.task_space import TaskSpace, task_space

PAPER_STIFFNESS = (1.0, 1.0, 1.0, 7.5, 7.5, 7.5, 7.5)
"""K of [COOP Section 4.1], on the similarity bivector rows e12 e13 e23 e0∞ e1∞ e2∞ e3∞."""
PAPER_DAMPING = (5.0,) * 7
"""D of [COOP Section 4.1]."""


@dataclass(frozen=True)
class Gains:
    """K and D (diagonals, on the 7 similarity bivector rows) and the posture spring and damper."""

    stiffness: tuple[float, ...] = PAPER_STIFFNESS
    damping: tuple[float, ...] = PAPER_DAMPING
    posture_stiffness: float = 25.0  # 1/s²: k_n, acting as M k_n
    posture_damping: float = 10.0  # 1/s: d_n (critically damped with k_n = 25)
    gravity_nullspace: bool = True

    def __post_init__(self) -> None:
        for name in ("stiffness", "damping"):
            values = np.asarray(getattr(self, name), dtype=float)
            if values.shape != (7,) or not np.all(np.isfinite(values)) or np.any(values < 0):
                raise ValueError(f"{name} must be 7 finite values >= 0 (one per similarity bivector), "
                                 f"got {getattr(self, name)!r}")
        for name in ("posture_stiffness", "posture_damping"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")


@dataclass(frozen=True)
class Step:
    """One controller evaluation."""

    tau: NDArray[np.float64]
    error: NDArray[np.float64]  # B_S,e
    twist: NDArray[np.float64]  # V_S = J_G q̇
    task: TaskSpace


class ImpedanceController:
    """τ(q, q̇) of Eq. 49-52 (and the posture term) for a target similarity V_Sd.

    ``module``: the system's generated module (its ``similarity``, ``task`` and ``similarity_rate``
    kernels); ``dynamics``: the system's joint-space dynamics; ``rank``: the primitive's controllable
    dimension (Table 1)."""

    def __init__(self, module: object, dynamics: SystemDynamics, target: ArrayLike, gains: Gains,
                 q_rest: ArrayLike, rank: int) -> None:
        self.c = module.c  # type: ignore[attr-defined]
        self.dynamics, self.gains, self.rank = dynamics, gains, rank
        self.target = np.asarray(target, dtype=float)
        self.q_rest = np.asarray(q_rest, dtype=float)
        self.K, self.D = np.asarray(gains.stiffness), np.asarray(gains.damping)

    def __call__(self, q: NDArray[np.float64], qd: NDArray[np.float64]) -> Step:
        _, conditioning, J = self.c.similarity(q)
        if not conditioning[0] > 0:
            raise DynamicsError(f"the cooperative primitive is degenerate at q (conditioning "
                                f"{conditioning[0]:.3g})")
        error, _ = self.c.task(q, self.target)
        twist, jdot_qdot = self.c.similarity_rate(q, qd)
        dyn = self.dynamics
        g = dyn.gravity(q)
        space = task_space(J, jdot_qdot, M := dyn.mass_matrix(q), dyn.bias(q, qd), g, self.rank)
        acceleration = self.K * error - self.D * twist  # V̇_Sd = K B + D Ḃ with Ḃ = −V_S
        wrench = space.inertia @ acceleration + space.coriolis + space.gravity
        gains = self.gains
        posture = M @ (gains.posture_stiffness * (self.q_rest - q) - gains.posture_damping * qd)
        if gains.gravity_nullspace:
            posture = posture + g
        tau = J.T @ wrench + space.nullspace_torque(J, posture)
        return Step(tau, error, twist, space)


@dataclass
class Run:
    """A simulated run: per controller step, the time, q, q̇, ‖B_S,e‖ and the energy E."""

    times: NDArray[np.float64]
    q: NDArray[np.float64]
    qd: NDArray[np.float64]
    error_norm: NDArray[np.float64]
    energy: NDArray[np.float64]
    torque_norm: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))

    @property
    def final_error(self) -> float:
        return float(self.error_norm[-1])


def simulate(controller: ImpedanceController, q0: ArrayLike, qd0: ArrayLike | None = None,
             duration: float = 4.0, dt: float = 1e-3, hold: bool = True,
             progress: Callable[[float], None] | None = None) -> Run:
    """Closed loop from (q0, q̇0) for ``duration`` s: the rigid-body dynamics integrated by RK4 with ABA,
    the torque of each step held for dt (a torque loop at 1/dt), or with ``hold=False`` evaluated at
    every RK4 stage (the continuous-time closed loop, for checks of its energy: holding a torque over a
    step adds O(dt³) energy). A non-finite state raises ``DynamicsError``."""
    if not (dt > 0 and duration > 0):
        raise ValueError(f"dt and duration must be > 0, got dt={dt}, duration={duration}")
    dynamics = controller.dynamics
    q = np.array(q0, dtype=float)
    qd = np.zeros_like(q) if qd0 is None else np.array(qd0, dtype=float)
    steps = round(duration / dt)
    times = np.arange(steps + 1, dtype=np.float64) * dt
    qs, qds = np.empty((steps + 1, q.size)), np.empty((steps + 1, q.size))
    errors, energies, torques = np.empty(steps + 1), np.empty(steps + 1), np.empty(steps + 1)
    K = controller.K

    def rate(x: NDArray[np.float64], v: NDArray[np.float64],
             tau: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return v, dynamics.forward(x, v, tau if hold else controller(x, v).tau)

    for k in range(steps + 1):
        step = controller(q, qd)
        qs[k], qds[k] = q, qd
        errors[k] = np.linalg.norm(step.error)
        energies[k] = 0.5 * step.twist @ step.twist + 0.5 * step.error @ (K * step.error)
        torques[k] = np.linalg.norm(step.tau)
        if k == steps:
            break
        tau = step.tau
        k1 = rate(q, qd, tau)
        k2 = rate(q + 0.5 * dt * k1[0], qd + 0.5 * dt * k1[1], tau)
        k3 = rate(q + 0.5 * dt * k2[0], qd + 0.5 * dt * k2[1], tau)
        k4 = rate(q + dt * k3[0], qd + dt * k3[1], tau)
        q = q + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        qd = qd + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
            raise DynamicsError(f"the simulation diverged at t = {times[k + 1]:.3f} s")
        if progress is not None and (k + 1) % 500 == 0:
            progress(times[k + 1])
    return Run(times, qs, qds, errors, energies, torques)


def random_starts(q0: ArrayLike, count: int, spread: float, seed: int,
                  lower: ArrayLike | None = None, upper: ArrayLike | None = None) -> NDArray[np.float64]:
    """``count`` configurations drawn uniformly in q0 ± spread (per joint), clipped to the limits."""
    rng = np.random.default_rng(seed)
    q0 = np.asarray(q0, dtype=float)
    starts = q0 + rng.uniform(-spread, spread, (count, q0.size))
    if lower is not None and upper is not None:
        starts = np.clip(starts, lower, upper)
    return starts
