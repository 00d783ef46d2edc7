"""The ``gagen`` command line: ``demo`` (the compiler core on CGA formulas), ``algebra`` (a preset's
metric and blade order), ``kernels`` (a spec's kernel catalogue with op counts) and ``build`` (the
generated module of a spec or of a Python file of kernels, optionally checked against the
interpreter), ``reach`` (IPOPT cooperative reaching on a paper scenario), ``smc`` (sliding-mode
tracking in a real-time loop), ``walk`` (a hexapod's tripod gait, with plots and an animation),
``linkage`` (planar linkages along a crank revolution: solver report, traced curves, a GIF),
``stereo`` (a bottle's symmetry axis from a rendered stereo pair as the sliding-mode reference) and
``sweep`` (chunked, resumable sweeps on Dask: manipulability maps, reachability of target circles)."""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

from gagen import __version__


def _cmd_demo(args: argparse.Namespace) -> int:
    from gagen.demo import run

    worst = run(samples=args.samples, seed=args.seed)
    if worst > args.tolerance:
        print(f"error: kernels disagree with the interpreter beyond {args.tolerance:g}", file=sys.stderr)
        return 1
    return 0


def _cmd_algebra(args: argparse.Namespace) -> int:
    from gagen.algebra.signature import preset

    try:
        algebra = preset(args.name)
    except KeyError as e:
        print(f"error: {e.args[0]}", file=sys.stderr)
        return 2
    p, q, r = algebra.signature
    print(f"{algebra.name}: G({p},{q},{r}), {algebra.size} blades")
    print("metric (e_i . e_j):")
    names = ["e" + v for v in algebra.vector_labels]
    width = max(map(len, names)) + 1
    print(" " * width + "".join(f"{n:>{width}}" for n in names))
    for n, row in zip(names, algebra.metric, strict=True):
        print(f"{n:>{width}}" + "".join(f"{v!s:>{width}}" for v in row))
    print("blades by bitmask: " + ", ".join(f"{m}:{algebra.blade_name(m)}" for m in range(algebra.size)))
    return 0


def _cmd_kernels(args: argparse.Namespace) -> int:
    import time

    from gagen.build import load_source
    from gagen.errors import SpecError
    from gagen.frontend import KernelError
    from gagen.report import op_count_table

    start = time.perf_counter()
    try:
        source = load_source(args.spec)
        kernels = [source.kernels[name] for name in source.kernels]
    except (SpecError, KernelError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"{source.name}: {source.title}; {len(kernels)} kernels built in "
          f"{time.perf_counter() - start:.2f} s\n")
    print(op_count_table(kernels))
    return 0


def _cmd_build(args: argparse.Namespace) -> int:
    from gagen.build import OutputError, build_many
    from gagen.codegen.backends import TemplateNotFound
    from gagen.codegen.compiler import CompileError
    from gagen.errors import SpecError

    if args.output and len(args.spec) > 1:
        print("error: -o/--output takes one file; several go to generated/<name>", file=sys.stderr)
        return 2
    if args.name and (len(args.spec) > 1 or Path(args.spec[0]).suffix != ".py"):
        print("error: --name names the module of one Python file (a spec names its system)", file=sys.stderr)
        return 2
    from gagen.frontend import KernelError

    errors: tuple[type[BaseException], ...] = (SpecError, KernelError, FileNotFoundError)
    try:
        results = build_many(args.spec, force=args.force, compile_c=not args.no_compile, jobs=args.jobs,
                             outputs=[args.output] if args.output else None,
                             names=[args.name] if args.name else None)
    except errors as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except (CompileError, OutputError, TemplateNotFound) as e:  # OutputError: "cannot write <path>: <reason>"
        print(f"error: {e}", file=sys.stderr)
        return 1
    status = 0
    if args.check:
        for spec, result in zip(args.spec, results, strict=True):
            if result.source.functions:  # front-end kernels (a Python file, a hexapod spec)
                status = max(status, _check_kernels(result, args.samples, args.tolerance))
            else:
                status = max(status, _check(spec, result.folder, args.samples, args.tolerance))
    return status


def _check_kernels(result, samples: int, tolerance: float) -> int:
    """The kernels of a Python file against their functions run on the interpreter (``gagen.check``)."""
    from gagen.check import check_kernels, failures, format_report
    from gagen.runtime import load

    source = result.source
    print(f"{source.name}: checking every kernel (C single, C batched, CasADi) against the interpreter on "
          f"{samples} random samples", flush=True)
    report = check_kernels(load(result.folder), source.functions, count=samples, rtol=tolerance,
                           progress=lambda line: print(line, flush=True))
    print(format_report(report))
    failed = failures(report)
    for d in failed:
        print(f"error: {source.name}: {d.message()}", file=sys.stderr)
    return 1 if failed else 0


def _check(spec: str, folder, samples: int, tolerance: float) -> int:
    """Every kernel against the interpreter on every named configuration and ``samples`` random ones
    within the joint limits; relative tolerances (``tolerance`` for values, 1e-6 for the Richardson
    differences of the AD Jacobians; see ``gagen.check``). Exit status 1 naming each failing output."""
    from gagen.apps.cooperative.spec import load_system
    from gagen.check import FD_RTOL, FD_STEPS, check_module, failures, format_report
    from gagen.runtime import load

    system, configurations = load_system(spec)
    named = ", ".join(configurations) or "none"
    print(f"{system.name}: checking every kernel (C single, C batched, CasADi) on {len(configurations)} "
          f"named configurations ({named}) and {samples} random samples within the joint limits", flush=True)
    report = check_module(load(folder), system, configurations, count=samples, rtol=tolerance,
                          progress=lambda line: print(line, flush=True))
    print(format_report(report))
    worst_value = max((d.worst for d in report if d.reference == "interpreter"), default=0.0)
    worst_fd = max((d.worst for d in report if d.reference != "interpreter"), default=0.0)
    print(f"max relative error: {worst_value:.2e} against the interpreter (tolerance {tolerance:g}), "
          f"{worst_fd:.2e} against Richardson central differences (steps {FD_STEPS[0]:g}…{FD_STEPS[-1]:g}, "
          f"tolerance {FD_RTOL:g})")
    failed = failures(report)
    for d in failed:
        print(f"error: {system.name}: {d.message()}", file=sys.stderr)
    return 1 if failed else 0


def non_negative_float(text: str) -> float:
    """argparse type: a finite number ≥ 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"expected a finite number ≥ 0, got {text!r}")
    return value


def non_negative_int(text: str) -> int:
    """argparse type: an integer ≥ 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer ≥ 0, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0 (nan, inf, 0 and negatives are refused with a message)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return value


def _cmd_smc(args: argparse.Namespace) -> int:
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
    print(f"sliding-mode pose tracking, Panda, {args.rate:g} Hz for {args.duration:g} s "
          f"(generated C step kernel and loop; building on first use)")
    try:
        summary = smc.run_loop(args.duration, args.rate, out / "smc_log.csv", fifo=args.fifo,
                               transient=transient)
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


def _cmd_reach(args: argparse.Namespace) -> int:
    from gagen.apps.cooperative.scenarios import main as scenarios

    try:  # the library's own checks (e.g. a horizon too short for N steps) as one line, not a traceback
        return scenarios([args.scenario, "--out", args.out, "--N", str(args.N), "--horizon",
                          repr(args.horizon), "--solver", args.solver, "--hessian", args.hessian]
                         + (["--view", "--port", str(args.port)] if args.view else []))
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


def _cmd_nullspace(args: argparse.Namespace) -> int:
    from gagen.apps.cooperative.nullspace_demo import main as demo

    return demo(["--out", args.out] + (["--view", "--port", str(args.port)] if args.view else []))


def _cmd_impedance(args: argparse.Namespace) -> int:
    from gagen.apps.cooperative.impedance_demo import main as demo
    from gagen.dynamics.rigid_body import DynamicsError

    try:  # a missing Pinocchio or a degenerate run as one line, not a traceback
        view = ["--view", "--port", str(args.port)] if args.view else []
        return demo(["--out", args.out, "--runs", str(args.runs), "--spread", repr(args.spread),
                     "--duration", repr(args.duration), *view])
    except DynamicsError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


def _cmd_mpc(args: argparse.Namespace) -> int:
    from gagen.apps.cooperative.mpc_demo import main as demo

    view = ["--view", "--port", str(args.port)] if args.view else []
    return demo(["--out", args.out, "--rate", repr(args.rate), "--duration", repr(args.duration), *view]
                + (["--no-animation"] if args.no_animation else []))


def _cmd_view(args: argparse.Namespace) -> int:
    from gagen.viewer.command import run

    return run(args)


def _cmd_teleop(args: argparse.Namespace) -> int:
    from gagen.apps.cooperative.teleop import main as teleop

    source = ["--trace", args.trace] if args.trace else ["--keyboard"] if args.keyboard else ["--spacemouse"]
    try:  # a malformed trace, an unknown system, a missing SpaceMouse: one line, not a traceback
        return teleop([args.system, *source, "--dt", repr(args.dt), "--out", args.out]
                      + (["--first-order"] if args.first_order else [])
                      + (["--view", "--port", str(args.port)] if args.view else []))
    except (ValueError, RuntimeError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


def _cmd_walk(args: argparse.Namespace) -> int:
    """A tripod gait of a hexapod: the report, plots and (unless --no-animation) a GIF in --out. Exit
    status 1 when a leg is unreachable or a joint passes its limit anywhere on the walk (the files are
    still written, to show where), 2 for a bad spec or parameters."""
    import time

    from gagen.apps.hexapod import gait
    from gagen.codegen.compiler import CompileError
    from gagen.errors import SpecError

    start = time.perf_counter()
    try:
        hexapod = gait.load_hexapod(args.spec)
        params = gait.GaitParameters(straight=args.straight, turn=math.radians(args.turn), radius=args.radius,
                                     height=args.height, stride=args.stride, step_time=args.step_time,
                                     step_height=args.step_height, rate=args.rate)
        ground = gait.Ground(math.radians(args.slope), math.radians(args.uphill))
        module = gait.hexapod_module(args.spec, args.module, progress=lambda line: print(line, flush=True))
    except (SpecError, ValueError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except CompileError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    result = gait.walk(module, hexapod, params, ground, progress=lambda line: print(line, flush=True))
    print(gait.summary(result))
    print(f"walk computed in {time.perf_counter() - start:.2f} s")
    from gagen.apps.hexapod import plots

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for path in (plots.joint_angles(result, out / "joint_angles.png"),
                 plots.toe_paths(result, out / "toe_paths.png")):
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
    return 0


def _cmd_stereo(args: argparse.Namespace) -> int:
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
    e = track.tracking_errors(run, transient=min(0.5, args.duration / 2))
    frames = len(run.frame_times)
    render, estimate = (1e3 * run.seconds[k] / frames for k in ("render", "estimate"))
    print(f"  frames: {frames}, failed {len(run.failures)}; render {render:.1f} ms, estimate "
          f"{estimate:.1f} ms per frame pair")
    print(f"  estimate vs the rendered pose: position median {1e3 * e['estimate_position_median']:.2f} mm "
          f"(max {1e3 * e['estimate_position_max']:.2f}), axis median {e['estimate_axis_median_deg']:.3f}° "
          f"(max {e['estimate_axis_max_deg']:.3f}°)")
    print(f"  tracking: end point within {1e3 * e['position_vs_estimate']:.2f} mm of the estimate and "
          f"{1e3 * e['position_vs_truth']:.2f} mm of the true path; direction within "
          f"{e['direction_vs_truth']:.3f} of the true axis")
    for failure in run.failures[:5]:
        print(f"  failed: {failure}")
    for path in track.plots(run, rig, out):
        print(f"  wrote {path}")
    print(f"done in {time.perf_counter() - start:.1f} s")
    return 0


def _cmd_linkage(args: argparse.Namespace) -> int:
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


def _view_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    """``--view`` and ``--port``: play a demo's joint trajectory in the browser (gagen.viewer)."""
    parser.add_argument("--view", action="store_true",
                        help=f"then play {what} in the browser viewer (http://127.0.0.1:PORT) until Ctrl-C")
    from gagen.viewer import DEFAULT_PORT

    parser.add_argument("--port", type=int, default=DEFAULT_PORT,
                        help=f"the viewer's port on 127.0.0.1 (default {DEFAULT_PORT})")


def _cmd_sweep(args: argparse.Namespace) -> int:
    try:
        from gagen.sweep.command import run
    except ImportError as e:  # dask or pyarrow missing: say which extra brings them
        print(f"error: gagen sweep needs the sweep extra (pip install 'gagen[sweep]'): {e}", file=sys.stderr)
        return 2
    return run(args)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="gagen", description="Symbolic code generation for conformal "
                                     "geometric algebra in robotics.")
    parser.add_argument("--version", action="version", version=f"gagen {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="flatten a few CGA formulas and check them against the interpreter")
    demo.add_argument("--samples", type=int, default=1000, help="random inputs per formula (default 1000)")
    demo.add_argument("--seed", type=int, default=0)
    demo.add_argument("--tolerance", type=float, default=1e-12, help="fail above this relative error")
    demo.set_defaults(run=_cmd_demo)

    alg = sub.add_parser("algebra", help="print an algebra preset: metric and blade order")
    alg.add_argument("name", help="cga3d, cga2d, pga3d or ga3d")
    alg.set_defaults(run=_cmd_algebra)

    kernels = sub.add_parser("kernels", help="build a spec's kernels and print their shapes and op counts")
    kernels.add_argument("spec", help="a spec (YAML: a robot system or a hexapod), e.g. "
                         "robots/three_pandas_circle.yaml, or a Python file of @gagen.kernel functions")
    kernels.set_defaults(run=_cmd_kernels)

    build = sub.add_parser("build", help="generate a module of kernels: CasADi Functions, C kernels, library")
    build.add_argument("spec", nargs="+", help="spec(s) (YAML: robot systems or hexapods), e.g. "
                       "robots/three_pandas_circle.yaml, or Python files of @gagen.kernel functions")
    build.add_argument("-o", "--output", help="output folder (one file only; default generated/<name>)")
    build.add_argument("--name", help="the module name of a Python file (default: the file's stem)")
    build.add_argument("--force", action="store_true", help="rebuild even if the cached build is up to date")
    build.add_argument("--no-compile", action="store_true", help="write the C source but do not compile it")
    build.add_argument("--check", action="store_true",
                       help="evaluate every kernel against the interpreter and print the maximum error")
    build.add_argument("-j", "--jobs", type=int, help="parallel C compilations (default: CPU count)")
    build.add_argument("--samples", type=int, default=5, help="random inputs for --check (default 5)")
    build.add_argument("--tolerance", type=float, default=1e-10, help="--check fails above this error")
    build.set_defaults(run=_cmd_build)

    reach = sub.add_parser("reach", help="cooperative reaching with IPOPT on a paper scenario, with plots")
    reach.add_argument("scenario", help="line, circle, plane, hand_sphere, humanoids_sphere or all")
    reach.add_argument("--out", default="plots", help="folder for the plots (default plots/)")
    reach.add_argument("--N", type=positive_int, default=100, help="time steps (default 100)")
    reach.add_argument("--horizon", type=positive_float, default=2.5, help="seconds (default 2.5)")
    reach.add_argument("--solver", choices=("ipopt", "fatrop", "ilqr"), default="ipopt",
                       help="solver (default ipopt; ilqr: the structured iLQR in C)")
    reach.add_argument("--hessian", choices=("exact", "gauss-newton"), default="exact",
                       help="Hessian of the Lagrangian (gauss-newton: IPOPT only; default exact)")
    _view_arguments(reach, "the optimal trajectory")
    reach.set_defaults(run=_cmd_reach)

    nullspace = sub.add_parser("nullspace", help="one of three Pandas moves along the circle through N(q), "
                               "with and without the projection (plots)")
    nullspace.add_argument("--out", default="plots", help="folder for the plot (default plots/)")
    _view_arguments(nullspace, "both runs")
    nullspace.set_defaults(run=_cmd_nullspace)

    impedance = sub.add_parser("impedance", help="similarity impedance control of three iiwa 14 on a "
                               "circle and a plane: runs of Pinocchio forward dynamics [COOP Fig. 6]")
    impedance.add_argument("--out", default="plots/impedance", help="folder for the plot and the report")
    impedance.add_argument("--runs", type=positive_int, default=10,
                           help="random starts per case (default 10)")
    impedance.add_argument("--spread", type=non_negative_float, default=0.2,
                           help="rad around the paper's q0, per joint (default 0.2)")
    impedance.add_argument("--duration", type=positive_float, default=4.0, help="seconds (default 4)")
    _view_arguments(impedance, "the first run")
    impedance.set_defaults(run=_cmd_impedance)

    mpc = sub.add_parser("mpc", help="cooperative MPC: three Pandas tracking a moving circle with "
                         "warm-started iLQR in closed loop (report, plots, GIF)")
    mpc.add_argument("--out", default="plots/mpc", help="folder for the report, plots and GIF")
    mpc.add_argument("--rate", type=positive_float, default=100.0, help="control rate in Hz (default 100)")
    mpc.add_argument("--duration", type=positive_float, default=4.0, help="seconds (default 4)")
    mpc.add_argument("--no-animation", action="store_true", help="skip the GIF")
    _view_arguments(mpc, "the run")
    mpc.set_defaults(run=_cmd_mpc)

    from gagen.viewer.command import add_arguments as view_arguments

    view = sub.add_parser("view", help="a system's robots and primitive in the browser, or as a PNG rendered "
                          "by headless Chromium (--png)")
    view_arguments(view)
    view.set_defaults(run=_cmd_view)

    teleop = sub.add_parser("teleop", help="teleoperate a cooperative primitive with six axes (a trace, the "
                            "keyboard or a SpaceMouse) by differential kinematics; report and plot")
    teleop.add_argument("system", help="a bundled system, e.g. leap_hand_sphere, three_pandas_circle")
    teleop_source = teleop.add_mutually_exclusive_group(required=True)
    teleop_source.add_argument("--trace", help="replay a trace file (CSV: t,tx,ty,tz,rx,ry,rz)")
    teleop_source.add_argument("--keyboard", action="store_true", help="drive from the terminal's keys")
    teleop_source.add_argument("--spacemouse", action="store_true",
                               help="drive with a 3Dconnexion SpaceMouse (pip install 'gagen[teleop]')")
    teleop.add_argument("--dt", type=positive_float, default=0.01, help="time step, s (default 0.01)")
    teleop.add_argument("--first-order", action="store_true", help="plain q <- q + dt q̇ steps, uncorrected")
    teleop.add_argument("--out", default="plots/teleop", help="folder for the report (default plots/teleop/)")
    _view_arguments(teleop, "the run")
    teleop.set_defaults(run=_cmd_teleop)

    smc = sub.add_parser("smc", help="sliding-mode pose tracking of a Panda in a real-time C loop (plots)")
    smc.add_argument("--duration", type=positive_float, default=10.0, help="seconds (default 10)")
    smc.add_argument("--rate", type=positive_float, default=1000.0, help="loop rate in Hz (default 1000)")
    smc.add_argument("--out", default="plots/smc", help="folder for the log and the plots")
    smc.add_argument("--fifo", action="store_true", help="ask for SCHED_FIFO and locked memory")
    smc.set_defaults(run=_cmd_smc)

    walk = sub.add_parser("walk", help="a hexapod's tripod gait (straight, then a turn) on flat or sloped "
                          "ground: slip, limit margins, reachability; plots and a GIF")
    from gagen.apps.hexapod.gait import SPEC as HEXAPOD

    walk.add_argument("spec", nargs="?", default=str(HEXAPOD), help="hexapod spec (default: the bundled one)")
    walk.add_argument("--out", default="walk", help="folder for the plots and the GIF (default walk/)")
    walk.add_argument("--module", help="build the module into this folder (default: the committed "
                      "generated/ for the bundled spec, else the gagen cache)")
    walk.add_argument("--straight", type=float, default=0.3, help="straight part of the path, m "
                      "(default 0.3)")
    walk.add_argument("--turn", type=float, default=60.0, help="then an arc turning this far, degrees, "
                      "+ left (default 60)")
    walk.add_argument("--radius", type=positive_float, default=0.3, help="the arc's radius, m (default 0.3)")
    walk.add_argument("--height", type=positive_float, default=0.15, help="body height above the ground "
                      "along its normal, m (default 0.15)")
    walk.add_argument("--stride", type=positive_float, default=0.10, help="body travel per gait cycle "
                      "(two steps), m (default 0.10)")
    walk.add_argument("--step-time", type=positive_float, default=0.5, help="seconds per step (default 0.5)")
    walk.add_argument("--step-height", type=float, default=0.05, help="swing toe lift, m (default 0.05)")
    walk.add_argument("--slope", type=float, default=0.0, help="ground slope, degrees (default 0: flat)")
    walk.add_argument("--uphill", type=float, default=0.0, help="heading the ground rises towards, degrees "
                      "from +x (default 0)")
    walk.add_argument("--rate", type=positive_float, default=100.0, help="samples per second (default 100)")
    walk.add_argument("--frames", type=positive_int, default=90, help="GIF frames (default 90)")
    walk.add_argument("--no-animation", action="store_true", help="skip the GIF")
    walk.set_defaults(run=_cmd_walk)

    stereo = sub.add_parser("stereo", help="a moving bottle rendered by a stereo rig at 30 Hz, its "
                            "symmetry axis estimated in CGA each frame, tracked by the Panda's sliding-mode "
                            "loop (plots)")
    rig = Path(__file__).resolve().parent / "apps" / "stereo" / "robots" / "stereo_rig.yaml"
    stereo.add_argument("--rig", default=str(rig), help="calibration file (default: the bundled rig)")
    stereo.add_argument("--duration", type=positive_float, default=5.0, help="seconds (default 5)")
    stereo.add_argument("--noise", type=non_negative_float, default=1.0,
                        help="σ of the rendered vertices, px (default 1)")
    stereo.add_argument("--pixel-noise", type=non_negative_float, default=2.0,
                        help="σ of the pixel values, grey levels (default 2)")
    stereo.add_argument("--blur", type=non_negative_float, default=0.0,
                        help="σ of a Gaussian blur, px (default 0)")
    stereo.add_argument("--clutter", type=non_negative_int, default=0, help="background shapes (default 0)")
    stereo.add_argument("--seed", type=int, default=0, help="random seed of the noise (default 0)")
    stereo.add_argument("--out", default="plots/stereo", help="folder for the log and the plots")
    stereo.set_defaults(run=_cmd_stereo)

    linkage = sub.add_parser("linkage", help="planar linkages: Lie-algebra Newton along the driver's cycle "
                             "(a crank's revolution, a slider's stroke); per-step report, traced curves, "
                             "solver plots and a GIF")
    linkage.add_argument("spec", nargs="*", help="linkage spec(s) (default: every bundled one in "
                         "gagen/apps/linkage/robots)")
    linkage.add_argument("--steps", type=positive_int, default=360, help="driver steps per cycle: per crank "
                         "revolution or slider stroke (default 360)")
    linkage.add_argument("--revolutions", type=positive_int, default=1, help="driver cycles (default 1)")
    linkage.add_argument("--out", default="linkage", help="folder; each mechanism's files go to "
                         "<out>/<name>/ (default linkage/)")
    linkage.add_argument("--frames", type=positive_int, default=72, help="GIF frames (default 72)")
    linkage.add_argument("--no-animation", action="store_true", help="skip the GIF")
    linkage.set_defaults(run=_cmd_linkage)

    sweep = sub.add_parser("sweep", help="distributed sweeps on Dask, chunked and resumable: a bundled "
                           "system's manipulability over random configurations or a grid, or iLQR reaching "
                           "over target circles or spheres")
    from gagen.sweep.command import add_arguments as sweep_arguments

    sweep_arguments(sweep)
    sweep.set_defaults(run=_cmd_sweep)

    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except BrokenPipeError:  # the output went into `head` or a closed pager: stop quietly, as cat does
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141  # 128 + SIGPIPE


if __name__ == "__main__":
    sys.exit(main())
