"""Load and validate a robot spec (YAML) into a ``System``.

A spec::

    name: three_pandas_circle
    primitive: circle                  # point, point_pair, line, circle, plane, sphere
    chains:                            # one per spanning point of the primitive
      - name: arm0
        urdf: panda/panda.urdf         # relative to the spec file
        base_link: panda_link0
        tip_link: panda_link8
        base: {xyz: [0.8, 0, 0], rpy: [0, 0, 3.14159]}     # placement of the chain's base (optional)
        tool: {xyz: [0, 0, 0.1034]}    # tool/TCP offset from the tip link's frame (optional)
        robot: left_rig                # optional: chains with one robot label share same-named joints
      - name: finger
        joints:                        # explicit joints instead of a URDF
          - {name: j1, type: revolute, axis: [0, 0, 1], xyz: [0, 0, 0.1], rpy: [0, 0, 0]}
    configurations:                    # named reference configurations (optional)
      ready: [0.0, ...]

Every error is a ``SpecError`` naming the file, the field (``chains[1].tip_link``) with its line,
and what was expected. The loader is strict:

* unknown keys are refused at every level, with the nearest valid key suggested (``bse`` ->
  ``base``); a chain takes either ``urdf`` (with ``base_link``, ``tip_link``) or ``joints``;
* duplicate keys are refused; anchors and aliases are allowed, but the document expanded through
  them may have at most ``MAX_NODES`` nodes (alias bombs) and no alias may refer to itself;
  the file must be UTF-8;
* names follow ``gagen.names``: the system and chain names are identifiers (a letter, then
  letters, digits and single underscores; no keywords; at most 64 characters), refused rather than
  mapped, so they can name files, C symbols and Python attributes as they are; joint names, robot
  labels and configuration names are labels (letters, digits, ``_ . : -``). No chain's kernel
  (``<chain>_fk``, ``<chain>_fk_jacobian``, ``<chain>_jacobians``) may equal another kernel's name,
  even up to case (a chain named ``similarity`` would make a second ``similarity_jacobians``);
* numbers are finite: positions within ±``MAX_COORDINATE`` m, rpy angles within ±``MAX_ANGLE`` rad,
  axes three finite numbers of length at least ``MIN_AXIS``, configuration values within
  ±``MAX_COORDINATE``. A URDF is checked likewise by ``gagen.robots.urdf``.

The ``tool`` placement becomes a fixed joint ``<chain>_tool`` after the tip link: the chain's end
point is then the tip frame's origin plus R_tip·tool.xyz.
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path
from typing import Any

import yaml

from gagen.apps.cooperative.system import Chain, System
from gagen.errors import SpecError, read_input
from gagen.model.kinematics import JOINT_KINDS, Joint
from gagen.model.primitives import KINDS, points_needed
from gagen.names import (
    IDENTIFIER_RULE,
    LABEL_RULE,
    SYSTEM_KERNELS,
    chain_kernel_names,
    identifier_problem,
    label_problem,
    suggest_identifier,
)
from gagen.robots.urdf import MAX_ANGLE, MAX_COORDINATE, MIN_AXIS, load_chain

MAX_NODES = 100_000  # YAML nodes of the document expanded through its aliases

TOP_KEYS = ("name", "primitive", "chains", "configurations")
CHAIN_KEYS = ("name", "robot", "base", "tool", "urdf", "base_link", "tip_link", "joints")
URDF_KEYS = ("urdf", "base_link", "tip_link")
PLACEMENT_KEYS = ("xyz", "rpy")
JOINT_KEYS = ("name", "type", "axis", "xyz", "rpy")


class _Spec:
    """The parsed document plus the line of every field, for error messages."""

    def __init__(self, path: Path) -> None:
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
                self.data = None if node is None else loader.construct_document(node)
            finally:
                loader.dispose()
        except SpecError:
            raise
        except yaml.YAMLError as e:
            mark = getattr(e, "problem_mark", None)
            where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
            raise SpecError(path, "spec", f"not valid YAML{where}: {getattr(e, 'problem', e)}") from e
        except RecursionError as e:
            raise SpecError(path, "spec", "not a spec: nested too deeply") from e
        except (ValueError, TypeError, OverflowError) as e:  # PyYAML's constructors (e.g. a bad date)
            raise SpecError(path, "spec", f"not valid YAML: {type(e).__name__}: {e}") from e
        if not isinstance(self.data, dict):
            raise SpecError(path, "spec", "a mapping with name, primitive and chains")

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


def _show(value: Any, limit: int = 60) -> str:
    """A value for an error message: its repr, shortened."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _known_keys(spec: _Spec, mapping: dict, field: str, allowed: tuple[str, ...]) -> None:
    """Refuse keys outside ``allowed``, suggesting the nearest valid one."""
    for key in mapping:
        if key in allowed:
            continue
        where = f"{field}.{key}" if field else str(key)
        close = difflib.get_close_matches(str(key), allowed, n=1)
        hint = f"did you mean {close[0]!r}?" if close else f"expected one of {', '.join(allowed)}"
        raise spec.error(where, f"unknown key {_show(key)}; {hint}")


def _require(spec: _Spec, mapping: dict, key: str, field: str, kind: type | tuple, expected: str) -> Any:
    if key not in mapping:
        raise spec.error(field, f"missing; expected {expected}")
    value = mapping[key]
    if not isinstance(value, kind) or isinstance(value, bool):
        raise spec.error(field, f"got {_show(value)}; expected {expected}")
    return value


def _identifier(spec: _Spec, value: Any, field: str, what: str) -> str:
    problem = identifier_problem(value)
    if problem:
        raise spec.error(field, f"got {_show(value)} ({problem}); {what} names files, C symbols and Python "
                                f"attributes: expected {IDENTIFIER_RULE}, e.g. "
                                f"{suggest_identifier(value)!r}")
    return value


def _label(spec: _Spec, value: Any, field: str, what: str) -> str:
    if not isinstance(value, str):
        raise spec.error(field, f"got {_show(value)}; expected {what}")
    problem = label_problem(value)
    if problem:
        raise spec.error(field, f"got {_show(value)} ({problem}); {what} becomes a row label in the "
                                f"generated code: expected {LABEL_RULE}")
    return value


def _number(value: Any, bound: float) -> bool:
    """A real number (not a bool) within ±bound; ints are compared exactly (no overflow)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    return (not isinstance(value, float) or math.isfinite(value)) and abs(value) <= bound


def _vector(spec: _Spec, value: Any, field: str, default: tuple[float, ...],
            bound: float = MAX_COORDINATE) -> tuple[float, ...]:
    if value is None:
        return default
    if not isinstance(value, list) or len(value) != 3 or not all(_number(v, bound) for v in value):
        raise spec.error(field, f"got {_show(value)}; expected a list of three finite numbers "
                                f"within ±{bound:g}")
    return tuple(float(v) for v in value)


def _placement(spec: _Spec, value: Any, field: str, name: str) -> Joint:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {_show(value)}; expected a mapping with xyz and rpy")
    _known_keys(spec, value, field, PLACEMENT_KEYS)
    return Joint(name, "fixed", _vector(spec, value.get("xyz"), f"{field}.xyz", (0.0, 0.0, 0.0)),
                 _vector(spec, value.get("rpy"), f"{field}.rpy", (0.0, 0.0, 0.0), MAX_ANGLE))


def _explicit_joint(spec: _Spec, value: Any, field: str) -> Joint:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {_show(value)}; expected a joint mapping (name, type, axis, xyz, rpy)")
    _known_keys(spec, value, field, JOINT_KEYS)
    name = _require(spec, value, "name", f"{field}.name", str, "a joint name")
    _label(spec, name, f"{field}.name", "a joint name")
    kind = _require(spec, value, "type", f"{field}.type", str, f"one of {', '.join(JOINT_KINDS)}")
    if kind not in JOINT_KINDS:
        raise spec.error(f"{field}.type", f"got {_show(kind)}; expected one of {', '.join(JOINT_KINDS)}")
    if kind != "fixed" and "axis" not in value:
        raise spec.error(f"{field}.axis", "missing; a moving joint needs its axis, e.g. [0, 0, 1]")
    axis = _vector(spec, value.get("axis"), f"{field}.axis", (0.0, 0.0, 1.0))
    norm = math.sqrt(sum(a * a for a in axis))
    if kind != "fixed" and norm < MIN_AXIS:
        raise spec.error(f"{field}.axis", f"got a zero vector (length below {MIN_AXIS:g}); expected a "
                                          f"direction")
    return Joint(name, kind, _vector(spec, value.get("xyz"), f"{field}.xyz", (0.0, 0.0, 0.0)),
                 _vector(spec, value.get("rpy"), f"{field}.rpy", (0.0, 0.0, 0.0), MAX_ANGLE),
                 tuple(a / norm for a in axis) if norm else axis)


def _chain(spec: _Spec, value: Any, field: str) -> Chain:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {_show(value)}; expected a chain mapping (name and urdf or joints)")
    _known_keys(spec, value, field, CHAIN_KEYS)
    name = _require(spec, value, "name", f"{field}.name", str, "a chain name")
    _identifier(spec, name, f"{field}.name", "a chain name")
    robot = _require(spec, value, "robot", f"{field}.robot", str, "a robot label") if "robot" in value else ""
    if "robot" in value:
        _label(spec, robot, f"{field}.robot", "a robot label")
    joints: list[Joint] = []
    if "base" in value:
        joints.append(_placement(spec, value["base"], f"{field}.base", f"{robot or name}_base"))
    if "urdf" in value and "joints" in value:
        raise spec.error(f"{field}.joints", "a chain takes either urdf (with base_link, tip_link) or joints, "
                                            "not both")
    if "urdf" in value:
        urdf = spec.path.parent / _require(spec, value, "urdf", f"{field}.urdf", str, "a URDF path")
        base = _require(spec, value, "base_link", f"{field}.base_link", str, "the chain's first link")
        tip = _require(spec, value, "tip_link", f"{field}.tip_link", str, "the chain's last link")
        try:
            joints += load_chain(urdf, base, tip)
        except SpecError as e:  # say which spec field led to the URDF problem
            field_name = f"{field}.{e.field}" if e.field in ("base_link", "tip_link") else f"{field}.urdf"
            detail = "" if e.field in ("urdf", "base_link", "tip_link") else f"{e.field}: "
            raise spec.error(field_name, f"{e.file}: {detail}{e.message}") from e
    elif "joints" in value:
        for key in URDF_KEYS:
            if key in value:
                raise spec.error(f"{field}.{key}", "only used with urdf; this chain lists its joints")
        listed = _require(spec, value, "joints", f"{field}.joints", list, "a list of joints")
        explicit = [_explicit_joint(spec, j, f"{field}.joints[{i}]") for i, j in enumerate(listed)]
        first: dict[str, int] = {}
        for i, joint in enumerate(explicit):
            k = first.setdefault(joint.name, i)
            if k != i:
                raise spec.error(f"{field}.joints[{i}].name", f"got {joint.name!r}, the name of joints[{k}] "
                                                              f"too; joint names in a chain must differ")
        joints += explicit
    else:
        raise spec.error(field, "needs either urdf (with base_link, tip_link) or joints")
    if "tool" in value:
        joints.append(_placement(spec, value["tool"], f"{field}.tool", f"{name}_tool"))
    try:
        chain = Chain(name, tuple(joints), robot)
    except ValueError as e:  # the model's own consistency checks
        raise spec.error(field, str(e)) from e
    if chain.dof == 0:
        raise spec.error(field, "has no moving joint")
    return chain


def _check_kernel_names(spec: _Spec, chains: tuple[Chain, ...]) -> None:
    """Every chain's kernel names differ from each other and from the system kernels, up to case
    (the C header upper-cases them in its size macros)."""
    owner = {kernel.lower(): f"the system kernel {kernel!r}" for kernel in SYSTEM_KERNELS}
    for i, chain in enumerate(chains):
        for j, other in enumerate(chains[:i]):
            if chain.name == other.name:
                raise spec.error(f"chains[{i}].name", f"got {chain.name!r} twice (also chains[{j}].name); "
                                                      f"chain names name the kernels and must differ")
        for kernel in chain_kernel_names(chain.name):
            if kernel.lower() in owner:
                raise spec.error(f"chains[{i}].name", f"chain {chain.name!r} names the kernel {kernel!r}, "
                                                      f"which collides with {owner[kernel.lower()]}; rename "
                                                      f"the chain")
        for kernel in chain_kernel_names(chain.name):
            owner[kernel.lower()] = f"kernel {kernel!r} of chains[{i}] ({chain.name!r})"


def _check_shared_robots(spec: _Spec, chains: tuple[Chain, ...]) -> None:
    """Chains of one robot share its base placement and every same-named moving joint."""
    first: dict[str, int] = {}
    for i, chain in enumerate(chains):
        if not chain.robot:
            continue
        k = first.setdefault(chain.robot, i)
        other = chains[k]
        bases = [c.joints[0] if c.joints and c.joints[0].name == f"{c.robot}_base" else None
                 for c in (chain, other)]
        if bases[0] != bases[1]:
            raise spec.error(f"chains[{i}].base", f"differs from chains[{k}].base; chains of robot "
                                                  f"{chain.robot!r} share one base placement")
        theirs = {j.name: j for j in other.joints if j.moves}
        for j in chain.joints:
            if j.moves and j.name in theirs and theirs[j.name] != j:
                raise spec.error(f"chains[{i}]", f"joint {j.name!r} differs from the one in chains[{k}]; "
                                                 f"chains of robot {chain.robot!r} share same-named joints")


def _configurations(spec: _Spec, system: System) -> dict[str, list[float]]:
    data = spec.data.get("configurations", {})
    if not isinstance(data, dict):
        raise spec.error("configurations", f"got {_show(data)}; expected a mapping of names to lists of "
                                           f"{system.dof} joint values")
    configurations = {}
    for key, q in data.items():
        field = f"configurations.{key}"
        _label(spec, key, field, "a configuration name")
        if not isinstance(q, list) or len(q) != system.dof:
            raise spec.error(field, f"expected a list of {system.dof} numbers (one per joint)")
        for i, v in enumerate(q):
            if not _number(v, MAX_COORDINATE):
                label = "/".join(system.joint_keys[i])
                raise spec.error(f"{field}[{i}]", f"got {_show(v)} for joint {label}; expected a finite "
                                                  f"number within ±{MAX_COORDINATE:g}")
        configurations[key] = [float(v) for v in q]
    return configurations


def load_system(path: str | Path) -> tuple[System, dict[str, list[float]]]:
    """The system of a spec file, and its named reference configurations."""
    spec = _Spec(Path(path))
    data = spec.data
    _known_keys(spec, data, "", TOP_KEYS)
    name = _require(spec, data, "name", "name", str, "the system's name")
    _identifier(spec, name, "name", "the system's name")
    kind = _require(spec, data, "primitive", "primitive", str, f"one of {', '.join(KINDS)}")
    if kind not in KINDS:
        raise spec.error("primitive", f"got {_show(kind)}; expected one of {', '.join(KINDS)}")
    chains_data = _require(spec, data, "chains", "chains", list, "a list of chains")
    if len(chains_data) != points_needed(kind):
        raise spec.error("chains", f"a {kind} is spanned by {points_needed(kind)} chains "
                                   f"(one per point), got {len(chains_data)}")
    chains = tuple(_chain(spec, c, f"chains[{i}]") for i, c in enumerate(chains_data))
    _check_kernel_names(spec, chains)
    _check_shared_robots(spec, chains)
    try:
        system = System(name, kind, chains)
    except ValueError as e:  # the model's own consistency checks (e.g. shared mimic joints)
        raise spec.error("chains", str(e)) from e
    return system, _configurations(spec, system)
