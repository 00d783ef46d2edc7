"""Load and validate a hexapod spec (YAML) into a :class:`Hexapod`.

A spec::

    app: hexapod
    name: hexapod
    leg:                                   # every leg's defaults (the [HEX] leg)
      lengths: [0.05, 0.20, 0.20]          # l1 hip offset, l2 thigh, l3 shank (m)
      axes: [[0, 0, 1], [0, 1, 0], [0, 1, 0]]   # hip yaw, thigh pitch, knee pitch (hip frame)
      limits: [[-0.785, 0.785], [-1.571, 1.571], [-2.618, 2.618]]   # rad
    legs:                                  # six mounts on the body: xyz and rpy of each hip frame
      - {name: front_left, xyz: [0.1039, 0.06, 0], rpy: [0, 0, 0.5236]}
      - ...                                # a leg may override lengths, axes or limits
    knee: up                               # the IK branch the body kernels use: up or down
    neutral: [0, -0.25, 1.8]               # the standing configuration of every leg (rad)

In its hip frame a leg turns about ``axes[0]`` through the origin, ``axes[1]`` through (l1, 0, 0)
and ``axes[2]`` through (l1 + l2, 0, 0); its toe is at (l1 + l2 + l3, 0, 0) in the zero pose.

Errors are ``SpecError``s naming the file, the field with its line, and what was expected, from the
strict reader every spec shares (``gagen.yaml_document``): unknown or duplicate keys, alias bombs,
non-UTF-8 text, names that are not identifiers, numbers out of range, zero axes, empty or reversed
limits, a neutral pose outside them, a leg named like the body kernels (``body``), more legs than
``gagen.limits`` allows (``hexapod_legs``) and a body with a number of legs other than six.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gagen.errors import SpecError
from gagen.limits import over_limit
from gagen.yaml_document import (
    MAX_ANGLE,
    MIN_AXIS,
    Document,
    identifier,
    known_keys,
    number,
    require,
    show,
    vector,
)

TOP_KEYS = ("app", "name", "leg", "legs", "knee", "neutral")
LEG_KEYS = ("lengths", "axes", "limits")
MOUNT_KEYS = ("name", "xyz", "rpy", *LEG_KEYS)
LEGS = 6
# a leg's kernels are <leg>_<suffix>; the body's must not be among them (gagen.apps.hexapod.kernels)
LEG_KERNEL_SUFFIXES = ("fk_pga", "fk_cga", "ik", "dls")
BODY_KERNELS = ("body_fk_pga", "body_fk_cga", "body_ik", "body_contact_pga", "body_contact_cga",
                "ground_pga", "ground_cga")
MAX_LENGTH = 100.0  # m: a longer link is a unit mistake
MIN_LENGTH = 1e-6  # m: so is a shorter one, whose squares underflow in the IK's 2 l2 l3 (1e-300)
KNEES = ("up", "down")
DEFAULT_AXES = ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (0.0, 1.0, 0.0))
Vec = tuple[float, float, float]


@dataclass(frozen=True)
class Leg:
    """One 3-DOF leg: its mount on the body (the hip frame's xyz and rpy), link lengths, joint axes
    in the hip frame and joint limits."""

    name: str
    xyz: Vec
    rpy: Vec
    lengths: Vec
    axes: tuple[Vec, Vec, Vec] = DEFAULT_AXES
    limits: tuple[tuple[float, float], ...] = ((-math.pi, math.pi),) * 3

    @property
    def centres(self) -> tuple[Vec, Vec, Vec]:
        """Where the three joint axes pass through, in the hip frame."""
        l1, l2, _ = self.lengths
        return (0.0, 0.0, 0.0), (l1, 0.0, 0.0), (l1 + l2, 0.0, 0.0)

    @property
    def toe(self) -> Vec:
        """The toe in the hip frame at the zero pose."""
        return (sum(self.lengths), 0.0, 0.0)

    @property
    def joint_names(self) -> tuple[str, str, str]:
        return f"{self.name}_yaw", f"{self.name}_thigh", f"{self.name}_knee"


@dataclass(frozen=True)
class Hexapod:
    name: str
    legs: tuple[Leg, ...]
    knee: str = "up"
    neutral: Vec = (0.0, -0.25, 1.8)

    @property
    def dof(self) -> int:
        return 3 * len(self.legs)

    @property
    def joint_names(self) -> list[str]:
        return [j for leg in self.legs for j in leg.joint_names]

    def leg(self, name: str) -> Leg:
        for leg in self.legs:
            if leg.name == name:
                return leg
        raise KeyError(f"{self.name} has no leg {name!r}; its legs: {', '.join(g.name for g in self.legs)}")


def _lengths(spec: Document, value: Any, field: str) -> Vec:
    if not isinstance(value, list) or len(value) != 3 or \
            not all(number(v, MAX_LENGTH) and v >= MIN_LENGTH for v in value):
        raise spec.error(field, f"got {show(value)}; expected three positive lengths l1, l2, l3 in metres "
                                f"(at least {MIN_LENGTH:g}, at most {MAX_LENGTH:g})")
    return tuple(float(v) for v in value)  # type: ignore[return-value]


def _axes(spec: Document, value: Any, field: str) -> tuple[Vec, Vec, Vec]:
    if not isinstance(value, list) or len(value) != 3:
        raise spec.error(field, f"got {show(value)}; expected three axes (hip yaw, thigh, knee), e.g. "
                                f"[[0, 0, 1], [0, 1, 0], [0, 1, 0]]")
    axes = []
    for i, axis in enumerate(value):
        v = vector(spec, axis, f"{field}[{i}]", (0.0, 0.0, 1.0))
        norm = math.sqrt(sum(a * a for a in v))
        if norm < MIN_AXIS:
            raise spec.error(f"{field}[{i}]", "got a zero vector; expected a direction")
        axes.append(tuple(a / norm for a in v))
    return tuple(axes)  # type: ignore[return-value]


def _limits(spec: Document, value: Any, field: str) -> tuple[tuple[float, float], ...]:
    if not isinstance(value, list) or len(value) != 3:
        raise spec.error(field, f"got {show(value)}; expected three [lower, upper] pairs in radians")
    limits = []
    for i, pair in enumerate(value):
        if not isinstance(pair, list) or len(pair) != 2 or not all(number(v, MAX_ANGLE) for v in pair):
            raise spec.error(f"{field}[{i}]", f"got {show(pair)}; expected [lower, upper] in radians")
        if not pair[0] < pair[1]:
            raise spec.error(f"{field}[{i}]", f"got {show(pair)}; the lower limit must be below the upper")
        limits.append((float(pair[0]), float(pair[1])))
    return tuple(limits)


def _leg_defaults(spec: Document, value: Any, field: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {show(value)}; expected a mapping with lengths, axes and limits")
    known_keys(spec, value, field, LEG_KEYS)
    return _leg_fields(spec, value, field, {})


def _leg_fields(spec: Document, value: dict[str, Any], field: str, defaults: dict[str, Any]
                ) -> dict[str, Any]:
    out = dict(defaults)
    if "lengths" in value:
        out["lengths"] = _lengths(spec, value["lengths"], f"{field}.lengths")
    if "axes" in value:
        out["axes"] = _axes(spec, value["axes"], f"{field}.axes")
    if "limits" in value:
        out["limits"] = _limits(spec, value["limits"], f"{field}.limits")
    return out


def _leg(spec: Document, value: Any, field: str, defaults: dict[str, Any]) -> Leg:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {show(value)}; expected a leg mapping (name, xyz, rpy)")
    known_keys(spec, value, field, MOUNT_KEYS)
    name = require(spec, value, "name", f"{field}.name", str, "a leg name")
    identifier(spec, name, f"{field}.name", "a leg name")
    fields = _leg_fields(spec, value, field, defaults)
    if "lengths" not in fields:
        raise spec.error(f"{field}.lengths", "missing; give lengths here or under leg")
    return Leg(name, vector(spec, value.get("xyz"), f"{field}.xyz", (0.0, 0.0, 0.0)),
               vector(spec, value.get("rpy"), f"{field}.rpy", (0.0, 0.0, 0.0), MAX_ANGLE), **fields)


def load_hexapod(path: str | Path) -> Hexapod:
    """The hexapod of a spec file."""
    spec = Document(Path(path), "a mapping with app: hexapod, name and legs")
    data = spec.data
    known_keys(spec, data, "", TOP_KEYS)
    if data.get("app") != "hexapod":
        raise spec.error("app", f"got {show(data.get('app'))}; a hexapod spec says app: hexapod")
    name = require(spec, data, "name", "name", str, "the hexapod's name")
    identifier(spec, name, "name", "the hexapod's name")
    defaults = _leg_defaults(spec, data["leg"], "leg") if "leg" in data else {}
    listed = require(spec, data, "legs", "legs", list, f"a list of {LEGS} legs")
    problem = over_limit("hexapod_legs", len(listed))  # before any leg is read
    if problem:
        raise spec.error("legs", problem)
    if len(listed) != LEGS:
        raise spec.error("legs", f"got {len(listed)} legs; a hexapod has {LEGS}")
    legs = tuple(_leg(spec, v, f"legs[{i}]", defaults) for i, v in enumerate(listed))
    seen: dict[str, int] = {}
    for i, leg in enumerate(legs):
        k = seen.setdefault(leg.name.lower(), i)
        if k != i:
            raise spec.error(f"legs[{i}].name", f"got {leg.name!r}, the name of legs[{k}] too (up to case); "
                                                f"leg names name kernels and must differ")
        clashes = [kernel for suffix in LEG_KERNEL_SUFFIXES
                   if (kernel := f"{leg.name}_{suffix}".lower()) in BODY_KERNELS]
        if clashes:
            raise spec.error(f"legs[{i}].name", f"got {leg.name!r}: the leg's kernels would collide with "
                                                f"the body's {', '.join(clashes)} (names are compared up to "
                                                f"case); expected a leg name other than 'body', e.g. "
                                                f"'body_leg'")
    knee = data.get("knee", "up")
    if knee not in KNEES:
        raise spec.error("knee", f"got {show(knee)}; expected one of {', '.join(KNEES)}")
    neutral = vector(spec, data.get("neutral"), "neutral", Hexapod.neutral, MAX_ANGLE)
    for leg_index, leg in enumerate(legs):
        for j, (q, (lo, hi)) in enumerate(zip(neutral, leg.limits, strict=True)):
            if not lo <= q <= hi:
                raise spec.error("neutral", f"joint {leg.joint_names[j]} of legs[{leg_index}] at {q:g} is "
                                            f"outside its limits [{lo:g}, {hi:g}]")
    return Hexapod(name, legs, knee, neutral)


__all__ = ["Hexapod", "Leg", "SpecError", "load_hexapod"]
