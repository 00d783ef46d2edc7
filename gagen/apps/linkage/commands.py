"""The linkage application's verb: ``linkage`` (planar linkages along the driver's cycle)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gagen.arguments import positive_int
from gagen.registry import Verb


def _linkage_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("spec", nargs="*", help="linkage spec(s) (default: every bundled one in "
                        "gagen/apps/linkage/robots)")
    parser.add_argument("--steps", type=positive_int, default=360, help="driver steps per cycle: per crank "
                        "revolution or slider stroke (default 360)")
    parser.add_argument("--revolutions", type=positive_int, default=1, help="driver cycles (default 1)")
    parser.add_argument("--out", default="linkage", help="folder; each mechanism's files go to "
                        "<out>/<name>/ (default linkage/)")
    parser.add_argument("--frames", type=positive_int, default=72, help="GIF frames (default 72)")
    parser.add_argument("--no-animation", action="store_true", help="skip the GIF")


def _linkage(args: argparse.Namespace) -> int:
    """Planar linkages: per mechanism a report of the Newton solve at every crank step, the traced curve,
    the solver statistics and (unless --no-animation) a GIF in --out/<name>/. Exit status 2 for a bad
    spec (every spec is read before anything is compiled), 1 when a step fails to converge (the files
    are still written, to show where) or the kernels do not compile."""
    import time

    from gagen.apps.linkage import demo
    from gagen.apps.linkage.spec import load_linkage
    from gagen.codegen.compiler import CompileError
    from gagen.errors import SpecError

    specs = args.spec or [str(p) for p in demo.bundled()]
    try:
        linkages = [load_linkage(spec) for spec in specs]
    except (SpecError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    out, status, start = Path(args.out), 0, time.perf_counter()
    print(f"{len(linkages)} mechanism(s): {', '.join(m.name for m in linkages)}; {args.steps} steps per "
          f"cycle, {args.revolutions} cycle(s)", flush=True)
    for linkage in linkages:
        try:
            result = demo.run(linkage, out / linkage.name, steps=args.steps, revolutions=args.revolutions,
                              animation=not args.no_animation, frames=args.frames,
                              progress=lambda line: print(line, flush=True))
        except CompileError as e:
            print(f"error: {linkage.name}: {e}", file=sys.stderr)
            status = 1
            continue
        print(demo.summary(linkage, result.trajectory))
        print("  time: " + ", ".join(f"{k} {v:.2f} s" for k, v in result.seconds.items()))
        for path in result.files:
            print(f"  wrote {path} ({path.stat().st_size / 1e3:.0f} kB)")
        for failure in result.trajectory.failures:
            print(f"error: {linkage.name}: {failure}", file=sys.stderr)
        status = max(status, 1 if result.trajectory.failures else 0)
    print(f"done in {time.perf_counter() - start:.2f} s")
    return status


def _singularity_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("spec", nargs="+", help="linkage spec(s) of one driver (mobility 1)")
    parser.add_argument("--steps", type=positive_int, default=360, help="driver steps per cycle "
                        "(default 360)")
    parser.add_argument("--switch", action="store_true", help="go on past each singular point on the other "
                        "branch (back from a dead centre, across at a branch point) until the path closes")
    parser.add_argument("--out", default="linkage", help="folder; each mechanism's singularities.png goes to "
                        "<out>/<name>/ (default linkage/)")


def _singularities(args: argparse.Namespace) -> int:
    """Singular configurations along the driven cycle: a table (kind, driver value, σ_min of J_q and of
    the full Jacobian) and singularities.png per spec. Exit status 2 for a bad spec or one that is not
    driven by one driver, 1 when the analysis could not go on past a singular point."""
    import time

    from gagen.apps.linkage import singularity
    from gagen.apps.linkage.solver import kernels
    from gagen.apps.linkage.spec import load_linkage
    from gagen.errors import SpecError

    try:
        linkages = [load_linkage(spec) for spec in args.spec]
    except (SpecError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    for spec, linkage in zip(args.spec, linkages, strict=True):
        if len(linkage.drivers) != 1:
            print(f"error: {spec}: driver: the singularity analysis follows one driver; {linkage.name} has "
                  f"{len(linkage.drivers)}", file=sys.stderr)
            return 2
    status = 0
    for linkage in linkages:
        start = time.perf_counter()
        print(f"{linkage.name}: compiling the kernels, following {args.steps} {linkage.driver.kind} steps "
              f"per cycle{' (switching branches)' if args.switch else ''}", flush=True)
        try:
            analysis = singularity.analyse(kernels(linkage), linkage, args.steps, switch=args.switch,
                                           progress=lambda line: print(line, flush=True))
        except ValueError as e:
            print(f"error: {linkage.name}: {e}", file=sys.stderr)
            status = 2
            continue
        print(singularity.table(linkage, analysis))
        folder = Path(args.out) / linkage.name
        folder.mkdir(parents=True, exist_ok=True)
        figure = singularity.plot(linkage, analysis, folder / "singularities.png")
        print(f"  {len(analysis.values)} path points ({'closed' if analysis.closed else 'open'}), max |F| "
              f"{analysis.residuals.max():.1e}; wrote {figure} in {time.perf_counter() - start:.2f} s")
        for failure in analysis.failures:
            print(f"error: {linkage.name}: {failure}", file=sys.stderr)
            status = max(status, 1)
    return status


VERBS = (Verb("linkage", "planar linkages: Lie-algebra Newton along the driver's cycle (a crank's "
              "revolution, a slider's stroke); per-step report, traced curves, solver plots and a GIF",
              _linkage_arguments, _linkage),
         Verb("singularities", "singular configurations of a linkage along its driven cycle, from the "
              "constraint Jacobian: dead centres and branch points located to 1e-12, a table and a plot; "
              "--switch follows the other branch past each", _singularity_arguments, _singularities))
