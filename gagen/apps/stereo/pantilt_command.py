"""The verb ``gagen track-head [RIG]``: the pan-tilt head's closed loop on the ideal object and through
vision without and with image noise (``pantilt_loop``): a table, ``offset.png`` and ``view.gif``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gagen.apps.stereo.bundled import RIG
from gagen.arguments import non_negative_float, positive_float
from gagen.registry import Verb


def _arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("rig", nargs="?", default=str(RIG),
                        help="calibration file (default: the bundled rig)")
    parser.add_argument("--duration", type=positive_float, default=5.0, help="seconds (default 5)")
    parser.add_argument("--noise", type=non_negative_float, default=1.0,
                        help="σ of the rendered vertices in the noisy run, px (default 1)")
    parser.add_argument("--pixel-noise", type=non_negative_float, default=2.0,
                        help="σ of the pixel values in the noisy run, grey levels (default 2)")
    parser.add_argument("--gain", type=positive_float, default=None, help="k, rad/s (default 2)")
    parser.add_argument("--epsilon", type=positive_float, default=None, help="tanh slope ε (default 100)")
    parser.add_argument("--seed", type=int, default=0, help="random seed of the noise (default 0)")
    parser.add_argument("--out", default="plots/track-head", help="folder for offset.png and view.gif")


def _run(args: argparse.Namespace) -> int:
    import time

    from gagen.apps.stereo import pantilt, pantilt_loop, scene
    from gagen.apps.stereo.calibration import load_rig
    from gagen.codegen.compiler import CompileError
    from gagen.errors import SpecError

    try:
        rig = load_rig(args.rig)
    except (SpecError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    start, out = time.perf_counter(), Path(args.out)

    def say(line: str) -> None:
        print(line, flush=True)

    try:
        head = pantilt.Head(rig, args.gain or pantilt.GAIN, args.epsilon or pantilt.EPSILON)
        path = pantilt_loop.for_rig(rig)
        bound = pantilt_loop.reaching_bound(head, path)
        say(f"pan-tilt tracking: {rig.name}, {args.duration:g} s, k = {head.gains[0]:g} rad/s, ε = "
            f"{head.gains[1]:g}; frames at {pantilt_loop.FPS:g} Hz, control at {pantilt_loop.RATE:g} Hz")
        ideal = pantilt_loop.run_ideal(rig, args.duration, head=head, trajectory=path)
        reached = pantilt_loop.reaching_time(ideal, bound.layer)
        say(f"  ideal loop: |σ| ≤ 1/ε after {reached:.3f} s (theory: {bound.earliest:.3f} … "
            f"{bound.bound:.3f} s)")
        runs = [ideal]
        for label, options in (("clean", scene.SceneOptions()),
                               (f"{args.noise:g} px, grey σ {args.pixel_noise:g}",
                                scene.SceneOptions(vertex_jitter=args.noise, pixel_noise=args.pixel_noise))):
            say(f"  vision loop, {label} images:")
            runs.append(pantilt_loop.run_vision(rig, args.duration, head=head, trajectory=path,
                                                options=options, seed=args.seed, keep_frames=3, progress=say))
    except (RuntimeError, ValueError, CompileError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    transient = min(pantilt_loop.TRANSIENT, args.duration / 2)
    say(f"\n{f'after {transient:g} s':<16} axis line px    centre px       angle °          estimate mm     "
        f"estimate axis °   failed")
    say("                 max / median    max / median    max / median     median / max    median / max")
    for name, run in zip(("ideal", "vision clean", "vision noisy"), runs, strict=True):
        m = run.summary(transient)
        est = ("         -                -" if run.mode == "ideal" else
               f"{m['estimate_mm_median']:6.2f} / {m['estimate_mm_max']:<6.2f}  "
               f"{m['estimate_deg_median']:6.3f} / {m['estimate_deg_max']:<6.3f}  {len(run.failures)}")
        say(f"{name:<16} {m['line_offset_px_max']:5.2f} / {m['line_offset_px_median']:<6.2f}  "
            f"{m['centre_offset_px_max']:5.2f} / {m['centre_offset_px_median']:<6.2f}  "
            f"{m['angle_deg_max']:6.3f} / {m['angle_deg_median']:<6.3f}  {est}")
    for failure in runs[-1].failures[:5]:
        say(f"  failed: {failure}")
    say(f"wrote {pantilt_loop.plot(runs, out, transient)}")
    if runs[-1].frames:
        say(f"wrote {pantilt_loop.gif(runs[-1].frames, out / 'view.gif')}")
    say(f"done in {time.perf_counter() - start:.1f} s")
    return 0


VERBS = (Verb("track-head", "a pan-tilt head carrying the stereo rig keeps a moving bottle centred: the "
                            "sliding-mode law on L_Vref [SMC Eq. 29], closed through rendering and the "
                            "estimator (table, plots, GIF)", _arguments, _run),)
