"""Strict YAML documents for gagen's specs (robots, hexapods, …): every field's line, refusal of
duplicate keys, alias bombs, recursive anchors and non-UTF-8 text, and the field checks the spec
loaders share (known keys with a suggestion, required values, identifiers, labels, bounded numbers).

Every error is a ``SpecError`` naming the file, the field (``chains[1].tip_link``) with its line, and
what was expected.
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path
from typing import Any, cast

import yaml

from gagen.errors import SpecError, read_input
from gagen.names import IDENTIFIER_RULE, LABEL_RULE, identifier_problem, label_problem, suggest_identifier

# bounds of the numbers of every input (specs and URDFs)
MAX_COORDINATE = 1e6  # metres: a larger joint offset is a unit mistake or garbage
MAX_ANGLE = 1e3  # radians, for rpy
MIN_AXIS = 1e-12  # an axis shorter than this is taken as the zero vector
MAX_NODES = 100_000  # YAML nodes of the document expanded through its aliases


class Document:
    """The parsed document plus the line of every field, for error messages."""

    def __init__(self, path: Path, expected: str = "a mapping") -> None:
        self.path = path
        raw = read_input(path, "spec")
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as e:
            raise SpecError(path, "spec", f"not UTF-8 text: byte 0x{raw[e.start]:02x} at offset {e.start}; "
                                          f"save the spec as UTF-8") from e
        self.lines: dict[str, int] = {}
        try:
            loader = yaml.SafeLoader(text)
            try:
                node = loader.get_single_node()
                if node is not None:
                    _check_size(path, node)
                    self.lines = _lines(path, node)
                data = None if node is None else loader.construct_document(node)
            finally:
                loader.dispose()
        except SpecError:
            raise
        except yaml.reader.ReaderError as e:  # PyYAML's own message is two lines without a line number
            line = text.count("\n", 0, e.position) + 1
            column = e.position - text.rfind("\n", 0, e.position)
            code = e.character if isinstance(e.character, int) else ord(e.character)
            raise SpecError(path, "spec", f"not valid YAML at line {line}, column {column}: the control "
                                          f"character U+{code:04X} is not allowed in YAML text") from e
        except yaml.YAMLError as e:
            mark = getattr(e, "problem_mark", None)
            where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
            problem = " ".join(str(getattr(e, "problem", None) or e).split())  # one line
            raise SpecError(path, "spec", f"not valid YAML{where}: {problem}") from e
        except RecursionError as e:
            raise SpecError(path, "spec", "not a spec: nested too deeply") from e
        except (ValueError, TypeError, OverflowError) as e:  # PyYAML's constructors (e.g. a bad date)
            detail = " ".join(str(e).split())
            raise SpecError(path, "spec", f"not valid YAML: {type(e).__name__}: {detail}") from e
        if not isinstance(data, dict):
            raise SpecError(path, "spec", expected)
        self.data: dict[Any, Any] = data

    def error(self, field: str, expected: str) -> SpecError:
        line = self.lines.get(field)
        return SpecError(self.path, f"{field} (line {line})" if line else field, expected)


def _check_size(path: Path, root: yaml.Node) -> None:
    """Refuse documents whose expansion through aliases exceeds MAX_NODES nodes, or that contain
    themselves (a recursive anchor). Each node is visited once (its expanded size memoised), so
    this takes time linear in the text even for an alias bomb."""
    size: dict[int, int] = {}
    active: set[int] = set()
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        children = _children(node)
        if done:
            active.discard(id(node))
            size[id(node)] = 1 + sum(size[id(c)] for c in children)
            if size[id(node)] > MAX_NODES:
                raise SpecError(path, "spec", f"line {node.start_mark.line + 1}: the document expands "
                                              f"(through its aliases) to more than {MAX_NODES} nodes")
            continue
        if id(node) in size:
            continue
        active.add(id(node))
        stack.append((node, True))
        for child in children:
            if id(child) in active:
                raise SpecError(path, "spec", f"line {child.start_mark.line + 1}: a recursive anchor "
                                              f"(an alias inside the node it names)")
            if id(child) not in size:
                stack.append((child, False))


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.MappingNode):
        return [n for pair in node.value for n in pair]
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    return []


def _lines(path: Path, node: yaml.Node, prefix: str = "") -> dict[str, int]:
    """Field path -> 1-based line, from PyYAML's node tree (size-checked: at most MAX_NODES entries);
    refuses a key given twice in one mapping."""
    out: dict[str, int] = {}
    if isinstance(node, yaml.MappingNode):
        seen: dict[tuple[str, str], int] = {}
        for key, value in node.value:
            text = key.value if isinstance(key, yaml.ScalarNode) else "?"  # a complex key: not a spec key
            field = f"{prefix}.{text}" if prefix else text
            line = key.start_mark.line + 1
            if isinstance(key, yaml.ScalarNode) and key.tag != "tag:yaml.org,2002:merge":
                if (key.tag, key.value) in seen:
                    first = seen[key.tag, key.value]
                    raise SpecError(path, f"{field} (line {line})",
                                    f"duplicate key {key.value!r} (first at line {first}); each key may "
                                    f"appear once")
                seen[key.tag, key.value] = line
            out[field] = line
            out.update(_lines(path, value, field))
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            field = f"{prefix}[{i}]"
            out[field] = item.start_mark.line + 1
            out.update(_lines(path, item, field))
    return out


def show(value: Any, limit: int = 60) -> str:
    """A value for an error message: its repr, shortened."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def known_keys(spec: Document, mapping: dict[Any, Any], field: str, allowed: tuple[str, ...]) -> None:
    """Refuse keys outside ``allowed``, suggesting the nearest valid one."""
    for key in mapping:
        if key in allowed:
            continue
        where = f"{field}.{key}" if field else str(key)
        close = difflib.get_close_matches(str(key), allowed, n=1)
        hint = f"did you mean {close[0]!r}?" if close else f"expected one of {', '.join(allowed)}"
        raise spec.error(where, f"unknown key {show(key)}; {hint}")


def require(spec: Document, mapping: dict[Any, Any], key: str, field: str, kind: type | tuple[type, ...],
            expected: str) -> Any:
    if key not in mapping:
        raise spec.error(field, f"missing; expected {expected}")
    value = mapping[key]
    if not isinstance(value, kind) or isinstance(value, bool):
        raise spec.error(field, f"got {show(value)}; expected {expected}")
    return value


def identifier(spec: Document, value: Any, field: str, what: str) -> str:
    problem = identifier_problem(value)
    if problem:
        raise spec.error(field, f"got {show(value)} ({problem}); {what} names files, C symbols and Python "
                                f"attributes: expected {IDENTIFIER_RULE}, e.g. "
                                f"{suggest_identifier(value)!r}")
    return cast(str, value)  # identifier_problem refuses anything but a str


def label(spec: Document, value: Any, field: str, what: str) -> str:
    if not isinstance(value, str):
        raise spec.error(field, f"got {show(value)}; expected {what}")
    problem = label_problem(value)
    if problem:
        raise spec.error(field, f"got {show(value)} ({problem}); {what} becomes a row label in the "
                                f"generated code: expected {LABEL_RULE}")
    return value


def number(value: Any, bound: float) -> bool:
    """A real number (not a bool) within ±bound; ints are compared exactly (no overflow)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    return (not isinstance(value, float) or math.isfinite(value)) and abs(value) <= bound


def vector(spec: Document, value: Any, field: str, default: tuple[float, float, float],
            bound: float = MAX_COORDINATE) -> tuple[float, float, float]:
    if value is None:
        return default
    if not isinstance(value, list) or len(value) != 3 or not all(number(v, bound) for v in value):
        raise spec.error(field, f"got {show(value)}; expected a list of three finite numbers "
                                f"within ±{bound:g}")
    x, y, z = (float(v) for v in value)
    return x, y, z


