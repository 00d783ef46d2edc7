"""The C loop's per-tick CSV log and its plots (like the paper's Figs. 6-8)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from gagen.control.smc.law import POSE


# -- logs and plots --------------------------------------------------------------------------------
def read_log(csv: str | Path) -> dict[str, NDArray[np.float64]]:
    """The runner's (or ``Simulation.write_csv``'s) CSV as column name -> array."""
    path = Path(csv)
    with path.open() as f:
        names = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {name: data[:, i] for i, name in enumerate(names)}


def plot_run(csv: str | Path, out_folder: str | Path, *, transient: float | None = 0.5) -> list[Path]:
    """Plots of a run like the paper's Figs. 6-8 (matplotlib, Agg): ``pose.png`` (the point and the
    direction with their references, Fig. 6), ``error.png`` (position and direction error norms, log
    scale), ``joint_velocities.png`` (u = q̇, Fig. 7) and ``joint_positions.png`` (q, Fig. 8)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    log = read_log(csv)
    out = Path(out_folder)
    out.mkdir(parents=True, exist_ok=True)
    t = log["t"]
    n = sum(1 for name in log if name.startswith("u") and name[1:].isdigit())
    written = []

    def save(fig: Figure, name: str) -> None:
        FigureCanvasAgg(fig)
        fig.tight_layout()
        path = out / name
        fig.savefig(path, dpi=110)
        written.append(path)

    fig = Figure(figsize=(11, 6))
    labels = ("x [m]", "y [m]", "z [m]", "direction x", "direction y", "direction z")
    for i, (name, label) in enumerate(zip(POSE, labels, strict=True)):
        ax = fig.add_subplot(2, 3, i + 1)
        ax.plot(t, log[name], label="end effector")
        ax.plot(t, log[f"ref_{name}"], "--", label="reference")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        if i == 0:
            ax.legend(fontsize=8)
    fig.suptitle("Pose tracking: end point and tool line direction (cf. [SMC] Fig. 6)")
    save(fig, "pose.png")

    fig = Figure(figsize=(8, 4))
    ax = fig.add_subplot(1, 1, 1)
    floor = 1e-12
    ax.semilogy(t, np.maximum(log["position_error"], floor), label="|x_p − x_p,ref| [m]")
    ax.semilogy(t, np.maximum(log["direction_error"], floor), label="|d − d_ref|")
    ax.semilogy(t, np.maximum(log["error_max"], floor), ":", label="max |s_i|")
    if transient is not None:
        ax.axvline(transient, color="gray", lw=0.8)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("tracking error")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.suptitle("Tracking error s = x − x_ref")
    save(fig, "error.png")

    for name, prefix, ylabel, title in (
            ("joint_velocities.png", "u", "q̇ [rad/s]", "Control: joint velocities u (cf. [SMC] Fig. 7)"),
            ("joint_positions.png", "q", "q [rad]", "Joint positions (cf. [SMC] Fig. 8)")):
        fig = Figure(figsize=(8, 4))
        ax = fig.add_subplot(1, 1, 1)
        for i in range(n):
            ax.plot(t, log[f"{prefix}{i + 1}"], label=f"{prefix}{i + 1}")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, ncol=min(n, 7))
        fig.suptitle(title)
        save(fig, name)
    return written


def csv_header(n: int) -> list[str]:
    return ["t", *[f"q{i + 1}" for i in range(n)], *POSE, *[f"ref_{p}" for p in POSE],
            *[f"u{i + 1}" for i in range(n)], "position_error", "direction_error", "error_max", "lateness",
            "work"]
