"""Torque-level cooperative MPC: the OCP of ``gagen.control.torque`` re-solved at a fixed rate from the
measured state, warm-started from the previous solution shifted by one node, toward a target that
moves (V_Sd(t)), closing the loop in MuJoCo (``gagen.dynamics.mujoco_model``).

The problem is built once. Each tick sets its initial state and every node's target (the task
residual's ``parameter``), then runs a few box-FDDP iterations. Between ticks the simulator runs at its
own rate under τ = u₀ − K₀ (x ⊖ x₀): the first control with FDDP's Riccati feedback gains. That is the
usual way to run Crocoddyl's MPC on a faster plant. A solve longer than the period is a deadline miss.
It is counted and its result applied late, as a real controller would.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.control.torque import TorqueOCP, crocoddyl
from gagen.dynamics.mujoco_model import MujocoSystem

Array = NDArray[np.float64]


@dataclass
class MpcRun:
    """A closed-loop run: per simulator step t, q, q̇, τ; per tick its time, solve time and FDDP
    iterations, and the task error toward the moving target."""

    t: Array
    q: Array
    qdot: Array
    tau: Array
    tick_t: Array
    solve_time: Array
    iterations: NDArray[np.int64]
    errors: Array  # ‖e(q; V_Sd(t))‖ at every tick
    period: float

    @property
    def misses(self) -> int:
        return int(np.sum(self.solve_time > self.period))


class TorqueMPC:
    """Receding-horizon box-FDDP on a ``TorqueOCP`` toward ``target(t)`` (see the module docstring)."""

    def __init__(self, ocp: TorqueOCP, q0: ArrayLike, target: Callable[[float], ArrayLike], *,
                 iterations: int = 3, first_iterations: int = 100) -> None:
        self.ocp, self.target, self.iterations = ocp, target, int(iterations)
        self._targets: dict[int, Array] = {}  # V_Sd by node time t / dt: a tick needs one new node's
        problem, _ = ocp.problem(q0, self.target_at)
        self.problem = problem
        self.solver = crocoddyl.SolverBoxFDDP(problem)
        self.solver.solve([problem.x0] * (ocp.N + 1), list(problem.quasiStatic([problem.x0] * ocp.N)),
                          first_iterations, False)
        models = [*problem.runningModels, problem.terminalModel]
        self._residuals = [m.differential.costs.costs["task"].cost.residual for m in models]

    def target_at(self, t: float) -> Array:
        """V_Sd(t), computed once per node time (ticks at multiples of dt share their nodes' targets)."""
        key = round(t / self.ocp.dt * 1e6)
        if key not in self._targets:
            value = np.asarray(self.target(t), dtype=float).reshape(-1)
            if value.size != 12 or not np.all(np.isfinite(value)):
                raise ValueError(f"the target at t = {t:g} s is not 12 finite values (a V_Sd): {value}")
            self._targets[key] = value
        return self._targets[key]

    def solve(self, t: float, q: ArrayLike, qdot: ArrayLike) -> tuple[float, int]:
        """Re-solve from the measured (q, q̇) at time t: (wall seconds, iterations)."""
        d, dt = self.ocp.dynamics, self.ocp.dt
        start = time.perf_counter()
        self.problem.x0 = np.concatenate([d._to_pin(q), d._to_pin(qdot)])
        for k, residual in enumerate(self._residuals):
            residual.parameter = self.target_at(t + k * dt)
        xs, us = list(self.solver.xs), list(self.solver.us)
        xs = [self.problem.x0, *xs[2:], xs[-1]]  # shifted by one node, the measured state first
        us = [*us[1:], us[-1]]
        self.solver.solve(xs, us, self.iterations, False)
        return time.perf_counter() - start, int(self.solver.iter)

    def torque(self, q: ArrayLike, qdot: ArrayLike) -> Array:
        """u₀ − K₀ (x ⊖ x₀) at the measured state, in the system's order."""
        d = self.ocp.dynamics
        x = np.concatenate([d._to_pin(q), d._to_pin(qdot)])
        dx = self.ocp.state.diff(self.solver.xs[0], x)
        u: Array = np.asarray(self.solver.us[0]) - np.asarray(self.solver.K[0]) @ dx
        return u[d.order]


def run(sim: MujocoSystem, mpc: TorqueMPC, *, duration: float, rate: float) -> MpcRun:
    """The loop in MuJoCo from the MPC's initial state: a solve every 1/rate s, the simulator at its
    timestep in between (see the module docstring)."""
    dt = float(sim.model.opt.timestep)
    per_tick = max(1, round(1.0 / (rate * dt)))
    x0 = np.asarray(mpc.problem.x0)
    n = sim.dof
    d = mpc.ocp.dynamics
    sim.set_state(x0[:n][d.order], x0[n:][d.order])
    ts, qs, qdots, taus, ticks, solves, iterations, errors = [], [], [], [], [], [], [], []
    task = mpc.ocp.task
    for i in range(round(duration / dt)):
        t = i * dt
        q, qdot = sim.state()
        if i % per_tick == 0:
            seconds, count = mpc.solve(t, q, qdot)
            ticks.append(t)
            solves.append(seconds)
            iterations.append(count)
            errors.append(float(np.linalg.norm(np.asarray(task(q, mpc.target_at(t))[0]))))
        tau = np.clip(mpc.torque(q, qdot), -sim.effort, sim.effort)
        ts.append(t)
        qs.append(q)
        qdots.append(qdot)
        taus.append(tau)
        sim.step(tau)
    return MpcRun(np.array(ts), np.array(qs), np.array(qdots), np.array(taus), np.array(ticks),
                  np.array(solves), np.array(iterations, dtype=np.int64), np.array(errors), per_tick * dt)
