"""Assemble the bundled six-bar, ten-bar and Jansen linkages by circle intersections and write their specs.

A mechanism is given by its link lengths: a crank point turning about a ground pivot, then every other
point at given distances from two points already placed, on a chosen side (the assembly branch). Its
closed-form positions at any crank angle (``positions``) give the spec's initial configuration
(``spec_text``: every body's points in world coordinates, with full ``repr`` precision so the link
lengths hold to rounding) and an independent reference for the solver's trajectories (the tests).

Run ``python -m gagen.apps.linkage.assemble`` to rewrite ``robots/{six_bar,ten_bar,jansen}.yaml``
(``--print`` prints them instead).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROBOTS = Path(__file__).resolve().parent / "robots"
Point = tuple[float, float]


@dataclass(frozen=True)
class Circles:
    """A point at distance ``rp`` from point ``p`` and ``rq`` from point ``q``, on the left (side +1)
    or the right (−1) of the direction p → q."""

    p: str
    rp: float
    q: str
    rq: float
    side: int


@dataclass(frozen=True)
class Mechanism:
    name: str
    header: str  # the spec's leading comment
    ground: dict[str, Point]
    pivot: str  # the ground point the crank turns about
    crank: tuple[str, float, float]  # the crank point: its name, radius and initial angle (rad)
    points: dict[str, Circles]  # every other moving point, constructed in this order
    bodies: dict[str, tuple[str, ...]]  # each body's points; the first body is the crank
    trace: str  # body.point

    def joints(self) -> list[tuple[str, str]]:
        """Revolute joints: each point shared by several holders (the ground first, then the bodies in
        order) pins every later holder to the first."""
        out = []
        for name in [*self.ground, self.crank[0], *self.points]:
            holders = (["ground"] if name in self.ground else []) + [b for b, ps in self.bodies.items()
                                                                     if name in ps]
            out += [(f"{holders[0]}.{name}", f"{h}.{name}") for h in holders[1:]]
        return out

    def lengths(self) -> dict[str, float]:
        """The construction's lengths by point pair ("A-B"), for checks."""
        out = {f"{self.pivot}-{self.crank[0]}": self.crank[1]}
        for name, c in self.points.items():
            out[f"{c.p}-{name}"], out[f"{c.q}-{name}"] = c.rp, c.rq
        return out


def intersect(p: np.ndarray, rp: float, q: np.ndarray, rq: float, side: int) -> np.ndarray:
    """The intersection of the circles (p, rp) and (q, rq) on the given side of p → q (arrays of
    points, shape (..., 2)); NaN where the circles do not meet."""
    d = q - p
    dist2 = np.sum(d * d, axis=-1, keepdims=True)
    along = (rp * rp - rq * rq + dist2) / (2 * dist2)
    h = np.sqrt(rp * rp / dist2 - along * along)
    normal = np.stack([-d[..., 1], d[..., 0]], axis=-1)  # d turned by +90°: the left
    point: np.ndarray = p + along * d + side * h * normal
    return point


def positions(mechanism: Mechanism, theta: np.ndarray | float) -> dict[str, np.ndarray]:
    """Every point at crank rotation ``theta`` (rad, counter-clockwise, from the initial angle; an
    array gives arrays of shape (len(theta), 2))."""
    theta = np.asarray(theta, dtype=float)
    out = {name: np.broadcast_to(np.array(xy, dtype=float), (*theta.shape, 2))
           for name, xy in mechanism.ground.items()}
    name, radius, start = mechanism.crank
    angle = start + theta
    out[name] = out[mechanism.pivot] + radius * np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    for name, c in mechanism.points.items():
        out[name] = intersect(out[c.p], c.rp, out[c.q], c.rq, c.side)
    return out


def _number(x: float) -> str:
    """Full precision in a form YAML reads as a float (PyYAML needs a dot before an exponent)."""
    text = repr(float(x) + 0.0)  # + 0.0: no "-0.0"
    mantissa, e, exponent = text.partition("e")
    return (mantissa if "." in mantissa else mantissa + ".0") + (e + exponent if e else "")


def _xy(point: np.ndarray | Point) -> str:
    return f"[{_number(point[0])}, {_number(point[1])}]"


def spec_text(mechanism: Mechanism) -> str:
    at = positions(mechanism, 0.0)
    if any(np.isnan(v).any() for v in at.values()):
        raise ValueError(f"{mechanism.name}: the initial configuration does not assemble")
    lines = [f"# {line}".rstrip() for line in mechanism.header.strip().splitlines()]
    lines += ["# Written by `python -m gagen.apps.linkage.assemble` (circle intersections at the initial "
              "crank angle).", "app: linkage", f"name: {mechanism.name}"]
    lines.append("ground: {" + ", ".join(f"{n}: {_xy(xy)}" for n, xy in mechanism.ground.items()) + "}")
    lines.append("bodies:")
    for body, names in mechanism.bodies.items():
        lines.append(f"  {body}: {{" + ", ".join(f"{n}: {_xy(at[n])}" for n in names) + "}")
    lines.append("joints:")
    lines += [f"  - {{revolute: [{a}, {b}]}}" for a, b in mechanism.joints()]
    crank = next(iter(mechanism.bodies))
    lines += [f"driver: {{body: {crank}, pivot: ground.{mechanism.pivot}}}", f"trace: {mechanism.trace}"]
    return "\n".join(lines) + "\n"


SIX_BAR = Mechanism(
    name="six_bar",
    header="""
A Watt II six-bar (1 DOF, 7 revolute joints; Grübler–Kutzbach 3·5 − 2·7 = 1): a Grashof crank-rocker
four-bar A–B–C–D (ground 3, crank A–B 1, coupler B–C 3, rocker C–D 2.5; s + l = 4 ≤ p + q = 5.5)
whose rocker is a ternary link C–D–R (|CR| = 2, |DR| = 2.5) driving a second four-bar D–R–S–E
through the dyad R–S (3), S–E (2) about the ground pivot E = (3.5, 1.5), a rocker-rocker whose output
S–E swings 51°. The ternary links: the ground (A, D, E) and the rocker (C, D, R), joined at D (Watt).
T on the output coupler R–S (2 from R and S) is traced.""",
    ground={"A": (0.0, 0.0), "D": (3.0, 0.0), "E": (3.5, 1.5)},
    pivot="A",
    crank=("B", 1.0, 0.0),
    points={"C": Circles("B", 3.0, "D", 2.5, -1),
            "R": Circles("C", 2.0, "D", 2.5, +1),
            "S": Circles("R", 3.0, "E", 2.0, +1),
            "T": Circles("R", 2.0, "S", 2.0, +1)},
    bodies={"crank": ("A", "B"), "coupler": ("B", "C"), "rocker": ("C", "D", "R"),
            "output_coupler": ("R", "S", "T"), "output_rocker": ("S", "E")},
    trace="output_coupler.T",
)

TEN_BAR = Mechanism(
    name="ten_bar",
    header="""
A ten-bar (10 links with the ground, 13 revolute joints; Grübler–Kutzbach 3·9 − 2·13 = 1): a Grashof
crank-rocker four-bar A–B–C–D (ground 4, crank A–B 1, coupler B–C 3, rocker C–D 3; s + l = 5 ≤ 6) and
a chain of three dyads, each pinned to a point of the previous stage and to a ground pivot:
P (on the coupler, 2 from B and C) –3.5– Q –2.5– E = (3, 4);
U (on the ternary link Q–E, |QU| = 1.5, |EU| = 3.5) –3– V –2.5– F = (−4, 4.5);
W (on the ternary link V–F, |VW| = 1.5, |FW| = 2) –2.5– X –2.5– G = (−4.5, 2).
The output links Q–E, V–F and X–G swing 42°, 42° and 34°. X is traced.""",
    ground={"A": (0.0, 0.0), "D": (4.0, 0.0), "E": (3.0, 4.0), "F": (-4.0, 4.5), "G": (-4.5, 2.0)},
    pivot="A",
    crank=("B", 1.0, 0.0),
    points={"C": Circles("B", 3.0, "D", 3.0, -1),
            "P": Circles("B", 2.0, "C", 2.0, +1),
            "Q": Circles("P", 3.5, "E", 2.5, +1),
            "U": Circles("Q", 1.5, "E", 3.5, +1),
            "V": Circles("U", 3.0, "F", 2.5, -1),
            "W": Circles("V", 1.5, "F", 2.0, +1),
            "X": Circles("W", 2.5, "G", 2.5, +1)},
    bodies={"crank": ("A", "B"), "coupler": ("B", "C", "P"), "rocker": ("C", "D"),
            "link_pq": ("P", "Q"), "link_qe": ("Q", "E", "U"), "link_uv": ("U", "V"),
            "link_vf": ("V", "F", "W"), "link_wx": ("W", "X"), "link_xg": ("X", "G")},
    trace="link_wx.X",
)

# Theo Jansen's "holy numbers" (Theo Jansen, "The Great Pattern", strandbeest.com/explains).
HOLY = {"a": 38.0, "b": 41.5, "c": 39.3, "d": 40.1, "e": 55.8, "f": 39.4, "g": 36.7, "h": 65.7, "i": 49.0,
        "j": 50.0, "k": 61.9, "l": 7.8, "m": 15.0}

JANSEN = Mechanism(
    name="jansen",
    header="""
Theo Jansen's Strandbeest leg with his "holy numbers" (source: Theo Jansen, "The Great Pattern",
strandbeest.com/explains): a = 38, b = 41.5, c = 39.3, d = 40.1, e = 55.8, f = 39.4, g = 36.7,
h = 65.7, i = 49.0, j = 50.0, k = 61.9, l = 7.8, m = 15.0.
Points: O the crank axle (origin), A the crank pin (|OA| = m), B the fixed pivot (−a, −l); C the
upper joint (|AC| = j, |BC| = b), D the outer corner of the upper triangle (|BD| = d, |CD| = e),
E the lower joint (|AE| = k, |BE| = c), F the upper-left corner of the foot triangle (|DF| = f,
|EF| = g), G the foot (|FG| = h, |EG| = i).
Links (named by their letters): crank m (O, A); bars j (A, C), k (A, E), c (B, E), f (D, F); the
ternary triangles bde (B, C, D) and ghi (E, F, G). 8 links, 10 revolute joints: 3·7 − 2·10 = 1.
The branch of the real leg: C above and E below the line B–A, D outside (left of B–C), F left of
D–E, the foot G at the bottom. The foot G is traced.""",
    ground={"O": (0.0, 0.0), "B": (-HOLY["a"], -HOLY["l"])},
    pivot="O",
    crank=("A", HOLY["m"], 0.0),
    points={"C": Circles("B", HOLY["b"], "A", HOLY["j"], +1),
            "D": Circles("B", HOLY["d"], "C", HOLY["e"], +1),
            "E": Circles("B", HOLY["c"], "A", HOLY["k"], -1),
            "F": Circles("D", HOLY["f"], "E", HOLY["g"], -1),
            "G": Circles("F", HOLY["h"], "E", HOLY["i"], -1)},
    bodies={"crank_m": ("O", "A"), "bar_j": ("A", "C"), "bar_k": ("A", "E"), "triangle_bde": ("B", "C", "D"),
            "bar_c": ("B", "E"), "bar_f": ("D", "F"), "triangle_ghi": ("E", "F", "G")},
    trace="triangle_ghi.G",
)

MECHANISMS = {m.name: m for m in (SIX_BAR, TEN_BAR, JANSEN)}


def main(argv: list[str]) -> None:
    for mechanism in MECHANISMS.values():
        text = spec_text(mechanism)
        if "--print" in argv:
            print(text)
        else:
            (ROBOTS / f"{mechanism.name}.yaml").write_text(text)


if __name__ == "__main__":
    main(sys.argv[1:])
