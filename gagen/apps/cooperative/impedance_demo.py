"""Similarity impedance control of three Kuka iiwa 14 arms on a circle [COOP Section 4.1, Figs. 5-6].

Three iiwa 14 (``three_iiwas_circle``, 21 DOF) start at ``COUNT`` random configurations drawn
uniformly in q0 ± ``SPREAD`` per joint around the paper's q0 = [0, −0.7854, 0, 1.3962, 0, 0.6109, 0]
per arm, at rest; the target is the circle of q0 (V_Sd = V_Sc(q0)). Each run simulates 4 s of the
rigid-body dynamics (Pinocchio, inertial parameters of Drake's iiwa 14) under the impedance
controller of ``gagen.control.impedance`` at 1 kHz, and records ‖B_S,e‖ (Fig. 6) and the closed loop's
energy.

Two gain sets run side by side:

- ``paper``: K = diag(1, 1, 1, 7.5, 7.5, 7.5, 7.5), D = diag(5, …) as in Section 4.1. The closed loop
  B̈ = −K B − D Ḃ then has a slow pole at (−5 + √21)/2 = −0.209 /s on the rotation rows: the error
  falls by only e^(−0.209·4) ≈ 0.43 in 4 s, which is what the paper's Fig. 6 shows (a decreasing
  cost, "further improved by tuning the stiffness and damping").
- ``tuned``: K = 25 I, D = 10 I, a double pole at −5 /s: ‖B_S,e‖ falls below 1e-6 within 4 s.

The same controller runs on a plane (``three_iiwas_plane``) with the tuned gains.

    gagen impedance --out plots/impedance [--runs 10] [--spread 0.2] [--duration 4]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gagen.check import joint_limits
from gagen.control.differential import CONTROLLABLE_DIMENSION
from gagen.control.impedance import Gains, ImpedanceController, Run, random_starts, simulate
from gagen.dynamics.rigid_body import SystemDynamics

ARM_REST = (0.0, -0.7854, 0.0, 1.3962, 0.0, 0.6109, 0.0)
"""q0 of each arm [COOP Section 4.1]."""
COUNT = 10
SPREAD = 0.2  # rad: the random starts are q0 ± SPREAD per joint
DURATION = 4.0
DT = 1e-3
GAINS = {"paper": Gains(), "tuned": Gains(stiffness=(25.0,) * 7, damping=(10.0,) * 7)}
SYSTEMS = {"circle": "three_iiwas_circle", "plane": "three_iiwas_plane"}
CONVERGED = 1e-6


@dataclass
class Result:
    """The runs of one system and gain set."""

    system: str
    gains: str
    runs: list[Run]
    wall: float  # seconds

    @property
    def final_errors(self) -> list[float]:
        return [run.final_error for run in self.runs]

    @property
    def largest_energy_increase(self) -> float:
        """The largest step-to-step increase of E over all runs (≤ 0: E never increases)."""
        return max(float(np.max(np.diff(run.energy))) for run in self.runs)


def start(system: str) -> np.ndarray:
    """q0 of a system: the paper's for its three iiwa systems [COOP Section 4.1], else the spec's ready."""
    from gagen.apps.cooperative.scenarios import ready

    return np.tile(ARM_REST, 3) if system in SYSTEMS.values() else ready(system)


def controller(system: str, gains: Gains) -> tuple[ImpedanceController, np.ndarray]:
    """The controller of a system (a bundled name or a spec file whose URDFs carry inertials) with
    V_Sd = V_Sc(q0), and q0 (``start``)."""
    from gagen.apps.cooperative.scenarios import module, spec_of

    dynamics = SystemDynamics(spec_of(system))  # before building: a URDF without inertials is refused here
    built = module(system)
    q0 = start(system)
    target, _, _ = built.c.similarity(q0)
    rank = CONTROLLABLE_DIMENSION[built.manifest["primitive"]]
    return ImpedanceController(built, dynamics, target, gains, q0, rank), q0


def run_all(system: str, gains_name: str, count: int = COUNT, spread: float = SPREAD,
            duration: float = DURATION, dt: float = DT, seed: int = 0,
            log: Callable[[str], None] = print, mujoco: bool = False) -> Result:
    """``count`` closed-loop runs of ``system`` from random starts around q0 (the same starts for every
    gain set: the seed is the system's), on Pinocchio's ABA by RK4 or, with ``mujoco``, in MuJoCo."""
    control, q0 = controller(system, GAINS[gains_name])
    lower, upper, _ = joint_limits(control.dynamics.system)
    starts = random_starts(q0, count, spread, seed, lower, upper)
    runs = []
    began = time.perf_counter()
    if mujoco:
        from gagen.apps.cooperative.scenarios import spec_of
        from gagen.control.mujoco_loop import impedance
        from gagen.dynamics.mujoco_model import MujocoSystem

        plant = MujocoSystem(spec_of(system), timestep=dt)
    for i, start in enumerate(starts):
        runs.append(impedance(plant, control, start, duration) if mujoco else
                    simulate(control, start, duration=duration, dt=dt))
        log(f"  {system} {gains_name} run {i + 1}/{count}: ‖B_S,e‖ {runs[-1].error_norm[0]:.3g} -> "
            f"{runs[-1].final_error:.3g} in {duration:g} s")
    return Result(system, gains_name, runs, time.perf_counter() - began)


def figure(results: Sequence[Result]) -> Any:
    """‖B_S,e‖ over time, one panel per result (log scale), as in Fig. 6."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5 * len(results), 4), layout="constrained")
    FigureCanvasAgg(fig)
    for k, result in enumerate(results):
        ax = fig.add_subplot(1, len(results), k + 1)
        for run in result.runs:
            ax.semilogy(run.times, np.maximum(run.error_norm, 1e-16), lw=1)
        ax.axhline(CONVERGED, color="grey", ls=":", lw=1)
        ax.set_title(f"{result.system}, {result.gains} gains")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("‖B_S,e‖")
        ax.grid(True, which="both", alpha=0.3)
    return fig


PLANTS = {False: "Pinocchio ABA, RK4", True: "MuJoCo's own integrator"}


def report(results: Sequence[Result], duration: float, mujoco: bool = False) -> str:
    lines = ["# Similarity impedance control [COOP Section 4.1]", "",
             f"{len(results[0].runs)} random starts around q0 (± {SPREAD} rad per joint), {duration:g} s of "
             f"forward dynamics ({PLANTS[mujoco]}, torque held over each 1 ms step).", "",
             "| system | gains | ‖B_S,e‖ at 0 s (median) | at the end (median / worst) | runs < 1e-6 | "
             "largest energy increase | wall time |",
             "|---|---|---:|---:|---:|---:|---:|"]
    for r in results:
        start = np.median([run.error_norm[0] for run in r.runs])
        final = r.final_errors
        lines.append(f"| {r.system} | {r.gains} | {start:.3g} | {np.median(final):.3g} / {max(final):.3g} | "
                     f"{sum(f < CONVERGED for f in final)}/{len(final)} | {r.largest_energy_increase:.2g} | "
                     f"{r.wall:.1f} s |")
    return "\n".join(lines) + "\n"


def run_command(args: argparse.Namespace) -> int:
    """``gagen impedance`` on its parsed arguments (``gagen.apps.cooperative.commands``)."""
    out = Path(args.out)
    cases = [(SYSTEMS["circle"], "paper"), (SYSTEMS["circle"], "tuned"), (SYSTEMS["plane"], "tuned")] \
        if not args.system else [(system, "tuned") for system in args.system]
    results = []
    for system, gains in cases:
        print(f"{system} with the {gains} gains:", flush=True)
        results.append(run_all(system, gains, args.runs, args.spread, args.duration, mujoco=args.mujoco))
    out.mkdir(parents=True, exist_ok=True)  # after the runs: a system refused leaves nothing behind
    figure(results).savefig(out / "impedance.png", dpi=100)
    text = report(results, args.duration, args.mujoco)
    (out / "impedance_report.md").write_text(text)
    print(text + f"wrote {out / 'impedance.png'} and {out / 'impedance_report.md'}")
    if args.view:  # the first system's first run with either gains, in a loop until Ctrl-C (gagen.viewer)
        from gagen.apps.cooperative.scenarios import system_of
        from gagen.viewer.scene import Scene, serve

        first = [r for r in results if r.system == results[0].system]
        every = 20  # 50 frames per second of the 1 kHz runs
        played = [(f"{r.gains} gains", r.runs[0].times[::every], r.runs[0].q[::every]) for r in first]
        serve(Scene(system_of(results[0].system), played[0][2][0], port=args.port), played)
    tuned = [r for r in results if r.gains == "tuned"]
    return 0 if all(max(r.final_errors) < CONVERGED for r in tuned) else 1
