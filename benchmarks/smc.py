"""Sliding-mode pose tracking [SMC V-VI] in C: step rate and the fixed-rate loop (gagen.control.smc).

    python benchmarks/smc.py [--steps 200000] [--repeats 21] [--duration 10] [--rate 1000] [--no-fifo]

- step: the generated ``smc_step`` (pose, 6×7 Jacobian, damped J⁺ by LDLᵀ, tanh law) plus the Euler update,
  in a tight loop of --steps steps in C; the median over --repeats loops (target ≥ 200 kHz);
- loop: the real-time runner at --rate Hz for --duration s, under SCHED_OTHER and (when permitted) SCHED_FIFO
  with locked memory: achieved rate, deadline misses (start lateness + work > period), start-lateness jitter
  (mean, std, max), work per tick and the tracking error after the 0.5 s transient.

Prints a markdown table on stdout; progress on stderr.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys

from gagen.control import smc


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--repeats", type=int, default=21)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--rate", type=float, default=1000.0)
    parser.add_argument("--no-fifo", action="store_true", help="only the SCHED_OTHER loop")
    args = parser.parse_args()

    log("building the step and the runner ...")
    built = smc.build()
    log(f"step: {args.repeats} x {args.steps} steps ...")
    step = smc.bench_step(args.steps, args.repeats, smc=built)
    loops = []
    for fifo in (False,) if args.no_fifo else (False, True):
        log(f"loop: {args.duration} s at {args.rate} Hz{' (SCHED_FIFO requested)' if fifo else ''} ...")
        loops.append(smc.run_loop(args.duration, args.rate, smc=built, fifo=fifo))

    target = 200_000
    print(f"## SMC pose tracking (Panda, 7 DOF) — {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} CPUs, load {' '.join(f'{v:.2f}' for v in os.getloadavg())}\n")
    print(f"Step kernel ops: {smc.op_count(built)}\n")
    print("| step (C, tight loop) | median | min | max | target |")
    print("|---|---|---|---|---|")
    met = "✓" if step["steps_per_second"] >= target else "✗"
    print(f"| steps/s | {step['steps_per_second']:,.0f} | {step['steps_per_second_min']:,.0f} | "
          f"{step['steps_per_second_max']:,.0f} | ≥ {target:,} {met} |")
    print(f"| ns/step | {step['ns_per_step']:.0f} | | | |\n")
    print(f"| loop {args.rate:g} Hz, {args.duration:g} s | achieved Hz | deadline misses | "
          "jitter mean / std / max (µs) | work mean / max (µs) | max \\|s_i\\| after 0.5 s | "
          "\\|x_p − x_p,ref\\| max (m) |")
    print("|---|---|---|---|---|---|---|")
    for s in loops:
        print(f"| {s.scheduler} | {s.achieved_rate_hz:.3f} | {s.deadline_misses} / {s.ticks} | "
              f"{s.jitter_mean_us:.1f} / {s.jitter_std_us:.1f} / {s.jitter_max_us:.0f} | "
              f"{s.work_mean_us:.2f} / {s.work_max_us:.1f} | {s.error_max:.3g} | "
              f"{s.position_error_max:.3g} |")
    bound = 0.2 / (smc.GAIN * smc.EPSILON)
    print(f"\nBoundary-layer error estimate max|ẋ_ref| / (K ε) = 0.2 / ({smc.GAIN:g} · {smc.EPSILON:g}) "
          f"= {bound:.3g}.")


if __name__ == "__main__":
    main()
