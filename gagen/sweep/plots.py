"""The sweeps' plots: a reachability map of target primitives, and the similarity-manipulability ellipsoid
volume over the workspace (binned by where the primitive is: a circle's or sphere's centre, else the end
points' centroid). Both take the table a sweep wrote (``ChunkStore.read``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.extras import MissingExtra

try:
    import pyarrow as pa
except ModuleNotFoundError as e:  # the sweep extra
    raise MissingExtra("pyarrow", "gagen.sweep") from e

FLOOR = 1e-12  # errors below this are drawn at it (a log colour scale has no 0)


def _figure(size: tuple[float, float]) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _column(table: pa.Table, name: str) -> NDArray[Any]:
    column: NDArray[Any] = table.column(name).to_numpy()  # (pyarrow has no type annotations)
    return column


def reach_map(table: pa.Table, path: str | Path, system: str = "three_pandas_circle",
              targets: str = "horizontal target circles") -> Path:
    """One panel per radius: the target centres' x-y grid coloured by the final error ‖e(q_N)‖ (log
    scale), the reached targets ringed in white."""
    from matplotlib.colors import LogNorm

    x, y, radius = (_column(table, k) for k in ("centre_x", "centre_y", "radius"))
    error, success = np.maximum(_column(table, "error"), FLOOR), _column(table, "success")
    radii, xs, ys = np.unique(radius), np.unique(x), np.unique(y)
    fig = _figure((4.6 * len(radii) + 0.6, 4.2))
    norm = LogNorm(vmin=FLOOR, vmax=max(float(error.max()), 10 * FLOOR))
    axes = fig.subplots(1, len(radii), squeeze=False)[0]
    image = None
    for ax, r in zip(axes, radii, strict=True):
        mine = radius == r
        grid = np.full((ys.size, xs.size), np.nan)
        grid[np.searchsorted(ys, y[mine]), np.searchsorted(xs, x[mine])] = error[mine]
        image = ax.pcolormesh(xs, ys, grid, norm=norm, cmap="viridis", shading="nearest")
        reached = mine & success
        ax.scatter(x[reached], y[reached], s=14, facecolors="none", edgecolors="white", linewidths=0.8)
        ax.set(xlabel="centre x [m]", ylabel="centre y [m]", aspect="equal",
               title=f"radius {r:g} m: reached {int(reached.sum())} of {int(mine.sum())}")
    fig.colorbar(image, ax=list(axes), label="final error ‖e(q_N)‖ (ringed: reached)")
    height = float(np.median(_column(table, "centre_z")))
    fig.suptitle(f"{system}, iLQR from ready:\n{targets}, centres at z = {height:.2f} m")
    return _save(fig, path)


def binned_median(a: NDArray[np.float64], b: NDArray[np.float64], value: NDArray[np.float64], bins: int,
                  ranges: list[tuple[float, float]]
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(median (bins_b, bins_a), a edges, b edges) of ``value`` over a bins × bins grid of (a, b); NaN in
    empty bins, points outside ``ranges`` left out. The median, not the mean: the volume spans decades
    (near-collinear end points give huge circles), and a mean follows a bin's few largest values."""
    a_edges, b_edges = (np.linspace(lo, hi, bins + 1) for lo, hi in ranges)
    ia = np.searchsorted(a_edges, a, side="right") - 1
    ib = np.searchsorted(b_edges, b, side="right") - 1
    ia[a == a_edges[-1]] = bins - 1  # the last bin is closed on the right, as in np.histogram
    ib[b == b_edges[-1]] = bins - 1
    inside = (ia >= 0) & (ia < bins) & (ib >= 0) & (ib < bins)
    flat = ib[inside] * bins + ia[inside]
    order = np.argsort(flat, kind="stable")
    keys, starts = np.unique(flat[order], return_index=True)
    medians = np.full(bins * bins, np.nan)
    for key, group in zip(keys, np.split(value[inside][order], starts[1:]), strict=True):
        medians[key] = np.median(group)
    return medians.reshape(bins, bins), a_edges, b_edges


def _range(values: NDArray[np.float64]) -> tuple[float, float]:
    """The 1-99 % quantiles, widened to 1 mm where they meet (a grid over joints that leave a coordinate
    fixed)."""
    lo, hi = (float(v) for v in np.quantile(values, [0.01, 0.99]))
    return (lo, hi) if hi - lo > 1e-3 else ((lo + hi) / 2 - 5e-4, (lo + hi) / 2 + 5e-4)


def manipulability_map(table: pa.Table, path: str | Path, bins: int = 40, system: str = "three_pandas_circle",
                       where: str = "circle centre") -> Path:
    """The median similarity-manipulability ellipsoid volume (column ``volume``: V_r · the product of
    J_G's r largest singular values, ``gagen.sweep.problems``) of the configurations binned by where the
    primitive is: over x-y (top view) and x-z (side view), within the 1-99 % quantiles of the places.
    ``where`` names the place in the axis labels."""
    from matplotlib.colors import LogNorm

    centre = {k: _column(table, f"centre_{k}") for k in "xyz"}
    volume = _column(table, "volume")
    finite = np.isfinite(volume) & np.all([np.isfinite(c) for c in centre.values()], axis=0) & (volume > 0)
    if not finite.any():
        raise ValueError("no configuration has a finite, positive ellipsoid volume and a finite centre: "
                         "nothing to map")
    ranges = {k: _range(c[finite]) for k, c in centre.items()}
    fig = _figure((11, 4.6))
    axes = fig.subplots(1, 2)
    image = None
    values = volume[finite]
    low, high = (float(v) for v in np.quantile(values, [0.02, 0.98]))
    norm = LogNorm(vmin=low, vmax=max(high, low * (1 + 1e-9)))
    for ax, (a, b) in zip(axes, (("x", "y"), ("x", "z")), strict=True):
        median, a_edges, b_edges = binned_median(centre[a][finite], centre[b][finite], values, bins,
                                                 [ranges[a], ranges[b]])
        image = ax.pcolormesh(a_edges, b_edges, median, norm=norm, cmap="magma")
        ax.set(xlabel=f"{where} {a} [m]", ylabel=f"{where} {b} [m]", aspect="equal",
               title=f"median volume by {where} {a}-{b}")
    fig.colorbar(image, ax=list(axes), label="similarity-manipulability ellipsoid volume (median per bin)")
    fig.suptitle(f"{system}: {int(finite.sum())} configurations within the joint limits")
    return _save(fig, path)


def _save(fig: Any, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path
