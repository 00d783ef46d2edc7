"""The verb ``gagen smc``: sliding-mode pose tracking of a Panda in a real-time C loop, with plots. Light at
import: the step is built when the verb runs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from gagen.arguments import positive_float
from gagen.registry import Verb


def _smc_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--spec", help="the arm: a spec file of one chain, or a bundled system of one chain, "
                        "started at its ready configuration (default: the bundled Panda, panda_point)")
    parser.add_argument("--duration", type=positive_float, default=10.0, help="seconds (default 10)")
    parser.add_argument("--rate", type=positive_float, default=1000.0, help="loop rate in Hz (default 1000)")
    parser.add_argument("--out", default="plots/smc", help="folder for the log and the plots")
    parser.add_argument("--fifo", action="store_true", help="ask for SCHED_FIFO and locked memory")


def _arm(spec: str) -> tuple[tuple[Any, ...], list[float] | None]:
    """(joints, start) of a one-chain system: a spec file or a bundled name."""
    from gagen.registry import resolve_spec
    from gagen.robots.spec import load_system

    path = resolve_spec(spec, "cooperative", "system")
    system, named = load_system(path)
    if len(system.chains) != 1:
        raise ValueError(f"{path}: chains: the sliding-mode loop drives one arm; the spec has "
                         f"{len(system.chains)} chains")
    return tuple(system.chains[0].joints), named.get("ready")


def _smc(args: argparse.Namespace) -> int:
    from gagen.codegen.compiler import CompileError
    from gagen.control import smc

    try:  # before anything is built or written: a run shorter than one tick is refused here
        ticks = smc.loop_ticks(args.duration, args.rate)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    transient = min(0.5, (ticks // 2) * (1.0 / args.rate))  # a short run still has settled ticks to report
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"sliding-mode pose tracking, {args.spec or 'the Panda'}, {args.rate:g} Hz for {args.duration:g} s "
          f"(generated C step kernel and loop; building on first use)")
    try:
        arm = None if args.spec is None else _arm(args.spec)
        summary = smc.run_loop(args.duration, args.rate, out / "smc_log.csv", fifo=args.fifo,
                               transient=transient, smc=None if arm is None else smc.build(arm[0], q0=arm[1]))
    except ValueError as e:  # a spec that is not one arm (SpecError included)
        print(f"error: {e}", file=sys.stderr)
        return 2
    except (RuntimeError, CompileError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    print(f"  scheduler {summary.scheduler}: achieved {summary.achieved_rate_hz:.3f} Hz over {summary.ticks} "
          f"ticks, {summary.deadline_misses} deadline misses")
    print(f"  tick lateness mean {summary.jitter_mean_us:.1f} µs, std {summary.jitter_std_us:.1f} µs, "
          f"max {summary.jitter_max_us:.1f} µs; step work mean {summary.work_mean_us:.2f} µs")
    print(f"  tracking after {summary.transient_s:g} s: max |s_i| {summary.error_max:.2e}, position "
          f"{summary.position_error_max:.2e} m, direction {summary.direction_error_max:.2e}")
    for path in smc.plot_run(out / "smc_log.csv", out, transient=transient):
        print(f"  wrote {path}")
    return 0


VERBS = (Verb("smc", "sliding-mode pose tracking of a Panda in a real-time C loop (plots)", _smc_arguments,
              _smc),)
