"""The cooperative application's verbs: ``reach``, ``nullspace``, ``impedance``, ``mpc``, ``teleop``,
``carry``, ``interpolate`` and ``follow`` (a system with a measured chain, which the others refuse).

Each verb's arguments are defined here, once (``gagen <verb>`` and ``python -m`` of its module use the
same ones); the work is done by the module that runs it, imported only when the verb runs.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable
from pathlib import Path

from gagen.apps.cooperative.scenario_table import SCENARIOS
from gagen.arguments import (
    FlagNeeding,
    finite_float,
    non_negative_float,
    non_negative_int,
    numbers,
    positive_float,
    positive_int,
    view_arguments,
)
from gagen.registry import Verb, bundled_specs


def _running(module: str) -> Callable[[argparse.Namespace], int]:
    """The verb's run: ``run_command`` of ``gagen.apps.cooperative.<module>``, imported when the verb runs. A
    ValueError it raises (a bad spec, goal or value) is the dispatcher's one line and exit status 2; a
    RuntimeError (a device that cannot be opened) is one line here, also exit status 2."""

    def run(args: argparse.Namespace) -> int:
        if module != "follow":
            _refuse_measured(args)
        loaded = importlib.import_module(f"gagen.apps.cooperative.{module}")
        command: Callable[[argparse.Namespace], int] = loaded.run_command
        try:
            return command(args)
        except RuntimeError as e:
            print(f"error: {e}", file=sys.stderr)
            return 2

    return run


def _refuse_measured(args: argparse.Namespace) -> None:
    """A ValueError (one line) when the verb's system has a measured chain: its joints are a leader's inputs,
    which only ``gagen follow`` takes; the other verbs drive every chain."""
    from gagen.registry import resolve_spec
    from gagen.robots.spec import load_system

    verb = getattr(getattr(args, "verb", None), "name", "this verb")
    given = [getattr(args, name, None) for name in ("system", "scenario", "target")]
    for value in (v for g in given for v in (g if isinstance(g, list) else [g]) if isinstance(v, str)):
        try:
            system, _ = load_system(resolve_spec(value, "cooperative"))
        except ValueError:  # not a system (a scenario's name), or a bad spec: the verb says so itself
            continue
        if system.measured_dof:
            raise ValueError(f"{value}: chain {system.measured_chains[0].name!r} is measured (a leader's "
                             f"input, not a robot's); gagen {verb} drives robots only: use gagen follow "
                             f"{value}")


def _follow_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("system", nargs="?", default="two_pandas_hand_circle",
                        help="a system with a measured chain (measured: true): a spec file or a leader "
                             "spec in robots/leader (default two_pandas_hand_circle: a hand and two Pandas "
                             "span a circle)")
    parser.add_argument("--trace", type=Path, help="the leader's joints over time (CSV: t, then one column "
                        "per measured joint; default the bundled synthetic hand trace "
                        "traces/leader/hand_circle.csv)")
    parser.add_argument("--gain", type=non_negative_float, default=20.0,
                        help="K of differential IK's feedback, 1/s (default 20)")
    parser.add_argument("--duration", type=positive_float, help="follow the trace's first seconds only "
                        "(default: all of it)")
    parser.add_argument("--out", type=Path, default=Path("plots/follow"),
                        help="folder for the report and the plot (default plots/follow/)")


def _reach_arguments(parser: argparse.ArgumentParser) -> None:
    systems = ", ".join(bundled_specs("cooperative"))
    parser.add_argument("scenario", metavar="TARGET",
                        help=f"a bundled scenario ({', '.join(SCENARIOS)}), all of them (all), or a system: "
                             f"a spec file or a bundled one ({systems}), with its goals (goals: in the "
                             "spec) or a goal given here")
    parser.add_argument("--goal", help="the spec's goal to reach (default: every goal the spec states)")
    parser.add_argument("--translation", type=numbers(3), metavar="X,Y,Z",
                        help="a goal given here: move the ready primitive by this translation, m")
    parser.add_argument("--rotation", type=numbers(4), metavar="AX,AY,AZ,ANGLE",
                        help="... rotated about this world axis by ANGLE rad about its reference point")
    parser.add_argument("--dilation", type=positive_float, help="... dilated by this factor (rounds)")
    parser.add_argument("--out", type=Path, default=Path("plots"),
                        help="folder for the plots (default plots/)")
    parser.add_argument("--N", type=positive_int, default=100, help="time steps (default 100)")
    parser.add_argument("--horizon", type=positive_float, default=2.5, help="seconds (default 2.5)")
    parser.add_argument("--solver", choices=("ipopt", "fatrop", "ilqr"), default="ipopt",
                        help="solver (default ipopt; ilqr: the structured iLQR in C)")
    parser.add_argument("--hessian", choices=("exact", "gauss-newton"), default="exact",
                        help="Hessian of the Lagrangian (gauss-newton: IPOPT only; default exact)")
    parser.add_argument("--dynamics", action=FlagNeeding, module="crocoddyl",
                        help="at the torque level instead: rigid-body dynamics from the URDFs' inertias, "
                             "torque and joint limits, solved by Crocoddyl's box-FDDP (gagen[ocp]); "
                             "--solver and --hessian do not apply")
    view_arguments(parser, "the optimal trajectory")


def _reach(args: argparse.Namespace) -> int:
    return _running("torque_reach" if args.dynamics else "scenarios")(args)


def _nullspace_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("system", nargs="?",
                        help="a system spanning a circle, a line or a plane: a spec file or a bundled one "
                             "(default: --primitive's bundled system); its first chain moves")
    parser.add_argument("--primitive", choices=("circle", "line", "plane"),
                        help="circle: three Pandas [COOP Figs. 14-15] (default); line: two iiwa 14, plane: "
                             "three iiwa 14, an end point moved within it [Fig. 18]")
    parser.add_argument("--out", type=Path, default=Path("plots"), help="folder for the plot (default "
                                                                        "plots/)")
    parser.add_argument("--steps", type=positive_int, default=400, help="RK4 steps (default 400)")
    parser.add_argument("--dt", type=positive_float, default=0.01, help="RK4 step, s (default 0.01)")
    parser.add_argument("--gain", type=finite_float, default=1.5,
                        help="k in q̇_sec = J_p⁺ k (p_target − p) (default 1.5)")
    view_arguments(parser, "both runs")


_nullspace = _running("nullspace_demo")


def _impedance_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("system", nargs="*", help="systems (spec files whose URDFs carry inertials, or "
                        "bundled ones) to run with the tuned gains from their ready configuration "
                        "(default: the paper's three iiwa 14 on a circle, paper and tuned gains, and on a "
                        "plane)")
    parser.add_argument("--out", type=Path, default=Path("plots/impedance"),
                        help="folder for the plot and the report (default plots/impedance/)")
    parser.add_argument("--runs", type=positive_int, default=10, help="random starts per case (default 10)")
    parser.add_argument("--spread", type=non_negative_float, default=0.2,
                        help="rad around the paper's q0, per joint (default 0.2)")
    parser.add_argument("--duration", type=positive_float, default=4.0, help="seconds (default 4)")
    parser.add_argument("--mujoco", action=FlagNeeding, module="mujoco",
                        help="run the plant in MuJoCo (gagen[sim]) instead of Pinocchio's ABA by RK4")
    view_arguments(parser, "the circle's first run")


_impedance = _running("impedance_demo")


def _mpc_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("system", nargs="?",
                        help="a system spanning a circle: a spec file or a bundled one (default "
                             "three_pandas_circle; with --dynamics three_iiwas_circle)")
    parser.add_argument("--out", type=Path, default=Path("plots/mpc"),
                        help="folder for the report, plots and GIF (default plots/mpc/)")
    parser.add_argument("--rate", type=positive_float,
                        help="control rate in Hz (default 100; with --dynamics 50)")
    parser.add_argument("--dynamics", action=FlagNeeding, module="mujoco",
                        help="at the torque level: box-FDDP MPC (Crocoddyl) closing the loop in MuJoCo "
                             "(gagen[ocp,sim])")
    parser.add_argument("--duration", type=positive_float, default=4.0, help="seconds (default 4)")
    parser.add_argument("--no-animation", action="store_true", help="skip the GIF")
    view_arguments(parser, "the run")


def _mpc(args: argparse.Namespace) -> int:
    return _running("torque_mpc_demo" if args.dynamics else "mpc_demo")(args)


def _teleop_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("system", help="a spec file, or a bundled system: "
                        + ", ".join(bundled_specs("cooperative")))
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--trace", type=Path, help="replay a trace file (CSV: t,tx,ty,tz,rx,ry,rz)")
    source.add_argument("--keyboard", action="store_true", help="drive from the terminal's keys")
    source.add_argument("--spacemouse", action=FlagNeeding, module="pyspacemouse",
                        help="drive with a 3Dconnexion SpaceMouse (pip install 'gagen[teleop]')")
    parser.add_argument("--dt", type=positive_float, default=0.01, help="time step, s (default 0.01)")
    parser.add_argument("--frame", choices=("world", "body"), default="world",
                        help="command frame (default world)")
    parser.add_argument("--first-order", action="store_true", help="plain q <- q + dt q̇ steps, uncorrected")
    parser.add_argument("--duration", type=positive_float, default=float("inf"),
                        help="stop a live run after this many seconds (default: when a button quits)")
    parser.add_argument("--speed", type=positive_float, default=0.05, help="m/s at full deflection (0.05)")
    parser.add_argument("--turn", type=positive_float, default=0.5, help="rad/s at full deflection (0.5)")
    parser.add_argument("--dilation", type=positive_float, default=0.5, help="1/s at full deflection (0.5)")
    parser.add_argument("--out", type=Path, default=Path("plots/teleop"),
                        help="folder for the report (default plots/teleop/)")
    parser.add_argument("--mujoco", action=FlagNeeding, module="mujoco",
                        help="also track the run by computed torque on MuJoCo's plant (gagen[sim]; a system "
                             "whose URDFs carry inertials)")
    view_arguments(parser, "the run")


_teleop = _running("teleop")


def _carry_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("system", nargs="?", help="three chains spanning a circle, with inertials: a spec "
                        "file or a bundled one (default three_iiwas_circle)")
    parser.add_argument("--out", type=Path, default=Path("plots/carry"),
                        help="folder for the report and the plot (default plots/carry/)")
    parser.add_argument("--duration", type=positive_float, default=2.5,
                        help="seconds: the 2 s motion, then holding (default 2.5)")
    parser.add_argument("--no-mpc", action="store_true", help="the impedance law only (no torque MPC)")
    parser.add_argument("--no-animation", action="store_true",
                        help="skip the GIF (MuJoCo's offscreen rendering of the MPC's run, or of the "
                             "impedance's)")


def _interpolate_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("target", metavar="TARGET",
                        help="a primitive kind (point, point_pair, line, circle, plane, sphere) with both "
                             "ends given by --from/--to key=value items; a system (a spec file or a bundled "
                             "one: "
                             f"{', '.join(bundled_specs('cooperative'))}) with a configuration or goal name "
                             "each; or fig4 (the paper's four panels)")
    parser.add_argument("--from", dest="start", nargs="+", metavar="ITEM",
                        help="the start: centre=X,Y,Z radius=R normal=X,Y,Z (per kind: position; first, "
                             "second; point, direction; centre, radius, normal; point, normal; centre, "
                             "radius; or points=X,Y,Z/X,Y,Z/...), or a system's configuration or goal name")
    parser.add_argument("--to", dest="end", nargs="+", metavar="ITEM", help="the end, as --from")
    parser.add_argument("--steps", type=positive_int, default=6,
                        help="values of t drawn and listed, 0 to 1 (default 6)")
    parser.add_argument("--gif", action="store_true", help="also write an animated GIF")
    parser.add_argument("--frames", type=positive_int, default=30, help="frames of the GIF (default 30)")
    parser.add_argument("--out", type=Path, default=Path("plots/interpolation"),
                        help="folder for the plot, the CSV and the GIF (default plots/interpolation/)")


def _objectives_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("system", help="a spec file or a bundled system: "
                        + ", ".join(bundled_specs("cooperative")))
    parser.add_argument("objectives", type=Path, help="the objectives file (YAML: objectives:, start:; see "
                                                      "docs/mixed-objectives.md)")
    parser.add_argument("--start", help="a configuration of the spec to start from (default: the file's "
                                        "start, else ready, else zeros)")
    parser.add_argument("--method", choices=("lm", "ipopt"), default=None,
                        help="IK method (default lm: damped Gauss-Newton; ipopt: casadi.nlpsol, the default "
                             "when the file states a hard term)")
    parser.add_argument("--N", type=non_negative_int, default=20,
                        help="OCP time steps (default 20; 0 skips the OCP)")
    parser.add_argument("--horizon", type=positive_float, default=2.0, help="OCP horizon, s (default 2)")
    parser.add_argument("--out", type=Path, default=Path("plots/objectives"),
                        help="folder for the plot (default plots/objectives/)")


def _manipulability_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("system", nargs="?", default="three_pandas_circle",
                        help="a spec file or a bundled system (default three_pandas_circle)")
    parser.add_argument("--objective", choices=("dilation", "volume"),
                        help="maximise the dilation force index (default for a point pair, circle or "
                             "sphere) or the force ellipsoid's volume (default otherwise)")
    parser.add_argument("--configuration", default="ready", help="the spec's configuration to start from "
                                                                 "(default ready)")
    parser.add_argument("--steps", type=non_negative_int, default=60, help="nullspace steps (default 60)")
    parser.add_argument("--step-size", type=positive_float, default=0.05,
                        help="largest joint-space step, rad (default 0.05)")
    parser.add_argument("--out", type=Path, default=Path("plots/manipulability"),
                        help="folder for the plot (default plots/manipulability/)")


VERBS = (
    Verb("reach", "cooperative reaching (IPOPT, FATROP or iLQR) on a paper scenario, with plots",
         _reach_arguments, _reach),
    Verb("nullspace", "one of three Pandas moves along the circle through N(q), with and without the "
         "projection (plots); --primitive line or plane: two or three iiwa 14 [COOP Fig. 18]",
         _nullspace_arguments, _nullspace),
    Verb("manipulability", "velocity and force manipulability ellipsoids of a system's similarity and a "
         "nullspace ascent of the dilation force index [COOP Sec. 3.11] (plot)", _manipulability_arguments,
         _running("manipulability_command")),
    Verb("impedance", "similarity impedance control of three iiwa 14 on a circle and a plane: runs of "
         "Pinocchio forward dynamics [COOP Fig. 6]", _impedance_arguments, _impedance, needs=("pinocchio",)),
    Verb("mpc", "cooperative MPC: three Pandas tracking a moving circle with warm-started iLQR in closed "
         "loop (report, plots, GIF)", _mpc_arguments, _mpc),
    Verb("teleop", "teleoperate a cooperative primitive with six axes (a trace, the keyboard or a "
         "SpaceMouse) by differential kinematics; report and plot", _teleop_arguments, _teleop),
    Verb("carry", "a ring held by three iiwa 14 carried in MuJoCo by the impedance law and the torque MPC "
         "(pose error, internal forces; report, plot)", _carry_arguments, _running("held_object_demo"),
         needs=("mujoco", "pinocchio", "crocoddyl")),
    Verb("follow", "leader and followers: robots keep a primitive's shape while a measured chain (a hand "
         "trace) moves one of its points [COOP Sec. 5]; report and plot", _follow_arguments,
         _running("follow")),
    Verb("interpolate", "interpolate two primitives (or a system's two configurations or goals) through "
         "their similarity versors [COOP Fig. 4]: plot, CSV, GIF", _interpolate_arguments,
         _running("interpolate_command")),
    Verb("objectives", "mixed objectives (cooperative primitives, Eq. 9 incidences, radii, normals) from a "
         "file, solved by IK and the reaching OCP: residuals per term and a plot", _objectives_arguments,
         _running("objectives_command")),
)
