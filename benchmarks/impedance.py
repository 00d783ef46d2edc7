"""Impedance control benchmark [COOP Section 4.1]: one controller step of the three iiwa 14 on a circle
(21 DOF) — the generated kinematics (``similarity``, ``task``, ``similarity_rate``), Pinocchio's
joint-space dynamics (CRBA, RNEA, gravity) and the task-space algebra (M_Sc, C_Sc, g_Sc, the posture
term) — with its parts; the same step in C++ called from Python (``gagen.control.impedance_native``)
and as the stand-alone program ``impedance_step.cpp``, side by side; and the closed-loop simulation's
simulated seconds per wall second (RK4 with four ABA calls and one controller step per 1 ms step) with
either controller; markdown on stdout.

    python benchmarks/impedance.py            # ≈ 1 min
    python benchmarks/impedance.py --quick

Python: medians of 5 rounds of repeated calls at one random state near q0. Native from Python:
``NativeImpedance.torque`` (generic over systems; compiled into gagen's cache on first use), the same
5 rounds at that state, and like the C++ program over 200 random states near q0, median of 51 passes.
C++: impedance_step.cpp (built by programs.py against the pip wheel's Pinocchio and the module's C;
specific to three iiwas), the same law over the 200 states, median of 51 passes. The torques of both
are checked against the Python controller's (relative 1e-9 for the program, 1e-10 for the native step
at every state). Not part of the test suite.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

BENCH = Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH))

import programs  # noqa: E402 -- benchmarks/ is not a package
from run import machine, table  # noqa: E402

from gagen.apps.cooperative.impedance_demo import GAINS, controller  # noqa: E402
from gagen.control.impedance import simulate  # noqa: E402
from gagen.control.impedance_native import NativeImpedance  # noqa: E402
from gagen.dynamics.task_space import task_space  # noqa: E402

STEP_TARGET_US = 20.0
NATIVE_TARGET_US = 15.0  # the native step called from Python (issue 30)
URDF = programs.ROOT / "robots" / "iiwa14" / "iiwa14.urdf"


def cpp_step(control, states: np.ndarray) -> tuple[float, np.ndarray]:
    """(ns per step, τ at the first state) of impedance_step.cpp over ``states`` (rows [q, q̇])."""
    built, _, _ = programs.build({"impedance"})
    gains = control.gains
    header = np.concatenate([control.target, control.K, control.D,
                             [gains.posture_stiffness, gains.posture_damping], control.q_rest])
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "states.bin"
        np.concatenate([header, states.ravel()]).astype(np.float64).tofile(path)
        out = subprocess.run([str(built["impedance"]), str(URDF), str(path), "51"], capture_output=True,
                             text=True, check=True).stdout
    result = json.loads(out)
    return result["step_ns"], np.array(result["tau0"])


def native_passes(native: NativeImpedance, states: np.ndarray, passes: int = 51) -> tuple[float, np.ndarray]:
    """(seconds per step, τ per state) of ``native`` over ``states`` (rows [q, q̇]): the median of
    ``passes`` passes, as impedance_step.cpp times itself."""
    n = states.shape[1] // 2
    rows = [(row[:n].copy(), row[n:].copy()) for row in states]
    taus = np.array([native.torque(q, qd) for q, qd in rows])
    times = []
    for _ in range(passes):
        start = time.perf_counter()
        for q, qd in rows:
            native.torque(q, qd)
        times.append((time.perf_counter() - start) / len(rows))
    return statistics.median(times), taus


def ratio(a: float, b: float) -> str:
    return f"{a / b:.1f}×"


def per_call(f: Callable[[], object], calls: int, rounds: int = 5) -> float:
    """Median seconds per call over ``rounds`` rounds of ``calls`` calls (after a warm-up)."""
    for _ in range(min(calls, 200)):
        f()
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        for _ in range(calls):
            f()
        times.append((time.perf_counter() - start) / calls)
    return statistics.median(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer calls")
    args = parser.parse_args()
    calls, sim_seconds = (300, 0.2) if args.quick else (2000, 1.0)
    began = time.perf_counter()
    control, q0 = controller("three_iiwas_circle", GAINS["tuned"])
    rng = np.random.default_rng(0)
    q, qd = q0 + rng.uniform(-0.2, 0.2, q0.size), rng.uniform(-0.5, 0.5, q0.size)
    c, dyn = control.c, control.dynamics
    _, _, J = c.similarity(q)
    _, jdot_qdot = c.similarity_rate(q, qd)
    M, bias, g = dyn.mass_matrix(q), dyn.bias(q, qd), dyn.gravity(q)
    parts = {
        "generated `similarity` (V_Sc, J_G)": lambda: c.similarity(q),
        "generated `task` (B_S,e; it also computes J_Be)": lambda: c.task(q, control.target),
        "generated `similarity_rate` (V_S, J̇_G q̇)": lambda: c.similarity_rate(q, qd),
        "Pinocchio M(q) (CRBA)": lambda: dyn.mass_matrix(q),
        "Pinocchio C q̇ + g (RNEA)": lambda: dyn.bias(q, qd),
        "Pinocchio g(q)": lambda: dyn.gravity(q),
        "task space: M_Sc, C_Sc, g_Sc, J̄ (numpy)": lambda: task_space(J, jdot_qdot, M, bias, g, 6),
    }
    timed = {name: per_call(f, calls) for name, f in parts.items()}
    native = NativeImpedance(control)  # compiled into gagen's cache on first use (minutes)
    step = per_call(lambda: control(q, qd), calls)
    native_step = per_call(lambda: native.torque(q, qd), calls * 10)
    states = np.hstack([q0 + rng.uniform(-0.2, 0.2, (200, q0.size)), rng.uniform(-0.5, 0.5, (200, q0.size))])
    cpp_ns, cpp_tau = cpp_step(control, states)
    native_states, native_taus = native_passes(native, states)
    python_taus = np.array([control(row[:q0.size], row[q0.size:]).tau for row in states])
    agreement = float(np.abs(cpp_tau - python_taus[0]).max() / np.abs(python_taus[0]).max())
    if agreement > 1e-9:
        raise SystemExit(f"impedance_step.cpp disagrees with gagen.control.impedance: {agreement:.2e}")
    native_agreement = float(np.max(np.abs(native_taus - python_taus).max(axis=1) /
                                    np.abs(python_taus).max(axis=1)))
    if native_agreement > 1e-10:
        raise SystemExit(f"NativeImpedance disagrees with gagen.control.impedance: {native_agreement:.2e}")
    start = control.q_rest + rng.uniform(-0.2, 0.2, q0.size)
    walls = {}
    for name, law in (("Python", control), ("native", native)):
        t0 = time.perf_counter()
        simulate(law, start, duration=sim_seconds, dt=1e-3)
        walls[name] = time.perf_counter() - t0

    print("# Impedance control benchmark\n\n`python benchmarks/impedance.py`\n\n" + machine())
    print(f"- three_iiwas_circle (21 DOF), tuned gains; {calls} calls × 5 rounds, medians; simulation "
          f"{sim_seconds:g} s at 1 kHz (RK4: 4 ABA + 1 controller step per step)\n")
    rows = [[name, f"{t * 1e6:.1f} µs", "", ""] for name, t in timed.items()]
    cpp = cpp_ns * 1e-9

    def goal(seconds: float, target: float = STEP_TARGET_US) -> str:
        us = seconds * 1e6
        return f"≤ {target:g} µs " + ("✓" if us <= target else f"✗ ({us / target:.1f}×)")

    rows.append(["**one controller step, Python** (all of the above: numpy + Pinocchio's Python API)",
                 f"**{step * 1e6:.1f} µs**", goal(step), f"{ratio(step, cpp)} the C++ program"])
    rows.append(["**one controller step, native from Python** (`NativeImpedance.torque`, one state)",
                 f"**{native_step * 1e6:.1f} µs**", goal(native_step, NATIVE_TARGET_US),
                 f"{ratio(step, native_step)} faster than Python; {ratio(native_step, cpp)} the C++ program"])
    rows.append(["one controller step, native from Python, over the program's 200 states",
                 f"{native_states * 1e6:.1f} µs", goal(native_states, NATIVE_TARGET_US),
                 f"{ratio(native_states, cpp)} the C++ program"])
    rows.append(["**one controller step, stand-alone C++** (`impedance_step.cpp`: three iiwas only)",
                 f"**{cpp * 1e6:.1f} µs**", goal(cpp), "1×"])
    for name, wall in walls.items():
        rows.append([f"closed-loop simulation, {name} controller", f"{sim_seconds / wall:.2f} simulated s "
                     f"per wall s ({wall / sim_seconds * 1e3:.0f} µs per 1 ms step)", "", ""])
    print(table(["what", "measured", "goal", "ratio"], "lrll", rows))
    print(f"\nC++ program τ = Python τ to {agreement:.1e}, native τ = Python τ to {native_agreement:.1e} "
          f"(relative, largest over the 200 states). _whole run {time.perf_counter() - began:.0f} s_")
    return 0


if __name__ == "__main__":
    sys.exit(main())
