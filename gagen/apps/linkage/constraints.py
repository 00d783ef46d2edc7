"""A planar linkage's constraints in 2D CGA, G(3,1) with the null basis e0, e∞ [LINK 3], [MATH §8].

Each body b has an SE(2) motor R_b (on 1, e12, e1∞, e2∞); its points are X = R_b up(x) R_b~, with
up(x) = e0 + x + ½|x|² e∞ and x the point at the initial configuration (the body's frame). The driven
body's motor is the driver's: a crank's turn by θ about its ground pivot p, T(p) R(θ) T(p)~, or a
slider's translation by s along its slot, T(s d) (with k drivers, each driven body's from its value).

Residuals that vanish *linearly* at a solution, so Newton converges quadratically. The paper's
x_i ∧ x_j read as its six coefficients does too (its e01/e02 part is b − a), in as many iterations;
only its scalar norm ‖x_i ∧ x_j‖² = ¼|a − b|⁴ stalls (a fourfold root). The rows used (a
revolute joint's 2 where the wedge has 6):

- revolute (two points coincide): the Euclidean part of the difference of the two (normalised) world
  points, loc(X_a) − loc(X_b): two rows, the difference a − b itself;
- prismatic (a point slides on a line carried by a body): the incidence of the point with the line,
  (X ∧ L)_{e012∞} / w, with L = R up(c) ∧ up(c + d) ∧ e∞ R~ and w its value for a point at unit
  distance: one row, the signed distance of the point from the line;
- slider (a block on a line): the prismatic row, and the sine of the block's turn relative to the
  line's body, u_a × u_b with u the slot direction as each body carries it (X(c + d) − X(c)): zero
  and of slope 1 at the solution.

The Jacobian is taken with respect to left perturbations of the moving bodies, R_b ← e^{−ε·B/2} R_b
with B = (e12, e1∞, e2∞): the derivative of a body's world point is the commutator X × B (likewise a
carried line, L × B), and each residual is linear in X and L, so its columns are exact and cheap.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from gagen.algebra.protocol import Multivector
from gagen.apps.linkage.spec import GROUND, Driver, Linkage, Prismatic, Revolute, Slider
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


def driver_motor(like: Multivector, driver: Driver, pivot: Sequence[Any] | None, value: Any) -> Multivector:
    """The driven body's motor at the driver's value: the crank's turn by θ about its pivot, or the
    slider's translation by s along its slot (the world direction: the ground carries every driver's
    slot or its point)."""
    if driver.slide is None:
        if pivot is None:
            raise ValueError(f"the crank {driver.body} has no pivot")
        return crank_motor(like, pivot, value)
    d = _exact(driver.slide.direction)
    sign = 1 if driver.slide.on == GROUND else -1  # a ground point in the block's slot: the block moves −s
    return translator(like, [sign * value * d[0], sign * value * d[1]])


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
    driven body's from the driver's value) and the world points and lines they carry. ``coordinates``
    replaces the spec's initial points (a parametric kernel's inputs: one kernel for a family of
    mechanisms)."""

    def __init__(self, like: Multivector, linkage: Linkage, motors: Mapping[str, Multivector], angle: Any,
                 coordinates: Coordinates | None = None):
        self.like, self.linkage = like, linkage
        self.coordinates = coordinates
        # one driver: ``angle`` is its value; k drivers: a sequence of k values, in the drivers' order
        values = [angle] if len(linkage.drivers) == 1 else [angle[i] for i in range(len(linkage.drivers))]
        driven = {}
        for driver, value in zip(linkage.drivers, values, strict=True):
            pivot = None if driver.pivot is None else self.initial((GROUND, driver.pivot))
            driven[driver.body] = driver_motor(like, driver, pivot, value)
        self.motors = {**motors, **driven}

    def initial(self, ref: tuple[str, str]) -> list[Any]:
        return _exact(self.coordinates[ref] if self.coordinates is not None else self.linkage.point(ref))

    def point(self, ref: tuple[str, str]) -> Multivector:
        return self.moved(ref[0], self.initial(ref))

    def moved(self, body: str, xy: Sequence[Any]) -> Multivector:
        """The world point of ``body`` (or the ground) that is at ``xy`` at the initial configuration."""
        x = up(self.like, xy)
        return x if body == GROUND else self.motors[body].sandwich(x)


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
            if isinstance(joint, Slider):
                rows_, entry = _no_turn(frames, generators, joint, columns_of)
                rows.append(rows_)
                grads.append(entry)
    columns = [[g.get(col, 0) for g in grads] for col in range(3 * len(moving))]
    return rows, columns


def _no_turn(frames: Frames, generators: list[Multivector], joint: Slider,
             columns_of: Any) -> tuple[Any, dict[int, Any]]:
    """A slider's second row, u_a × u_b: the slot direction d as the point's body and as the slot's body
    carry it (the difference of their points at c + d and c), crossed; its columns from the points'
    commutators, exact as the others."""
    c, d = _exact(joint.through), _exact(joint.direction)
    ends = (c, [c[0] + d[0], c[1] + d[1]])

    def direction(body: str) -> tuple[list[Any], list[list[Any]]]:
        start, end = (frames.moved(body, xy) for xy in ends)
        u = [a - b for a, b in zip(location(end), location(start), strict=True)]
        moved = [[a - b for a, b in zip(location(end.commutator(g)), location(start.commutator(g)),
                                        strict=True)] for g in generators]
        return u, moved

    (ua, da), (ub, db) = direction(joint.point[0]), direction(joint.on)
    entry = {col: du[0] * ub[1] - du[1] * ub[0]
             for col, du in zip(columns_of(joint.point[0]), da, strict=False)}
    entry.update({col: ua[0] * du[1] - ua[1] * du[0]
                  for col, du in zip(columns_of(joint.on), db, strict=False)})
    return ua[0] * ub[1] - ua[1] * ub[0], entry


def positions(like: Multivector, linkage: Linkage, motors: Mapping[str, Multivector], angle: Any,
              coordinates: Coordinates | None = None) -> list[Any]:
    """Every named point of every body, x and y, at this configuration."""
    frames = Frames(like, linkage, motors, angle, coordinates)
    out: list[Any] = []
    for body, points in linkage.bodies.items():
        for name in points:
            out += location(frames.point((body, name)))
    return out


def cayley_rotor(like: Multivector, angle: Any, norm2: Any = 1) -> Multivector:
    """The Cayley rotor (1 − (ε/2) e12)/√(1 + ε²/4): a counter-clockwise turn by 2 atan(ε/2), which is
    ε to first order, for one square root where the exact rotor needs a sine and a cosine; divided
    besides by √norm2 (a motor's R R~, to renormalise it in the same square root)."""
    half = angle * 0.5
    scale = 1 / like.math.sqrt((1 + half * half) * norm2)
    return like.make({"1": scale, "e12": -half * scale})


def retract(like: Multivector, motor: Multivector, step: Sequence[Any]) -> Multivector:
    """R ← T(Δt) C(Δθ) R for the Lie-algebra step (Δθ on e12, Δt on e1∞, e2∞), C the Cayley rotor: it
    agrees with e^{−ΔB/2} R to first order, which keeps Newton quadratic, and costs no trigonometric
    call. C also divides by √(R R~) = √(R₁² + R₁₂²), so R stays a unit SE(2) motor to rounding
    instead of drifting over thousands of updates (a point's weight, and so every length, would
    drift with it)."""
    dtheta, dx, dy = step
    norm2 = motor["1"] * motor["1"] + motor["e12"] * motor["e12"]
    # e^{−ε e12/2} ≈ the turn by ε; e^{−ε e1∞/2} = translator((ε, 0))
    return translator(like, [dx, dy]) * cayley_rotor(like, dtheta, norm2) * motor
