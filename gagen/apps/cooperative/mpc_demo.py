"""Cooperative MPC of three Franka Pandas tracking a moving circle [COOP Sections 3.9, 4.2; issue 18].

The three Pandas (``three_pandas_circle``, 21 DOF) start at rest in their ``ready`` configuration; the
target circle starts as theirs and then translates, turns and grows:

    centre(t) = c0 + (A sin ωt, A (1 − cos ωt), B t / T),   tilt(t) = θ sin ωt about x,
    radius(t) = r0 (1 + δ sin ωt)

(A = 5 cm, B = 5 cm over the run, θ = 0.15 rad, δ = 0.1, ω = 2π / 4 s). ``gagen.control.mpc`` tracks it
with warm-started iLQR, N = 50 steps over a 0.2 s horizon, at ``rate`` = 100 Hz by default, in closed
loop with the kinematic simulation; the report gives the solve times (median, worst, deadline misses at
the rate) and the tracking error, the plots the error and the solve times over time and the circle's radius
against the target's; the animation shows the end points and both circles.

    gagen mpc --out plots/mpc [--rate 100] [--duration 4] [--no-animation] [--view]
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.check import joint_limits
from gagen.control.mpc import MPCRun, run
from gagen.control.ocp import target_from, target_primitive
from gagen.robots.points import end_points
from gagen.runtime import GeneratedModule
from gagen.viewer.geometry import circumcircle

SYSTEM = "three_pandas_circle"
AMPLITUDE = 0.05  # m
RISE = 0.05  # m over the run
TILT = 0.15  # rad
GROWTH = 0.1  # relative radius change
PERIOD = 4.0  # s


def setup(system: str = SYSTEM) -> tuple[GeneratedModule, NDArray[np.float64], Any]:
    """The module, the start configuration (the spec's ``ready``) and the moving target t -> V_Sd(t) of a
    system spanning a circle: a bundled name or a spec file (a ValueError for another primitive)."""
    from gagen.apps.cooperative.scenarios import module as module_of
    from gagen.apps.cooperative.scenarios import ready, system_of

    kind = system_of(system).kind
    if kind != "circle":  # before anything is built
        raise ValueError(f"{system}: the MPC demo tracks a moving circle; this system spans a {kind}")
    module = module_of(system)
    q0 = ready(system)
    start = np.array(module.c.similarity(q0)[0])

    def target(t: float) -> NDArray[np.float64]:
        w = 2 * np.pi / PERIOD
        translation = (AMPLITUDE * np.sin(w * t), AMPLITUDE * (1 - np.cos(w * t)), RISE * t / PERIOD)
        return target_from(start, translation, ((1.0, 0.0, 0.0), TILT * np.sin(w * t)),
                           1 + GROWTH * np.sin(w * t), kind="circle")

    return module, q0, target


def circle_of(points: NDArray[np.float64]) -> tuple[NDArray[np.float64], float, NDArray[np.float64]]:
    """Centre, radius and unit normal of the circle through three points (the viewer's closed form)."""
    found = circumcircle(*np.asarray(points, dtype=float))
    if found is None:
        raise ValueError("the three end points are collinear: no circle through them")
    return found


def report(result: MPCRun, rate: float, system: str = SYSTEM) -> str:
    times = result.solve_time * 1e3
    settled = result.tracking_error[len(result.tracking_error) // 4:]
    return "\n".join([
        f"# Cooperative MPC: {Path(system).stem} tracking a moving circle", "",
        f"{len(result.u)} ticks at {rate:g} Hz, warm-started iLQR over a 0.2 s horizon (N = 50)",
        "",
        "| what | value |", "|---|---:|",
        f"| solve time median / 95 % / worst | {np.median(times):.2f} / {np.percentile(times, 95):.2f} / "
        f"{times.max():.2f} ms |",
        f"| deadline misses at {rate:g} Hz (solve > {1e3 / rate:g} ms) | {result.deadline_misses} of "
        f"{len(times)} |",
        f"| iLQR iterations median / worst | {np.median(result.iterations):.0f} / "
        f"{result.iterations.max()} |",
        f"| solves that reached their tolerance | {int(result.solved.sum())} of {len(result.solved)} |",
        f"| tracking error ‖e(q, V_Sd(t))‖ after the first quarter: median / worst | "
        f"{np.median(settled):.2e} / {settled.max():.2e} |", ""])


def figure(module: GeneratedModule, result: MPCRun, target: Any) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 4), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 3, 1)
    ax.semilogy(result.t, np.maximum(result.tracking_error, 1e-16))
    ax.set(xlabel="t [s]", ylabel="‖e(q, V_Sd(t))‖", title="tracking error")
    ax.grid(True, which="both", alpha=0.3)
    ax = fig.add_subplot(1, 3, 2)
    ax.plot(result.t[:-1], result.solve_time * 1e3, lw=0.8)
    ax.axhline(result.period * 1e3, color="red", ls="--", lw=1, label="deadline")
    ax.set(xlabel="t [s]", ylabel="solve time [ms]", title="iLQR solve per tick")
    ax.legend()
    ax.grid(True, alpha=0.3)
    ax = fig.add_subplot(1, 3, 3)
    radius = [circle_of(end_points(module, q))[1] for q in result.q]
    wanted = [_target_circle(module, target(t))[1] for t in result.t]
    ax.plot(result.t, radius, label="arms' circle")
    ax.plot(result.t, wanted, "--", label="target")
    ax.set(xlabel="t [s]", ylabel="radius [m]", title="radius")
    ax.legend()
    ax.grid(True, alpha=0.3)
    return fig


def _target_circle(module: GeneratedModule, V_Sd: NDArray[np.float64]
                   ) -> tuple[NDArray[np.float64], float, NDArray[np.float64]]:
    """Centre, radius, normal of the target circle X_d = V_Sd X_u V_Sd~ (from three of its points)."""
    from gagen.control.ocp import multivector
    from gagen.model.primitives import centre as centre_of
    from gagen.model.primitives import radius as radius_of
    from gagen.model.primitives import unit_normal

    rows = next(p["rows"] for k in module.manifest["kernels"] if k["name"] == "primitive"
                for p in k["outputs"] if p["name"] == "X_c")
    x = multivector(rows, target_primitive(module, V_Sd))
    c = centre_of(x)
    return (np.array([c["e1"], c["e2"], c["e3"]]), float(radius_of(x)),
            np.array([unit_normal(x)[b] for b in ("e1", "e2", "e3")]))


def ring(centre: NDArray[np.float64], radius: float, normal: NDArray[np.float64],
         count: int = 90) -> NDArray[np.float64]:
    """``count`` points around the circle of this centre, radius and unit normal (closed: the last is
    the first)."""
    s = np.linspace(0, 2 * np.pi, count)
    a = np.cross(normal, [1.0, 0, 0] if abs(normal[0]) < 0.9 else [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    points: NDArray[np.float64] = centre + radius * (np.outer(np.cos(s), a) + np.outer(np.sin(s), b))
    return points


def target_ring(module: GeneratedModule, V_Sd: NDArray[np.float64], count: int = 90) -> NDArray[np.float64]:
    """Points around the target circle X_d = V_Sd X_u V_Sd~."""
    return ring(*_target_circle(module, V_Sd), count=count)


def animate(module: GeneratedModule, result: MPCRun, target: Any, path: Path, fps: int = 20) -> Path:
    """A GIF of the three end points, the arms' circle and the target circle, seen from above-front."""
    from matplotlib.animation import FuncAnimation, PillowWriter
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="3d")
    every = max(1, round(1 / (fps * result.period)))
    frames = list(range(0, len(result.t), every))

    def draw(k: int) -> None:
        ax.clear()
        points = end_points(module, result.q[k])
        mine, wanted = ring(*circle_of(points)), target_ring(module, target(result.t[k]))
        ax.plot(*wanted.T, "--", color="grey", lw=1)
        ax.plot(*mine.T, color="magenta", lw=2)
        ax.scatter(*points.T, color="black", s=20)
        ax.set(xlim=(-0.7, 0.7), ylim=(-0.7, 0.7), zlim=(0.0, 1.0), title=f"t = {result.t[k]:.2f} s")

    animation = FuncAnimation(fig, draw, frames=frames)
    animation.save(path, writer=PillowWriter(fps=fps))
    return path


def run_command(args: argparse.Namespace) -> int:
    """``gagen mpc`` on its parsed arguments (``gagen.apps.cooperative.commands``)."""
    from gagen.apps.cooperative.scenarios import system_of

    args.system = args.system or SYSTEM
    args.rate = args.rate or 100.0
    module, q0, target = setup(args.system)
    loaded = system_of(args.system)
    limits = joint_limits(loaded)[:2]
    result = run(module.c.task, target, q0, rate=args.rate, duration=args.duration, limits=limits,
                 progress=lambda t: print(f"  t = {t:.1f} s", flush=True))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    text = report(result, args.rate, args.system)
    (out / "mpc_report.md").write_text(text)
    figure(module, result, target).savefig(out / "mpc.png", dpi=100)
    print(text + f"wrote {out / 'mpc_report.md'}, {out / 'mpc.png'}")
    if not args.no_animation:
        print(f"wrote {animate(module, result, target, out / 'mpc.gif')}")
    if args.view:
        from gagen.viewer.scene import Scene, serve

        serve(Scene(loaded, result.q[0], port=args.port), [("MPC", result.t, result.q)])
    return 0
