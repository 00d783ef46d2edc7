"""The paper's optimal-control reaching scenarios on the bundled systems [COOP Section 4.2, Figs. 7-13].

Each scenario starts a system at rest in its spec's ``ready`` configuration, moves its cooperative
primitive by a chosen similarity (``gagen.control.ocp.target_from``) to get the target V_Sd, solves
the reaching OCP of Eq. 53-57 with IPOPT (``gagen.control.ocp.reach``, URDF joint limits as bounds)
and writes two plots into an output folder:

- ``<scenario>_command.png``: the bivector command over time, B_k = J_G,Sc(q_k) q̇_k, the primitive's
  similarity twist (7 curves labelled by blade), above the remaining error e(q_k) = log(V_Sc(q_k)~ V_Sd);
- ``<scenario>_trajectory.png``: the primitive in 3D: the chains' end points over time, the initial
  primitive (green), the final one (turquoise), the target (black, dashed), some intermediate ones
  (red) and, for rounds, the centre's path; circles and spheres are drawn from centre, radius (and
  normal), lines and planes as a segment or patch around the end points.

    gagen reach circle --out plots/ [--N 100] [--horizon 2.5]
    gagen reach all --out plots/
    gagen reach circle --solver fatrop      # or --hessian gauss-newton
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from gagen.apps.cooperative.scenario_table import SCENARIOS, Scenario, of_goal, scenarios_of
from gagen.control.goals import desired
from gagen.control.ocp import (
    bivector_command,
    multivector,
    reach,
    task_errors,
)
from gagen.control.reaching import BLADES, DEFAULT_HORIZON, DEFAULT_N, OCPResult
from gagen.modules import bundled_module
from gagen.registry import resolve_spec
from gagen.robots.goals import Goal
from gagen.robots.points import end_points
from gagen.robots.spec import load_system
from gagen.robots.system import System
from gagen.runtime import GeneratedModule

Array = NDArray[np.float64]
LABELS = {"e12": "e12", "e13": "e13", "e23": "e23", "e0inf": "e0∞", "e1inf": "e1∞", "e2inf": "e2∞",
          "e3inf": "e3∞"}


@dataclass(frozen=True)
class ScenarioResult:
    scenario: Scenario
    module: GeneratedModule
    q0: NDArray[np.float64]
    V_Sd: NDArray[np.float64]
    limits: tuple[NDArray[np.float64], NDArray[np.float64]]
    result: OCPResult
    command: NDArray[np.float64]
    errors: NDArray[np.float64]
    plots: tuple[Path, ...]


# -- systems: a bundled name or a spec file -----------------------------------------------------------------
def spec_of(system: str) -> Path:
    return resolve_spec(system, "cooperative", "system")


@cache
def _loaded(system: str) -> tuple[System, dict[str, list[float]]]:
    return load_system(spec_of(system))


def system_of(system: str) -> System:
    """The loaded ``System`` of a bundled name or a spec file."""
    return _loaded(system)[0]


@cache
def module(system: str) -> GeneratedModule:
    """The generated module of ``system``, built on first use (``gagen.modules``)."""
    return bundled_module(spec_of(system))


def ready(system: str) -> NDArray[np.float64]:
    """The spec's ``ready`` configuration (a ValueError naming the spec when it has none)."""
    named = _loaded(system)[1]
    if "ready" not in named:
        raise ValueError(f"{spec_of(system)}: configurations: no 'ready' configuration, which reaching "
                         "starts from")
    return np.array(named["ready"], dtype=float)


@cache
def _urdf(path: Path) -> Any:
    import yourdfpy

    return yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False,
                              build_collision_scene_graph=False, load_collision_meshes=False).robot


def joint_limits(system: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(lower, upper) of every entry of q, from the URDFs the spec's chains name (continuous joints:
    ±inf). Joints of spec-defined chains (no URDF) get ±inf."""
    spec_path = spec_of(system)
    spec = yaml.safe_load(spec_path.read_text())
    sys_ = _loaded(system)[0]
    limits: dict[tuple[str, str], tuple[float, float]] = {}
    for chain, entry in zip(sys_.chains, spec["chains"], strict=True):
        joints = {}
        if "urdf" in entry:
            joints = {j.name: j for j in _urdf(spec_path.parent / entry["urdf"]).joints}
        for key in chain.joint_keys():
            joint = joints.get(key[1])
            if joint is None or joint.type == "continuous" or joint.limit is None:
                limits.setdefault(key, (-np.inf, np.inf))
            else:
                limits.setdefault(key, (float(joint.limit.lower), float(joint.limit.upper)))
    lower, upper = zip(*(limits[key] for key in sys_.joint_keys), strict=True)
    return np.array(lower), np.array(upper)


def primitive_coefficients(m: GeneratedModule, q: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.array(m.c.primitive(q)[0])


def _rows(m: GeneratedModule, kernel: str, port: str) -> list[str]:
    entry = next(k for k in m.manifest["kernels"] if k["name"] == kernel)
    return next(p["rows"] for p in entry["outputs"] + entry["inputs"] if p["name"] == port)


# -- solving -----------------------------------------------------------------------------------------
def run(scenario: Scenario | str, out: str | Path | None = None, *, N: int = DEFAULT_N,
        horizon: float = DEFAULT_HORIZON, **options: Any) -> ScenarioResult:
    """Solve one scenario from the ready configuration; write its two plots into ``out`` (if given).
    ``options`` go to ``reach`` (R, Q, rest, hessian, …)."""
    s = SCENARIOS[scenario] if isinstance(scenario, str) else scenario
    m = module(s.system)
    q0 = ready(s.system)
    limits = joint_limits(s.system)
    V_Sc0 = np.array(m.c.similarity(q0)[0])
    goal = s.goal or Goal(s.name, "move", s.title, s.translation, s.rotation, s.dilation)
    V_Sd = desired(goal, V_Sc0, m.manifest["primitive"])
    result = reach(m, q0, V_Sd, N=N, horizon=horizon, limits=limits, **options)
    command, errors = bivector_command(m, result), task_errors(m, result)
    plots: tuple[Path, ...] = ()
    if out is not None:
        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        plots = (plot_command(s, result, command, errors, folder / f"{s.name}_command.png"),
                 plot_trajectory(s, m, result, folder / f"{s.name}_trajectory.png"))
    return ScenarioResult(s, m, q0, V_Sd, limits, result, command, errors, plots)


def line(out: str | Path | None = None, **kwargs: Any) -> ScenarioResult:
    """Two arms → line: the G1's waist and arms, hands span the line [COOP Fig. 7]."""
    return run("line", out, **kwargs)


def circle(out: str | Path | None = None, **kwargs: Any) -> ScenarioResult:
    """Three Pandas → a larger, raised, tilted circle: the dilation command is non-zero [Fig. 8]."""
    return run("circle", out, **kwargs)


def plane(out: str | Path | None = None, **kwargs: Any) -> ScenarioResult:
    """Three LEAP fingers → a tilted, raised plane: no dilation for a flat [Fig. 11]."""
    return run("plane", out, **kwargs)


def hand_sphere(out: str | Path | None = None, **kwargs: Any) -> ScenarioResult:
    """Four LEAP fingers → a smaller, shifted sphere [Fig. 12] (the grasp closes: in the ready pose the
    index is straight, so the fingertips' sphere cannot grow much)."""
    return run("hand_sphere", out, **kwargs)


def humanoids_sphere(out: str | Path | None = None, **kwargs: Any) -> ScenarioResult:
    """Two G1s' four hands → a raised, larger sphere [Fig. 13]."""
    return run("humanoids_sphere", out, **kwargs)


# -- plots -------------------------------------------------------------------------------------------
def _figure(**kwargs: Any) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(**kwargs)
    FigureCanvasAgg(figure)  # the Agg backend, without touching pyplot's global state
    return figure


def plot_command(s: Scenario, result: OCPResult, command: Array, errors: Array, path: Path) -> Path:
    figure = _figure(figsize=(8, 6.5), layout="constrained")
    top, bottom = figure.subplots(2, 1, sharex=True)
    t = result.t
    for i, blade in enumerate(BLADES):
        top.plot(t, command[:, i], label=LABELS[blade], color=f"C{i}")
        bottom.plot(t, errors[:, i], label=LABELS[blade], color=f"C{i}")
    top.set_ylabel("B = J_G,Sc q̇  (rad/s, m/s)")
    top.set_title(f"bivector command: {s.title}", fontsize=10)
    top.legend(ncols=7, fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.02))
    bottom.set_ylabel("e = log(V_Sc~ V_Sd)")
    bottom.set_xlabel("t (s)")
    bottom.set_title(f"remaining error; final ‖e‖ = {result.error_norm:.1e}", fontsize=10)
    for ax in (top, bottom):
        ax.axhline(0.0, color="0.6", linewidth=0.5)
        ax.grid(True, linewidth=0.3)
    figure.savefig(path, dpi=110)
    return path


def _geometry(kind: str, rows: Sequence[str], x: Array, anchor: Array, size: float) -> list[Array]:
    """Polylines (each (k, 3)) drawing the primitive with coefficients x: a circle, a sphere's three
    great circles, a segment of a line or the outline and diagonals of a square patch of a plane, the
    flats placed around ``anchor`` (projected onto them) with half-size ``size``."""
    from gagen.model.conformal import EUCLID, location, part, point, unit, vector
    from gagen.model.primitives import centre, direction, project_point, radius, unit_normal

    X = multivector(rows, x)
    angles = np.linspace(0.0, 2 * np.pi, 73)

    def ring(c: Array, r: float, normal: Array) -> Array:
        normal = normal / np.linalg.norm(normal)
        a = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
        a /= np.linalg.norm(a)
        b = np.cross(normal, a)
        polyline: Array = c + r * (np.outer(np.cos(angles), a) + np.outer(np.sin(angles), b))
        return polyline

    def xyz(v: Any) -> Array:
        return np.array([v[k] for k in EUCLID])

    if kind == "point":  # a marker where the point is
        return [np.array([xyz(location(X))])]
    if kind == "point_pair":  # a marker at its centre, with a ring of its half-distance about the e3 axis
        c, r = xyz(location(centre(X))), float(radius(X))
        return [np.array([c]), ring(c, r, np.eye(3)[2])]
    if kind in ("circle", "sphere"):
        c, r = xyz(location(centre(X))), float(radius(X))
        if kind == "circle":
            return [ring(c, r, xyz(unit_normal(X)))]
        return [ring(c, r, np.eye(3)[i]) for i in range(3)]
    foot = xyz(location(project_point(point(vector(X, list(anchor))), X)))
    if kind == "line":
        d = xyz(direction(X))
        return [np.array([foot - size * d, foot + size * d])]
    normal = xyz(unit(part(X.dual(), EUCLID)))
    a = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    corners = [foot + size * (i * a + j * b) for i, j in ((1, 1), (-1, 1), (-1, -1), (1, -1), (1, 1))]
    return [np.array(corners), np.array([corners[0], corners[2]]), np.array([corners[1], corners[3]])]


def plot_trajectory(s: Scenario, m: GeneratedModule, result: OCPResult, path: Path) -> Path:
    from gagen.control.ocp import target_primitive

    kind = m.manifest["primitive"]
    rows = _rows(m, "primitive", "X_c")
    points = np.array([end_points(m, q) for q in result.q])  # (N+1, chains, 3)
    figure = _figure(figsize=(7.5, 7), layout="constrained")
    ax = figure.add_subplot(projection="3d")
    for i in range(points.shape[1]):
        ax.plot(*points[:, i].T, color="0.35", linewidth=1.0)
        ax.scatter(*points[0, i], color="tab:green", s=18)
        ax.scatter(*points[-1, i], color="darkturquoise", s=18)
    spread = float(np.ptp(points.reshape(-1, 3), axis=0).max())

    def draw(x: Array, anchor_points: Array, first_only: bool = False, **style: Any) -> None:
        anchor = anchor_points.mean(axis=0)
        reach_ = float(np.linalg.norm(anchor_points - anchor, axis=1).max())
        size = (1.25 if kind == "line" else 0.8) * max(reach_, 0.1 * spread)
        polylines = _geometry(kind, rows, x, anchor, size)
        for k, polyline in enumerate(polylines[:1] if first_only else polylines):
            drawn = {**style, "label": None} if k else style
            ax.plot(*polyline.T, **({**drawn, "marker": "o"} if len(polyline) == 1 else drawn))

    N = result.N
    steps = np.unique(np.linspace(0, N, 9).round().astype(int))[1:-1]
    for k in steps:  # a sphere's intermediates: its equator only
        draw(primitive_coefficients(m, result.q[k]), points[k], first_only=True, color="tab:red",
             linewidth=0.6, alpha=0.6, label="intermediate" if k == steps[0] else None)
    draw(primitive_coefficients(m, result.q[0]), points[0], color="tab:green", linewidth=2.0, label="initial")
    draw(target_primitive(m, result.V_Sd), points[-1], color="black", linewidth=1.0, linestyle="--",
         label="target")
    draw(primitive_coefficients(m, result.q[-1]), points[-1], color="darkturquoise", linewidth=2.0,
         label="final")
    if kind in ("circle", "sphere"):
        from gagen.model.conformal import location
        from gagen.model.primitives import centre

        centres = np.array([[location(centre(multivector(rows, primitive_coefficients(m, q))))[k]
                             for k in ("e1", "e2", "e3")] for q in result.q])
        ax.plot(*centres.T, color="tab:red", linestyle=":", linewidth=1.2, label="centre")
    limits = np.array([ax.get_xlim3d(), ax.get_ylim3d(), ax.get_zlim3d()])  # equal scales: true shapes
    middle, half = limits.mean(axis=1), (limits[:, 1] - limits[:, 0]).max() / 2
    ax.set_xlim3d(middle[0] - half, middle[0] + half)
    ax.set_ylim3d(middle[1] - half, middle[1] + half)
    ax.set_zlim3d(middle[2] - half, middle[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title(f"{s.title}\nN = {N}, T = {result.t[-1]:.2f} s: {result.iterations} {result.solver.upper()} "
                 f"iterations, "
                 f"{result.wall_time:.2f} s, final ‖e‖ = {result.error_norm:.1e}", fontsize=9)
    ax.legend(fontsize=8, loc="upper left")
    figure.savefig(path, dpi=110)
    return path


# -- command line ------------------------------------------------------------------------------------
def chosen_scenarios(args: argparse.Namespace) -> list[Scenario]:
    """The scenarios ``gagen reach`` names: a bundled one, all, or a system's goals (or the goal given by
    --translation, --rotation and --dilation)."""
    given = (args.translation, args.rotation, args.dilation)
    if any(v is not None for v in given):  # a goal given on the command line: a move of the ready primitive
        if args.goal is not None or args.scenario == "all":
            raise ValueError("--translation, --rotation and --dilation state a goal of one system: give no "
                             "--goal, and a system (a spec or a bundled one), not all")
        r = args.rotation
        goal = Goal("command_line", "move", "", args.translation or (0.0, 0.0, 0.0),
                    None if r is None else ((r[0], r[1], r[2]), r[3]), args.dilation or 1.0)
        target = SCENARIOS[args.scenario].system if args.scenario in SCENARIOS else args.scenario
        spec_of(target)  # a ValueError naming the bundled ones for an unknown system
        return [of_goal(target, goal)]
    return list(scenarios_of(args.scenario, args.goal))


def run_command(args: argparse.Namespace) -> int:
    """``gagen reach`` on its parsed arguments (``gagen.apps.cooperative.commands``); with --dynamics,
    ``torque_reach.run_command``."""
    chosen = chosen_scenarios(args)
    ok = True
    solved = []
    for scenario in chosen:
        name = scenario.name
        r = run(scenario, args.out, N=args.N, horizon=args.horizon, solver=args.solver, hessian=args.hessian)
        solved.append(r)
        res = r.result
        ok &= res.success
        hessian = "Gauss-Newton model" if args.solver == "ilqr" else f"{args.hessian} Hessian"
        print(f"{name} ({r.scenario.system}, {r.q0.size} DOF, N = {args.N}): {args.solver}, {hessian}: "
              f"{res.iterations} iterations, "
              f"{res.wall_time:.3f} s wall (+ {res.build_time:.3f} s building the NLP), "
              f"final ‖e‖ = {res.error_norm:.2e}, {res.status}")
        print(f"  {'reached' if res.success else 'NOT reached'}: {res.message}",
              file=sys.stdout if res.success else sys.stderr)
        for p in r.plots:
            print(f"  {p}")
    if args.view:
        view(solved, args.port)
    return 0 if ok else 1


def view(results: Sequence[ScenarioResult], port: int) -> None:
    """Play each scenario's optimal trajectory in the browser viewer, one system after another, each
    until Ctrl-C (``gagen.viewer``)."""
    from gagen.viewer.scene import Scene, serve

    for r in results:
        system = _loaded(r.scenario.system)[0]
        t = r.result.dt * np.arange(r.result.q.shape[0])
        print(f"{r.scenario.name}: {r.scenario.title}")
        serve(Scene(system, r.result.q[0], port=port), [(r.scenario.name, t, r.result.q)])
