"""Controllers closing their loop in MuJoCo (``gagen.dynamics.mujoco_model``: the same URDF inertias
in another engine and integrator).

- ``impedance``: the similarity impedance law of ``gagen.control.impedance`` at the simulator's rate.
- ``track``: an optimal torque trajectory (``gagen.control.torque``) closed by a joint-space PD around
  it, τ = τ*(t) + M(q) (K_p (q*(t) − q) + K_d (q̇*(t) − q̇)). The PD acts through the mass matrix
  (gains in 1/s², 1/s), so a light wrist and a heavy shoulder get the same bandwidth and the explicit
  integration stays stable. q*, q̇* are linear between the solution's nodes, and τ* is held over each
  interval as the solver applied it. The PD absorbs the difference between the two engines, so the
  task error the loop reaches measures how well the plan carries over.
- ``follow``: a joint trajectory from a kinematic controller (a teleoperation's q(t)) tracked by
  computed torque, τ = M(q) (q̈*(t) + K_p (q* − q) + K_d (q̇* − q̇)) + C(q, q̇) q̇ + g(q), the reference
  read at the current time only (what an online loop would have).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gagen.control.impedance import ImpedanceController, Run
from gagen.control.torque import TorqueResult
from gagen.dynamics.mujoco_model import MujocoSystem
from gagen.dynamics.rigid_body import DynamicsError

Array = NDArray[np.float64]


@dataclass
class LoopResult:
    """The simulated run: times, joint positions and velocities, applied torques (every step)."""

    t: Array
    q: Array
    qdot: Array
    tau: Array


def reference(plan: TorqueResult, t: float) -> tuple[Array, Array, Array]:
    """(q*, q̇*, τ*) of the plan at time t: states linear between nodes, the torque of the interval."""
    dt = float(plan.t[1] - plan.t[0])
    k = min(int(t / dt), len(plan.tau) - 1)
    s = min(max(t / dt - k, 0.0), 1.0)
    q = (1 - s) * plan.q[k] + s * plan.q[k + 1]
    qdot = (1 - s) * plan.qdot[k] + s * plan.qdot[k + 1]
    return q, qdot, plan.tau[k]


def track(sim: MujocoSystem, plan: TorqueResult, *, kp: float = 400.0, kd: float = 40.0,
          duration: float | None = None) -> LoopResult:
    """Run the plan from its first state for ``duration`` (default: the plan's horizon; after it, the
    last state is held with MuJoCo's own bias forces as the feedforward) in MuJoCo at its timestep."""
    sim.set_state(plan.q[0], plan.qdot[0])
    dt = float(sim.model.opt.timestep)
    horizon = float(plan.t[-1])
    steps = round((horizon if duration is None else duration) / dt)
    ts, qs, qdots, taus = [], [], [], []
    for i in range(steps):
        t = i * dt
        q, qdot = sim.state()
        q_ref, qdot_ref, tau_ref = reference(plan, min(t, horizon))
        if t >= horizon:  # past the plan: hold its last state against gravity (MuJoCo's bias forces)
            qdot_ref, tau_ref = np.zeros_like(qdot_ref), sim.bias_now()
        feedback = sim.current_mass_matrix() @ (kp * (q_ref - q) + kd * (qdot_ref - qdot))
        tau = np.clip(tau_ref + feedback, -sim.effort, sim.effort)
        ts.append(t)
        qs.append(q)
        qdots.append(qdot)
        taus.append(tau)
        sim.step(tau)
    q, qdot = sim.state()
    ts.append(steps * dt)
    qs.append(q)
    qdots.append(qdot)
    return LoopResult(np.array(ts), np.array(qs), np.array(qdots), np.array(taus))


def follow(sim: MujocoSystem, t: Array, q: Array, *, kp: float = 400.0, kd: float = 40.0) -> LoopResult:
    """Track the joint trajectory q(t) (rows at the increasing times t, q linear between them, q̇* and q̈*
    by differences) in MuJoCo at its timestep from q(t₀) at the reference's velocity, until t's end."""
    t, q = np.asarray(t, dtype=float), np.asarray(q, dtype=float)
    if t.ndim != 1 or len(t) < 2 or q.shape != (len(t), sim.dof) or not np.all(np.diff(t) > 0):
        raise ValueError(f"follow needs increasing times and a ({len(t)}, {sim.dof}) joint trajectory, got "
                         f"times {t.shape} and q {q.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))):
        raise ValueError("follow needs a finite joint trajectory")
    velocity = np.diff(q, axis=0) / np.diff(t)[:, None]  # per interval
    acceleration = np.zeros_like(velocity)
    acceleration[1:] = np.diff(velocity, axis=0) / np.diff(t)[1:, None]  # at each interval's start
    dt = float(sim.model.opt.timestep)
    steps = round((t[-1] - t[0]) / dt)
    sim.set_state(q[0], velocity[0])
    ts, qs, qdots, taus = [], [], [], []
    for i in range(steps):
        now = t[0] + i * dt
        k = min(int(np.searchsorted(t, now, side="right")) - 1, len(velocity) - 1)
        s = (now - t[k]) / (t[k + 1] - t[k])
        q_ref, qdot_ref = (1 - s) * q[k] + s * q[k + 1], velocity[k]
        position, rate = sim.state()
        command = acceleration[k] + kp * (q_ref - position) + kd * (qdot_ref - rate)
        tau = np.clip(sim.current_mass_matrix() @ command + sim.bias_now(), -sim.effort, sim.effort)
        ts.append(now)
        qs.append(position)
        qdots.append(rate)
        taus.append(tau)
        sim.step(tau)
        if not np.all(np.isfinite(sim.data.qpos)):
            raise DynamicsError(f"the MuJoCo state became non-finite at t = {now:.4f} s")
    position, rate = sim.state()
    return LoopResult(np.array([*ts, t[0] + steps * dt]), np.array([*qs, position]),
                      np.array([*qdots, rate]), np.array(taus))


def impedance(sim: MujocoSystem, controller: ImpedanceController, q0: NDArray[np.float64],
              duration: float = 4.0) -> Run:
    """The similarity impedance law (``gagen.control.impedance``) at the simulator's rate on MuJoCo's
    plant from rest at q0: the same record as ``impedance.simulate`` (which integrates Pinocchio's ABA by
    RK4), so the two plants can be compared run for run. A non-finite state raises ``DynamicsError``."""
    sim.set_state(q0, np.zeros_like(q0))
    dt = float(sim.model.opt.timestep)
    steps = round(duration / dt)
    times = np.arange(steps + 1, dtype=np.float64) * dt
    n = len(q0)
    qs, qds = np.empty((steps + 1, n)), np.empty((steps + 1, n))
    errors, energies, torques = np.empty(steps + 1), np.empty(steps + 1), np.empty(steps + 1)
    for k in range(steps + 1):
        q, qd = sim.state()
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
            raise DynamicsError(f"the MuJoCo simulation diverged at t = {times[k]:.3f} s")
        step = controller(q, qd)
        qs[k], qds[k] = q, qd
        errors[k] = np.linalg.norm(step.error)
        energies[k] = 0.5 * step.twist @ step.twist + 0.5 * step.error @ (controller.K * step.error)
        torques[k] = np.linalg.norm(step.tau)
        if k < steps:
            sim.step(step.tau)
    return Run(times, qs, qds, errors, energies, torques)
