"""The geometric nullspace demo [COOP Section 4.3, Eq. 58 and 60, Figs. 14-15].

Three Franka Pandas (``generated/three_pandas_circle``, 21 DOF) start in their spec's ``ready``
configuration; their end points span the initial cooperative circle, whose similarity is
V_Sd = V_Sc(q0). A secondary task moves arm0's end point p_0 toward a target point **on** that circle
(``TARGET_ANGLE`` = +60° from p_0 along the circle, in the direction arm0 → arm1 → arm2) with the
classical resolved-rate law

    q̇_sec = [J_p,0⁺ k (p_target − p_0); 0; 0]          (J_p,0: arm0's 3 × 7 position Jacobian).

- projected (Eq. 60): q̇ = N(q) q̇_sec with N = I − J_G⁺ J_G (Eq. 58), J_G = J_G,Sc the geometric
  similarity Jacobian of the ``similarity`` kernel, as in the paper. J_G N = 0 means the similarity
  twist B = J_G q̇ vanishes, so V_Sc — and with it the circle — stays fixed along the exact flow, and
  arm0 can only slide along the circle. Its kernel is the product of the per-arm sets {q̇_i: ṗ_i
  tangent to the circle} (each 7 − 3 + 1 = 5 dimensional, 15 in all = 21 − rank 6), so N is block
  diagonal and arm1 and arm2 do not move at all. N(J_c) of the ``primitive`` kernel would be the
  wrong choice here: J_c also fixes the weight of X_c = P_0 ∧ P_1 ∧ P_2, X_c² = (½ d_01 d_02 d_12)²
  (d_ij the distances of the end points), which changes as a point slides along the circle. So
  away from the symmetric start (where d_01 d_02 is stationary and rank J_c drops from 7 to 6,
  making N(J_c) jump) arm0 could not slide alone: N(J_c) drags arm1 and arm2 along the circle too.
- not projected (Fig. 14): q̇ = q̇_sec. arm0's point cuts the chord toward the target, leaves the
  circle, and the circle through the three points changes.

Recorded per time step: the similarity distance ‖e(q)‖ = ‖log(V_Sc(q)~ V_Sd)‖ (the ``task`` kernel's
error with respect to the initial circle), arm0's distance to the target and to the initial circle.
The flow is integrated with classical RK4 (the vector field is smooth while rank J_G = 6): the exact
projected flow keeps ‖e‖ = 0, so the recorded ‖e‖ of the projected run is the integration error,
O(dt⁴) (explicit Euler would drift off the circle by O(dt) in total: each step goes along the
tangent, (v dt)² / 2r off the circle).

    python -m gagen.apps.cooperative.nullspace_demo --out plots/ [--steps 400] [--dt 0.01] [--gain 1.5]
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.apps.cooperative.geometric_nullspace import integrate_rk4
from gagen.control.differential import damped_pseudo_inverse, nullspace_projector
from gagen.robots.points import chain_kernels, end_points
from gagen.runtime import GeneratedModule

SYSTEM = "three_pandas_circle"
TARGET_ANGLE = np.pi / 3
"""The target is the initial circle's point at this angle from arm0's point (toward arm1)."""
DEFAULT_STEPS = 400
DEFAULT_DT = 0.01
DEFAULT_GAIN = 1.5
PLOT_NAME = "nullspace_demo.png"

ArrayLike3 = Sequence[float] | NDArray[np.float64]


@cache
def module(system: str = SYSTEM) -> GeneratedModule:
    from gagen.apps.cooperative.scenarios import module as module_of

    return module_of(system)


def ready(system: str = SYSTEM) -> NDArray[np.float64]:
    from gagen.apps.cooperative.scenarios import ready as ready_of

    return ready_of(system)


# -- geometry ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Circle:
    """A circle in space: ``centre``, ``radius`` and unit ``normal`` of its plane."""

    centre: NDArray[np.float64]
    radius: float
    normal: NDArray[np.float64]

    def distance(self, p: ArrayLike3) -> float:
        """Euclidean distance of p from the circle (in-plane radial offset and height over the plane)."""
        d = np.asarray(p, dtype=float) - self.centre
        height = float(d @ self.normal)
        in_plane = float(np.linalg.norm(d - height * self.normal))
        return float(np.hypot(in_plane - self.radius, height))

    def rotate(self, p: ArrayLike3, angle: float) -> NDArray[np.float64]:
        """The circle's point at ``angle`` (right-handed about ``normal``) from the circle point of p."""
        d = np.asarray(p, dtype=float) - self.centre
        d = d - (d @ self.normal) * self.normal
        u = d / np.linalg.norm(d)
        w = np.cross(self.normal, u)
        point: NDArray[np.float64] = self.centre + self.radius * (np.cos(angle) * u + np.sin(angle) * w)
        return point

    def polyline(self, samples: int = 145) -> NDArray[np.float64]:
        """(samples, 3) points around the circle, closed."""
        a = np.cross(self.normal, [1.0, 0.0, 0.0] if abs(self.normal[0]) < 0.9 else [0.0, 1.0, 0.0])
        a /= np.linalg.norm(a)
        b = np.cross(self.normal, a)
        angles = np.linspace(0.0, 2 * np.pi, samples)
        points: NDArray[np.float64] = self.centre + self.radius * (np.outer(np.cos(angles), a)
                                                                   + np.outer(np.sin(angles), b))
        return points



def circumcircle(a: ArrayLike3, b: ArrayLike3, c: ArrayLike3) -> Circle:
    """The circle through three points (plain vector algebra); its normal orients a → b → c
    counter-clockwise. Raises ValueError for (nearly) collinear points."""
    a, b, c = (np.asarray(x, dtype=float) for x in (a, b, c))
    u, v = b - a, c - a
    n = np.cross(u, v)
    nn = float(n @ n)
    if nn <= 1e-24 * float(u @ u) * float(v @ v):
        raise ValueError("collinear points have no circumcircle")
    centre = a + (float(u @ u) * np.cross(v, n) + float(v @ v) * np.cross(n, u)) / (2.0 * nn)
    return Circle(centre, float(np.linalg.norm(a - centre)), n / np.sqrt(nn))


# -- simulation --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DemoResult:
    """One run: ``t`` (steps + 1,), ``q`` (steps + 1, 21), ``points`` (steps + 1, 3 arms, 3), and per
    time ``similarity_distance`` ‖log(V_Sc(q)~ V_Sc(q0))‖, arm0's ``target_distance`` ‖p_target − p_0‖
    and ``circle_distance`` (from the initial circle); ``circle`` the initial circle, ``target``."""

    projected: bool
    t: NDArray[np.float64]
    q: NDArray[np.float64]
    points: NDArray[np.float64]
    similarity_distance: NDArray[np.float64]
    target_distance: NDArray[np.float64]
    circle_distance: NDArray[np.float64]
    circle: Circle
    target: NDArray[np.float64]
    dt: float
    gain: float

    @property
    def label(self) -> str:
        return "projected: q̇ = N(q) q̇_sec" if self.projected else "not projected: q̇ = q̇_sec"


def secondary_velocity(m: GeneratedModule, q: NDArray[np.float64], target: NDArray[np.float64],
                       gain: float) -> NDArray[np.float64]:
    """q̇_sec = [J_p,0⁺ k (p_target − p_0); 0; …]: the first chain's resolved-rate step toward the target
    (its joints' entries of q; the rest zero)."""
    name, indices = chain_kernels(m.manifest)[0]  # the first chain's <chain>_fk and its joints in q
    jacobians = getattr(m.c, name.removesuffix("_fk") + "_jacobians")
    outputs = jacobians(q[indices])  # M, P, J_S, J_b, J_A, J_P, L, J_L
    P, J_P = np.array(outputs[1]), np.array(outputs[5])
    p = P[1:4] / P[0]
    J_p = J_P[1:4] / P[0]  # rows e1 e2 e3; the e0 weight is the constant 1
    velocity = np.zeros(q.shape[0])
    velocity[indices] = damped_pseudo_inverse(J_p) @ (gain * (target - p))
    return velocity


def velocity(m: GeneratedModule, q: NDArray[np.float64], target: NDArray[np.float64], gain: float,
             projected: bool) -> NDArray[np.float64]:
    """q̇ = N(q) q̇_sec with N = I − J_G⁺ J_G [Eq. 58, 60] if ``projected``, else q̇_sec."""
    v = secondary_velocity(m, q, target, gain)
    if not projected:
        return v
    J_G = np.array(m.c.similarity(q)[2])
    return nullspace_projector(J_G) @ v


def run(projected: bool, *, steps: int = DEFAULT_STEPS, dt: float = DEFAULT_DT, gain: float = DEFAULT_GAIN,
        angle: float = TARGET_ANGLE, q0: ArrayLike3 | None = None, system: str = SYSTEM) -> DemoResult:
    """Integrate q̇ = f(q) (see ``velocity``) from ``q0`` (default: ready) with ``steps`` RK4 steps of
    ``dt`` seconds; the target is the initial circle's point ``angle`` from the first chain's point.
    ``system``: a bundled name or a spec file of a system spanning a circle (a ValueError otherwise)."""
    if steps < 1 or dt <= 0 or gain <= 0:
        raise ValueError("need steps >= 1, dt > 0 and gain > 0")
    from gagen.apps.cooperative.scenarios import system_of

    kind = system_of(system).kind
    if kind != "circle":  # before anything is built
        raise ValueError(f"{system}: the nullspace demo moves a point along its circle; this system spans a "
                         f"{kind}")
    m = module(system)
    q = ready(system) if q0 is None else np.array(q0, dtype=float)
    V_Sd = np.array(m.c.similarity(q)[0])
    start = end_points(m, q)
    circle = circumcircle(*start)
    target = circle.rotate(start[0], angle)

    def f(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return velocity(m, x, target, gain, projected)

    Q = integrate_rk4(f, q, dt, steps)
    points = np.array([end_points(m, x) for x in Q])
    similarity = np.array([np.linalg.norm(np.array(m.c.task(x, V_Sd)[0])) for x in Q])
    return DemoResult(
        projected=projected, t=dt * np.arange(steps + 1, dtype=np.float64), q=Q, points=points,
        similarity_distance=similarity,
        target_distance=np.linalg.norm(points[:, 0] - target, axis=1),
        circle_distance=np.array([circle.distance(p) for p in points[:, 0]]),
        circle=circle, target=target, dt=dt, gain=gain)


# -- plot --------------------------------------------------------------------------------------------
COLOURS = {True: "tab:blue", False: "tab:red"}


def figure(results: Sequence[DemoResult]) -> Any:
    """The Figure (Agg canvas, no pyplot state): similarity distance (log), arm0's distance to the
    target, arm0's distance to the initial circle (log), and arm0's end-point paths in 3D with the
    initial circle, the target and the other end points. Lines carry gid ``<quantity>:<projected>``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 8), layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(3, 2, width_ratios=(1, 1.15))
    axes = [fig.add_subplot(grid[i, 0]) for i in range(3)]
    ax3 = fig.add_subplot(grid[:, 1], projection="3d")
    quantities = [("similarity_distance", "‖log(V_Sc(q)~ V_Sc(q0))‖", True),
                  ("target_distance", "‖p_target − p_0‖ (m)", False),
                  ("circle_distance", "p_0 to initial circle (m)", True)]
    for ax, (name, ylabel, log) in zip(axes, quantities, strict=True):
        for r in results:
            ax.plot(r.t, getattr(r, name), color=COLOURS[r.projected], label=r.label,
                    gid=f"{name}:{r.projected}")
        if log:
            ax.set_yscale("log")
        ax.set_ylabel(ylabel, fontsize=9)
        ax.grid(True, linewidth=0.3)
    axes[0].set_title("similarity distance to the initial circle", fontsize=10)
    axes[1].set_title("secondary task: arm0's end point to the target", fontsize=10)
    axes[2].set_title("arm0's end point off the initial circle", fontsize=10)
    axes[0].legend(fontsize=8)
    axes[2].set_xlabel("t (s)")

    first = results[0]
    ax3.plot(*first.circle.polyline().T, color="tab:green", linewidth=1.2, linestyle="--",
             label="initial circle", gid="circle")
    ax3.scatter(*first.target, color="black", marker="x", s=60, label="target")
    ax3.scatter(*first.points[0, 1:].T, color="0.4", s=20, label="arm1, arm2 end points")
    for r in results:
        ax3.plot(*r.points[:, 0].T, color=COLOURS[r.projected], linewidth=2.5, label=f"arm0 path, {r.label}",
                 gid=f"path:{r.projected}")
    ax3.scatter(*first.points[0, 0], color="tab:green", s=30, label="arm0 start")
    ends = np.concatenate([first.circle.polyline(), *(r.points[:, 0] for r in results)])
    middle, half = (ends.max(axis=0) + ends.min(axis=0)) / 2, np.ptp(ends, axis=0).max() / 2 * 1.05
    for set_limits, c in zip((ax3.set_xlim3d, ax3.set_ylim3d, ax3.set_zlim3d), middle, strict=True):
        set_limits(c - half, c + half)
    ax3.set_box_aspect((1, 1, 1))
    ax3.set_xlabel("x (m)")
    ax3.set_ylabel("y (m)")
    ax3.set_zlabel("z (m)")
    ax3.legend(fontsize=8, loc="upper left")
    ax3.set_title("three Pandas (21 DOF): arm0 to a point on the circle [COOP Figs. 14-15]", fontsize=10)
    return fig


def plot(results: Sequence[DemoResult], out_folder: str | Path, name: str = PLOT_NAME) -> Path:
    """Write ``figure(results)`` as ``out_folder/name`` (PNG); returns the path."""
    folder = Path(out_folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    figure(results).savefig(path, dpi=100)
    return path


# -- command line ------------------------------------------------------------------------------------
def run_command(args: argparse.Namespace) -> int:
    """``gagen nullspace`` on its parsed arguments (``gagen.apps.cooperative.commands``); a system spanning
    a line or a plane runs the Fig. 18 demo (``geometric_nullspace``)."""
    from gagen.apps.cooperative import geometric_nullspace

    args.system = geometric_nullspace.chosen_system(args.system, args.primitive)
    if geometric_nullspace.kind_of(args.system) in geometric_nullspace.KINDS:
        return geometric_nullspace.run_command(args)
    results = [run(projected, steps=args.steps, dt=args.dt, gain=args.gain, system=args.system)
               for projected in (True, False)]
    c = results[0].circle
    print(f"initial circle: centre {np.round(c.centre, 4)}, radius {c.radius:.4f} m, "
          f"normal {np.round(c.normal, 4)}")
    print(f"target {np.round(results[0].target, 4)}, start distance {results[0].target_distance[0]:.4f} m; "
          f"T = {results[0].t[-1]:.2f} s ({args.steps} RK4 steps of {args.dt} s), k = {args.gain}")
    for r in results:
        print(f"{r.label:28s}: final distance to target {r.target_distance[-1]:.3e} m, "
              f"similarity distance max {r.similarity_distance.max():.3e} "
              f"final {r.similarity_distance[-1]:.3e}, "
              f"off circle max {r.circle_distance.max():.3e} m")
    print(f"plot: {plot(results, args.out)}")
    if args.view:  # the two runs one after the other, in a loop, until Ctrl-C (gagen.viewer)
        from gagen.apps.cooperative.scenarios import system_of
        from gagen.viewer.scene import Scene, serve

        serve(Scene(system_of(args.system), results[0].q[0], port=args.port),
              [(r.label, r.t, r.q) for r in results])
    return 0
