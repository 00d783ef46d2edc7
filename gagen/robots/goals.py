"""A spec's ``goals:`` section: the target primitives a task on the system reaches, by name.

    goals:
      circle:                           # a name (a label): gagen reach SPEC --goal circle
        title: a larger, raised circle  # optional, for reports and plots
        move:                           # the ready primitive moved by a similarity (ocp.target_from)
          translation: [0, 0, 0.1]      # m
          rotation: {axis: [1, 0, 0], angle: 0.2}   # rad, about the primitive's reference point
          dilation: 1.3                 # about it (rounds only)
      over_the_table:
        circle: {centre: [0.6, 0, 0.5], radius: 0.25, normal: [0, 0, 1]}   # a primitive stated outright

A goal is a ``move`` of the system's ``ready`` primitive or a primitive of the system's own kind, stated
as ``gagen.control.goals`` takes it: ``point: {position}``, ``point_pair: {first, second}``, ``line:
{point, direction}``, ``circle: {centre, radius, normal}``, ``plane: {point, normal}``, ``sphere:
{centre, radius}``. Errors name the file, the field and its line, like every spec error; turning a goal
into the desired similarity V_Sd is ``gagen.control.goals.desired``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gagen.yaml_document import MAX_ANGLE, MAX_COORDINATE, Document, known_keys, label, number, show, vector

PRIMITIVE_PARAMETERS = {
    "point": ("position",),
    "point_pair": ("first", "second"),
    "line": ("point", "direction"),
    "circle": ("centre", "radius", "normal"),
    "plane": ("point", "normal"),
    "sphere": ("centre", "radius"),
}
"""A primitive goal's parameters, in the order ``gagen.control.goals`` takes them."""
MOVE_KEYS = ("translation", "rotation", "dilation")
MAX_DILATION = 1e3


@dataclass(frozen=True)
class Goal:
    """One goal: ``kind`` is ``move`` (``translation``, ``rotation`` = (axis, angle) or None, ``dilation``)
    or a primitive kind with its ``parameters`` (vectors as 3-tuples, radii as floats)."""

    name: str
    kind: str
    title: str = ""
    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[tuple[float, float, float], float] | None = None
    dilation: float = 1.0
    parameters: dict[str, Any] = field(default_factory=dict)

    @property
    def is_move(self) -> bool:
        return self.kind == "move"


def _positive(spec: Document, value: Any, field: str, bound: float) -> float:
    if not number(value, bound) or float(value) <= 0:
        raise spec.error(field, f"got {show(value)}; expected a finite number > 0 within {bound:g}")
    return float(value)


def _move(spec: Document, value: Any, field: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {show(value)}; expected a mapping of {', '.join(MOVE_KEYS)}")
    known_keys(spec, value, field, MOVE_KEYS)
    rotation = None
    if "rotation" in value:
        where = f"{field}.rotation"
        r = value["rotation"]
        if not isinstance(r, dict):
            raise spec.error(where, f"got {show(r)}; expected a mapping with axis and angle")
        known_keys(spec, r, where, ("axis", "angle"))
        axis = vector(spec, r.get("axis"), f"{where}.axis", (0.0, 0.0, 0.0))
        if sum(a * a for a in axis) < 1e-24:
            raise spec.error(f"{where}.axis", "missing or zero; expected the rotation's axis, three numbers")
        angle = r.get("angle")
        if angle is None or not number(angle, MAX_ANGLE):
            raise spec.error(f"{where}.angle", f"got {show(angle)}; expected a finite angle in rad within "
                                               f"±{MAX_ANGLE:g}")
        rotation = (axis, float(angle))
    dilation = _positive(spec, value["dilation"], f"{field}.dilation", MAX_DILATION) \
        if "dilation" in value else 1.0
    return {"translation": vector(spec, value.get("translation"), f"{field}.translation", (0.0, 0.0, 0.0)),
            "rotation": rotation, "dilation": dilation}


def _primitive(spec: Document, kind: str, value: Any, field: str) -> dict[str, Any]:
    names = PRIMITIVE_PARAMETERS[kind]
    if not isinstance(value, dict):
        raise spec.error(field, f"got {show(value)}; expected a mapping of {', '.join(names)}")
    known_keys(spec, value, field, names)
    parameters: dict[str, Any] = {}
    for name in names:
        where = f"{field}.{name}"
        if name not in value:
            raise spec.error(where, f"missing; a {kind} goal states {', '.join(names)}")
        parameters[name] = _positive(spec, value[name], where, MAX_COORDINATE) if name == "radius" else \
            vector(spec, value[name], where, (0.0, 0.0, 0.0))
    return parameters


def _goal(spec: Document, name: Any, value: Any, kind: str | None) -> Goal:
    field = f"goals.{name}"
    label(spec, name, field, "a goal name")
    if not isinstance(value, dict):
        raise spec.error(field, f"got {show(value)}; expected a mapping with a title (optional) and move or "
                                f"a primitive ({', '.join(PRIMITIVE_PARAMETERS)})")
    known_keys(spec, value, field, ("title", "move", *PRIMITIVE_PARAMETERS))
    title = value.get("title", "")
    if not isinstance(title, str) or len(title) > 200:
        raise spec.error(f"{field}.title", f"got {show(title)}; expected a line of text")
    stated = [k for k in ("move", *PRIMITIVE_PARAMETERS) if k in value]
    if len(stated) != 1:
        raise spec.error(field, f"states {', '.join(stated) or 'nothing'}; expected exactly one of move or "
                                f"a primitive ({', '.join(PRIMITIVE_PARAMETERS)})")
    if stated[0] == "move":
        return Goal(str(name), "move", title, **_move(spec, value["move"], f"{field}.move"))
    if kind is not None and stated[0] != kind:
        raise spec.error(f"{field}.{stated[0]}", f"the system spans a {kind}; a goal of it is a {kind} (or a "
                                                 f"move)")
    return Goal(str(name), stated[0], title,
                parameters=_primitive(spec, stated[0], value[stated[0]], f"{field}.{stated[0]}"))


def goals_of(spec: Document) -> dict[str, Goal]:
    """The goals of a loaded spec document (its ``goals`` section; none without one)."""
    data = spec.data.get("goals", {})
    if not isinstance(data, dict):
        raise spec.error("goals", f"got {show(data)}; expected a mapping of goal names to goals")
    kind = spec.data.get("primitive")
    return {str(name): _goal(spec, name, value, kind if isinstance(kind, str) else None)
            for name, value in data.items()}


def load_goals(path: str | Path) -> dict[str, Goal]:
    """The goals of a spec file, by name, in the order the spec states them."""
    return goals_of(Document(Path(path), "a mapping (a spec)"))
