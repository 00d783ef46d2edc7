"""Secondary objectives in the geometric nullspace of a line and a plane [COOP Section 5.2, Fig. 18].

Two iiwa 14 span a line (``two_iiwas_line``), three span a plane (``three_iiwas_plane``); the spec's
``ready`` configuration gives the primitive to keep, V_Sd = V_Sc(q0). A secondary task pulls the first
chain's end point p_0 toward a target that is partly along the primitive and partly off it,

    p_target = p_0(0) + ``along`` · t + ``off`` · n      (t a unit tangent: toward p_1; n a unit normal),

with the resolved-rate law of the circle demo (``nullspace_demo``), J_p the first chain's 3 × m
position Jacobian (zero columns for the other joints):

- projected (task priority in the geometric nullspace): q̇ = (J_p N)⁺ k (p_target − p_0), N = I −
  J_G⁺ J_G [Eq. 58]. range (J_p N)⁺ ⊂ range N, so J_G q̇ = 0 and V_Sc — the line or plane — stays
  fixed along the exact flow; J_p N maps onto the tangent space (the line's direction, the plane), so
  ṗ_0 = k P_T (p_target − p_0): the tangential part of the target is reached exactly and the normal
  part is rejected, as in Fig. 18 ("secondary objectives tangential to the line will not change the
  line"). (N q̇_sec, Eq. 60 as the circle demo uses it, keeps the primitive too, but the point then
  settles where a configuration-dependent combination of the tangential and normal parts vanishes,
  not at the tangential target.)
- not projected: q̇ = J_p⁺ k (p_target − p_0): the point reaches the target off the primitive and the
  line or plane through the end points moves.

Recorded per RK4 step: the similarity distance ‖e(q)‖ = ‖log(V_Sc(q)~ V_Sd)‖ (``task`` kernel), p_0's
distance to the tangential target p_0(0) + along · t, to the full target, and to the initial primitive.

    gagen nullspace --primitive line --out plots/     # or plane; or a spec file spanning a line or plane
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.control.differential import damped_pseudo_inverse, nullspace_projector
from gagen.robots.points import chain_kernels, end_points
from gagen.runtime import GeneratedModule

Array = NDArray[np.float64]
KINDS = ("line", "plane")
DEFAULT_SYSTEMS = {"circle": "three_pandas_circle", "line": "two_iiwas_line", "plane": "three_iiwas_plane"}
ALONG = 0.15  # m along the primitive (toward the second end point)
OFF = 0.10  # m along its normal


def kind_of(system: str) -> str:
    """The primitive a bundled system or a spec file spans (the spec is read, nothing is built)."""
    from gagen.apps.cooperative.scenarios import system_of

    return system_of(system).kind


def chosen_system(system: str | None, primitive: str | None) -> str:
    """``gagen nullspace``'s system: the one given, else the bundled one of ``primitive`` (default circle); a
    ValueError when both are given and the system spans another primitive."""
    if system is None:
        return DEFAULT_SYSTEMS[primitive or "circle"]
    if primitive is not None and kind_of(system) != primitive:
        raise ValueError(f"--primitive {primitive}: {system} spans a {kind_of(system)}")
    return system



def integrate_rk4(f: Any, q: Array, dt: float, steps: int) -> Array:
    """q over ``steps`` classical Runge-Kutta steps of q̇ = f(q) (the joint paths of the nullspace demos):
    an array of steps + 1 configurations, q first."""
    qs = [q]
    for _ in range(steps):
        k1 = f(q)
        k2 = f(q + 0.5 * dt * k1)
        k3 = f(q + 0.5 * dt * k2)
        k4 = f(q + dt * k3)
        q = q + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        qs.append(q)
    return np.array(qs)

@dataclass(frozen=True)
class Flat:
    """The initial primitive: a ``point`` on it, its unit ``tangent`` t (toward the second end point) and
    the unit ``normal`` n of the offset (a line's: horizontal-most perpendicular; a plane's: its normal);
    ``basis`` spans its directions (one for a line, two for a plane)."""

    kind: str
    point: Array
    tangent: Array
    normal: Array
    basis: Array

    def distance(self, p: Array) -> float:
        """Euclidean distance of p from the line or plane."""
        d = np.asarray(p, dtype=float) - self.point
        return float(np.linalg.norm(d - self.basis.T @ (self.basis @ d)))


def flat_through(kind: str, points: Array) -> Flat:
    """The line through the first two points or the plane through three (ValueError when degenerate)."""
    p0, p1 = points[0], points[1]
    t = p1 - p0
    if np.linalg.norm(t) < 1e-9:
        raise ValueError("the first two end points coincide: no line through them")
    t = t / np.linalg.norm(t)
    if kind == "line":
        n = np.cross(t, [0.0, 0.0, 1.0])
        if np.linalg.norm(n) < 1e-6:
            n = np.cross(t, [1.0, 0.0, 0.0])
        n = n / np.linalg.norm(n)
        return Flat(kind, p0, t, n, t[None, :])
    n = np.cross(t, points[2] - p0)
    if np.linalg.norm(n) < 1e-9:
        raise ValueError("the end points are collinear: no plane through them")
    n = n / np.linalg.norm(n)
    return Flat(kind, p0, t, n, np.array([t, np.cross(n, t)]))


@dataclass(frozen=True)
class FlatResult:
    """One run: ``t``, ``q`` and ``points`` (steps + 1, chains, 3) per time, the recorded distances,
    the initial ``flat``, the ``target`` and the ``tangential`` target."""

    system: str
    projected: bool
    t: Array
    q: Array
    points: Array
    similarity_distance: Array
    tangential_distance: Array
    target_distance: Array
    off_distance: Array
    flat: Flat
    target: Array
    tangential: Array

    @property
    def label(self) -> str:
        if self.projected:
            return "projected: q̇ = (J_p N)⁺ k (p* − p)"
        return "not projected: q̇ = J_p⁺ k (p* − p)"


def position_jacobian(m: GeneratedModule, q: Array) -> tuple[Array, Array]:
    """The first chain's end point p (3,) and its position Jacobian over all of q (3, m)."""
    name, indices = chain_kernels(m.manifest)[0]
    outputs = getattr(m.c, name.removesuffix("_fk") + "_jacobians")(q[indices])  # M, P, J_S, J_b, J_A, J_P, …
    P, J_P = np.array(outputs[1]).ravel(), np.array(outputs[5])
    J = np.zeros((3, q.size))
    J[:, indices] = J_P[1:4] / P[0]
    return P[1:4] / P[0], J


def velocity(m: GeneratedModule, q: Array, target: Array, gain: float, projected: bool) -> Array:
    """q̇ = (J_p N)⁺ k (p* − p) with N = N(J_G) if ``projected``, else J_p⁺ k (p* − p)."""
    p, J_p = position_jacobian(m, q)
    if projected:
        J_p = J_p @ nullspace_projector(np.array(m.c.similarity(q)[2]))
    qdot: Array = damped_pseudo_inverse(J_p) @ (gain * (target - p))
    return qdot


def run(system: str, projected: bool, *, steps: int = 400, dt: float = 0.01, gain: float = 1.5,
        along: float = ALONG, off: float = OFF) -> FlatResult:
    """Integrate the demo's flow by ``steps`` RK4 steps of ``dt`` from the ready configuration of
    ``system`` (a bundled name or a spec file spanning a line or a plane; a ValueError otherwise)."""
    from gagen.apps.cooperative.scenarios import module, ready

    if steps < 1 or not dt > 0 or not gain > 0:
        raise ValueError("need steps >= 1, dt > 0 and gain > 0")
    kind = kind_of(system)
    if kind not in KINDS:
        raise ValueError(f"{system}: the Fig. 18 demo moves an end point within a line or a plane; this "
                         f"system spans a {kind}")
    m = module(system)
    q = ready(system)
    V_Sd = np.array(m.c.similarity(q)[0])
    start = end_points(m, q)
    flat = flat_through(kind, start)
    tangential = start[0] + along * flat.tangent
    target = tangential + off * flat.normal

    def f(x: Array) -> Array:
        return velocity(m, x, target, gain, projected)

    Q = integrate_rk4(f, q, dt, steps)
    points = np.array([end_points(m, x) for x in Q])
    return FlatResult(
        system=system, projected=projected, t=dt * np.arange(steps + 1, dtype=np.float64), q=Q, points=points,
        similarity_distance=np.array([np.linalg.norm(np.array(m.c.task(x, V_Sd)[0])) for x in Q]),
        tangential_distance=np.linalg.norm(points[:, 0] - tangential, axis=1),
        target_distance=np.linalg.norm(points[:, 0] - target, axis=1),
        off_distance=np.array([flat.distance(p) for p in points[:, 0]]),
        flat=flat, target=target, tangential=tangential)


# -- plot --------------------------------------------------------------------------------------------
COLOURS = {True: "tab:blue", False: "tab:red"}
FLOOR = 1e-16  # a log axis has no 0


def figure(results: Sequence[FlatResult]) -> Any:
    """Similarity distance (log), p_0 to the tangential target (log), p_0 off the initial primitive, and
    the end points' paths in 3D with the primitive. Lines carry gid ``<quantity>:<projected>``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 6.5), layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(3, 2, width_ratios=(1, 1.1))
    axes = [fig.add_subplot(grid[i, 0]) for i in range(3)]
    ax3 = fig.add_subplot(grid[:, 1], projection="3d")
    first = results[0]
    quantities = [("similarity_distance", "‖log(V_Sc(q)~ V_Sc(q0))‖", True),
                  ("tangential_distance", "p_0 to tangential target (m)", True),
                  ("off_distance", f"p_0 off the initial {first.flat.kind} (m)", False)]
    for ax, (name, ylabel, log) in zip(axes, quantities, strict=True):
        for r in results:
            values = getattr(r, name)
            ax.plot(r.t, np.maximum(values, FLOOR) if log else values, color=COLOURS[r.projected],
                    label=r.label, gid=f"{name}:{r.projected}")
        if log:
            ax.set_yscale("log")
        ax.set_ylabel(ylabel, fontsize=9)
        ax.grid(True, linewidth=0.3)
    axes[0].legend(fontsize=8)
    axes[2].set_xlabel("t (s)")
    flat = first.flat
    ends = np.concatenate([r.points[:, 0] for r in results] + [first.target[None]])  # around p_0's moves
    middle, half = (ends.max(axis=0) + ends.min(axis=0)) / 2, np.ptp(ends, axis=0).max() / 2 * 1.3 + 0.02
    if flat.kind == "line":
        s = np.linspace(-2 * half, 2 * half, 2) + flat.tangent @ (middle - flat.point)
        ax3.plot(*(flat.point + np.outer(s, flat.tangent)).T, color="tab:green", linestyle="--",
                 label="initial line")
    else:
        a, b = np.meshgrid(np.linspace(-half, half, 2), np.linspace(-half, half, 2))
        centre = middle - flat.normal * (flat.normal @ (middle - flat.point))
        patch = centre + a[..., None] * flat.basis[0] + b[..., None] * flat.basis[1]
        ax3.plot_surface(patch[..., 0], patch[..., 1], patch[..., 2], color="tab:green", alpha=0.15)
    ax3.scatter(*first.target, color="black", marker="x", s=60, label="target p*")
    ax3.scatter(*first.tangential, color="tab:green", marker="+", s=80, label="tangential target")
    ax3.scatter(*first.points[0, 0], color="tab:green", s=30, label="p_0 at t = 0")
    for r in results:
        ax3.plot(*r.points[:, 0].T, color=COLOURS[r.projected], linewidth=2.5, label=f"p_0, {r.label}",
                 gid=f"path:{r.projected}")
    for set_limits, c in zip((ax3.set_xlim3d, ax3.set_ylim3d, ax3.set_zlim3d), middle, strict=True):
        set_limits(c - half, c + half)
    ax3.set_box_aspect((1, 1, 1))
    ax3.set(xlabel="x (m)", ylabel="y (m)", zlabel="z (m)")
    ax3.legend(fontsize=7, loc="upper left")
    chains = first.points.shape[1]
    ax3.set_title(f"{first.system}: the {flat.kind} nullspace of {chains} arms [COOP Fig. 18]", fontsize=10)
    return fig


def plot(results: Sequence[FlatResult], out_folder: str | Path) -> Path:
    """Write ``figure(results)`` as ``out_folder/nullspace_<kind>.png``; returns the path."""
    folder = Path(out_folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"nullspace_{results[0].flat.kind}.png"
    figure(results).savefig(path, dpi=90)
    return path


def run_command(args: argparse.Namespace) -> int:
    """``gagen nullspace`` for a system spanning a line or a plane (``nullspace_demo.run_command``)."""
    print(f"{args.system}: {args.steps} RK4 steps of {args.dt} s, k = {args.gain}", flush=True)
    results = [run(args.system, projected, steps=args.steps, dt=args.dt, gain=args.gain)
               for projected in (True, False)]
    r0 = results[0]
    print(f"initial {r0.flat.kind} through {np.round(r0.flat.point, 4)}, tangent "
          f"{np.round(r0.flat.tangent, 4)}; target {ALONG} m along it and {OFF} m off it")
    for r in results:
        print(f"{r.label:36s}: similarity distance max {r.similarity_distance.max():.3e}, "
              f"to tangential target {r.tangential_distance[-1]:.3e} m, "
              f"to target {r.target_distance[-1]:.3e} m, "
              f"off the {r.flat.kind} max {r.off_distance.max():.3e} m")
    print(f"plot: {plot(results, args.out)}")
    if args.view:
        from gagen.apps.cooperative.scenarios import system_of
        from gagen.viewer.scene import Scene, serve

        serve(Scene(system_of(args.system), results[0].q[0], port=args.port),
              [(r.label, r.t, r.q) for r in results])
    return 0
