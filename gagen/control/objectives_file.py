"""Mixed objectives from a YAML file, kept apart from the robot spec (``gagen.control.objectives``).

    start: ready                        # optional: a configuration of the system's spec
    objectives:
      - name: ring                      # optional (a label; default <type><index>)
        weight: 1.0                     # optional, > 0 (default 1)
        radius: {of: {circle: [arm0, arm1, arm2]}, radius: 0.3}
      - normal: {of: {circle: [arm0, arm1, arm2]}, normal: [0, 0, 1]}
      - incidence:                      # Eq. 9: ‖A ∧ B‖²
          a: {centre: {circle: [arm0, arm1, arm2]}}
          b: {line: {point: [0.05, 0.05, 0.0], direction: [0, 0, 1]}}
        weight: 4
      - target:                         # the line through two arms reaches a stated line
          of: {line: [arm0, arm1]}
          goal: {line: {point: [0.3, 0.0, 0.5], direction: [0, 1, 0]}}
        hard: false                     # optional, targets only: an equality constraint (IPOPT)
      - dilation_force: {of: {circle: [arm0, arm1, arm2]}}   # 1/β_D² [Sec. 3.11]

Each entry states exactly one of ``target``, ``incidence``, ``radius``, ``normal``, ``dilation_force``.
An operand is a mapping with one key: a primitive kind with a list of chain names (the cooperative
primitive through their end points) or with its parameters (a fixed primitive, stated as a spec's
goals state it: ``point: {position}``, ``line: {point, direction}``, ``plane: {point, normal}``,
``circle: {centre, radius, normal}``, ``sphere: {centre, radius}``, ``point_pair: {first, second}``),
or ``centre: OPERAND``, or ``meet: [OPERAND, OPERAND]``. Every key is checked; an error is one
``SpecError`` line naming the file, the field and its line (and the nearest valid key or chain name).
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gagen.control import goals
from gagen.control import objectives as O
from gagen.model.primitives import KINDS, points_needed
from gagen.robots.goals import PRIMITIVE_PARAMETERS, _primitive
from gagen.robots.system import System
from gagen.yaml_document import Document, known_keys, label, number, show

TERMS = ("target", "incidence", "radius", "normal", "dilation_force")
OPERANDS = (*KINDS, "centre", "meet")
MAX_WEIGHT = 1e12


@dataclass(frozen=True)
class ObjectivesFile:
    """The terms of an objectives file, and its ``start`` configuration's name (None when not stated)."""

    terms: tuple[O.Term, ...]
    start: str | None


class _Reader:
    def __init__(self, document: Document, system: System) -> None:
        self.doc, self.system = document, system
        self.chains = [c.name for c in system.chains]

    def error(self, field: str, message: str) -> Exception:
        return self.doc.error(field, message)

    def mapping(self, value: Any, field: str, expected: str) -> dict[Any, Any]:
        if not isinstance(value, dict):
            raise self.error(field, f"got {show(value)}; expected {expected}")
        return value

    def one_of(self, value: dict[Any, Any], field: str, allowed: tuple[str, ...]) -> str:
        known_keys(self.doc, value, field, allowed)
        stated = [k for k in allowed if k in value]
        if len(stated) != 1:
            raise self.error(field, f"states {', '.join(stated) or 'nothing'}; expected exactly one of "
                                    f"{', '.join(allowed)}")
        return stated[0]

    def chain(self, value: Any, field: str) -> str:
        if not isinstance(value, str) or value not in self.chains:
            close = difflib.get_close_matches(str(value), self.chains, n=1)
            hint = f"did you mean {close[0]!r}?" if close else f"expected one of {', '.join(self.chains)}"
            raise self.error(field, f"unknown chain {show(value)} of system {self.system.name!r}; {hint}")
        return value

    def operand(self, value: Any, field: str) -> O.Operand:
        mapping = self.mapping(value, field, f"an operand: a mapping with one of {', '.join(OPERANDS)}")
        key = self.one_of(mapping, field, OPERANDS)
        inner, where = mapping[key], f"{field}.{key}"
        try:
            if key == "centre":
                return O.Centre(self.operand(inner, where))
            if key == "meet":
                if not isinstance(inner, list) or len(inner) != 2:
                    raise self.error(where, f"got {show(inner)}; expected a list of two operands")
                return O.Meet(self.operand(inner[0], f"{where}[0]"), self.operand(inner[1], f"{where}[1]"))
            if isinstance(inner, list):
                count = points_needed(key)
                if len(inner) != count:
                    raise self.error(where, f"got {len(inner)} chains; a cooperative {key} is spanned by "
                                            f"{count}")
                return O.Cooperative(key, tuple(self.chain(c, f"{where}[{i}]") for i, c in enumerate(inner)))
            return fixed(key, _primitive(self.doc, key, inner, where))
        except ValueError as e:
            if type(e) is not ValueError:  # a SpecError from below: already names its field
                raise
            raise self.error(where, str(e)) from e

    def term(self, value: Any, field: str) -> O.Term:
        mapping = self.mapping(value, field, f"a mapping with a name, a weight and one of {', '.join(TERMS)}")
        known_keys(self.doc, mapping, field, ("name", "weight", "hard", *TERMS))
        stated = [k for k in TERMS if k in mapping]
        if len(stated) != 1:
            raise self.error(field, f"states {', '.join(stated) or 'nothing'}; expected exactly one of "
                                    f"{', '.join(TERMS)}")
        kind = stated[0]
        name = label(self.doc, mapping["name"], f"{field}.name", "a term name") if "name" in mapping else ""
        weight = mapping.get("weight", 1.0)
        if not number(weight, MAX_WEIGHT) or float(weight) <= 0:
            raise self.error(f"{field}.weight", f"got {show(weight)}; expected a number > 0 within "
                                                f"{MAX_WEIGHT:g}")
        hard = mapping.get("hard", False)
        if not isinstance(hard, bool) or (hard and kind != "target"):
            raise self.error(f"{field}.hard", f"got {show(hard)}; expected true or false, and true only on a "
                                              "target")
        where = f"{field}.{kind}"
        body = self.mapping(mapping[kind], where, f"the {kind} term's mapping")
        allowed = {"target": ("of", "goal"), "incidence": ("a", "b"), "radius": ("of", "radius"),
                   "normal": ("of", "normal"), "dilation_force": ("of",)}[kind]
        known_keys(self.doc, body, where, allowed)
        for key in allowed:
            if key not in body:
                raise self.error(f"{where}.{key}", f"missing; a {kind} term states {', '.join(allowed)}")
        try:
            if kind == "incidence":
                a, b = self.operand(body["a"], f"{where}.a"), self.operand(body["b"], f"{where}.b")
                return O.Incidence(a, b, float(weight), name)
            of = self.operand(body["of"], f"{where}.of")
            if kind in ("target", "dilation_force"):
                if not isinstance(of, O.Cooperative):
                    raise self.error(f"{where}.of", "expected a cooperative primitive: a kind with a list of "
                                                    "chains")
                if kind == "dilation_force":
                    return O.DilationForce(of.chains, of.kind, float(weight), name)
                target = self.goal(body["goal"], f"{where}.goal", of.kind)
                return O.PrimitiveTarget(of.chains, of.kind, target, float(weight), name, hard)
            if kind == "radius":
                r = body["radius"]
                if not number(r, 1e6) or float(r) <= 0:
                    raise self.error(f"{where}.radius", f"got {show(r)}; expected a number > 0 (m)")
                return O.Radius(of, float(r), float(weight), name)
            n = body["normal"]
            if not isinstance(n, list) or len(n) != 3 or not all(number(v, 1e6) for v in n) \
                    or not any(float(v) != 0 for v in n):
                raise self.error(f"{where}.normal", f"got {show(n)}; expected three numbers, not all zero")
            return O.Normal(of, (float(n[0]), float(n[1]), float(n[2])), float(weight), name)
        except ValueError as e:
            if type(e) is not ValueError:
                raise
            raise self.error(where, str(e)) from e

    def goal(self, value: Any, field: str, kind: str) -> tuple[float, ...]:
        mapping = self.mapping(value, field, f"a {kind} stated by its parameters "
                                             f"({', '.join(PRIMITIVE_PARAMETERS[kind])})")
        known_keys(self.doc, mapping, field, (kind,))
        if kind not in mapping:
            raise self.error(field, f"missing {kind}; the goal of a cooperative {kind} is a {kind}")
        parameters = _primitive(self.doc, kind, mapping[kind], f"{field}.{kind}")
        try:
            makers: dict[str, Callable[..., Any]] = {
                "point": goals.point, "point_pair": goals.point_pair, "line": goals.line,
                "circle": goals.circle, "plane": goals.plane, "sphere": goals.sphere}
            V_Sd = makers[kind](*(parameters[p] for p in PRIMITIVE_PARAMETERS[kind]))
        except ValueError as e:
            raise self.error(f"{field}.{kind}", str(e)) from e
        return tuple(float(v) for v in np.asarray(V_Sd).ravel())


def fixed(kind: str, parameters: dict[str, Any]) -> O.Fixed:
    """A fixed primitive from a spec-style parameter mapping (``PRIMITIVE_PARAMETERS``)."""
    makers: dict[str, Callable[..., O.Fixed]] = {
        "point": O.point_at, "point_pair": O.point_pair, "line": O.line, "plane": O.plane,
        "circle": O.circle, "sphere": O.sphere}
    return makers[kind](*(parameters[p] for p in PRIMITIVE_PARAMETERS[kind]))


def load_objectives(path: str | Path, system: System,
                    configurations: dict[str, Any] | None = None) -> ObjectivesFile:
    """The terms of the objectives file at ``path`` for ``system`` (chain names are checked against it;
    ``start`` against ``configurations`` when given). A ``SpecError`` (a ValueError) names the file, the
    field and its line."""
    document = Document(Path(path), "a mapping with objectives (and start)")
    reader = _Reader(document, system)
    known_keys(document, document.data, "", ("objectives", "start"))
    entries = document.data.get("objectives")
    if not isinstance(entries, list) or not entries:
        raise document.error("objectives", f"got {show(entries)}; expected a list of terms")
    terms = tuple(reader.term(entry, f"objectives[{i}]") for i, entry in enumerate(entries))
    names = [t.name for t in terms if t.name]
    for i, term in enumerate(terms):
        if term.name and names.count(term.name) > 1:
            raise document.error(f"objectives[{i}].name", f"{term.name!r} is used twice; names must differ")
    start = document.data.get("start")
    if start is not None:
        if not isinstance(start, str):
            raise document.error("start", f"got {show(start)}; expected a configuration's name")
        if configurations is not None and start not in configurations:
            close = difflib.get_close_matches(start, list(configurations), n=1)
            hint = f"did you mean {close[0]!r}?" if close else \
                f"expected one of {', '.join(configurations) or '(none stated)'}"
            raise document.error("start", f"unknown configuration {start!r}; {hint}")
    return ObjectivesFile(terms, start)


def objective_from_file(path: str | Path, system: System) -> O.Objective:
    """``Objective(system, load_objectives(path, system).terms)``."""
    return O.Objective(system, load_objectives(path, system).terms)
