"""Load and validate a planar linkage spec (YAML) into a :class:`Linkage` [LINK].

A spec::

    app: linkage
    name: four_bar
    ground: {A: [0, 0], D: [4, 0]}           # fixed pivots (world, at the initial configuration)
    bodies:                                  # each body's points, in world coordinates at the initial
      crank: {A: [0, 0], B: [0.5, 0.866]}    # configuration (which is then the body's own frame)
      coupler: {B: [0.5, 0.866], C: [3.4, 2.2], P: [2.0, 2.5]}
      rocker: {C: [3.4, 2.2], D: [4, 0]}
    joints:
      - {revolute: [crank.A, ground.A]}      # two points that coincide
      - {revolute: [crank.B, coupler.B]}
      - {revolute: [coupler.C, rocker.C]}
      - {revolute: [rocker.D, ground.D]}
      # a point sliding on a line fixed in a body or the ground (one constraint: a pin in a slot;
      # "slot" names the body carrying the line: YAML reads a key "on" as true):
      # - {prismatic: {point: slider.P, slot: ground, through: [0, 0], direction: [0, 1], travel: [3, 5]}}
      #   travel: the range of (x − through)·direction the point may take
    driver: {body: crank, pivot: ground.A}   # the crank turns about the pivot
    trace: coupler.P                          # the coupler point whose curve is drawn

The initial configuration needs to be assembled only roughly: the solver assembles it exactly at the
crank's initial angle first. Each body's frame is the world frame at that configuration.

Errors are ``SpecError``s naming the file, the field with its line and what was expected (the strict
reader of every spec, ``gagen.yaml_document``): unknown bodies or points, a joint joining a body to
itself, a body no joint reaches from the ground (dangling), a driver whose pivot is not the crank's
ground pivot, bad numbers. Mobility is counted by Grübler–Kutzbach, 3 (n − 1) − 2 j_R − j_P with the
ground among the n links and a prismatic joint (a pin in a slot) taking one freedom; a count other
than 1 is reported by name (over- or under-constrained). The rank of the constraint Jacobian at the
initial configuration is checked by the solver (``gagen.apps.linkage.solver``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gagen.yaml_document import Document, identifier, known_keys, number, require, show

TOP_KEYS = ("app", "name", "ground", "bodies", "joints", "driver", "trace")
PRISMATIC_KEYS = ("point", "slot", "through", "direction", "travel")
DRIVER_KEYS = ("body", "pivot")
GROUND = "ground"
MAX_COORDINATE = 1e4
Point = tuple[float, float]


@dataclass(frozen=True)
class Revolute:
    a: tuple[str, str]  # (body, point): the two points that coincide; body may be "ground"
    b: tuple[str, str]

    @property
    def rows(self) -> int:
        return 2


@dataclass(frozen=True)
class Prismatic:
    point: tuple[str, str]
    on: str  # the body (or ground) that carries the line
    through: Point  # the line at the initial configuration (world = that body's frame)
    direction: Point  # unit
    # [lower, upper] of the point's coordinate (x − through)·direction along the line, or None
    travel: tuple[float, float] | None = None

    @property
    def rows(self) -> int:
        return 1


Joint = Revolute | Prismatic


@dataclass(frozen=True)
class Linkage:
    name: str
    ground: dict[str, Point]
    bodies: dict[str, dict[str, Point]]
    joints: tuple[Joint, ...]
    crank: str
    pivot: str  # the ground point the crank turns about
    trace: tuple[str, str] | None = None

    @property
    def unknown(self) -> list[str]:
        """The bodies the solver moves: all but the crank, in spec order."""
        return [b for b in self.bodies if b != self.crank]

    @property
    def active_joints(self) -> tuple[Joint, ...]:
        """The joints the solver enforces: all but those between the crank and the ground (the crank's
        pivot, which the driver's motion keeps by construction)."""
        fixed = {GROUND, self.crank}
        return tuple(j for j in self.joints if not {*_bodies(j)} <= fixed)

    @property
    def constraint_rows(self) -> int:
        return sum(j.rows for j in self.active_joints)

    def mobility(self) -> int:
        """Grübler–Kutzbach: 3 (n − 1) − 2 j_R − j_P, the ground counted among the n links."""
        n = len(self.bodies) + 1
        return 3 * (n - 1) - sum(2 if isinstance(j, Revolute) else 1 for j in self.joints)

    def point(self, ref: tuple[str, str]) -> Point:
        body, name = ref
        return self.ground[name] if body == GROUND else self.bodies[body][name]


def _bodies(joint: Joint) -> tuple[str, str]:
    return (joint.a[0], joint.b[0]) if isinstance(joint, Revolute) else (joint.point[0], joint.on)


def _xy(spec: Document, value: Any, field: str) -> Point:
    if not isinstance(value, list) or len(value) != 2 or not all(number(v, MAX_COORDINATE) for v in value):
        raise spec.error(field, f"got {show(value)}; expected [x, y], two finite numbers within "
                                f"±{MAX_COORDINATE:g}")
    return float(value[0]), float(value[1])


def _points(spec: Document, value: Any, field: str, what: str) -> dict[str, Point]:
    if not isinstance(value, dict) or not value:
        raise spec.error(field, f"got {show(value)}; expected a mapping of point names to [x, y] ({what})")
    out = {}
    for name, xy in value.items():
        identifier(spec, name, f"{field}.{name}", "a point name")
        out[name] = _xy(spec, xy, f"{field}.{name}")
    return out


def _ref(spec: Document, value: Any, field: str, ground: dict, bodies: dict) -> tuple[str, str]:
    if not isinstance(value, str) or value.count(".") != 1:
        raise spec.error(field, f"got {show(value)}; expected body.point (or ground.point)")
    body, name = value.split(".")
    if body != GROUND and body not in bodies:
        raise spec.error(field, f"unknown body {body!r}; the bodies: {', '.join(bodies)} (or ground)")
    known = ground if body == GROUND else bodies[body]
    if name not in known:
        raise spec.error(field, f"{body} has no point {name!r}; its points: {', '.join(known)}")
    return body, name


def _joint(spec: Document, value: Any, field: str, ground: dict, bodies: dict) -> Joint:
    if not isinstance(value, dict) or len(value) != 1 or next(iter(value)) not in ("revolute", "prismatic"):
        raise spec.error(field, f"got {show(value)}; expected {{revolute: [body.point, body.point]}} or "
                                f"{{prismatic: {{point, slot, through, direction, travel}}}}")
    kind, body = next(iter(value.items()))
    where = f"{field}.{kind}"
    if kind == "revolute":
        if not isinstance(body, list) or len(body) != 2:
            raise spec.error(where, f"got {show(body)}; expected two points [body.point, body.point]")
        a, b = (_ref(spec, v, f"{where}[{i}]", ground, bodies) for i, v in enumerate(body))
        if a[0] == b[0]:
            raise spec.error(where, f"joins {a[0]} to itself; a joint connects two different bodies")
        if a[0] == GROUND:
            a, b = b, a
        return Revolute(a, b)
    if not isinstance(body, dict):
        raise spec.error(where, f"got {show(body)}; expected a mapping (point, slot, through, direction)")
    known_keys(spec, body, where, PRISMATIC_KEYS)
    point = _ref(spec, require(spec, body, "point", f"{where}.point", str, "body.point"), f"{where}.point",
                 ground, bodies)
    on = require(spec, body, "slot", f"{where}.slot", str, "the body (or ground) carrying the slot line")
    if on != GROUND and on not in bodies:
        raise spec.error(f"{where}.slot", f"unknown body {on!r}; the bodies: {', '.join(bodies)} (or ground)")
    if on == point[0]:
        raise spec.error(f"{where}.slot", f"the point is on {on} itself; a joint connects two different "
                                          f"bodies")
    through = _xy(spec, require(spec, body, "through", f"{where}.through", list, "[x, y]"),
                  f"{where}.through")
    dx, dy = _xy(spec, require(spec, body, "direction", f"{where}.direction", list, "[dx, dy]"),
                 f"{where}.direction")
    norm = math.hypot(dx, dy)
    if norm < 1e-12:
        raise spec.error(f"{where}.direction", "got a zero vector; expected the line's direction")
    travel = None
    if "travel" in body:
        lo, hi = _xy(spec, body["travel"], f"{where}.travel")
        if not lo < hi:
            raise spec.error(f"{where}.travel", f"got {show(body['travel'])}; expected [lower, upper] with "
                                                f"lower < upper")
        travel = (lo, hi)
    return Prismatic(point, on, through, (dx / norm, dy / norm), travel)


def _connected(linkage: Linkage) -> list[str]:
    """The bodies no chain of joints reaches from the ground."""
    edges: dict[str, set[str]] = {}
    for j in linkage.joints:
        a, b = _bodies(j)
        edges.setdefault(a, set()).add(b)
        edges.setdefault(b, set()).add(a)
    seen, todo = {GROUND}, [GROUND]
    while todo:
        for other in edges.get(todo.pop(), ()):
            if other not in seen:
                seen.add(other)
                todo.append(other)
    return [b for b in linkage.bodies if b not in seen]


def load_linkage(path: str | Path) -> Linkage:
    """The linkage of a spec file."""
    spec = Document(Path(path), "a mapping with app: linkage, name, ground, bodies, joints and driver")
    data = spec.data
    known_keys(spec, data, "", TOP_KEYS)
    if data.get("app") != "linkage":
        raise spec.error("app", f"got {show(data.get('app'))}; a linkage spec says app: linkage")
    name = identifier(spec, require(spec, data, "name", "name", str, "the linkage's name"), "name",
                      "the linkage's name")
    ground = _points(spec, require(spec, data, "ground", "ground", dict, "the ground pivots"), "ground",
                     "the ground pivots")
    listed = require(spec, data, "bodies", "bodies", dict, "a mapping of body names to their points")
    bodies = {}
    for body, points in listed.items():
        identifier(spec, body, f"bodies.{body}", "a body name")
        if body == GROUND:
            raise spec.error(f"bodies.{body}", "'ground' names the fixed frame; give the body another name")
        bodies[body] = _points(spec, points, f"bodies.{body}", "the body's points")
    joints_data = require(spec, data, "joints", "joints", list, "a list of joints")
    joints = tuple(_joint(spec, j, f"joints[{i}]", ground, bodies) for i, j in enumerate(joints_data))
    driver = require(spec, data, "driver", "driver", dict, "{body: crank, pivot: ground.point}")
    known_keys(spec, driver, "driver", DRIVER_KEYS)
    crank = require(spec, driver, "body", "driver.body", str, "the crank body")
    if crank not in bodies:
        raise spec.error("driver.body", f"unknown body {crank!r}; the bodies: {', '.join(bodies)}")
    pivot = _ref(spec, require(spec, driver, "pivot", "driver.pivot", str, "ground.point"), "driver.pivot",
                 ground, bodies)
    if pivot[0] != GROUND:
        raise spec.error("driver.pivot", f"got {pivot[0]}.{pivot[1]}; the crank turns about a ground point")
    pinned = any(isinstance(j, Revolute) and j.a[0] == crank and j.b == pivot for j in joints)
    if not pinned:
        raise spec.error("driver.pivot", f"no revolute joint pins {crank} to ground.{pivot[1]}; the crank "
                                         f"turns about its ground pivot")
    trace = _ref(spec, data["trace"], "trace", ground, bodies) if "trace" in data else None
    linkage = Linkage(name, ground, bodies, joints, crank, pivot[1], trace)
    dangling = _connected(linkage)
    if dangling:
        raise spec.error("joints", f"no joint connects {', '.join(dangling)} to the ground (directly or "
                                   f"through other bodies): dangling bodies")
    mobility = linkage.mobility()
    if mobility != 1:
        kind = "over-constrained" if mobility < 1 else "under-constrained"
        raise spec.error("joints", f"the mechanism is {kind}: Grübler–Kutzbach counts {mobility} "
                                   f"degrees of freedom (3 × {len(bodies)} moving links − 2 per revolute − 1 "
                                   f"per prismatic joint); one crank drives a mechanism of exactly 1")
    return linkage
