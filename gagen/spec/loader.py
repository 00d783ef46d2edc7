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
        robot: left_rig                # optional: chains with one robot label share same-named joints
      - name: finger
        joints:                        # explicit joints instead of a URDF
          - {name: j1, type: revolute, axis: [0, 0, 1], xyz: [0, 0, 0.1], rpy: [0, 0, 0]}
    configurations:                    # named reference configurations (optional)
      ready: [0.0, ...]

Every error is a ``SpecError`` naming the file, the field (``chains[1].tip_link``) with its line,
and what was expected.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import yaml

from gagen.errors import SpecError
from gagen.model.cooperative import Chain, System
from gagen.model.kinematics import JOINT_KINDS, Joint
from gagen.model.primitives import KINDS, points_needed
from gagen.robots.urdf import load_chain


class _Spec:
    """The parsed document plus the line of every field, for error messages."""

    def __init__(self, path: Path) -> None:
        self.path = path
        if not path.is_file():
            raise SpecError(path, "spec", "file not found")
        text = path.read_text()
        try:
            self.data = yaml.safe_load(text)
            self.lines = _lines(yaml.compose(text))
        except yaml.YAMLError as e:
            mark = getattr(e, "problem_mark", None)
            where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
            raise SpecError(path, "spec", f"not valid YAML{where}: {getattr(e, 'problem', e)}") from e
        if not isinstance(self.data, dict):
            raise SpecError(path, "spec", "a mapping with name, primitive and chains")

    def error(self, field: str, expected: str) -> SpecError:
        line = self.lines.get(field)
        return SpecError(self.path, f"{field} (line {line})" if line else field, expected)


def _lines(node: Any, prefix: str = "") -> dict[str, int]:
    """Field path -> 1-based line, from PyYAML's node tree."""
    out: dict[str, int] = {}
    if isinstance(node, yaml.MappingNode):
        for key, value in node.value:
            path = f"{prefix}.{key.value}" if prefix else str(key.value)
            out[path] = key.start_mark.line + 1
            out.update(_lines(value, path))
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            path = f"{prefix}[{i}]"
            out[path] = item.start_mark.line + 1
            out.update(_lines(item, path))
    return out


def _require(spec: _Spec, mapping: dict, key: str, field: str, kind: type | tuple, expected: str) -> Any:
    if key not in mapping:
        raise spec.error(field, f"missing; expected {expected}")
    value = mapping[key]
    if not isinstance(value, kind) or isinstance(value, bool):
        raise spec.error(field, f"got {value!r}; expected {expected}")
    return value


def _vector(spec: _Spec, value: Any, field: str, default: tuple[float, ...]) -> tuple[float, ...]:
    if value is None:
        return default
    if (not isinstance(value, list) or len(value) != 3
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                       for v in value)):
        raise spec.error(field, f"got {value!r}; expected a list of three finite numbers")
    return tuple(float(v) for v in value)


def _placement(spec: _Spec, value: Any, field: str, name: str) -> Joint:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {value!r}; expected a mapping with xyz and rpy")
    return Joint(name, "fixed", _vector(spec, value.get("xyz"), f"{field}.xyz", (0.0, 0.0, 0.0)),
                 _vector(spec, value.get("rpy"), f"{field}.rpy", (0.0, 0.0, 0.0)))


def _explicit_joint(spec: _Spec, value: Any, field: str) -> Joint:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {value!r}; expected a joint mapping (name, type, axis, xyz, rpy)")
    name = _require(spec, value, "name", f"{field}.name", str, "a joint name")
    kind = _require(spec, value, "type", f"{field}.type", str, f"one of {', '.join(JOINT_KINDS)}")
    if kind not in JOINT_KINDS:
        raise spec.error(f"{field}.type", f"got {kind!r}; expected one of {', '.join(JOINT_KINDS)}")
    if kind != "fixed" and "axis" not in value:
        raise spec.error(f"{field}.axis", "missing; a moving joint needs its axis, e.g. [0, 0, 1]")
    axis = _vector(spec, value.get("axis"), f"{field}.axis", (0.0, 0.0, 1.0))
    norm = math.sqrt(sum(a * a for a in axis))
    if kind != "fixed" and norm == 0:
        raise spec.error(f"{field}.axis", "got a zero vector; expected a direction")
    return Joint(name, kind, _vector(spec, value.get("xyz"), f"{field}.xyz", (0.0, 0.0, 0.0)),
                 _vector(spec, value.get("rpy"), f"{field}.rpy", (0.0, 0.0, 0.0)),
                 tuple(a / norm for a in axis) if norm else axis)


def _chain(spec: _Spec, value: Any, field: str) -> Chain:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {value!r}; expected a chain mapping (name and urdf or joints)")
    name = _require(spec, value, "name", f"{field}.name", str, "a chain name")
    robot = _require(spec, value, "robot", f"{field}.robot", str, "a robot label") if "robot" in value else ""
    joints: list[Joint] = []
    if "base" in value:
        joints.append(_placement(spec, value["base"], f"{field}.base", f"{robot or name}_base"))
    if "urdf" in value:
        urdf = spec.path.parent / _require(spec, value, "urdf", f"{field}.urdf", str, "a URDF path")
        base = _require(spec, value, "base_link", f"{field}.base_link", str, "the chain's first link")
        tip = _require(spec, value, "tip_link", f"{field}.tip_link", str, "the chain's last link")
        try:
            joints += load_chain(urdf, base, tip)
        except SpecError as e:  # say which spec field led to the URDF problem
            field_name = f"{field}.{e.field}" if e.field in ("base_link", "tip_link") else f"{field}.urdf"
            raise spec.error(field_name, f"{e.file}: {e.message}") from e
    elif "joints" in value:
        listed = _require(spec, value, "joints", f"{field}.joints", list, "a list of joints")
        joints += [_explicit_joint(spec, j, f"{field}.joints[{i}]") for i, j in enumerate(listed)]
    else:
        raise spec.error(field, "needs either urdf (with base_link, tip_link) or joints")
    chain = Chain(name, tuple(joints), robot)
    if chain.dof == 0:
        raise spec.error(field, "has no moving joint")
    return chain


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


def load_system(path: str | Path) -> tuple[System, dict[str, list[float]]]:
    """The system of a spec file, and its named reference configurations."""
    spec = _Spec(Path(path))
    data = spec.data
    name = _require(spec, data, "name", "name", str, "the system's name")
    kind = _require(spec, data, "primitive", "primitive", str, f"one of {', '.join(KINDS)}")
    if kind not in KINDS:
        raise spec.error("primitive", f"got {kind!r}; expected one of {', '.join(KINDS)}")
    chains_data = _require(spec, data, "chains", "chains", list, "a list of chains")
    if len(chains_data) != points_needed(kind):
        raise spec.error("chains", f"a {kind} is spanned by {points_needed(kind)} chains "
                                   f"(one per point), got {len(chains_data)}")
    chains = tuple(_chain(spec, c, f"chains[{i}]") for i, c in enumerate(chains_data))
    for i, chain in enumerate(chains):
        if chain.name in [c.name for c in chains[:i]]:
            raise spec.error(f"chains[{i}].name", f"got {chain.name!r} twice; chain names name the "
                                                  f"generated kernels and must differ")
    _check_shared_robots(spec, chains)
    system = System(name, kind, chains)
    configurations = {}
    for key, q in (data.get("configurations") or {}).items():
        field = f"configurations.{key}"
        if (not isinstance(q, list) or len(q) != system.dof
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in q)):
            raise spec.error(field, f"expected a list of {system.dof} numbers (one per joint)")
        configurations[key] = [float(v) for v in q]
    return system, configurations
