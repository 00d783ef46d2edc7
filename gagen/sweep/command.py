"""``gagen sweep {manipulability,reach}``: the command line of the sweeps (arguments, run, report, plot).

The arguments need nothing beyond the standard library (every ``gagen`` call builds them); dask and pyarrow
are imported only when a sweep runs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gagen.cli import non_negative_int, positive_float, positive_int


def _common(parser: argparse.ArgumentParser, chunk: int) -> None:
    parser.add_argument("--out", required=True, help="folder of the chunk files, sweep.json and the plot; "
                        "a re-run into it skips the finished chunks")
    parser.add_argument("--workers", type=positive_int, default=2,
                        help="worker processes of the local cluster (default 2; ignored with --scheduler)")
    parser.add_argument("--chunk", type=positive_int, default=chunk,
                        help=f"rows per chunk (default {chunk})")
    parser.add_argument("--scheduler", help="address of a running Dask scheduler (tcp://host:8786) instead "
                        "of a local cluster")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    kinds = parser.add_subparsers(dest="sweep", required=True)
    manipulability = kinds.add_parser("manipulability", help="the similarity-manipulability index of the "
                                      "three Pandas over random configurations, by the circle's centre")
    _common(manipulability, 10_000)
    manipulability.add_argument("--samples", type=positive_int, default=200_000,
                                help="random configurations (default 200000)")
    manipulability.add_argument("--seed", type=non_negative_int, default=0, help="random seed (default 0)")
    reach = kinds.add_parser("reach", help="iLQR reaching of a grid of horizontal target circles by the "
                             "three Pandas: success and final error per target, a reachability map")
    _common(reach, 16)
    reach.add_argument("--grid", type=positive_int, default=21, help="centres per axis (default 21)")
    reach.add_argument("--span", type=float, default=0.6,
                       help="half-width of the centre grid, m (default 0.6)")
    reach.add_argument("--radius", type=positive_float, action="append",
                       help="target radius, m; repeat for several (default 0.5)")
    reach.add_argument("--height", type=float, default=0.59, help="the circles' height, m (default 0.59: "
                       "the ready configuration's)")
    reach.add_argument("--N", type=positive_int, default=50, help="iLQR time steps (default 50)")


def run(args: argparse.Namespace) -> int:
    """Exit status 0 when every chunk is written, 1 when some failed (re-run to retry), 2 for bad input."""
    from gagen.sweep import plots
    from gagen.sweep.engine import run as run_sweep
    from gagen.sweep.problems import Manipulability, Reach
    from gagen.sweep.store import ChunkStore, SweepError

    try:
        if args.sweep == "manipulability":
            sweep = Manipulability(samples=args.samples, chunk=args.chunk, seed=args.seed)
        else:
            sweep = Reach(grid=args.grid, span=args.span, radii=tuple(args.radius or (0.5,)),
                          height=args.height, N=args.N, chunk=args.chunk)
        where = args.scheduler or f"a local cluster of {args.workers} worker processes"
        print(f"{sweep.kind} sweep: {sweep.chunks} chunks of {sweep.chunk} into {args.out}, on {where}",
              flush=True)
        outcome = run_sweep(sweep, args.out, scheduler=args.scheduler, workers=args.workers,
                            progress=not args.no_progress)
    except (SweepError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    rate = f", {outcome.rows / outcome.seconds:,.0f} rows/s" if outcome.rows and outcome.seconds > 0 else ""
    print(f"  computed {len(outcome.computed)} chunks in {outcome.seconds:.2f} s on {outcome.workers} workers"
          f"{rate}; {outcome.skipped} were already finished")
    for index, error in sorted(outcome.failed.items()):
        print(f"error: chunk {index} failed: {error}", file=sys.stderr)
    if outcome.failed:
        print(f"error: {len(outcome.failed)} chunks failed; re-run the same command to retry them",
              file=sys.stderr)
        return 1
    table = ChunkStore(args.out).read(sweep.chunks)
    if sweep.kind == "reach":
        reached = int(table.column("success").to_numpy().sum())
        print(f"  reached {reached} of {table.num_rows} target circles")
        path = plots.reach_map(table, Path(args.out) / "reachability.png")
    else:
        path = plots.manipulability_map(table, Path(args.out) / "manipulability.png")
    print(f"  wrote {path}")
    return 0
