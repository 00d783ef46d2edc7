"""Plots of a walk (``gagen.apps.hexapod.gait``) with matplotlib's Agg backend (no display):
``joint_angles.png`` (the 18 joint angles, one panel per leg, limits dashed, swing shaded),
``toe_paths.png`` (the toes and the body seen from above and from the side) and ``walk.gif`` (a 3D
stick figure walking over the ground patch, written by Pillow: no ffmpeg needed)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gagen.apps.hexapod.gait import GaitResult, joint_points

if TYPE_CHECKING:
    from matplotlib.figure import Figure

TRIPOD_COLOURS = ("tab:blue", "tab:orange")


def _figure(size: tuple[float, float]) -> Figure:  # (matplotlib imported lazily)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size)
    FigureCanvasAgg(fig)
    return fig


def _leg_colour(result: GaitResult, i: int) -> str:
    return TRIPOD_COLOURS[0 if i in result.tripods[0] else 1]


def joint_angles(result: GaitResult, path: str | Path) -> Path:
    """The joint angles over time: a panel per leg with its yaw, thigh and knee; swing shaded."""
    fig = _figure((12, 7))
    t = result.t
    for i, leg in enumerate(result.hexapod.legs):
        ax = fig.add_subplot(2, 3, i + 1)
        for j, (name, colour) in enumerate(zip(("yaw", "thigh", "knee"), ("C0", "C1", "C2"), strict=True)):
            ax.plot(t, result.q[:, 3 * i + j], color=colour, label=name)
            for limit in leg.limits[j]:
                ax.axhline(limit, color=colour, ls="--", lw=0.7, alpha=0.6)
        swing = result.swing[:, i].astype(float)
        ax.fill_between(t, 0, 1, where=swing > 0, transform=ax.get_xaxis_transform(), color="0.9",
                        zorder=0, lw=0)
        ax.set_title(f"{leg.name} (tripod {'A' if i in result.tripods[0] else 'B'})", fontsize=10)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("q [rad]")
        ax.grid(alpha=0.3)
        if i == 0:
            ax.legend(fontsize=8, loc="lower left")
    fig.suptitle("Joint angles from the analytic IK (swing shaded, limits dashed)")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=100)
    return out


def toe_paths(result: GaitResult, path: str | Path) -> Path:
    """The toes' world paths from above (x, y) and from the side (x, z), with the body's path."""
    fig = _figure((12, 5.5))
    top, side = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    body = result.body.position
    for i in range(len(result.hexapod.legs)):
        colour = _leg_colour(result, i)
        top.plot(result.toes[:, i, 0], result.toes[:, i, 1], color=colour, lw=1)
        stance = ~result.swing[:, i]
        top.plot(result.toes[stance, i, 0], result.toes[stance, i, 1], ".", color=colour, ms=3)
        side.plot(result.toes[:, i, 0], result.toes[:, i, 2], color=colour, lw=1)
    top.plot(body[:, 0], body[:, 1], "k--", lw=1, label="body")
    side.plot(body[:, 0], body[:, 2], "k--", lw=1, label="body")
    x = np.linspace(result.toes[..., 0].min(), result.toes[..., 0].max(), 2)
    side.plot(x, result.ground.lift(np.column_stack([x, np.zeros(2)]))[:, 2], color="tab:green", lw=1,
              label="ground (y = 0)")
    top.set_aspect("equal")
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.set_title("top view (dots: stance)")
    top.grid(alpha=0.3)
    top.legend(fontsize=8)
    side.set_xlabel("x [m]")
    side.set_ylabel("z [m]")
    side.set_title("side view")
    side.grid(alpha=0.3)
    side.legend(fontsize=8)
    fig.suptitle("Toe paths (FK of the IK's joint angles): tripod A blue, tripod B orange")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=100)
    return out


def animate(result: GaitResult, path: str | Path, frames: int = 90, size: float = 5.0, dpi: int = 80,
            progress: Callable[[str], None] = lambda _: None) -> Path:
    """A GIF of the walk: the body hexagon through the hips, each leg hip → thigh → knee → toe (the
    joint positions of the IK's angles, carried to the world by the body pose) and the ground patch.
    ``frames`` samples spread evenly over the walk, played at its real speed."""
    from matplotlib.animation import PillowWriter

    n = len(result.t)
    picks = np.unique(np.linspace(0, n - 1, max(2, frames)).round().astype(int))
    legs = len(result.hexapod.legs)
    points = joint_points(result.hexapod, result.q[picks])  # frames×6×4×3, body frame
    pose = type(result.body)(result.t[picks], result.body.position[picks], result.body.rotation[picks],
                             result.body.motor[picks])
    world = pose.to_world(points.reshape(len(picks), legs * 4, 3)).reshape(points.shape)
    order = np.argsort([np.arctan2(leg.xyz[1], leg.xyz[0]) for leg in result.hexapod.legs])
    fig = _figure((size, size))
    ax = fig.add_subplot(1, 1, 1, projection="3d")
    everything = np.concatenate([world.reshape(-1, 3), result.toes.reshape(-1, 3)])
    lo, hi = everything.min(0) - 0.05, everything.max(0) + 0.05
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half / 2, centre[2] + half / 2)
    ax.set_box_aspect((1, 1, 0.5))
    gx, gy = np.meshgrid(np.linspace(centre[0] - half, centre[0] + half, 2),
                         np.linspace(centre[1] - half, centre[1] + half, 2))
    gz = result.ground.lift(np.column_stack([gx.ravel(), gy.ravel()]))[:, 2].reshape(gx.shape)
    ax.plot_surface(gx, gy, gz, color="tab:green", alpha=0.15, lw=0)
    ax.plot(*result.body.position.T, "k:", lw=0.8)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.view_init(elev=25, azim=-60)
    body_line, = ax.plot([], [], [], "k-", lw=2)
    leg_lines = [ax.plot([], [], [], "-o", color=_leg_colour(result, i), lw=2, ms=2.5)[0]
                 for i in range(legs)]
    title = ax.set_title("")
    out = Path(path)
    fps = max(1.0, len(picks) / result.t[-1])
    writer = PillowWriter(fps=fps)
    with writer.saving(fig, str(out), dpi):
        for k, sample in enumerate(picks):
            hips = world[k, order, 0]
            ring = np.vstack([hips, hips[:1]])
            body_line.set_data_3d(ring[:, 0], ring[:, 1], ring[:, 2])
            for i, line in enumerate(leg_lines):
                chain = world[k, i]
                line.set_data_3d(chain[:, 0], chain[:, 1], chain[:, 2])
            title.set_text(f"{result.hexapod.name} walking, t = {result.t[sample]:.2f} s")
            writer.grab_frame()
            if (k + 1) % 30 == 0 or k + 1 == len(picks):
                progress(f"  animation: frame {k + 1}/{len(picks)}")
    return out


__all__ = ["animate", "joint_angles", "toe_paths"]
