"""``gagen view`` / ``python -m gagen.viewer``: one configuration of a system in the browser, or as a PNG.

    gagen view three_pandas_circle                      # serve it until Ctrl-C: open the URL it prints
    gagen view three_pandas_circle --png frame.png      # headless Chromium renders it to a PNG
    gagen view robots/two_iiwas_line.yaml --q 0,0.5,... --size 1280x960 --no-primitive --png f.png

SYSTEM is a bundled system's name or a spec file; the configuration is the spec's ``ready`` one unless
``--configuration NAME`` or ``--q`` (the system's joint vector, comma-separated) says otherwise. Links
are drawn from their URDF ``<visual>`` meshes and shapes where the URDF has them (``--no-meshes``:
sticks throughout); a mesh file that cannot be read is a warning, and its link a stick. ``--goal NAME``
also draws a goal of the spec's ``goals:`` section (its target primitive, in cyan-blue). The server
listens on 127.0.0.1 only and answers only the URL it prints, ``http://127.0.0.1:PORT/?token=…``: the
token is new each run, and keeps other web pages the browser opens out (``gagen.viewer.access``).
Exit status: 0, 1 when the browser fails, 2 for malformed arguments.
"""

from __future__ import annotations

import argparse
import re
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from gagen.arguments import port
from gagen.registry import Verb, bundled_specs
from gagen.viewer import DEFAULT_PORT

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from gagen.robots.system import System
    from gagen.viewer.geometry import Shape

DEFAULT_SIZE = (1024, 768)


def size(text: str) -> tuple[int, int]:
    match = re.fullmatch(r"\s*(\d{1,5})\s*[xX×]\s*(\d{1,5})\s*", text)
    if not match or not all(16 <= int(v) <= 8192 for v in match.groups()):
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels (16 to 8192 each), e.g. 1024x768; "
                                         f"got {text!r}")
    return int(match[1]), int(match[2])


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("system", help="a spec file, or a bundled system: "
                        + ", ".join(bundled_specs("cooperative")))
    parser.add_argument("--q", help="the joint vector, comma-separated (default: the ready configuration)")
    parser.add_argument("--configuration", default="ready", help="a configuration named in the spec")
    parser.add_argument("--png", type=Path, help="render headless to this PNG and exit (needs Chromium)")
    parser.add_argument("--size", type=size, default=DEFAULT_SIZE, help="PNG size, WIDTHxHEIGHT (1024x768)")
    parser.add_argument("--no-primitive", action="store_true", help="draw the robots only")
    parser.add_argument("--goal", metavar="NAME",
                        help="also draw the target primitive of a goal in the spec's goals: section")
    parser.add_argument("--no-meshes", action="store_true",
                        help="draw the links as sticks even where the URDF has visual meshes or shapes")
    parser.add_argument("--frames", choices=("none", "ends", "all"), default="ends",
                        help="joint frames drawn: each chain's base and end (default), all, none")
    parser.add_argument("--port", type=port, default=DEFAULT_PORT,
                        help=f"server port on 127.0.0.1 (default {DEFAULT_PORT}; 0: any free one); the "
                        "server answers only the URL it prints, which carries a new ?token= each run")


def _system(name: str) -> tuple[System, dict[str, list[float]], Path]:
    """(System, configurations, spec path) of a bundled system's name or a spec file."""
    from gagen.registry import resolve_spec
    from gagen.robots.spec import load_system

    path = resolve_spec(name, "cooperative", "system")
    system, configurations = load_system(path)
    measured = [chain.name for chain in system.chains if chain.measured]
    if measured:  # (their joints are a trace's, not a configuration's: gagen follow draws them)
        raise ValueError(f"{path}: {system.name} has measured chains ({', '.join(measured)}) that a "
                         "configuration does not place; gagen follow draws the run of such a system")
    return system, configurations, path


def configuration(args: argparse.Namespace, system: System,
                  named: dict[str, list[float]]) -> NDArray[np.float64]:
    """The joint vector (numpy) from ``--q`` or ``--configuration``."""
    import numpy as np

    if args.q is not None:
        try:
            q = np.array([float(v) for v in args.q.split(",")])
        except ValueError:
            raise ValueError(f"--q: expected {system.dof} comma-separated numbers, got {args.q!r}") from None
        if q.shape != (system.dof,) or not np.all(np.isfinite(q)):
            raise ValueError(f"--q: expected {system.dof} finite comma-separated numbers for "
                             f"{system.name}, got {q.shape[0]}")
        return q
    if args.configuration not in named:
        raise ValueError(f"--configuration: {system.name} names {', '.join(named) or 'no configurations'}; "
                         f"got {args.configuration!r}")
    return np.array(named[args.configuration], dtype=float)


def goal_shape(name: str, spec: Path, system: System, named: dict[str, list[float]]) -> Shape:
    """The target primitive of the spec's goal ``name``: stated outright, or the ``ready`` primitive moved."""
    import numpy as np

    from gagen.robots.goals import load_goals
    from gagen.viewer import geometry

    goals = load_goals(spec)
    if name not in goals:
        raise ValueError(f"--goal: {system.name} names {', '.join(goals) or 'no goals'}; got {name!r}")
    goal = goals[name]
    if not goal.is_move:
        return geometry.goal_shape(goal.kind, goal.parameters)
    if "ready" not in named:
        raise ValueError(f"--goal {name}: a move of the ready primitive, but {system.name} has no ready "
                         f"configuration")
    ready = geometry.system_pose(system, np.array(named["ready"], dtype=float))
    start = geometry.shape(system.kind, np.array([pose.end_point for pose in ready]))
    return geometry.moved(start, goal.translation, goal.rotation, goal.dilation)


def run(args: argparse.Namespace) -> int:
    from gagen.errors import SpecError, print_error
    from gagen.viewer.browser import BrowserError, export_png
    from gagen.viewer.scene import Scene
    from gagen.viewer.visuals import load_visuals

    try:
        system, named, spec = _system(args.system)
        q = configuration(args, system, named)
        goal = None if args.goal is None else goal_shape(args.goal, spec, system, named)
    except (ValueError, SpecError) as e:
        print_error(e)
        return 2
    visuals = None if args.no_meshes else load_visuals(spec, system)
    if args.png is not None:
        start = time.monotonic()
        width, height = args.size
        try:
            path, _ = export_png(system, q, args.png, width=width, height=height,
                                 primitive=not args.no_primitive, frames=args.frames, visuals=visuals,
                                 goal=goal)
        except BrowserError as e:
            print_error(e)
            return 1
        print(f"{system.name}: wrote {path} ({width}x{height}) in {time.monotonic() - start:.1f} s")
        return 0
    try:
        scene = Scene(system, q, port=args.port, frames=args.frames, visuals=visuals, goal=goal)
    except ValueError as e:
        print_error(e)
        return 2
    scene.show_primitive(not args.no_primitive)
    print(f"viewer: open {scene.url} in a browser (Ctrl-C to stop)", flush=True)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        scene.close()
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gagen.viewer", description=__doc__.split("\n")[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


VERBS = (Verb("view", "a system's robots and primitive in the browser, or as a PNG rendered by headless "
                      "Chromium "
              "(--png)", add_arguments, run, needs=("viser",)),)
