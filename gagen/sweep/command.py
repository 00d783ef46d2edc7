"""``gagen sweep {manipulability,reach}``: the command line of the sweeps (arguments, run, report, plot).

The arguments need nothing beyond the standard library (every ``gagen`` call builds them); dask and pyarrow
are imported only when a sweep runs, and the system and the grid are checked then (they need its spec):
their errors name the option."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from gagen.arguments import finite_float, non_negative_int, positive_float, positive_int
from gagen.errors import print_error
from gagen.registry import Verb, bundled_specs

if TYPE_CHECKING:
    from gagen.sweep.problems import Sweep

DEFAULT_SYSTEM = "three_pandas_circle"  # = gagen.sweep.problems.DEFAULT_SYSTEM, without importing it
OPTIONS = {"system": "--system", "grid": "--grid", "samples": "--samples", "seed": "--seed",
           "chunk": "--chunk", "span": "--span", "radii": "--radius", "height": "--height", "N": "--N",
           "normal": "--normal"}
"""A SweepError's leading field -> the option that set it."""


def _common(parser: argparse.ArgumentParser, chunk: int) -> None:
    parser.add_argument("--system", default=DEFAULT_SYSTEM,
                        help="a spec file, or a bundled cooperative system: "
                             f"{', '.join(bundled_specs('cooperative'))} (default {DEFAULT_SYSTEM})")
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
    manipulability = kinds.add_parser("manipulability", help="the similarity-manipulability index and "
                                      "ellipsoid volume over random configurations or a grid, mapped by "
                                      "where the primitive is")
    _common(manipulability, 10_000)
    drawn = manipulability.add_mutually_exclusive_group()
    drawn.add_argument("--samples", type=positive_int, help="random configurations within the joint limits "
                       "(the default: 200000)")
    drawn.add_argument("--grid", action="append", metavar="JOINT=COUNT[:LOW:HIGH],...",
                       help="a regular grid instead: COUNT values of each named joint (its label, e.g. "
                       "arm0/panda_joint2, or its 0-based index in q) over its limits or [LOW, HIGH], the "
                       "other joints at the ready configuration; repeat or join with commas")
    manipulability.add_argument("--seed", type=non_negative_int, default=0,
                                help="random seed of --samples (default 0)")
    reach = kinds.add_parser("reach", help="iLQR reaching of a grid of target circles (horizontal) or "
                             "spheres, for a system spanning a circle or a sphere: success and final error "
                             "per target, a reachability map")
    _common(reach, 16)
    reach.add_argument("--grid", type=positive_int, default=21, help="centres per axis (default 21)")
    reach.add_argument("--span", type=finite_float,
                       help="half-width of the centre grid, m (default: 1.2 × the "
                       "default radius, 0.6 for the three Pandas)")
    reach.add_argument("--radius", type=positive_float, action="append",
                       help="target radius, m; repeat for several (default: the ready configuration's, to "
                       "5 cm: 0.5 for the three Pandas)")
    reach.add_argument("--height", type=finite_float, help="the centres' height, m (default: the ready "
                       "configuration's, to 1 cm: 0.59 for the three Pandas)")
    reach.add_argument("--normal", type=finite_float, nargs=3, metavar=("X", "Y", "Z"),
                       help="the target circles' "
                       "normal (default: the ready circle's, to 0.01: +z for the three Pandas); circles only")
    reach.add_argument("--N", type=positive_int, default=50, help="iLQR time steps (default 50)")


def _named(error: Exception) -> str:
    """The error with its leading field replaced by the option (``grid: …`` -> ``--grid: …``)."""
    text = str(error)
    field, colon, rest = text.partition(":")
    return f"{OPTIONS[field]}:{rest}" if colon and field in OPTIONS else text


def _sweep(args: argparse.Namespace) -> Sweep:
    from gagen.sweep.problems import Manipulability, Reach

    if args.sweep == "manipulability":
        if args.grid is not None:
            return Manipulability(grid=args.grid, chunk=args.chunk, seed=args.seed, system=args.system)
        return Manipulability(samples=args.samples or 200_000, chunk=args.chunk, seed=args.seed,
                              system=args.system)
    return Reach(grid=args.grid, span=args.span, radii=tuple(args.radius) if args.radius else None,
                 height=args.height, N=args.N, chunk=args.chunk, system=args.system,
                 normal=tuple(args.normal) if args.normal else None)


def run(args: argparse.Namespace) -> int:
    """Exit status 0 when every chunk is written, 1 when some failed (re-run to retry), 2 for bad input (a
    missing ``sweep`` extra included: the verb ``needs`` its modules)."""
    from gagen.sweep import plots, problems
    from gagen.sweep.engine import run as run_sweep
    from gagen.sweep.store import ChunkStore, SweepError

    try:
        sweep = _sweep(args)
    except SweepError as e:
        print_error(_named(e))
        return 2
    try:
        where = args.scheduler or f"a local cluster of {args.workers} worker processes"
        print(f"{sweep.kind} sweep of {sweep.system}: {sweep.rows} rows in {sweep.chunks} chunks of "
              f"{sweep.chunk} into {args.out}, on {where}", flush=True)
        outcome = run_sweep(sweep, args.out, scheduler=args.scheduler, workers=args.workers,
                            progress=not args.no_progress)
    except (SweepError, OSError) as e:
        print_error(e)
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
    kind = sweep.cell.kind
    if isinstance(sweep, problems.Reach):
        reached = int(table.column("success").to_numpy(zero_copy_only=False).sum())
        if kind == "sphere":
            targets = "target spheres"
        else:
            assert sweep.normal is not None  # circle targets have one (Reach.__post_init__)
            targets = ("horizontal target circles" if sweep.normal == (0.0, 0.0, 1.0) else
                       f"target circles normal to ({', '.join(f'{n:g}' for n in sweep.normal)})")
        print(f"  reached {reached} of {table.num_rows} {targets}")
        path = plots.reach_map(table, Path(args.out) / "reachability.png", system=sweep.system,
                               targets=targets)
    else:
        where = {"circle": "circle centre", "sphere": "sphere centre", "point_pair": "midpoint"}.get(
            kind, "end points' centroid")
        try:
            path = plots.manipulability_map(table, Path(args.out) / "manipulability.png", system=sweep.system,
                                            where=where)
        except ValueError as e:
            print(f"  no map: {e}")
            return 0
    print(f"  wrote {path}")
    return 0


VERBS = (Verb("sweep", "distributed sweeps on Dask, chunked and resumable: a bundled system's manipulability "
              "over random configurations or a grid, or iLQR reaching over target circles or spheres",
              add_arguments, run, needs=("dask", "distributed", "pyarrow", "tqdm")),)
