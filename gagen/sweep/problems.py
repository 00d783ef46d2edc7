"""What a sweep computes, chunk by chunk, for a bundled cooperative system (default: the three-Panda circle).

- ``Manipulability``: configurations of the system, either ``samples`` random ones uniform within the
  joint limits (chunk i draws from ``default_rng([seed, i])``) or a regular ``grid`` over chosen joints,
  the others at the ``ready`` configuration (``gagen.sweep.grid``: chunk i is the flat index range
  [i·chunk, (i+1)·chunk)). Either way any chunk can be recomputed alone, on any worker, with the same
  numbers. Per configuration: where the primitive the end points span is (``places.locate``: the centre
  of a circle or sphere, else the end points' centroid) and its radius, the similarity kernel's
  ``conditioning``, the similarity-manipulability ``index`` (``gagen.control.differential.
  manipulability_index`` of J_G at the primitive's controllable rank r, ``CONTROLLABLE_DIMENSION``) and
  the ellipsoid's ``volume``, V_r · index with V_r the volume of the unit r-ball: the r-dimensional
  volume of {J_G q̇ : ‖q̇‖ ≤ 1}, whose semi-axes are J_G's r largest singular values. (√det(J_G J_Gᵀ),
  Yoshikawa's measure, is 0 for every configuration here: J_G has 7 rows but rank r < 7.) Also the force
  ellipsoid's ``force_volume`` V_r / index and, for a point pair, circle or sphere, the dilation force
  index ``dilation_force`` 1/‖J_Gᵀ e_D‖ (``gagen.control.force_manipulability``; ∞ where singular). All
  from the batched C kernels (one call per chunk and per chain) and one stacked SVD.
- ``Reach``: a grid of target primitives (centres on an x-y grid at one height, each radius in
  ``radii``; circles about one ``normal`` for a system spanning a circle, spheres for one spanning a
  sphere),
  each solved by the structured iLQR (``gagen.control.ilqr``) from the ``ready`` configuration within
  the joint limits, cold-started so that a target's result does not depend on which chunk or worker
  solved it; per target success, status, final error ‖e(q_N)‖, iterations, multiplier updates, solve
  time and q_N. Unset centre, radius, span and normal default to the ready primitive's (rounded to 1 cm,
  its radius to 5 cm, the span 1.2 radii, the normal to 0.01): for the three Pandas (0, 0, 0.59), 0.5 m,
  0.6 m and +z (horizontal circles).

A sweep is a frozen, picklable description (shipped to the workers with its ``Cell``: the joint limits,
the ready configuration, read from the spec where the sweep is made); ``compute(i)`` is
chunk i's rows as a pyarrow table. The generated module and the iLQR solver are loaded once per worker
process and system.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any, TypeVar, cast

import numpy as np
from numpy.typing import NDArray

from gagen.control.force_manipulability import DILATING, DILATION_ROW
from gagen.extras import MissingExtra
from gagen.robots.points import end_points
from gagen.sweep import grid as grids
from gagen.sweep.places import locate, unit_ball_volume
from gagen.sweep.store import SweepError

try:
    import pyarrow as pa
except ModuleNotFoundError as e:  # the sweep extra
    raise MissingExtra("pyarrow", "gagen.sweep") from e

DEFAULT_SYSTEM = "three_pandas_circle"
TARGETS = ("circle", "sphere")  # the primitives the reach sweep has targets for
T = TypeVar("T")


@dataclass(frozen=True)
class Cell:
    """What the chunks need to know of the system beyond its kernels: its name and primitive ``kind``,
    the joint labels and limits, the ``ready`` configuration, the primitive's controllable dimension
    (the manipulability index's rank); the chains' end points come from the module's FK kernels
    (``gagen.robots.points``)."""

    system: str
    kind: str
    joints: tuple[str, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    ready: tuple[float, ...]
    rank: int


def _spec(system: Any) -> Path:
    """The spec of ``system``: a bundled cooperative system's name or a spec file (a SweepError starting
    ``system:`` naming the bundled ones otherwise)."""
    from gagen.registry import bundled_specs, resolve_spec

    names = list(bundled_specs("cooperative"))
    if isinstance(system, str):
        try:
            return resolve_spec(system, "cooperative", "system")
        except ValueError:
            pass
    raise SweepError(f"system: expected a bundled cooperative system ({', '.join(names)}) or a spec file, "
                     f"got {system!r}")


@cache
def cell(system: str = DEFAULT_SYSTEM) -> Cell:
    """The cell of bundled ``system``, from its spec (≈ 1 s the first time: the URDFs are parsed). Loaded
    once where a sweep is described and shipped with it, so that a worker needs only the generated module
    (``build_module``). A SweepError starting ``system:`` says why a system cannot be swept."""
    from gagen.check import joint_limits
    from gagen.control.differential import CONTROLLABLE_DIMENSION
    from gagen.robots.spec import load_system

    spec = _spec(system)
    loaded, configurations = load_system(spec)
    lower, upper, _ = joint_limits(loaded)
    labels = tuple(f"{robot}/{joint}" for robot, joint in loaded.joint_keys)
    unlimited = [label for label, lo, hi in zip(labels, lower, upper, strict=True)
                 if not (np.isfinite(lo) and np.isfinite(hi))]
    if unlimited:
        raise SweepError(f"system: {system} has joints without limits ({', '.join(unlimited)}); the sweeps "
                         "sample and grid within the joint limits")
    if "ready" not in configurations:
        raise SweepError(f"system: {spec} names no 'ready' configuration, which the sweeps start from")
    measured = [chain.name for chain in loaded.chains if chain.measured]
    if measured:
        raise SweepError(f"system: {system} has measured chains ({', '.join(measured)}), which are inputs, "
                         "not variables; the sweeps vary every joint (gagen follow runs such a system)")
    return Cell(system, loaded.kind, labels, tuple(lower.tolist()), tuple(upper.tolist()),
                tuple(map(float, configurations["ready"])), CONTROLLABLE_DIMENSION[loaded.kind])


def build_module(system: str) -> None:
    """Build the generated module of bundled ``system`` where the sweep is started, on first use (the
    committed module, else the gagen cache: ``gagen.modules``), so that no two workers build it at once
    and a system the sweep refuses is never built. A SweepError starting ``system:`` when it cannot be."""
    from gagen.build import CompileError, OutputError
    from gagen.modules import module_folder
    try:
        module_folder(_spec(system))
    except (CompileError, OutputError) as e:
        raise SweepError(f"system: cannot build the generated module of {system}: {e}") from e


@cache
def _module(system: str = DEFAULT_SYSTEM) -> Any:
    from gagen.modules import bundled_module
    return bundled_module(_spec(system))


@cache
def _solver(system: str, dof: int, N: int) -> Any:
    from gagen.control.ilqr import ILQR

    return ILQR(_module(system).c.task, dof, N=N)


def _limits(cell: Cell) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    return np.array(cell.lower), np.array(cell.upper)


def _positive_int(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise SweepError(f"{name}: expected a positive integer, got {value!r}")
    return int(value)


def _finite(value: Any, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer) \
            or not math.isfinite(value):
        raise SweepError(f"{name}: expected a finite number, got {value!r}")
    return float(value)


def _filled(value: T | None) -> T:
    """A field that ``__post_init__`` has checked or filled in (``Reach``: from the ready primitive)."""
    assert value is not None, "set by __post_init__"
    return value


def _make_cell(sweep: Any) -> Cell:
    _spec(sweep.system)  # a SweepError for anything but a bundled name or a spec file, before the cache
    found = cell(sweep.system)
    object.__setattr__(sweep, "cell", found)
    return found


@dataclass(frozen=True)
class Manipulability:
    """The similarity-manipulability index and ellipsoid volume over ``samples`` random configurations,
    or over a ``grid`` (``gagen.sweep.grid``: a string such as ``"arm0/panda_joint2=50,arm0/panda_joint4=50"``
    or ``"1=50,3=50"``, a sequence of such items, or ``Axis`` objects; kept as axes): exactly one of the
    two."""

    samples: int | None = None
    chunk: int = 10_000
    seed: int = 0
    grid: str | Sequence[str] | tuple[grids.Axis, ...] | None = None
    system: str = DEFAULT_SYSTEM
    kind: str = field(default="manipulability", init=False)
    cell: Cell = field(default=None, init=False, repr=False, compare=False)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        found = _make_cell(self)
        _positive_int(self.chunk, "chunk")
        if self.grid is None:
            _positive_int(self.samples, "samples")
            if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
                raise SweepError(f"seed: expected an integer ≥ 0, got {self.seed!r}")
            return
        if self.samples is not None:
            raise SweepError(f"grid: a sweep has random samples or a grid, not both (samples = "
                             f"{self.samples!r})")
        if self.seed != 0:
            raise SweepError(f"seed: a grid has no random seed, got {self.seed!r}")
        spec = self.grid
        if isinstance(spec, tuple | list):
            axes = [a for a in spec if isinstance(a, grids.Axis)]
            if axes and len(axes) == len(spec):
                # re-checked against this system as text (repr round-trips every float)
                spec = [f"{a.joint}={a.count}:{float(a.lower)!r}:{float(a.upper)!r}" for a in axes]
        object.__setattr__(self, "grid", grids.parse(spec, found.joints, found.lower, found.upper))

    @property
    def axes(self) -> tuple[grids.Axis, ...] | None:
        """The grid's axes (``__post_init__`` parses the grid into them), or None: random samples."""
        return cast("tuple[grids.Axis, ...] | None", self.grid)

    @property
    def rows(self) -> int:
        axes = self.axes
        return grids.size(axes) if axes is not None else _filled(self.samples)

    @property
    def chunks(self) -> int:
        return -(-self.rows // self.chunk)

    def description(self) -> dict[str, Any]:
        """The parameters as ``sweep.json`` records them (the cell follows from the system)."""
        axes = self.axes
        drawn = ({"samples": self.samples, "seed": self.seed} if axes is None else
                 {"grid": [{"joint": a.name, "index": a.joint, "count": a.count, "lower": a.lower,
                            "upper": a.upper} for a in axes], "fixed": list(self.cell.ready)})
        return {"system": self.system, "kind": self.kind, "chunk": self.chunk, **drawn}

    def configurations(self, index: int) -> NDArray[np.float64]:
        """Chunk ``index``'s configurations (rows): uniform within the joint limits, or the grid's."""
        first = index * self.chunk
        count = min(self.chunk, self.rows - first)
        axes = self.axes
        if axes is not None:
            return grids.configurations(axes, self.cell.ready, first, count)
        lower, upper = _limits(self.cell)
        return lower + (upper - lower) * np.random.default_rng([self.seed, index]).random((count, lower.size))

    def compute(self, index: int) -> pa.Table:
        q = self.configurations(index)
        _, conditioning, J_G = _module(self.system).c.similarity.batch(q)
        centre, radius = locate(self.cell.kind, end_points(_module(self.system), q))
        rank = self.cell.rank
        # manipulability_index's definition (the product of the rank largest singular values) on numpy's
        # stacked SVD: 4× the throughput of one call per row, equal to it within a few ulp (not bit for bit)
        index_values = np.prod(np.linalg.svd(J_G, compute_uv=False)[:, :rank], axis=1)
        first = index * self.chunk
        columns = {"sample": np.arange(first, first + len(q), dtype=np.int64),
                   "centre_x": centre[:, 0], "centre_y": centre[:, 1], "centre_z": centre[:, 2],
                   "radius": radius, "conditioning": conditioning[:, 0], "index": index_values,
                   "volume": unit_ball_volume(rank) * index_values,
                   # the force ellipsoid's r-volume V_r / Π σ_i (gagen.control.force_manipulability)
                   "force_volume": _reciprocal(index_values) * unit_ball_volume(rank)}
        if self.cell.kind in DILATING:  # β_D = 1/‖J_Gᵀ e_D‖, the dilation force index (∞ at a zero row)
            columns["dilation_force"] = _reciprocal(np.linalg.norm(J_G[:, DILATION_ROW, :], axis=1))
        return pa.table(columns)


def _reciprocal(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """1 / values, ∞ where a value is 0 (a singular configuration is reported, never NaN)."""
    out = np.full(values.shape, np.inf)
    np.divide(1.0, values, out=out, where=values > 0)
    return out


def ready_primitive(found: Cell) -> tuple[NDArray[np.float64], float, NDArray[np.float64]]:
    """Centre, radius and unit normal (a circle's; NaN otherwise) of the primitive the ready configuration
    spans (single FK calls)."""
    points = end_points(_module(found.system), np.array([found.ready]))
    centre, radius = locate(found.kind, points)
    normal = np.full(3, np.nan)
    if found.kind == "circle":
        normal = np.cross(points[0, 1] - points[0, 0], points[0, 2] - points[0, 0])
        normal /= np.linalg.norm(normal)
    return centre[0], float(radius[0]), normal


@dataclass(frozen=True)
class Reach:
    """iLQR reaching over target primitives: centres on ``grid`` × ``grid`` points of [x ± span] × [y ±
    span] at ``height``, for each of ``radii`` (circles about ``normal``, or spheres); ``N`` time steps
    (horizon the iLQR default). Unset (None) centre, radii, span and normal follow from the ready
    configuration (see the module's docstring)."""

    grid: int = 21
    span: float | None = None
    radii: tuple[float, ...] | None = None
    height: float | None = None
    x: float | None = None
    y: float | None = None
    N: int = 50
    chunk: int = 16
    system: str = DEFAULT_SYSTEM
    normal: tuple[float, float, float] | None = None
    kind: str = field(default="reach", init=False)
    cell: Cell = field(default=None, init=False, repr=False, compare=False)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        found = _make_cell(self)
        if found.kind not in TARGETS:
            raise SweepError(f"system: the reach sweep has circle and sphere targets; {self.system} spans a "
                             f"{found.kind}")
        _positive_int(self.grid, "grid")
        _positive_int(self.N, "N")
        _positive_int(self.chunk, "chunk")
        if self.normal is not None:
            self._check_normal(found)
        if None in (self.x, self.y, self.height, self.radii, self.span) or \
                (self.normal is None and found.kind == "circle"):
            self._defaults(found)
        span = _finite(self.span, "span")
        for name in ("height", "x", "y"):
            _finite(getattr(self, name), name)
        if span < 0:
            raise SweepError(f"span: expected a half-width ≥ 0 m, got {self.span!r}")
        if not isinstance(self.radii, tuple) or not self.radii:
            raise SweepError(f"radii: expected a non-empty tuple of radii in m, got {self.radii!r}")
        for r in self.radii:
            if _finite(r, "radii") <= 0:
                raise SweepError(f"radii: expected radii > 0 m, got {r!r}")

    def _check_normal(self, found: Cell) -> None:
        if found.kind != "circle":
            raise SweepError(f"normal: only circle targets have a normal; {self.system} spans a {found.kind}")
        if not isinstance(self.normal, tuple | list) or len(self.normal) != 3:
            raise SweepError(f"normal: expected 3 numbers, got {self.normal!r}")
        normal = tuple(_finite(n, "normal") for n in self.normal)
        if not any(normal):
            raise SweepError(f"normal: expected a non-zero direction, got {self.normal!r}")
        object.__setattr__(self, "normal", normal)

    def _defaults(self, found: Cell) -> None:
        centre, radius, normal = ready_primitive(found)
        if not (np.all(np.isfinite(centre)) and math.isfinite(radius)):
            raise SweepError(f"system: the ready configuration of {self.system} spans a degenerate "
                             f"{found.kind}: give the centre, radius and span")
        rounded = [round(float(c), 2) + 0.0 for c in centre]  # + 0.0: no −0.0 in sweep.json
        r = round(round(radius / 0.05) * 0.05, 2) or 0.05
        defaults = {"x": rounded[0], "y": rounded[1], "height": rounded[2], "radii": (r,),
                    "span": round(1.2 * r, 2)}
        if found.kind == "circle":
            defaults["normal"] = tuple(round(float(n), 2) + 0.0 for n in normal)
        for name, value in defaults.items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, value)

    def targets(self) -> NDArray[np.float64]:
        """(T, 4): centre x, y, z and radius of every target, radius-major, then x, then y."""
        span = _filled(self.span)
        offsets = np.linspace(-span, span, self.grid) if self.grid > 1 else np.zeros(1)  # 1: (x, y)
        xs, ys = _filled(self.x) + offsets, _filled(self.y) + offsets
        r, x, y = np.meshgrid(np.array(self.radii, dtype=float), xs, ys, indexing="ij")
        return np.column_stack([x.ravel(), y.ravel(), np.full(x.size, self.height), r.ravel()])

    @property
    def rows(self) -> int:
        return len(_filled(self.radii)) * self.grid**2

    @property
    def chunks(self) -> int:
        return -(-self.rows // self.chunk)

    def description(self) -> dict[str, Any]:
        names = ("grid", "span", "radii", "height", "x", "y", "normal", "N", "chunk", "kind")
        return {"system": self.system, **{name: getattr(self, name) for name in names}}

    def goal(self, centre: NDArray[np.float64], radius: float) -> NDArray[np.float64]:
        from gagen.control import goals

        if self.cell.kind == "sphere":
            return goals.sphere(centre, radius)
        return goals.circle(centre, radius, _filled(self.normal))

    def compute(self, index: int) -> pa.Table:
        solver = _solver(self.system, len(self.cell.lower), self.N)
        limits, q0 = _limits(self.cell), np.array(self.cell.ready)
        first = index * self.chunk
        targets = self.targets()[first:first + self.chunk]
        rows: dict[str, list[Any]] = {k: [] for k in ("success", "status", "error", "iterations", "updates",
                                                      "solve_time", "q_final")}
        for cx, cy, cz, radius in targets:
            result = solver.solve(q0, self.goal(np.array([cx, cy, cz]), radius), limits=limits)
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
    """Load what the chunks of ``sweep`` need (module, solver) in this process, ahead of them."""
    _module(sweep.system)
    if isinstance(sweep, Reach):
        _solver(sweep.system, len(sweep.cell.lower), sweep.N)


def compute_chunk(sweep: Sweep, index: int) -> tuple[int, pa.Table]:
    """The task a worker runs: chunk ``index`` of ``sweep`` (the index comes back with the rows)."""
    return index, sweep.compute(index)
