"""What a sweep computes, chunk by chunk: the two sweeps of the three-Panda circle cell.

- ``Manipulability``: ``samples`` random configurations, uniform within the joint limits, in chunks of
  ``chunk``; per configuration the circle the three end points span (centre, radius, from the batched
  arm FK kernels), the similarity kernel's ``conditioning`` output and the similarity-manipulability
  index (``gagen.control.differential.manipulability_index`` of J_G at the circle's controllable rank,
  6), from the batched C kernels (one call per chunk) and one stacked SVD. Chunk i draws its
  configurations from ``default_rng([seed, i])``: any chunk can be recomputed alone, on any worker, with
  the same numbers.
- ``Reach``: a grid of target circles (centres on an x-y grid at one height, normal +z, each radius in
  ``radii``), each solved by the structured iLQR (``gagen.control.ilqr``) from the ``ready``
  configuration within the joint limits, cold-started so that a target's result does not depend on
  which chunk or worker solved it; per target success, status, final error ‖e(q_N)‖, iterations,
  multiplier updates, solve time and q_N.

A sweep is a frozen, picklable description (shipped to the workers, with the ``Cell``: the joint limits
and the ready configuration, read from the spec where the sweep is made); ``compute(i)`` is chunk i's
rows as a pyarrow table. The generated module and the iLQR solver are loaded once per worker process.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from functools import cache
from typing import Any

import numpy as np
import pyarrow as pa
from numpy.typing import NDArray

from gagen.sweep.store import SweepError

SYSTEM = "three_pandas_circle"
ARMS = 3
NORMAL = (0.0, 0.0, 1.0)  # the target circles lie in horizontal planes


@cache
def _module() -> Any:
    from gagen.apps.cooperative.bundled import generated_folder
    from gagen.runtime import load

    return load(generated_folder() / SYSTEM)


@dataclass(frozen=True)
class Cell:
    """What the chunks need to know of the system beyond its kernels: the joint limits, the ``ready``
    configuration and the primitive's controllable dimension (the manipulability index's rank)."""

    lower: tuple[float, ...]
    upper: tuple[float, ...]
    ready: tuple[float, ...]
    rank: int


@cache
def cell() -> Cell:
    """The three-Panda cell, from its spec (≈ 1 s: the URDFs are parsed). Loaded once where a sweep is
    described and shipped with it, so that a worker needs only the generated module."""
    from gagen.apps.cooperative.bundled import bundled_specs
    from gagen.apps.cooperative.spec import load_system
    from gagen.check import joint_limits
    from gagen.control.differential import CONTROLLABLE_DIMENSION

    system, configurations = load_system(bundled_specs()[SYSTEM])
    lower, upper, _ = joint_limits(system)
    return Cell(tuple(lower.tolist()), tuple(upper.tolist()), tuple(map(float, configurations["ready"])),
                CONTROLLABLE_DIMENSION[system.kind])


@cache
def _solver(N: int) -> Any:
    from gagen.control.ilqr import ILQR

    return ILQR(_module().c.task, len(cell().lower), N=N)


def _limits(cell: Cell) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    return np.array(cell.lower), np.array(cell.upper)


def _description(sweep: Any) -> dict[str, Any]:
    """The sweep's parameters as ``sweep.json`` records them (the cell follows from the system)."""
    return {"system": SYSTEM, **{k: v for k, v in asdict(sweep).items() if k != "cell"}}


def _positive_int(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise SweepError(f"{name}: expected a positive integer, got {value!r}")
    return int(value)


def _finite(value: Any, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer) \
            or not math.isfinite(value):
        raise SweepError(f"{name}: expected a finite number, got {value!r}")
    return float(value)


def circumcircles(a: NDArray, b: NDArray, c: NDArray) -> tuple[NDArray, NDArray]:
    """Centres (n, 3) and radii (n,) of the circles through the rows of a, b, c (NaN when collinear)."""
    u, v = b - a, c - a
    n = np.cross(u, v)
    nn = np.einsum("ij,ij->i", n, n)
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = (np.einsum("ij,ij->i", u, u)[:, None] * np.cross(v, n)
                  + np.einsum("ij,ij->i", v, v)[:, None] * np.cross(n, u)) / (2.0 * nn[:, None])
    return a + offset, np.linalg.norm(offset, axis=1)


@dataclass(frozen=True)
class Manipulability:
    """The similarity-manipulability index over ``samples`` random configurations."""

    samples: int
    chunk: int = 10_000
    seed: int = 0
    kind: str = field(default="manipulability", init=False)
    cell: Cell = field(default=None, init=False, repr=False, compare=False)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        object.__setattr__(self, "cell", cell())
        _positive_int(self.samples, "samples")
        _positive_int(self.chunk, "chunk")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise SweepError(f"seed: expected an integer ≥ 0, got {self.seed!r}")

    @property
    def chunks(self) -> int:
        return -(-self.samples // self.chunk)

    def description(self) -> dict[str, Any]:
        return _description(self)

    def configurations(self, index: int) -> NDArray[np.float64]:
        """Chunk ``index``'s configurations (rows), uniform within the joint limits."""
        lower, upper = _limits(self.cell)
        count = min(self.chunk, self.samples - index * self.chunk)
        return lower + (upper - lower) * np.random.default_rng([self.seed, index]).random((count, lower.size))

    def compute(self, index: int) -> pa.Table:
        module, q = _module(), self.configurations(index)
        _, conditioning, J_G = module.c.similarity.batch(q)
        ends = [getattr(module.c, f"arm{i}_fk").batch(q[:, 7 * i:7 * i + 7])[1][:, 1:4] for i in range(ARMS)]
        centre, radius = circumcircles(*ends)
        rank = self.cell.rank
        # manipulability_index's definition (the product of the rank largest singular values) on numpy's
        # stacked SVD: 4× the throughput of one call per row, equal to it within a few ulp (not bit for bit)
        index_values = np.prod(np.linalg.svd(J_G, compute_uv=False)[:, :rank], axis=1)
        first = index * self.chunk
        return pa.table({"sample": np.arange(first, first + len(q), dtype=np.int64),
                         "centre_x": centre[:, 0], "centre_y": centre[:, 1], "centre_z": centre[:, 2],
                         "radius": radius, "conditioning": conditioning[:, 0], "index": index_values})


@dataclass(frozen=True)
class Reach:
    """iLQR reaching over target circles: centres on ``grid`` × ``grid`` points of [x ± span] × [y ± span]
    around (x, y) at ``height``, for each of ``radii``; ``N`` time steps (horizon the iLQR default)."""

    grid: int = 21
    span: float = 0.6
    radii: tuple[float, ...] = (0.5,)
    height: float = 0.59
    x: float = 0.0
    y: float = 0.0
    N: int = 50
    chunk: int = 16
    kind: str = field(default="reach", init=False)
    cell: Cell = field(default=None, init=False, repr=False, compare=False)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        object.__setattr__(self, "cell", cell())
        _positive_int(self.grid, "grid")
        _positive_int(self.N, "N")
        _positive_int(self.chunk, "chunk")
        for name in ("span", "height", "x", "y"):
            _finite(getattr(self, name), name)
        if self.span < 0:
            raise SweepError(f"span: expected a half-width ≥ 0 m, got {self.span!r}")
        if not isinstance(self.radii, tuple) or not self.radii:
            raise SweepError(f"radii: expected a non-empty tuple of radii in m, got {self.radii!r}")
        for r in self.radii:
            if _finite(r, "radii") <= 0:
                raise SweepError(f"radii: expected radii > 0 m, got {r!r}")

    def targets(self) -> NDArray[np.float64]:
        """(T, 4): centre x, y, z and radius of every target, radius-major, then x, then y."""
        xs = self.x + np.linspace(-self.span, self.span, self.grid)
        ys = self.y + np.linspace(-self.span, self.span, self.grid)
        r, x, y = np.meshgrid(np.array(self.radii, dtype=float), xs, ys, indexing="ij")
        return np.column_stack([x.ravel(), y.ravel(), np.full(x.size, self.height), r.ravel()])

    @property
    def chunks(self) -> int:
        return -(-len(self.radii) * self.grid**2 // self.chunk)

    def description(self) -> dict[str, Any]:
        return _description(self)

    def compute(self, index: int) -> pa.Table:
        from gagen.apps.cooperative import goals

        solver, limits, q0 = _solver(self.N), _limits(self.cell), np.array(self.cell.ready)
        first = index * self.chunk
        targets = self.targets()[first:first + self.chunk]
        rows: dict[str, list[Any]] = {k: [] for k in ("success", "status", "error", "iterations", "updates",
                                                      "solve_time", "q_final")}
        for cx, cy, cz, radius in targets:
            result = solver.solve(q0, goals.circle([cx, cy, cz], radius, NORMAL), limits=limits)
            for key, value in (("success", result.success), ("status", result.status),
                               ("error", result.error_norm), ("iterations", result.iterations),
                               ("updates", result.updates), ("solve_time", result.wall_time),
                               ("q_final", result.q[-1])):
                rows[key].append(value)
        q_final = np.array(rows.pop("q_final"), dtype=float).reshape(len(targets), -1)
        return pa.table({"target": np.arange(first, first + len(targets), dtype=np.int64),
                         "centre_x": targets[:, 0], "centre_y": targets[:, 1], "centre_z": targets[:, 2],
                         "radius": targets[:, 3], **rows,
                         "q_final": pa.FixedSizeListArray.from_arrays(pa.array(q_final.ravel()),
                                                                      q_final.shape[1])})


Sweep = Manipulability | Reach


def prepare(sweep: Sweep) -> None:
    """Load what the chunks of ``sweep`` need (module, limits, solver) in this process, ahead of them."""
    _module()
    if isinstance(sweep, Reach):
        _solver(sweep.N)


def compute_chunk(sweep: Sweep, index: int) -> tuple[int, pa.Table]:
    """The task a worker runs: chunk ``index`` of ``sweep`` (the index comes back with the rows)."""
    return index, sweep.compute(index)
