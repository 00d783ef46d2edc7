"""A planar linkage's constraints in 2D CGA, G(3,1) with the null basis e0, e∞ [LINK 3], [MATH §8].

Each body b has an SE(2) motor R_b (on 1, e12, e1∞, e2∞); its points are X = R_b up(x) R_b~, with
up(x) = e0 + x + ½|x|² e∞ and x the point at the initial configuration (the body's frame). The crank's
motor is the turn by θ about its ground pivot p, T(p) R(θ) T(p)~.

Residuals that vanish *linearly* at a solution, so Newton converges quadratically (the paper's
x_i ∧ x_j has ‖x_i ∧ x_j‖² = ¼|a − b|⁴, a double root):

- revolute (two points coincide): the Euclidean part of the difference of the two (normalised) world
  points, loc(X_a) − loc(X_b): two rows, the difference a − b itself;
- prismatic (a point slides on a line carried by a body): the incidence of the point with the line,
  (X ∧ L)_{e012∞} / w, with L = R up(c) ∧ up(c + d) ∧ e∞ R~ and w its value for a point at unit
  distance: one row, the signed distance of the point from the line.

The Jacobian is taken with respect to left perturbations of the moving bodies, R_b ← e^{−ε·B/2} R_b
with B = (e12, e1∞, e2∞): the derivative of a body's world point is the commutator X × B (likewise a
carried line, L × B), and each residual is linear in X and L, so its columns are exact and cheap.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from gagen.algebra.protocol import Multivector
from gagen.apps.linkage.spec import GROUND, Linkage, Prismatic, Revolute
from gagen.symbolic.backend import to_exact

GENERATORS = ("e12", "e1inf", "e2inf")  # the Lie algebra se(2): rotation, translations
MOTOR = ("1", "e12", "e1inf", "e2inf")
PSEUDOSCALAR = "e012inf"


def up(like: Multivector, xy: Sequence[Any]) -> Multivector:
    x, y = xy
    return like.make({"e0": 1, "e1": x, "e2": y, "einf": (x * x + y * y) * 0.5})


def location(p: Multivector) -> list[Any]:
    """The position of a point of weight 1 (every point a motor moved from up(x))."""
    return [p["e1"], p["e2"]]


def translator(like: Multivector, t: Sequence[Any]) -> Multivector:
    return like.make({"1": 1, "e1inf": -0.5 * t[0], "e2inf": -0.5 * t[1]})


def rotor(like: Multivector, angle: Any) -> Multivector:
    """The turn by ``angle`` (counter-clockwise) about the origin."""
    m = like.math
    return like.make({"1": m.cos(angle * 0.5), "e12": -m.sin(angle * 0.5)})


def crank_motor(like: Multivector, pivot: Sequence[Any], angle: Any) -> Multivector:
    """The turn by ``angle`` about ``pivot``: T(p) R(θ) T(p)~."""
    p = _exact(pivot)
    return translator(like, p) * rotor(like, angle) * translator(like, [-p[0], -p[1]])


def _exact(xy: Sequence[Any]) -> list[Any]:
    """Spec numbers as exact constants; symbolic values (a parametric kernel's inputs) as they are."""
    return [v if to_exact(v) is None else to_exact(v) for v in xy]


def _line(like: Multivector, through: Sequence[float], direction: Sequence[float]) -> tuple[Multivector, Any]:
    """The line through a point along a unit direction, up(c) ∧ up(c + d) ∧ e∞, and 1/w with w its
    incidence with a point at unit distance on the side of the normal (−d_y, d_x)."""
    c, d = list(through), list(direction)
    line = up(like, _exact(c)) ^ up(like, _exact([c[0] + d[0], c[1] + d[1]])) ^ like.make({"einf": 1})
    # the weight as an exact constant: evaluate at an exact point one unit along the normal
    w = (up(like, _exact([c[0] - d[1], c[1] + d[0]])) ^ line)[PSEUDOSCALAR]
    return line, 1 / w


Coordinates = Mapping[tuple[str, str], Sequence[Any]]  # (body or ground, point) -> initial (x, y)


class Frames:
    """The world motors of a linkage's bodies at one configuration (moving bodies' motors given, the
    crank's from its angle) and the world points and lines they carry. ``coordinates`` replaces the
    spec's initial points (a parametric kernel's inputs: one kernel for a family of mechanisms)."""

    def __init__(self, like: Multivector, linkage: Linkage, motors: Mapping[str, Multivector], angle: Any,
                 coordinates: Coordinates | None = None):
        self.like, self.linkage = like, linkage
        self.coordinates = coordinates
        pivot = self.initial((GROUND, linkage.pivot))
        self.motors = {**motors, linkage.crank: crank_motor(like, pivot, angle)}

    def initial(self, ref: tuple[str, str]) -> list[Any]:
        return _exact(self.coordinates[ref] if self.coordinates is not None else self.linkage.point(ref))

    def point(self, ref: tuple[str, str]) -> Multivector:
        x = up(self.like, self.initial(ref))
        return x if ref[0] == GROUND else self.motors[ref[0]].sandwich(x)


def _generators(like: Multivector) -> list[Multivector]:
    return [like.make({g: 1}) for g in GENERATORS]


def constraints(like: Multivector, linkage: Linkage, motors: Mapping[str, Multivector], angle: Any,
                coordinates: Coordinates | None = None) -> tuple[list[Any], list[list[Any]]]:
    """The residual F (one entry per constraint row, joints in spec order) and its Jacobian as
    columns, three per moving body (``linkage.unknown`` order): ∂F/∂ε for R_b ← e^{−ε·B/2} R_b."""
    frames = Frames(like, linkage, motors, angle, coordinates)
    moving, generators = linkage.unknown, _generators(like)
    rows: list[Any] = []
    grads: list[dict[int, Any]] = []  # per row: column -> entry

    def columns_of(body: str) -> list[int]:
        return [3 * moving.index(body) + k for k in range(3)] if body in moving else []

    for joint in linkage.active_joints:
        if isinstance(joint, Revolute):
            xa, xb = frames.point(joint.a), frames.point(joint.b)
            moved_a = [location(xa.commutator(g)) for g in generators]
            moved_b = [location(xb.commutator(g)) for g in generators]
            for i, (u, v) in enumerate(zip(location(xa), location(xb), strict=True)):
                entry = dict(zip(columns_of(joint.a[0]), (d[i] for d in moved_a), strict=False))
                for col, d in zip(columns_of(joint.b[0]), moved_b, strict=False):
                    entry[col] = entry.get(col, 0) - d[i]
                rows.append(u - v)
                grads.append(entry)
        elif isinstance(joint, Prismatic):
            x = frames.point(joint.point)
            line0, scale = _line(like, joint.through, joint.direction)
            line = line0 if joint.on == GROUND else frames.motors[joint.on].sandwich(line0)
            entry = {col: (x.commutator(g) ^ line)[PSEUDOSCALAR] * scale
                     for col, g in zip(columns_of(joint.point[0]), generators, strict=False)}
            entry.update({col: (x ^ line.commutator(g))[PSEUDOSCALAR] * scale
                          for col, g in zip(columns_of(joint.on), generators, strict=False)})
            rows.append((x ^ line)[PSEUDOSCALAR] * scale)
            grads.append(entry)
    columns = [[g.get(col, 0) for g in grads] for col in range(3 * len(moving))]
    return rows, columns


def positions(like: Multivector, linkage: Linkage, motors: Mapping[str, Multivector], angle: Any,
              coordinates: Coordinates | None = None) -> list[Any]:
    """Every named point of every body, x and y, at this configuration."""
    frames = Frames(like, linkage, motors, angle, coordinates)
    out: list[Any] = []
    for body, points in linkage.bodies.items():
        for name in points:
            out += location(frames.point((body, name)))
    return out


def retract(like: Multivector, motor: Multivector, step: Sequence[Any]) -> Multivector:
    """R ← T(Δt) R(Δθ) R for the Lie-algebra step (Δθ on e12, Δt on e1∞, e2∞): it agrees with
    e^{−ΔB/2} R to first order, which keeps Newton quadratic, and keeps R an exact SE(2) motor."""
    dtheta, dx, dy = step
    # e^{−ε e12/2} = rotor(ε), the counter-clockwise turn by ε; e^{−ε e1∞/2} = translator((ε, 0))
    return translator(like, [dx, dy]) * rotor(like, dtheta) * motor
