"""The hexapod application's verb: ``walk`` (a tripod gait with plots and an animation)."""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path
from typing import Any

from gagen.apps.hexapod.bundled import SPEC
from gagen.arguments import finite_float, non_negative_float, positive_float, positive_int
from gagen.registry import Verb


def _gait_arguments(parser: argparse.ArgumentParser, out: str) -> None:
    """The spec, the module, the output folder, the path, the ground and the lean: ``walk`` and
    ``walk-sim`` plan the same gait."""
    parser.add_argument("spec", nargs="?", default=str(SPEC), help="hexapod spec (default: the bundled one)")
    parser.add_argument("--out", default=out, help=f"folder for the plots and the GIF (default {out}/)")
    parser.add_argument("--module", help="build the module into this folder (default: the committed "
                        "generated/ for the bundled spec, else the gagen cache)")
    parser.add_argument("--straight", type=finite_float, default=0.3, help="straight part of the path, m "
                        "(default 0.3)")
    parser.add_argument("--turn", type=finite_float, default=60.0,
                        help="then an arc turning this far, degrees, "
                        "+ left (default 60)")
    parser.add_argument("--radius", type=positive_float, default=0.3, help="the arc's radius, m "
                                                                           "(default 0.3)")
    parser.add_argument("--height", type=positive_float, default=0.15, help="body height above the ground "
                        "along its normal, m (default 0.15)")
    parser.add_argument("--stride", type=positive_float, default=0.10, help="body travel per gait cycle "
                        "(two steps), m (default 0.10)")
    parser.add_argument("--step-time", type=positive_float, default=0.5, help="seconds per step "
                                                                              "(default 0.5)")
    parser.add_argument("--step-height", type=finite_float, default=0.05,
                        help="swing toe lift, m (default 0.05)")
    parser.add_argument("--slope", type=finite_float, default=0.0,
                        help="ground slope, degrees (default 0: flat)")
    parser.add_argument("--uphill", type=finite_float, default=0.0,
                        help="heading the ground rises towards, degrees "
                        "from +x (default 0)")
    parser.add_argument("--rate", type=positive_float, default=100.0, help="samples per second (default 100)")
    parser.add_argument("--lean", type=_lean, default=0.0, help="lean the body uphill this many m, the "
                        "footholds unmoved, or 'auto': the lean that puts the CoM back over the feet "
                        "as on flat ground (default 0)")
    parser.add_argument("--no-animation", action="store_true", help="skip the GIF")


def _walk_arguments(parser: argparse.ArgumentParser) -> None:
    _gait_arguments(parser, "walk")
    parser.add_argument("--frames", type=positive_int, default=90, help="GIF frames (default 90)")
    parser.add_argument("--margin", type=finite_float, help="keep a static stability margin of at least this "
                        "many m (shortens the stride; refused when no stride keeps it)")
    parser.add_argument("--mu", type=non_negative_float, default=0.5, help="friction coefficient of the "
                        "feet's cones (default 0.5)")


def _lean(text: str) -> float | str:
    return "auto" if text == "auto" else finite_float(text)


def _plan(args: argparse.Namespace) -> tuple[Any, Any, Any, Any] | int:
    """(hexapod, module, gait parameters, ground) of the command line, the lean solved for 'auto'; or,
    printed in one line, the exit status: 2 for a bad file or parameter, 1 for a failed build."""
    from gagen.codegen.compiler import CompileError
    from gagen.errors import SpecError

    try:
        return _planned(args)
    except (SpecError, ValueError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except CompileError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1


def _planned(args: argparse.Namespace) -> tuple[Any, Any, Any, Any]:
    from gagen.apps.hexapod import gait, gait_statics
    from gagen.apps.hexapod.spec import load_hexapod

    hexapod = load_hexapod(args.spec)
    params = gait.GaitParameters(straight=args.straight, turn=math.radians(args.turn), radius=args.radius,
                                 height=args.height, stride=args.stride, step_time=args.step_time,
                                 step_height=args.step_height, rate=args.rate)
    ground = gait.Ground(math.radians(args.slope), math.radians(args.uphill))
    module = gait.hexapod_module(args.spec, args.module, progress=lambda line: print(line, flush=True))
    try:
        lean = (gait_statics.balanced_lean(module, hexapod, params, ground) if args.lean == "auto"
                else args.lean)
    except ValueError as e:
        raise ValueError(f"--lean: {e}") from e
    params = dataclasses.replace(params, lean=lean)
    if params.lean:
        print(f"the body leans {params.lean:.4f} m uphill (footholds unmoved)", flush=True)
    return hexapod, module, params, ground


def _walk(args: argparse.Namespace) -> int:
    """A tripod gait of a hexapod: the report, plots and (unless --no-animation) a GIF in --out. Exit
    status 1 when a leg is unreachable or a joint passes its limit anywhere on the walk (the files are
    still written, to show where), 2 for a bad spec or parameters."""
    import time

    from gagen.apps.hexapod import gait

    start = time.perf_counter()
    planned = _plan(args)
    if isinstance(planned, int):
        return planned
    hexapod, module, params, ground = planned
    from gagen.apps.hexapod import gait_statics

    if args.margin is not None:
        print(f"keeping a stability margin >= {args.margin:g} m: searching the stride", flush=True)
        try:
            plan = gait_statics.keep_margin(module, hexapod, params, ground, args.margin,
                                            progress=lambda line: print(line, flush=True))
        except ValueError as e:
            print(f"error: {e}", file=sys.stderr)
            return 2
        print(f"stride {params.stride:g} -> {plan.params.stride:.4f} m (min margin {plan.margin:.4f} m, "
              f"{len(plan.tries)} walks)")
        params = plan.params
    result = gait.walk(module, hexapod, params, ground, progress=lambda line: print(line, flush=True))
    from gagen.apps.hexapod.statics import DegenerateSupport

    try:
        statics = gait_statics.check_walk(result, mu=args.mu, progress=lambda line: print(line, flush=True))
    except DegenerateSupport as e:
        print(f"error: the walk's stance has no support polygon: {e}", file=sys.stderr)
        return 1
    print(gait.summary(result))
    print("\n".join(statics.lines()))
    print(f"walk computed in {time.perf_counter() - start:.2f} s")
    from gagen.apps.hexapod import plots

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for path in (plots.joint_angles(result, out / "joint_angles.png"),
                 plots.toe_paths(result, out / "toe_paths.png"),
                 gait_statics.margin_plot(statics, out / "margin.png", args.margin)):
        print(f"  wrote {path}")
    if not args.no_animation:
        print(f"animating {args.frames} frames (matplotlib 3D, Pillow GIF)", flush=True)
        gif = plots.animate(result, out / "walk.gif", frames=args.frames,
                            progress=lambda line: print(line, flush=True))
        print(f"  wrote {gif} ({gif.stat().st_size / 1e6:.2f} MB)")
    print(f"done in {time.perf_counter() - start:.2f} s")
    if not result.ok:
        print(f"error: the walk is not feasible: {len(result.unreachable)} unreachable run(s), "
              f"{len(result.past_limits)} joint-limit violation(s); first: {result.flags()[0]}",
              file=sys.stderr)
        return 1
    if not statics.ok:
        print(f"error: the walk does not stand: min stability margin {statics.margin_min()[0]:.4f} m, "
              f"max |f_t|/f_n {statics.ratio_max()[0]:.4f} (mu = {args.mu:g})"
              + (f"; {statics.first_infeasible}" if statics.first_infeasible else ""), file=sys.stderr)
        return 1
    return 0


def _walk_sim_arguments(parser: argparse.ArgumentParser) -> None:
    _gait_arguments(parser, "walk_sim")
    parser.add_argument("--fps", type=positive_float, default=10.0, help="GIF frames per second (default 10)")


def _walk_sim(args: argparse.Namespace) -> int:
    """The tripod gait played in MuJoCo (gagen.apps.hexapod.mujoco_walk): drift, slip, margin, cones.
    Exit 2 for a bad spec or parameters, 1 when the planned walk is not feasible or the simulated walk
    fails its bounds."""
    from gagen.apps.hexapod.mujoco_walk import walk_sim

    planned = _plan(args)
    return planned if isinstance(planned, int) else walk_sim(args, *planned)


VERBS = (Verb("walk", "a hexapod's tripod gait (straight, then a turn) on flat or sloped ground: slip, "
                      "limit margins, "
                 "reachability; plots and a GIF", _walk_arguments, _walk, needs=("proxsuite",)),
         Verb("walk-sim", "the tripod gait played in MuJoCo on flat or sloped ground: body drift, slip, "
                          "stability margin, friction cones; a plot and an offscreen GIF",
              _walk_sim_arguments, _walk_sim, needs=("mujoco",)))
