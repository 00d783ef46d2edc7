"""The stereo application's verb: ``stereo`` (a bottle's symmetry axis from a rendered stereo pair as the
sliding-mode reference)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gagen.apps.stereo.bundled import RIG
from gagen.apps.stereo.pantilt_command import VERBS as PANTILT_VERBS
from gagen.arguments import non_negative_float, non_negative_int, positive_float
from gagen.registry import Verb


def _stereo_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--rig", default=str(RIG), help="calibration file (default: the bundled rig)")
    parser.add_argument("--duration", type=positive_float, default=5.0, help="seconds (default 5)")
    parser.add_argument("--noise", type=non_negative_float, default=1.0,
                        help="σ of the rendered vertices, px (default 1)")
    parser.add_argument("--pixel-noise", type=non_negative_float, default=2.0,
                        help="σ of the pixel values, grey levels (default 2)")
    parser.add_argument("--blur", type=non_negative_float, default=0.0,
                        help="σ of a Gaussian blur, px (default 0)")
    parser.add_argument("--clutter", type=non_negative_int, default=0, help="background shapes (default 0)")
    parser.add_argument("--seed", type=int, default=0, help="random seed of the noise (default 0)")
    parser.add_argument("--out", default="plots/stereo", help="folder for the log and the plots")


def _stereo(args: argparse.Namespace) -> int:
    import time

    from gagen.apps.stereo import track
    from gagen.apps.stereo.calibration import load_rig
    from gagen.apps.stereo.scene import SceneOptions
    from gagen.codegen.compiler import CompileError
    from gagen.errors import SpecError

    try:
        rig = load_rig(args.rig)
    except (SpecError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    out, start = Path(args.out), time.perf_counter()
    options = SceneOptions(vertex_jitter=args.noise, pixel_noise=args.pixel_noise, blur=args.blur,
                           clutter=args.clutter)
    print(f"stereo symmetry-axis tracking: {rig.name} ({rig.baseline:g} m baseline), {args.duration:g} s, "
          f"frames at {track.FPS:g} Hz, sliding-mode control at {track.RATE:g} Hz", flush=True)
    try:
        run = track.close_loop(rig, args.duration, options=options, seed=args.seed,
                               progress=lambda line: print(line, flush=True))
    except (RuntimeError, CompileError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    err = track.tracking_errors(run, transient=min(0.5, args.duration / 2))
    frames = len(run.frame_times)
    render, estimate = (1e3 * run.seconds[k] / frames for k in ("render", "estimate"))
    print(f"  frames: {frames}, failed {len(run.failures)}; render {render:.1f} ms, estimate "
          f"{estimate:.1f} ms per frame pair")
    print(f"  estimate vs the rendered pose: position median {1e3 * err['estimate_position_median']:.2f} mm "
          f"(max {1e3 * err['estimate_position_max']:.2f}), "
          f"axis median {err['estimate_axis_median_deg']:.3f}° "
          f"(max {err['estimate_axis_max_deg']:.3f}°)")
    print(f"  tracking: end point within {1e3 * err['position_vs_estimate']:.2f} mm of the estimate and "
          f"{1e3 * err['position_vs_truth']:.2f} mm of the true path; direction within "
          f"{err['direction_vs_truth']:.3f} of the true axis")
    for failure in run.failures[:5]:
        print(f"  failed: {failure}")
    for path in track.plots(run, rig, out):
        print(f"  wrote {path}")
    print(f"done in {time.perf_counter() - start:.1f} s")
    return 0


VERBS = (Verb("stereo", "a moving bottle rendered by a stereo rig at 30 Hz, its symmetry axis estimated "
                        "in CGA each "
                 "frame, tracked by the Panda's sliding-mode loop (plots)", _stereo_arguments, _stereo),
         *PANTILT_VERBS)
