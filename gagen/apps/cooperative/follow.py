"""``gagen follow``: a measured leader (a human's hand) and robots span a primitive; the robots keep its
shape while the leader moves [COOP Sec. 5, future work].

The system is a spec with a ``measured: true`` chain (``robots/leader/two_pandas_hand_circle.yaml``: a hand
and two Pandas span a circle). A trace gives the leader's joints q_m over time (CSV: ``t`` and one column
per measured joint, e.g. ``hand/x,hand/y,hand/z``, uniformly sampled). From the spec's ``ready``
configuration the robots hold the rows of the task error that a translation leaves (``SHAPE_ROWS``: a
circle's normal and radius) at the start's values, by ``gagen.control.leader_follower``: per-sample IK
(the default) and, for comparison, differential IK with and without the leader's feed-forward J_Be,m q̇_m.

The bundled trace ``traces/leader/hand_circle.csv`` is synthetic, not recorded: rest-to-rest minimum-jerk
reaches [Flash & Hogan 1985] between via points 11-23 cm apart (peak speed 0.33 m/s), 6.6 s at 100 Hz
(``synthetic_hand_trace``), written by ``write_synthetic_trace``.

    gagen follow --out plots/follow
    gagen follow my_spec.yaml --trace my_hand.csv --out plots/follow
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.control.leader_follower import FollowResult, follow, shape_rows
from gagen.robots.system import System

Array = NDArray[np.float64]
HERE = Path(__file__).resolve().parent
LEADER_SPECS = HERE / "robots" / "leader"  # not bundled systems: the other verbs drive robots only
DEFAULT_SYSTEM = "two_pandas_hand_circle"
DEFAULT_TRACE = HERE / "traces" / "leader" / "hand_circle.csv"
PLOT_NAME, REPORT_NAME = "follow.png", "follow.txt"
HAND_START = (-0.246490215, -0.426933576, 0.590269558)  # three_pandas_circle's arm2 at ready
VIA = ((0.0, 0.0, 0.0, 0.5), (0.10, -0.05, 0.08, 1.2), (0.10, -0.05, 0.08, 0.3), (-0.05, -0.12, 0.03, 1.4),
       (-0.05, -0.12, 0.03, 0.3), (0.04, 0.06, -0.08, 1.3), (0.04, 0.06, -0.08, 0.3), (0.0, 0.0, 0.0, 1.0),
       (0.0, 0.0, 0.0, 0.3))
"""Hand displacement from the start (m) reached at the end of each segment, and the segment's seconds."""


# -- the leader's trace ------------------------------------------------------------------------------
def minimum_jerk(s: Array) -> Array:
    """The rest-to-rest minimum-jerk profile 10 s³ − 15 s⁴ + 6 s⁵ on s ∈ [0, 1]."""
    return s ** 3 * (10.0 - 15.0 * s + 6.0 * s * s)


def synthetic_hand_trace(rate: float = 100.0) -> tuple[Array, Array]:
    """(t, positions (n, 3)): the bundled hand trace, minimum-jerk segments through ``VIA`` from
    ``HAND_START`` (holds where a segment repeats its point)."""
    times, points = [0.0], [np.zeros(3)]
    for *point, duration in VIA:
        times.append(times[-1] + duration)
        points.append(np.array(point))
    t = np.round(np.arange(round(times[-1] * rate) + 1) / rate, 12)
    out = np.empty((t.size, 3))
    for k, tk in enumerate(t):
        i = min(int(np.searchsorted(times, tk, side="right")) - 1, len(VIA) - 1)
        s = np.clip((tk - times[i]) / (times[i + 1] - times[i]), 0.0, 1.0)
        out[k] = points[i] + (points[i + 1] - points[i]) * minimum_jerk(np.array(s))
    return t, out + np.array(HAND_START)


def format_leader_trace(t: Sequence[float] | Array, q_m: Array, labels: Sequence[str], comment: str) -> str:
    lines = [f"# {line}" for line in comment.splitlines()]
    lines.append(",".join(["t", *labels]))
    lines += [",".join([f"{tk:.2f}", *(f"{v:.9f}" for v in row)]) for tk, row in zip(t, q_m, strict=True)]
    return "\n".join(lines) + "\n"


def write_synthetic_trace(path: str | Path = DEFAULT_TRACE) -> Path:
    """Write ``synthetic_hand_trace`` as the bundled trace file (how ``traces/leader/hand_circle.csv`` was
    made)."""
    t, positions = synthetic_hand_trace()
    comment = ("A SYNTHETIC human hand trace (not recorded): rest-to-rest minimum-jerk reaches [Flash & "
               "Hogan 1985]\nthrough via points 11-23 cm apart (peak 0.33 m/s), 100 Hz, made by\n"
               "gagen.apps.cooperative.follow.write_synthetic_trace(). Columns: time (s), then the hand's "
               "position (m)\nin the world frame: the joints of the measured chain hand (three prismatic "
               "joints along x, y, z\nfrom the origin) of robots/leader/two_pandas_hand_circle.yaml.")
    Path(path).write_text(format_leader_trace(t, positions, ("hand/x", "hand/y", "hand/z"), comment),
                          encoding="utf-8")
    return Path(path)


@dataclass(frozen=True)
class LeaderTrace:
    """A leader's samples: ``t`` (n + 1,), ``q_m`` (n + 1, m) with column ``labels``, sampled every ``dt``."""

    t: Array
    q_m: Array
    labels: tuple[str, ...]
    dt: float


def read_leader_trace(path: str | Path) -> LeaderTrace:
    """A CSV trace (``#`` comment lines, a header ``t,<joint>,...``, then rows); times start at 0 and are
    uniformly spaced (to 1e-9 s). A ValueError names the file, the line and what was expected."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"{path}: cannot read the trace ({e})") from None
    rows = [(n, line) for n, line in enumerate(text.splitlines(), 1) if line.strip() and
            not line.lstrip().startswith("#")]
    if len(rows) < 3:
        raise ValueError(f"{path}: expected a header (t, then one column per measured joint) and at least "
                         "two rows")
    header = [h.strip() for h in rows[0][1].split(",")]
    if header[0] != "t" or len(header) < 2:
        raise ValueError(f"{path}:{rows[0][0]}: expected the header t,<joint>,..., got {rows[0][1]!r}")
    values = []
    for n, line in rows[1:]:
        try:
            row = [float(v) for v in line.split(",")]
        except ValueError:
            row = []
        if len(row) != len(header) or not all(math.isfinite(v) for v in row):
            raise ValueError(f"{path}:{n}: expected {len(header)} finite numbers, got {line!r}")
        values.append(row)
    data = np.array(values)
    steps = np.diff(data[:, 0])
    dt = float(steps.mean()) if steps.size else 0.0
    if abs(data[0, 0]) > 1e-9 or dt <= 0 or np.abs(steps - dt).max() > 1e-9:
        raise ValueError(f"{path}: times must start at 0 and be uniformly spaced (one sample every dt s)")
    return LeaderTrace(data[:, 0], data[:, 1:], tuple(header[1:]), dt)


def measured_columns(trace: LeaderTrace, system: System, where: str) -> tuple[Array, str]:
    """The trace's columns in q_m's order: by name, or in the file's order when the names differ but the
    count matches (with a note saying so)."""
    labels = [f"{robot}/{joint}" for robot, joint in system.measured_keys]
    if set(labels) <= set(trace.labels):
        return trace.q_m[:, [trace.labels.index(label) for label in labels]], ""
    if len(trace.labels) == len(labels):
        return trace.q_m, f"note: trace columns {', '.join(trace.labels)} taken as {', '.join(labels)}"
    raise ValueError(f"{where}: the trace has columns {', '.join(trace.labels)}; the system's measured "
                     f"joints are {', '.join(labels)}")


# -- the system's kernels on numbers -------------------------------------------------------------------
@dataclass(frozen=True)
class Kernels:
    """CasADi Functions of the system's kernels: ``task(q, q_m, V_Sd) -> (e, J_Be, J_Be_m)``,
    ``similarity(q, q_m) -> (V_Sc, conditioning, J_G, J_G_m)`` and each chain's end point."""

    system: System
    task: Callable[[Array, Array, Array], tuple[Array, Array, Array]]
    similarity: Callable[[Array, Array], tuple[Array, ...]]
    ends: Callable[[Array, Array], Array]


def system_kernels(system: System) -> Kernels:
    """The kernels ``follow`` needs, traced from the catalogue (CasADi: no C compiler needed)."""
    from gagen.apps.cooperative.catalogue import kernel_functions

    functions = kernel_functions(system)
    task_f = functions["task"].trace().function
    similarity_f = functions["similarity"].trace().function
    fk = [functions[f"{chain.name}_fk"].trace().function for chain in system.chains]

    def task(q: Array, q_m: Array, V_Sd: Array) -> tuple[Array, Array, Array]:
        e, J, J_m = task_f(q, q_m, V_Sd)
        return np.array(e).ravel(), np.array(J), np.array(J_m)

    def similarity(q: Array, q_m: Array) -> tuple[Array, ...]:
        return tuple(np.array(x) for x in similarity_f(q, q_m))

    def ends(q: Array, q_m: Array) -> Array:
        chains = system.split(list(q), list(q_m))
        points = [np.array(f(qc)[1]).ravel() for f, qc in zip(fk, chains, strict=True)]
        return np.array([p[1:4] / p[0] for p in points])

    return Kernels(system, task, similarity, ends)


def circumcircle(points: Array) -> tuple[Array, float, Array]:
    """(centre, radius, unit normal) of the circle through three points (numpy, no geometric algebra)."""
    a, b, c = points
    u, v = b - a, c - a
    n = np.cross(u, v)
    centre = a + (np.dot(v, v) * np.cross(n, u) + np.dot(u, u) * np.cross(v, n)) / (2.0 * np.dot(n, n))
    return centre, float(np.linalg.norm(centre - a)), n / np.linalg.norm(n)


# -- runs ----------------------------------------------------------------------------------------------
RUNS = (("ik", True), ("rate", True), ("rate", False))
"""The runs of a demo: per-sample IK with the feed-forward predictor, differential IK with and without it."""


def _name(mode: str, feedforward: bool) -> str:
    return {"ik": "IK per sample", "rate": "differential IK"}[mode] + \
        (" + feed-forward" if feedforward else ", feedback only")


def run(k: Kernels, q0: Array, trace: Array, dt: float, *, limits: tuple[Array, Array] | None = None,
        runs: Sequence[tuple[str, bool]] = RUNS, progress: Callable[[str], None] | None = None,
        **options: Any) -> tuple[Array, list[FollowResult]]:
    """(V_Sd, one ``FollowResult`` per run): the start's own similarity is the target."""
    V_Sd = k.similarity(q0, trace[0])[0].ravel()
    rows = shape_rows(k.system.kind)
    results = []
    for mode, feedforward in runs:
        def report(step: int, t: float, error: float, name: str = _name(mode, feedforward)) -> None:
            if progress is not None and (step % 100 == 0 or step == len(trace) - 1):
                progress(f"  {name}: step {step}/{len(trace) - 1}, t = {t:.2f} s, ‖e‖ = {error:.2e}")

        results.append(follow(k.task, q0, trace, dt, V_Sd, rows, mode=mode, feedforward=feedforward,
                              limits=limits, progress=report, **options))
    return V_Sd, results


def geometry(k: Kernels, r: FollowResult) -> dict[str, Array]:
    """Per sample of a run: the end points (n + 1, chains, 3) and their circumcircle's centre, radius and
    normal (circles only)."""
    ends = np.array([k.ends(q, qm) for q, qm in zip(r.q, r.q_m, strict=True)])
    out = {"ends": ends}
    if k.system.kind == "circle":
        circles = [circumcircle(p) for p in ends]
        out |= {"centre": np.array([c for c, _, _ in circles]),
                "radius": np.array([radius for _, radius, _ in circles]),
                "normal": np.array([n for _, _, n in circles])}
    return out


def summary(system: System, trace: Array, dt: float, results: Sequence[FollowResult],
            shapes: Sequence[dict[str, Array]]) -> str:
    leader = float(np.linalg.norm(np.diff(trace, axis=0), axis=1).max() / dt)
    rows = ", ".join(("e12", "e13", "e23", "e0inf")[i] for i in results[0].rows)
    lines = [f"leader-follower on {system.name} ({system.kind}): measured "
             f"{', '.join(c.name for c in system.measured_chains)} ({system.measured_dof} joints), robots "
             f"{', '.join(c.name for c in system.chains if not c.measured)} ({system.dof} joints)",
             f"leader trace: {len(trace) - 1} steps of {dt:g} s ({(len(trace) - 1) * dt:.2f} s), fastest "
             f"{leader:.3f} /s (m/s for a point), moves {np.ptp(trace, axis=0).max():.3f} at most",
             f"kept: rows {rows} of e = log(V_Sc~ V_Sd) at the start's values (the shape; the rest follows "
             "the leader)"]
    for r, shape in zip(results, shapes, strict=True):
        line = (f"{_name(r.mode, r.feedforward):38s} max ‖e‖ while the leader moves {r.moving_error:.2e}; "
                f"fastest joint {np.abs(r.speed).max():.3f} rad/s")
        if "radius" in shape:
            normal = shape["normal"]
            tilt = np.degrees(np.arctan2(np.linalg.norm(np.cross(normal, normal[0]), axis=1),
                                         np.abs(normal @ normal[0]))).max()
            line += (f"; radius drift {np.abs(shape['radius'] - shape['radius'][0]).max():.2e} m, normal "
                     f"tilt {tilt:.2e}°")
        if r.mode == "ik":
            line += f"; iterations mean {r.iterations.mean():.2f}, max {r.iterations.max()}"
        if r.clipped.any():
            line += f"; joints at a limit in {np.count_nonzero(r.clipped)} steps"
        lines.append(line)
        lines += [f"    {m}" for m in r.messages[:5]]
    return "\n".join(lines)


def figure(system: System, results: Sequence[FollowResult], shapes: Sequence[dict[str, Array]]) -> Any:
    """Agg figure: top and side views of the end points and the circle (first run), ‖e‖ of every run
    (log), the circle's radius drift and the joint speeds."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 7.5), layout="constrained")
    FigureCanvasAgg(fig)
    (ax_top, ax_side), (ax_error, ax_speed) = fig.subplots(2, 2)
    r, shape = results[0], shapes[0]
    views = ((ax_top, (0, 1, "top view: x, y (m)")), (ax_side, (0, 2, "side view: x, z (m)")))
    for view, (i, j, name) in views:
        for c, chain in enumerate(system.chains):
            path = shape["ends"][:, c]
            view.plot(path[:, i], path[:, j], color="tab:red" if chain.measured else f"C{c}",
                      label=f"{chain.name}{' (measured)' if chain.measured else ''}")
        if "centre" in shape:
            view.plot(shape["centre"][:, i], shape["centre"][:, j], "k--", linewidth=0.8, label="centre")
            for k_, alpha in ((0, 0.35), (len(r.t) - 1, 0.9)):
                centre, radius, normal = shape["centre"][k_], shape["radius"][k_], shape["normal"][k_]
                a = np.cross(normal, [0.0, 0.0, 1.0] if abs(normal[2]) < 0.9 else [1.0, 0.0, 0.0])
                a /= np.linalg.norm(a)
                b = np.cross(normal, a)
                s = np.linspace(0, 2 * np.pi, 120)
                ring = centre + radius * (np.outer(np.cos(s), a) + np.outer(np.sin(s), b))
                view.plot(ring[:, i], ring[:, j], color="0.4", alpha=alpha, linewidth=0.8)
        view.set_title(name, fontsize=9)
        view.set_aspect("equal", adjustable="datalim")
        view.grid(True, linewidth=0.3)
    ax_top.legend(fontsize=7)
    for n, res in enumerate(results):
        label = _name(res.mode, res.feedforward)
        ax_error.semilogy(res.t, np.maximum(res.error, 1e-17), color=f"C{n}", label=label)
        ax_speed.plot(res.t[1:], np.abs(res.speed).max(axis=1), color=f"C{n}", label=label)
    ax_error.set_ylabel("‖e‖ on the kept rows")
    ax_error.set_xlabel("t (s)")
    ax_error.legend(fontsize=7)
    ax_error.grid(True, linewidth=0.3)
    ax_speed.set_ylabel("fastest joint (rad/s)")
    ax_speed.set_xlabel("t (s)")
    ax_speed.grid(True, linewidth=0.3)
    fig.suptitle(f"{system.name}: the robots keep the {system.kind}'s shape while the measured leader moves "
                 "[COOP Sec. 5]", fontsize=10)
    return fig


# -- command line ----------------------------------------------------------------------------------------
def spec_path(system: str) -> Path:
    """A leader-follower spec: a name in ``robots/leader``, a bundled system or a spec file."""
    own = LEADER_SPECS / f"{system}.yaml"
    if own.is_file() and not Path(system).is_file():
        return own
    from gagen.registry import resolve_spec

    return resolve_spec(system, "cooperative", "system")


def run_command(args: argparse.Namespace) -> int:
    """``gagen follow`` on its parsed arguments (``gagen.apps.cooperative.commands``)."""
    from gagen.apps.cooperative.scenarios import joint_limits
    from gagen.robots.spec import load_system

    path = spec_path(args.system)
    system, configurations = load_system(path)
    if not system.measured_dof:
        raise ValueError(f"{path}: no chain is measured (measured: true); gagen follow needs a leader, e.g. "
                         f"{DEFAULT_SYSTEM}")
    if "ready" not in configurations:
        raise ValueError(f"{path}: configurations: no 'ready' configuration, which the robots start from")
    trace = read_leader_trace(args.trace or DEFAULT_TRACE)
    q_m, note = measured_columns(trace, system, str(args.trace or DEFAULT_TRACE))
    if note:
        print(note)
    if args.duration is not None:
        q_m = q_m[:max(2, round(args.duration / trace.dt) + 1)]
    print(f"{system.name}: tracing the kernels (task, similarity, {len(system.chains)} chains' fk) ...",
          flush=True)
    k = system_kernels(system)
    q0 = np.array(configurations["ready"])
    limits = joint_limits(str(path))
    _, results = run(k, q0, q_m, trace.dt, limits=limits, gain=args.gain,
                     progress=lambda line: print(line, flush=True))
    shapes = [geometry(k, r) for r in results]
    text = summary(system, q_m, trace.dt, results, shapes)
    print(text)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / REPORT_NAME).write_text(text + "\n", encoding="utf-8")
    figure(system, results, shapes).savefig(out / PLOT_NAME, dpi=90)
    print(f"wrote {out / REPORT_NAME}\nwrote {out / PLOT_NAME}")
    return 0 if bool(np.all(results[0].converged)) else 1
