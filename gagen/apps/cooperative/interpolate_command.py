"""``gagen interpolate``: two primitives of one kind joined through their similarity versors [COOP Fig. 4].

The two ends are either primitives stated on the command line, by kind,

    gagen interpolate circle --from centre=0,0,0 radius=0.3 normal=0,0,1 \\
                             --to centre=1,0.5,0.4 radius=0.6 normal=1,0,1 --out plots/interpolation
    gagen interpolate plane --from points=0,0,0/1,0,0/0,1,0 --to point=0,0,1 normal=0,1,1

(keys per kind as a spec's goals state them: point ``position``; point_pair ``first``, ``second``; line
``point``, ``direction``; circle ``centre``, ``radius``, ``normal``; plane ``point``, ``normal``; sphere
``centre``, ``radius``; or ``points`` spanning it, ``/`` between points), or two named states of a
cooperative system (a spec file or a bundled name): a configuration (the primitive its chains span) or a
goal of the spec, ``gagen interpolate three_pandas_circle --from ready --to circle``. ``fig4`` draws the
paper's four panels (line, plane, circle, sphere) into one figure.

Writes ``interpolation_<name>.png`` (the primitive at ``--steps`` values of t, in 3D), a CSV of the
path (t, conditioning, reference point, scale, axis: see ``describe``) and, with ``--gif``, an animation.
The work is ``gagen.model.interpolation`` on the reference interpreter.
"""

from __future__ import annotations

import argparse
import csv
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from gagen.algebra.signature import cga3d
from gagen.control import goals
from gagen.interp import MultiVector
from gagen.model.conformal import SIMILARITY, e0, location, point, vector
from gagen.model.interpolation import interpolate
from gagen.model.primitives import KINDS, ROUNDS
from gagen.model.similarity import cooperative_similarity
from gagen.robots.goals import PRIMITIVE_PARAMETERS, load_goals
from gagen.robots.spec import load_system
from gagen.robots.system import cooperative_primitive

Array = NDArray[np.float64]
Sample = tuple[float, MultiVector, float]  # t, V(t), conditioning
FIG4 = "fig4"
MIN_CONDITIONING = 1e-9  # below this the path is reported as ill-conditioned (values still finite)
# [COOP] Fig. 4's four panels: (kind, from, to) as command-line items
PANELS = (
    ("line", ["point=0,0,0", "direction=1,0,0"], ["point=0.2,0.9,0.6", "direction=0,0.5,1"]),
    ("plane", ["point=0,0,0", "normal=0,0,1"], ["point=0.6,0.6,0.7", "normal=1,0.4,0.8"]),
    ("circle", ["centre=0,0,0", "radius=0.3", "normal=0,0,1"], ["centre=1,0.8,0.6", "radius=0.6",
                                                                "normal=1,0,1"]),
    ("sphere", ["centre=0,0,0", "radius=0.2"], ["centre=1,0.7,0.5", "radius=0.5"]),
)


# -- the two ends ---------------------------------------------------------------------------------------
def _zero() -> MultiVector:
    return MultiVector.zero(cga3d())


def _primitive_of(kind: str, v: Array) -> MultiVector:
    return goals.primitive(kind, v)


def _triple(text: str, what: str) -> list[float]:
    try:
        values = [float(s) for s in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3 or not all(np.isfinite(values)):
        raise ValueError(f"{what}: expected three comma-separated finite numbers, got {text!r}")
    return values


def primitive_from_items(kind: str, items: Sequence[str], option: str = "--from") -> MultiVector:
    """The primitive stated by ``key=value`` items (module docstring); a ValueError naming the option and
    the key otherwise."""
    keys = PRIMITIVE_PARAMETERS[kind]
    found: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or key not in (*keys, "points"):
            raise ValueError(f"{option}: expected key=value with key one of {', '.join((*keys, 'points'))} "
                             f"for a {kind}, got {item!r}")
        if key in found:
            raise ValueError(f"{option}: {key} given twice")
        found[key] = value
    if "points" in found:
        if len(found) > 1:
            others = ", ".join(sorted(set(found) - {"points"}))
            raise ValueError(f"{option}: points= spans the {kind} alone; drop {others}")
        spanning = [_triple(p, f"{option} points") for p in found["points"].split("/")]
        return _primitive_of(kind, goals.through(kind, spanning))
    missing = [k for k in keys if k not in found]
    if missing:
        raise ValueError(f"{option}: a {kind} needs {', '.join(keys)} (or points=); "
                         f"missing {', '.join(missing)}")
    values: list[Any] = []
    for k in keys:
        if k == "radius":
            try:
                values.append(float(found[k]))
            except ValueError:
                raise ValueError(f"{option} radius: expected a number, got {found[k]!r}") from None
        else:
            values.append(_triple(found[k], f"{option} {k}"))
    makers: dict[str, Callable[..., Array]] = {"point": goals.point, "point_pair": goals.point_pair,
                                               "line": goals.line, "circle": goals.circle,
                                               "plane": goals.plane, "sphere": goals.sphere}
    return _primitive_of(kind, makers[kind](*values))


def system_primitive(spec: str, name: str, option: str = "--from") -> tuple[str, MultiVector]:
    """(kind, primitive) of a spec's configuration or goal ``name`` (a goal that moves the ready primitive
    is moved from the ``ready`` configuration)."""
    from gagen.apps.cooperative.scenarios import spec_of

    path = spec_of(spec)
    system, configurations = load_system(path)
    named_goals = load_goals(path)
    zero = _zero()
    if name in configurations:
        return system.kind, cast(MultiVector, cooperative_primitive(zero, system, configurations[name]))
    if name in named_goals:
        if "ready" not in configurations and named_goals[name].is_move:
            raise ValueError(f"{option}: goal {name!r} moves the ready primitive; {path} has no 'ready' "
                             "configuration")
        start = cast(MultiVector, cooperative_primitive(zero, system, configurations.get("ready", [])))
        v0 = cooperative_similarity(system.kind, start).versor
        desired = goals.desired(named_goals[name], [v0[b] for b in SIMILARITY], system.kind)
        return system.kind, _primitive_of(system.kind, desired)
    raise ValueError(f"{option}: {path.name} names configurations {', '.join(configurations) or '(none)'} "
                     f"and goals {', '.join(named_goals) or '(none)'}; got {name!r}")


# -- the path -------------------------------------------------------------------------------------------
def affine_map(v: MultiVector) -> tuple[Array, Array]:
    """(u, A) of the similarity x ↦ u + A x of a versor (A = s R): images of the origin and of e1, e2, e3."""
    def image(x: Any) -> Array:
        return _xyz(location(v.sandwich(cast(MultiVector, x))))

    u = image(e0(v))
    columns = [image(point(vector(v, list(np.eye(3)[k])))) - u for k in range(3)]
    return u, np.array(columns).T


def _xyz(x: Any) -> Array:
    return np.array([x["e1"], x["e2"], x["e3"]])


def describe(kind: str, v: MultiVector) -> tuple[Array, float, Array | None]:
    """(reference point, scale, axis) of the primitive V X_u V~: the centre of a round (a point of a flat,
    the point itself), its radius (the scale for flats and points), and the pair's or line's direction
    (V e1) or the circle's or plane's normal (V e3); no axis for points and spheres."""
    u, a = affine_map(v)
    scale = float(np.cbrt(np.linalg.det(a)))
    axis = {"point_pair": 0, "line": 0, "circle": 2, "plane": 2}.get(kind)
    return u, scale, None if axis is None else a[:, axis] / scale


def path_samples(kind: str, x1: MultiVector, x2: MultiVector, ts: Sequence[float]
                 ) -> list[Sample]:
    """(t, V(t), conditioning) at each t."""
    out = []
    for t in ts:
        _, v, conditioning = interpolate(kind, x1, x2, float(t))
        out.append((float(t), cast(MultiVector, v), float(conditioning)))
    return out


def write_csv(kind: str, samples: Sequence[Sample], path: Path) -> Path:
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["t", "conditioning", "x", "y", "z", "scale", "ax", "ay", "az"])
        for t, v, conditioning in samples:
            u, scale, axis = describe(kind, v)
            writer.writerow([f"{t:.6g}", f"{conditioning:.17g}", *(f"{c:.17g}" for c in u), f"{scale:.17g}",
                             *((f"{c:.17g}" for c in axis) if axis is not None else ("", "", ""))])
    return path


# -- drawing --------------------------------------------------------------------------------------------
def _shape(kind: str, v: MultiVector, size: float) -> list[Array]:
    """Polylines (n, 3) of the primitive: the unit primitive's drawing mapped by V's similarity."""
    u, a = affine_map(v)
    phi = np.linspace(0, 2 * np.pi, 61)
    ring = np.stack([np.cos(phi), np.sin(phi), 0 * phi], axis=1)
    half = size / max(float(np.cbrt(np.linalg.det(a))), 1e-12)  # flats: a fixed drawn size
    unit: list[Array] = {
        "point": [np.zeros((1, 3))],
        "point_pair": [np.array([[-1.0, 0, 0], [1.0, 0, 0]])],
        "line": [np.array([[-half, 0, 0], [half, 0, 0]])],
        "circle": [ring],
        "plane": [np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0],
                            [-half, -half, 0]]), np.array([[-half, 0, 0], [half, 0, 0]]),
                  np.array([[0, -half, 0], [0, half, 0]])],
        "sphere": [ring, ring[:, [0, 2, 1]], ring[:, [2, 0, 1]]],
    }[kind]
    return [u + p @ a.T for p in unit]


def draw(ax: Any, kind: str, samples: Sequence[Sample], size: float) -> None:
    """The primitive at each sample, coloured by t (viridis), the ends thicker."""
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    for i, (t, v, _) in enumerate(samples):
        end = i in (0, len(samples) - 1)
        for line in _shape(kind, v, size):
            style = {"color": cmap(t), "lw": 2.2 if end else 1.0, "alpha": 1.0 if end else 0.7}
            if len(line) == 1 or kind == "point_pair":
                ax.plot(*line.T, "o", ms=5 if end else 3, **{k: style[k] for k in ("color", "alpha")})
                if kind == "point_pair":
                    ax.plot(*line.T, "--", **style)
            else:
                ax.plot(*line.T, **style)
    centres = np.array([affine_map(v)[0] for _, v, _ in samples])
    if kind in ROUNDS or kind == "point":
        ax.plot(*centres.T, ":", color="0.4", lw=1)
    _equal_axes(ax, np.vstack([p for _, v, _ in samples for p in _shape(kind, v, size)]))


def _equal_axes(ax: Any, points: Array) -> None:
    centre, radius = points.mean(axis=0), max(float(np.ptp(points, axis=0).max()) / 2, 1e-3)
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
        setter(c - radius, c + radius)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")


def _size(samples: Sequence[Sample]) -> float:
    """Half the drawn size of a flat: half the distance between the ends' reference points, at least 0.3."""
    first, last = affine_map(samples[0][1])[0], affine_map(samples[-1][1])[0]
    return max(0.3, 0.5 * float(np.linalg.norm(last - first)))


def plot(panels: Sequence[tuple[str, str, Sequence[Sample]]], path: Path) -> Path:
    """One 3D panel per (kind, title, samples)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(panels)
    cols = min(n, 2)
    fig = plt.figure(figsize=(4.2 * cols, 3.9 * ((n + cols - 1) // cols)))
    for i, (kind, title, samples) in enumerate(panels):
        ax = fig.add_subplot((n + cols - 1) // cols, cols, i + 1, projection="3d")
        draw(ax, kind, samples, _size(samples))
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def animate(kind: str, samples: Sequence[Sample], path: Path) -> Path:
    """A GIF: the primitive moving from t = 0 to 1 over the two ends (grey)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    size = _size(samples)
    fig = plt.figure(figsize=(4.5, 4.5))
    ax = fig.add_subplot(projection="3d")
    everything = np.vstack([p for _, v, _ in samples for p in _shape(kind, v, size)])

    def frame(i: int) -> None:
        ax.cla()
        for _, v, _ in (samples[0], samples[-1]):
            for line in _shape(kind, v, size):
                ax.plot(*line.T, "o-" if len(line) <= 2 and kind in ("point", "point_pair") else "-",
                        color="0.7", lw=1)
        t, v, _ = samples[i]
        for line in _shape(kind, v, size):
            ax.plot(*line.T, "o-" if kind in ("point", "point_pair") else "-", color="C3", lw=2)
        _equal_axes(ax, everything)
        ax.set_title(f"{kind}, t = {t:.2f}")

    FuncAnimation(fig, frame, frames=len(samples)).save(path, writer=PillowWriter(fps=12))
    plt.close(fig)
    return path


# -- the command ----------------------------------------------------------------------------------------
def _ends(args: argparse.Namespace) -> tuple[str, MultiVector, MultiVector, str]:
    """(kind, X1, X2, name for the files) from the target and --from/--to."""
    if args.start is None or args.end is None:
        raise ValueError(f"interpolate {args.target}: give both --from and --to")
    if args.target in KINDS:
        x1 = primitive_from_items(args.target, args.start, "--from")
        return args.target, x1, primitive_from_items(args.target, args.end, "--to"), args.target
    for option, value in (("--from", args.start), ("--to", args.end)):
        if len(value) != 1:
            raise ValueError(f"{option}: a system's end is one configuration or goal name, "
                             f"got {' '.join(value)}")
    kind, x1 = system_primitive(args.target, args.start[0], "--from")
    _, x2 = system_primitive(args.target, args.end[0], "--to")
    stem = Path(args.target).stem
    return kind, x1, x2, f"{stem}_{args.start[0]}_{args.end[0]}"


def figure4(path: Path, steps: int = 6) -> Path:
    """[COOP] Fig. 4: line, plane, circle and sphere interpolated, one panel each."""
    ts = np.linspace(0, 1, steps)
    panels: list[tuple[str, str, list[Sample]]] = []
    for kind, start, end in PANELS:
        x1, x2 = primitive_from_items(kind, start), primitive_from_items(kind, end, "--to")
        panels.append((kind, f"({'abcd'[len(panels)]}) {kind}", path_samples(kind, x1, x2, list(ts))))
    return plot(panels, path)


def run_command(args: argparse.Namespace) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.target == FIG4:
        print(f"wrote {figure4(out / 'interpolation.png', args.steps)}")
        return 0
    kind, x1, x2, name = _ends(args)
    samples = path_samples(kind, x1, x2, list(np.linspace(0, 1, args.steps)))
    conditioning = samples[0][2]
    print(f"{kind}: conditioning {conditioning:.3g}" + (
        " (ill-conditioned: a degenerate primitive, one opposite to the unit primitive's orientation, or a "
        "half turn between the two; the path is not meaningful)" if conditioning < MIN_CONDITIONING else ""))
    for t, v, _ in samples:
        u, scale, axis = describe(kind, v)
        extra = "" if axis is None else f"  axis {np.array2string(axis, precision=3, suppress_small=True)}"
        where = np.array2string(u, precision=3, suppress_small=True)
        print(f"  t = {t:.3f}  point {where}  scale {scale:.4g}{extra}")
    title = f"{kind.replace('_', ' ')}: {name}"
    print(f"wrote {plot([(kind, title, samples)], out / f'interpolation_{name}.png')}")
    print(f"wrote {write_csv(kind, samples, out / f'interpolation_{name}.csv')}")
    if args.gif:
        frames = path_samples(kind, x1, x2, list(np.linspace(0, 1, args.frames)))
        print(f"wrote {animate(kind, frames, out / f'interpolation_{name}.gif')}")
    return 0


if __name__ == "__main__":
    import sys

    from gagen.apps.cooperative.commands import VERBS

    verb = next(v for v in VERBS if v.name == "interpolate")
    sys.exit(verb.run(verb.parser("python -m gagen.apps.cooperative.interpolate_command").parse_args()))
