"""``gagen mpc --dynamics``: the MPC demo's moving circle (``mpc_demo.setup``: it moves, tilts and grows)
tracked at the torque level. Receding-horizon box-FDDP (``gagen.control.torque_mpc``) closes the loop in
MuJoCo. Writes a report (solve times against the deadline, misses, tracking error, torques over their
limits), a plot, and a GIF rendered by MuJoCo (``gagen.dynamics.mujoco_render``; matplotlib's drawing of
the end points' circle where MuJoCo's renderer cannot start)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from gagen.apps.cooperative.mpc_demo import animate, setup, target_ring
from gagen.apps.cooperative.scenarios import spec_of
from gagen.control.mpc import MPCRun
from gagen.control.torque import TorqueOCP
from gagen.control.torque_mpc import MpcRun, TorqueMPC, run
from gagen.dynamics.mujoco_model import MujocoSystem
from gagen.dynamics.mujoco_render import RenderUnavailable, render_gif

SYSTEM = "three_iiwas_circle"  # (MuJoCo refuses the published Panda's link-4 inertia)
RATE = 50.0  # Hz
N, DT, ITERATIONS = 20, 0.02, 2  # a 0.4 s horizon, two FDDP iterations a tick (4: fewer errors, misses)
TRANSIENT = 0.5  # s before the tracking error is reported


def report(loop: MpcRun, rate: float, system: str, effort: np.ndarray) -> str:
    times = loop.solve_time * 1e3
    settled = loop.errors[loop.tick_t >= min(TRANSIENT, loop.tick_t[-1])]
    return "\n".join([
        f"# Torque-level MPC: {system} in MuJoCo", "",
        f"{len(loop.tick_t)} ticks at {rate:g} Hz: box-FDDP (Crocoddyl) over N = {N} × {DT * 1e3:g} ms, "
        f"{ITERATIONS} iterations a tick, warm-started; MuJoCo at {1e3 * (loop.t[1] - loop.t[0]):g} ms "
        f"steps under u₀ − K₀ (x ⊖ x₀) between ticks", "",
        "| what | value |", "| --- | ---: |",
        f"| solve time median / worst | {np.median(times):.1f} / {times.max():.1f} ms |",
        f"| deadline misses at {rate:g} Hz (solve > {1e3 / rate:g} ms) | {loop.misses} of {len(times)} |",
        f"| task error ‖e‖ after {TRANSIENT:g} s, max | {settled.max():.2e} |",
        f"| max \\|τ\\| / effort limit | {np.max(np.abs(loop.tau) / effort):.2f} |", ""])


def plot(loop: MpcRun, path: Path) -> Path:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(9, 7), layout="constrained")
    FigureCanvasAgg(figure)
    error, solve, torque = figure.subplots(3, 1, sharex=True)
    error.semilogy(loop.tick_t, np.maximum(loop.errors, 1e-16))
    error.set_ylabel("‖e(q; V_Sd(t))‖")
    error.set_title("torque-level MPC in MuJoCo: tracking a moving circle")
    solve.plot(loop.tick_t, loop.solve_time * 1e3, lw=0.8)
    solve.axhline(loop.period * 1e3, color="red", ls="--", lw=1, label="deadline")
    solve.set_ylabel("solve (ms)")
    solve.legend()
    torque.plot(loop.t, loop.tau, lw=0.6)
    torque.set_ylabel("τ (N m)")
    torque.set_xlabel("t (s)")
    figure.savefig(path, dpi=100)
    return path


def animation(sim: MujocoSystem, module: Any, loop: MpcRun, target: Any, path: Path,
              fps: float = 20.0) -> Path:
    """The run rendered by MuJoCo (the arms, their end points and the target circle), or, where MuJoCo's
    offscreen renderer cannot start, the end points' circle against the target's drawn by matplotlib
    (with a line saying why)."""
    every = max(1, round(1.0 / (fps * (loop.t[1] - loop.t[0]))))
    frames = np.arange(0, len(loop.t), every)
    qpos = np.tile(sim.model.qpos0, (len(frames), 1))
    qpos[:, sim.qpos] = loop.q[frames]
    rings = np.array([[target_ring(module, target(loop.t[k]), 64)] for k in frames])
    try:
        return render_gif(sim.mjspec.to_xml(), qpos, path, polylines=rings, fps=fps)
    except RenderUnavailable as e:
        print(f"note: {e}; drawing the GIF with matplotlib instead", flush=True)
    ticks = np.round(loop.tick_t / (loop.t[1] - loop.t[0])).astype(int)
    kinematic = MPCRun(loop.tick_t, loop.q[ticks], loop.qdot[ticks], loop.tau[ticks[:-1]], loop.errors,
                       loop.solve_time[:-1], loop.iterations[:-1], np.ones(len(ticks) - 1, bool), loop.period)
    return animate(module, kinematic, target, path)


def run_command(args: argparse.Namespace) -> int:
    """``gagen mpc --dynamics`` on its parsed arguments (``gagen.apps.cooperative.commands``)."""
    system = args.system or SYSTEM
    rate = args.rate or RATE
    sim = MujocoSystem(spec_of(system))  # (a robot MuJoCo cannot load is refused first, before any build)
    module, q0, target = setup(system)
    mpc = TorqueMPC(TorqueOCP(spec_of(system), module.c.task, N=N, dt=DT), q0, target, iterations=ITERATIONS)
    loop = run(sim, mpc, duration=args.duration, rate=rate)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    text = report(loop, rate, system, sim.effort)
    (out / "torque_mpc_report.md").write_text(text)
    written = [out / "torque_mpc_report.md", plot(loop, out / "torque_mpc.png")]
    if not args.no_animation:
        written.append(animation(sim, module, loop, target, out / "torque_mpc.gif"))
    print(text + "wrote " + ", ".join(map(str, written)))
    return 0
