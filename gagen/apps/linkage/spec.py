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
      # a slider block (a prismatic pair: the point on the line and no turning relative to the line's
      # body; two constraints), same keys:
      # - {slider: {point: block.P, slot: ground, through: [0, 0], direction: [1, 0], travel: [1, 2.6]}}
    driver: {body: crank, pivot: ground.A, rate: 1.0}   # the crank turns about the pivot
    trace: coupler.P                          # the coupler point whose curve is drawn

The driver is a crank (a body pinned to a ground point by a revolute joint; it turns by θ about it) or
a slider (a body on a ground ``slider`` joint; it translates by s along the slot). ``pivot`` names the
crank's ground point (optional where one revolute pins it). ``rate`` (rad/s, default 1) sets the time
axis: the crank angle is θ = rate · t; a slider runs its stroke as s = amplitude · sin(rate · t) over
its travel.

The initial configuration needs to be assembled only roughly: the solver assembles it exactly at the
crank's initial angle first. Each body's frame is the world frame at that configuration.

Errors are ``SpecError``s naming the file, the field with its line and what was expected (the strict
reader of every spec, ``gagen.yaml_document``): names that are not identifiers (also those YAML reads
as numbers or booleans: ``1:``, ``on:``), more bodies or joints than the limits ``linkage_bodies`` and
``linkage_joints`` allow (``gagen.limits``), unknown bodies or points, a joint joining a body to
itself, a body no joint reaches from the ground (dangling), a driver that is neither a crank nor a
slider (or whose pivot is not the crank's ground pivot), bad numbers. Mobility is counted by
Grübler–Kutzbach, 3 (n − 1) − 2 j_R − 2 j_S − j_P with the ground among the n links, a slider (a block
on a line) taking two freedoms and a prismatic joint (a pin in a slot) one; a mechanism of mobility k
takes k drivers (``driver:`` a list, each on its own body: two cranks, a crank and a slider; the
solver's and the kernels' driver value is then a vector of k), and a count that does not match the
drivers is reported by name (over- or under-constrained). The rank of the constraint Jacobian at the initial
configuration is checked by the solver (``gagen.apps.linkage.solver``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gagen.errors import SpecError
from gagen.limits import over_limit
from gagen.names import IDENTIFIER_RULE, identifier_problem, suggest_identifier
from gagen.yaml_document import Document, identifier, known_keys, number, require, show

if TYPE_CHECKING:
    import numpy as np

TOP_KEYS = ("app", "name", "ground", "bodies", "joints", "driver", "trace")
PRISMATIC_KEYS = ("point", "slot", "through", "direction", "travel")
JOINT_KINDS = ("revolute", "prismatic", "slider")
DRIVER_KEYS = ("body", "pivot", "rate")
MAX_RATE = 1e4
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


@dataclass(frozen=True)
class Slider(Prismatic):
    """A slider block: the point on the line (as a prismatic joint) and, besides, no turning relative
    to the body carrying the line, a lower pair of two constraints."""

    @property
    def rows(self) -> int:
        return 2


Joint = Revolute | Prismatic


@dataclass(frozen=True)
class Driver:
    body: str
    pivot: str | None  # a crank's ground point; None for a slider
    slide: Slider | None = None  # a slider's joint to the ground; None for a crank
    rate: float = 1.0  # rad/s of the crank angle or of the slider's stroke phase

    @property
    def kind(self) -> str:
        return "crank" if self.slide is None else "slider"

    @property
    def input(self) -> str:
        """The driver's coordinate: the crank angle θ (rad) or the slider's displacement s (m)."""
        return "theta" if self.slide is None else "s"


@dataclass(frozen=True)
class Linkage:
    name: str
    ground: dict[str, Point]
    bodies: dict[str, dict[str, Point]]
    joints: tuple[Joint, ...]
    driver: Driver  # the first driver
    trace: tuple[str, str] | None = None
    more_drivers: tuple[Driver, ...] = ()  # the others, for a mechanism of mobility k > 1

    @property
    def drivers(self) -> tuple[Driver, ...]:
        """Every driver, one per degree of freedom, in spec order."""
        return (self.driver, *self.more_drivers)

    @property
    def crank(self) -> str:
        """The (first) driven body (a crank, or a slider block)."""
        return self.driver.body

    @property
    def driven(self) -> tuple[str, ...]:
        """Every driven body, in the drivers' order."""
        return tuple(d.body for d in self.drivers)

    @property
    def pivot(self) -> str | None:
        return self.driver.pivot

    @property
    def unknown(self) -> list[str]:
        """The bodies the solver moves: all but the driven ones, in spec order."""
        return [b for b in self.bodies if b not in self.driven]

    @property
    def active_joints(self) -> tuple[Joint, ...]:
        """The joints the solver enforces: all but those between a driven body and the ground (the
        crank's pivot or the slider's slot, which the driver's motion keeps by construction)."""
        return tuple(j for j in self.joints if not any({*_bodies(j)} <= {GROUND, d} for d in self.driven))

    @property
    def constraint_rows(self) -> int:
        return sum(j.rows for j in self.active_joints)

    def mobility(self) -> int:
        """Grübler–Kutzbach: 3 (n − 1) − 2 j_R − 2 j_S − j_P (revolute, slider, pin in slot), the ground
        counted among the n links."""
        n = len(self.bodies) + 1
        return 3 * (n - 1) - sum(2 if isinstance(j, Revolute) else j.rows for j in self.joints)

    def point(self, ref: tuple[str, str]) -> Point:
        body, name = ref
        return self.ground[name] if body == GROUND else self.bodies[body][name]

    def at(self, value: Any) -> str:
        """The driver(s) at a value, for messages: "crank 12.0°" or "slider s = 0.25" (k drivers: a
        vector of k values, "crank1 12.0°, crank2 −3.000°")."""
        values = [float(v) for v in value.reshape(-1)] if hasattr(value, "reshape") else (
            [float(v) for v in value] if isinstance(value, list | tuple) else [float(value)])
        if len(self.drivers) == 1:
            return _at(self.driver, values[0])
        return ", ".join(f"{d.body} {_at(d, v).split(' ', 1)[1]}" for d, v in zip(self.drivers, values,
                                                                                     strict=False))

    def stroke(self, driver: Driver | None = None) -> tuple[float, float]:
        """A slider driver's range of s (lower < 0 < upper): its travel, as a displacement from the
        initial configuration (the first driver's, or ``driver``'s)."""
        slide = (driver or self.driver).slide
        if slide is None or slide.travel is None:
            raise ValueError(f"{self.name}: the driver is not a slider with a travel")
        start = slot_coordinate(slide, self.point(slide.point))
        lo, hi = slide.travel
        # the ground carries the slot: the point's coordinate is start + s; the block carries it: start − s
        return (lo - start, hi - start) if slide.on == GROUND else (start - hi, start - lo)


def _at(driver: Driver, value: float) -> str:
    return f"crank {math.degrees(value):.3f}°" if driver.slide is None else f"slider s = {value:.4g}"


def slot_coordinate(joint: Prismatic, x: Point | np.ndarray) -> float:
    """A point's coordinate along a slot, (x − through)·direction, in the frame of the slot's body."""
    return (x[0] - joint.through[0]) * joint.direction[0] + (x[1] - joint.through[1]) * joint.direction[1]


def _bodies(joint: Joint) -> tuple[str, str]:
    return (joint.a[0], joint.b[0]) if isinstance(joint, Revolute) else (joint.point[0], joint.on)


# how YAML 1.1 may spell a boolean key: to find the field (and its line) of a key read as true or false
_BOOLEAN_WORDS = {True: ("on", "yes", "true", "y"), False: ("off", "no", "false", "n")}


def _shown(key: Any) -> str:
    """A mapping key as a part of a field in a one-line message: as written where it is short and
    printable, else its repr (a key with a newline or a NUL must not break the message's line)."""
    if not isinstance(key, str):
        return str(key)
    return key if key.isprintable() and len(key) <= 64 else show(key)


def _key_field(spec: Document, prefix: str, key: Any) -> str:
    """The field of a mapping key for a message, with its line: as the document spells the key where
    that spelling is found among the document's fields (``bodies.on``, not ``bodies.True``)."""
    if isinstance(key, bool):
        spellings = [w for word in _BOOLEAN_WORDS[key] for w in (word, word.capitalize(), word.upper())]
    else:
        spellings = ["null", "~", "Null", "NULL", ""] if key is None else [str(key)]
    for text in spellings:
        line = spec.lines.get(f"{prefix}.{text}")
        if line:
            return f"{prefix}.{_shown(text)} (line {line})"
    return f"{prefix}.{_shown(key)}"


def _name(spec: Document, value: Any, prefix: str, what: str) -> str:
    """A body or point name (a key of ``prefix``): an identifier. YAML reads some unquoted names as
    numbers, booleans or null (``1:``, ``on:``, ``~:``); those are named as what YAML made of them."""
    field = _key_field(spec, prefix, value)
    if isinstance(value, bool):
        message = (f"got the boolean {value} (YAML reads an unquoted on, off, yes, no, true or false as a "
                   f"boolean); expected {what}: quote it, e.g. \"on\"")
    elif value is None:
        message = (f"got null (YAML reads an unquoted null or ~ as no value); expected {what}: "
                   f"{IDENTIFIER_RULE}")
    elif isinstance(value, int | float):
        message = (f"got the number {show(value)} (YAML reads it as a number); expected {what}: "
                   f"{IDENTIFIER_RULE}, e.g. {suggest_identifier(str(value))!r}")
    elif not isinstance(value, str):
        message = f"got {show(value)}; expected {what}: {IDENTIFIER_RULE}"
    else:
        problem = identifier_problem(value)
        if problem is None:
            return value
        message = (f"got {show(value)} ({problem}); {what} names files, C symbols and Python attributes: "
                   f"expected {IDENTIFIER_RULE}, e.g. {suggest_identifier(value)!r}")
    raise SpecError(spec.path, field, message)


def _known_keys(spec: Document, mapping: dict[Any, Any], field: str, allowed: tuple[str, ...]) -> None:
    """``known_keys``, with an unknown key that is not printable text named by its repr (one line)."""
    for key in mapping:
        if key not in allowed and isinstance(key, str) and _shown(key) != key:
            where = f"{field}.{_shown(key)}" if field else _shown(key)
            raise SpecError(spec.path, where, f"unknown key {show(key)}; expected one of "
                                              f"{', '.join(allowed)}")
    known_keys(spec, mapping, field, allowed)


def _check_count(spec: Document, name: str, count: int, field: str) -> None:
    """Refuse a count over the limit ``name`` (``gagen.limits``) before any per-item work."""
    problem = over_limit(name, count)
    if problem:
        raise spec.error(field, problem)


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
        _name(spec, name, field, "a point name")
        out[name] = _xy(spec, xy, f"{field}.{name}")
    return out


def _ref(spec: Document, value: Any, field: str, ground: dict[str, Point],
         bodies: dict[str, dict[str, Point]]) -> tuple[str, str]:
    if not isinstance(value, str) or value.count(".") != 1:
        raise spec.error(field, f"got {show(value)}; expected body.point (or ground.point)")
    body, name = value.split(".")
    if body != GROUND and body not in bodies:
        raise spec.error(field, f"unknown body {body!r}; the bodies: {', '.join(bodies)} (or ground)")
    known = ground if body == GROUND else bodies[body]
    if name not in known:
        raise spec.error(field, f"{body} has no point {name!r}; its points: {', '.join(known)}")
    return body, name


def _joint(spec: Document, value: Any, field: str, ground: dict[str, Point],
           bodies: dict[str, dict[str, Point]]) -> Joint:
    if not isinstance(value, dict) or len(value) != 1 or next(iter(value)) not in JOINT_KINDS:
        raise spec.error(field, f"got {show(value)}; expected {{revolute: [body.point, body.point]}}, "
                                f"{{prismatic: {{point, slot, through, direction, travel}}}} (a pin in a "
                                f"slot) or {{slider: {{…the same keys}}}} (a slider block)")
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
    _known_keys(spec, body, where, PRISMATIC_KEYS)
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
    kind_of = Slider if kind == "slider" else Prismatic
    return kind_of(point, on, through, (dx / norm, dy / norm), travel)


def _drivers(spec: Document, listed: Any, ground: dict[str, Point], bodies: dict[str, dict[str, Point]],
             joints: tuple[Joint, ...]) -> tuple[Driver, ...]:
    """One driver (a mapping) or k drivers (a list of mappings, a mechanism of mobility k), each on a
    different body."""
    expected = ("{body: crank, pivot: ground.point}, {body: slider}, or a list of them (one per degree of "
                "freedom)")
    if isinstance(listed, dict):
        return (_driver(spec, listed, ground, bodies, joints, "driver"),)
    if not isinstance(listed, list) or not listed:
        raise spec.error("driver", f"got {show(listed)}; expected {expected}")
    out: list[Driver] = []
    for i, item in enumerate(listed):
        if not isinstance(item, dict):
            raise spec.error(f"driver[{i}]", f"got {show(item)}; expected {{body: crank, pivot: "
                                             f"ground.point}} or {{body: slider}}")
        driver = _driver(spec, item, ground, bodies, joints, f"driver[{i}]")
        if driver.body in (d.body for d in out):
            raise spec.error(f"driver[{i}].body", f"{driver.body} is driven twice; each driver moves its own "
                                                  f"body")
        out.append(driver)
    return tuple(out)


def _driver(spec: Document, driver: dict[str, Any], ground: dict[str, Point],
            bodies: dict[str, dict[str, Point]], joints: tuple[Joint, ...], field: str) -> Driver:
    """A crank (pinned to a ground point by a revolute joint) or a slider (on a ground slider joint)."""
    _known_keys(spec, driver, field, DRIVER_KEYS)
    body = require(spec, driver, "body", f"{field}.body", str, "the crank or slider body")
    if body not in bodies:
        raise spec.error(f"{field}.body", f"unknown body {body!r}; the bodies: {', '.join(bodies)}")
    rate = driver.get("rate", 1.0)
    if not number(rate, MAX_RATE) or rate == 0:
        raise spec.error(f"{field}.rate", f"got {show(rate)}; expected a non-zero rate in rad/s within "
                                          f"±{MAX_RATE:g}")
    pivots = [j.b[1] for j in joints if isinstance(j, Revolute) and j.a[0] == body and j.b[0] == GROUND]
    slides = [j for j in joints if isinstance(j, Slider) and {j.point[0], j.on} == {body, GROUND}]
    if "pivot" in driver:
        pivot = _ref(spec, require(spec, driver, "pivot", f"{field}.pivot", str, "ground.point"),
                     f"{field}.pivot", ground, bodies)
        if pivot[0] != GROUND:
            raise spec.error(f"{field}.pivot", f"got {pivot[0]}.{pivot[1]}; the crank turns about a ground "
                                               f"point")
        if pivot[1] not in pivots:
            raise spec.error(f"{field}.pivot", f"no revolute joint pins {body} to ground.{pivot[1]}; the "
                                               f"crank turns about its ground pivot")
        return Driver(body, pivot[1], None, float(rate))
    if len(pivots) == 1 and not slides:
        return Driver(body, pivots[0], None, float(rate))
    if len(slides) == 1 and not pivots:
        slide = slides[0]
        along = slot_coordinate(slide, ground[slide.point[1]] if slide.point[0] == GROUND
                                else bodies[body][slide.point[1]])
        if slide.travel is None or not slide.travel[0] < along < slide.travel[1]:
            raise spec.error(field, f"the slider {body} runs its stroke over its joint's travel: give the "
                                       f"slider joint a travel [lower, upper] with the initial position "
                                       f"{along:g} strictly inside (got {show(slide.travel)})")
        return Driver(body, None, slide, float(rate))
    raise spec.error(field, f"{body} is pinned to the ground by {len(pivots)} revolute and {len(slides)} "
                               f"slider joint(s); a driver is a crank (one revolute joint to a ground point, "
                               f"or name it with pivot: ground.<point>) or a slider (one slider joint to "
                               f"the ground)")


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
    _known_keys(spec, data, "", TOP_KEYS)
    if data.get("app") != "linkage":
        raise spec.error("app", f"got {show(data.get('app'))}; a linkage spec says app: linkage")
    name = identifier(spec, require(spec, data, "name", "name", str, "the linkage's name"), "name",
                      "the linkage's name")
    ground = _points(spec, require(spec, data, "ground", "ground", dict, "the ground pivots"), "ground",
                     "the ground pivots")
    listed = require(spec, data, "bodies", "bodies", dict, "a mapping of body names to their points")
    _check_count(spec, "linkage_bodies", len(listed), "bodies")
    bodies = {}
    for body, points in listed.items():
        _name(spec, body, "bodies", "a body name")
        if body == GROUND:
            raise spec.error(f"bodies.{body}", "'ground' names the fixed frame; give the body another name")
        bodies[body] = _points(spec, points, f"bodies.{body}", "the body's points")
    joints_data = require(spec, data, "joints", "joints", list, "a list of joints")
    _check_count(spec, "linkage_joints", len(joints_data), "joints")
    joints = tuple(_joint(spec, j, f"joints[{i}]", ground, bodies) for i, j in enumerate(joints_data))
    if "driver" not in data:
        require(spec, data, "driver", "driver", dict, "{body: crank, pivot: ground.point} or {body: slider}")
    drivers = _drivers(spec, data["driver"], ground, bodies, joints)
    trace = _ref(spec, data["trace"], "trace", ground, bodies) if "trace" in data else None
    linkage = Linkage(name, ground, bodies, joints, drivers[0], trace, drivers[1:])
    dangling = _connected(linkage)
    if dangling:
        raise spec.error("joints", f"no joint connects {', '.join(dangling)} to the ground (directly or "
                                   f"through other bodies): dangling bodies")
    mobility, count = linkage.mobility(), len(drivers)
    if mobility != count:
        kind = "over-constrained" if mobility < count else "under-constrained"
        counted = (f"Grübler–Kutzbach counts {mobility} degrees of freedom (3 × {len(bodies)} moving links "
                   f"− 2 per revolute or slider − 1 per prismatic joint)")
        if mobility < 1:
            raise spec.error("joints", f"the mechanism is {kind}: {counted}; one driver moves a mechanism of "
                                       f"exactly 1")
        drivers_ = f"{count} driver" + ("s" if count > 1 else "")
        raise spec.error("driver", f"the mechanism is {kind}: {counted} and {drivers_} move it; give one "
                                   f"driver per degree of freedom (driver: a list of {mobility} drivers)"
                                   if mobility > 1 else
                                   f"the mechanism is {kind}: {counted} and {drivers_} move it; give one")
    return linkage
