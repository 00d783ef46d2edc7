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
      - name: hand
        measured: true                 # optional: its joints are measured inputs q_m, not variables
        joints: [...]                  # (a tracked point: three prismatic joints along x, y, z)
      - name: finger
        joints:                        # explicit joints instead of a URDF
          - {name: j1, type: revolute, axis: [0, 0, 1], xyz: [0, 0, 0.1], rpy: [0, 0, 0]}
          - {name: j2, type: revolute, axis: [0, 1, 0], mimic: {joint: j1, multiplier: 2, offset: 0}}
    configurations:                    # named reference configurations (optional)
      ready: [0.0, ...]
    snap: true                         # optional (default true): see below

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

``snap`` (a bool, default true) snaps every rpy angle within 1e-9 of a multiple of π/4 to that exact
multiple (a URDF's ``1.57079632679`` becomes π/2, giving exact zeros and ≈ 30 % fewer flops; the
kinematics then differ from the file's numbers by ≈ 1e-11); ``snap: false`` keeps the URDF's and the
spec's numbers as written. Either way the loaded system's repr, and so the build key, says which.

The ``tool`` placement becomes a fixed joint ``<chain>_tool`` after the tip link: the chain's end
point is then the tip frame's origin plus R_tip·tool.xyz.

A ``measured: true`` chain (a leader: a human's hand) spans the primitive like the others, but its joints
are inputs q_m, not variables of q (``docs/leader-follower.md``); it may share no joint with a robot
chain, and configurations list q only.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

from gagen.errors import SpecError
from gagen.limits import over_limit
from gagen.model.kinematics import JOINT_KINDS, Joint
from gagen.model.primitives import KINDS, points_needed
from gagen.names import (
    DUAL_TASK_KERNELS,
    SYSTEM_KERNELS,
    chain_kernel_names,
)
from gagen.robots.goals import goals_of
from gagen.robots.system import Chain, System
from gagen.robots.urdf import load_chain
from gagen.yaml_document import (
    MAX_ANGLE,
    MAX_COORDINATE,
    MIN_AXIS,
    Document,
    identifier,
    known_keys,
    label,
    number,
    require,
    show,
    vector,
)

TOP_KEYS = ("app", "name", "primitive", "chains", "configurations", "goals", "snap")
CHAIN_KEYS = ("name", "robot", "base", "tool", "urdf", "base_link", "tip_link", "joints", "measured")
URDF_KEYS = ("urdf", "base_link", "tip_link")
PLACEMENT_KEYS = ("xyz", "rpy")
JOINT_KEYS = ("name", "type", "axis", "xyz", "rpy", "mimic")
MIMIC_KEYS = ("joint", "multiplier", "offset")


def _placement(spec: Document, value: Any, field: str, name: str) -> Joint:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {show(value)}; expected a mapping with xyz and rpy")
    known_keys(spec, value, field, PLACEMENT_KEYS)
    return Joint(name, "fixed", vector(spec, value.get("xyz"), f"{field}.xyz", (0.0, 0.0, 0.0)),
                 vector(spec, value.get("rpy"), f"{field}.rpy", (0.0, 0.0, 0.0), MAX_ANGLE))


def _explicit_joint(spec: Document, value: Any, field: str) -> Joint:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {show(value)}; expected a joint mapping (name, type, axis, xyz, rpy)")
    known_keys(spec, value, field, JOINT_KEYS)
    name = require(spec, value, "name", f"{field}.name", str, "a joint name")
    label(spec, name, f"{field}.name", "a joint name")
    kind = require(spec, value, "type", f"{field}.type", str, f"one of {', '.join(JOINT_KINDS)}")
    if kind not in JOINT_KINDS:
        raise spec.error(f"{field}.type", f"got {show(kind)}; expected one of {', '.join(JOINT_KINDS)}")
    if kind != "fixed" and "axis" not in value:
        raise spec.error(f"{field}.axis", "missing; a moving joint needs its axis, e.g. [0, 0, 1]")
    axis = vector(spec, value.get("axis"), f"{field}.axis", (0.0, 0.0, 1.0))
    norm = math.sqrt(sum(a * a for a in axis))
    if kind != "fixed" and norm < MIN_AXIS:
        raise spec.error(f"{field}.axis", f"got a zero vector (length below {MIN_AXIS:g}); expected a "
                                          f"direction")
    return Joint(name, kind, vector(spec, value.get("xyz"), f"{field}.xyz", (0.0, 0.0, 0.0)),
                 vector(spec, value.get("rpy"), f"{field}.rpy", (0.0, 0.0, 0.0), MAX_ANGLE),
                 (axis[0] / norm, axis[1] / norm, axis[2] / norm) if norm else axis,
                 _mimic(spec, value, field, name, kind))


def _mimic(spec: Document, value: dict[Any, Any], field: str, name: str,
           kind: str) -> tuple[str, float, float] | None:
    """``mimic: {joint: LEADER, multiplier: 1, offset: 0}`` of an explicit joint, as a URDF's <mimic>: the
    joint turns by multiplier·q_leader + offset and has no entry of its own in q."""
    if "mimic" not in value:
        return None
    where, mimic = f"{field}.mimic", value["mimic"]
    if not isinstance(mimic, dict):
        raise spec.error(where, f"got {show(mimic)}; expected a mapping with joint, multiplier, offset")
    known_keys(spec, mimic, where, MIMIC_KEYS)
    if kind == "fixed":
        raise spec.error(where, "a fixed joint cannot mimic another; give it a type that moves")
    leader = require(spec, mimic, "joint", f"{where}.joint", str, "the leader joint's name")
    label(spec, leader, f"{where}.joint", "a joint name")
    if leader == name:
        raise spec.error(f"{where}.joint", f"got {show(leader)}; a joint cannot mimic itself")
    numbers = []
    for key, default in (("multiplier", 1.0), ("offset", 0.0)):
        v = mimic.get(key, default)
        if not number(v, MAX_COORDINATE):
            raise spec.error(f"{where}.{key}", f"got {show(v)}; expected a finite number")
        numbers.append(float(v))
    return leader, numbers[0], numbers[1]


def _chain(spec: Document, value: Any, field: str, snap: bool = True) -> Chain:
    if not isinstance(value, dict):
        raise spec.error(field, f"got {show(value)}; expected a chain mapping (name and urdf or joints)")
    known_keys(spec, value, field, CHAIN_KEYS)
    name = require(spec, value, "name", f"{field}.name", str, "a chain name")
    identifier(spec, name, f"{field}.name", "a chain name")
    robot = require(spec, value, "robot", f"{field}.robot", str, "a robot label") if "robot" in value else ""
    if "robot" in value:
        label(spec, robot, f"{field}.robot", "a robot label")
    joints: list[Joint] = []
    if "base" in value:
        joints.append(_placement(spec, value["base"], f"{field}.base", f"{robot or name}_base"))
    if "urdf" in value and "joints" in value:
        raise spec.error(f"{field}.joints", "a chain takes either urdf (with base_link, tip_link) or joints, "
                                            "not both")
    if "urdf" in value:
        urdf = spec.path.parent / require(spec, value, "urdf", f"{field}.urdf", str, "a URDF path")
        base = require(spec, value, "base_link", f"{field}.base_link", str, "the chain's first link")
        tip = require(spec, value, "tip_link", f"{field}.tip_link", str, "the chain's last link")
        try:
            joints += load_chain(urdf, base, tip, snap)
        except SpecError as e:  # say which spec field led to the URDF problem
            field_name = f"{field}.{e.field}" if e.field in ("base_link", "tip_link") else f"{field}.urdf"
            detail = "" if e.field in ("urdf", "base_link", "tip_link") else f"{e.field}: "
            raise spec.error(field_name, f"{e.file}: {detail}{e.message}") from e
    elif "joints" in value:
        for key in URDF_KEYS:
            if key in value:
                raise spec.error(f"{field}.{key}", "only used with urdf; this chain lists its joints")
        listed = require(spec, value, "joints", f"{field}.joints", list, "a list of joints")
        _within(spec, "joints_per_chain", len(listed), f"{field}.joints")
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
    if not snap:  # placements and listed joints keep their numbers as written too
        joints = [replace(j, snap=False) for j in joints]
    measured = _measured(spec, value, field)
    try:
        chain = Chain(name, tuple(joints), robot, measured)
    except ValueError as e:  # the model's own consistency checks
        raise spec.error(field, str(e)) from e
    if chain.dof == 0:
        raise spec.error(field, "has no moving joint")
    return chain


def _measured(spec: Document, value: dict[Any, Any], field: str) -> bool:
    """``measured: true`` marks a chain whose joints are measured inputs (q_m), not variables."""
    measured = value.get("measured", False)
    if not isinstance(measured, bool):
        raise spec.error(f"{field}.measured", f"got {show(measured)}; expected true (the chain's joints are "
                                              f"measured inputs, e.g. a human's hand) or false (a robot's)")
    return measured


def _check_measured(spec: Document, chains: tuple[Chain, ...]) -> None:
    """A measured chain shares no joint with a robot chain, and at least one chain is a robot's."""
    robot = {key: i for i, chain in enumerate(chains) if not chain.measured for key in chain.joint_keys()}
    for i, chain in enumerate(chains):
        shared = [key for key in chain.joint_keys() if key in robot] if chain.measured else []
        if shared:
            k = robot[shared[0]]
            raise spec.error(f"chains[{i}].measured", f"chain {chain.name!r} is measured but shares joint "
                                                      f"{shared[0][1]!r} of robot {shared[0][0]!r} with "
                                                      f"chains[{k}] ({chains[k].name!r}); a measured chain's "
                                                      f"joints are inputs, not variables: give it its own "
                                                      f"robot label")
    if all(chain.measured for chain in chains):
        raise spec.error("chains", "every chain is measured; at least one must be a robot's "
                                   "(measured: false)")


def _within(spec: Document, limit_name: str, count: int, field: str) -> None:
    """A SpecError at ``field`` when ``count`` passes the resource limit ``limit_name`` (gagen.limits)."""
    problem = over_limit(limit_name, count)
    if problem:
        raise spec.error(field, problem)


def _check_kernel_names(spec: Document, chains: tuple[Chain, ...]) -> None:
    """Every chain's kernel names differ from each other and from the system kernels, up to case
    (the C header upper-cases them in its size macros)."""
    system_kernels = SYSTEM_KERNELS + (DUAL_TASK_KERNELS if len(chains) == 2 else ())
    owner = {kernel.lower(): f"the system kernel {kernel!r}" for kernel in system_kernels}
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


def _check_shared_robots(spec: Document, chains: tuple[Chain, ...]) -> None:
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


def _configurations(spec: Document, system: System) -> dict[str, list[float]]:
    data = spec.data.get("configurations", {})
    if not isinstance(data, dict):
        raise spec.error("configurations", f"got {show(data)}; expected a mapping of names to lists of "
                                           f"{system.dof} joint values")
    configurations = {}
    for key, q in data.items():
        field = f"configurations.{key}"
        label(spec, key, field, "a configuration name")
        if not isinstance(q, list) or len(q) != system.dof:
            raise spec.error(field, f"expected a list of {system.dof} numbers (one per joint)")
        for i, v in enumerate(q):
            if not number(v, MAX_COORDINATE):
                joint = "/".join(system.joint_keys[i])
                raise spec.error(f"{field}[{i}]", f"got {show(v)} for joint {joint}; expected a finite "
                                                  f"number within ±{MAX_COORDINATE:g}")
        configurations[key] = [float(v) for v in q]
    return configurations


def load_system(path: str | Path) -> tuple[System, dict[str, list[float]]]:
    """The system of a spec file, and its named reference configurations."""
    spec = Document(Path(path), "a mapping with name, primitive and chains")
    data = spec.data
    known_keys(spec, data, "", TOP_KEYS)
    if data.get("app", "cooperative") != "cooperative":
        raise spec.error("app", f"got {show(data['app'])}; a robot spec is app: cooperative (or has no app)")
    name = require(spec, data, "name", "name", str, "the system's name")
    identifier(spec, name, "name", "the system's name")
    kind = require(spec, data, "primitive", "primitive", str, f"one of {', '.join(KINDS)}")
    if kind not in KINDS:
        raise spec.error("primitive", f"got {show(kind)}; expected one of {', '.join(KINDS)}")
    chains_data = require(spec, data, "chains", "chains", list, "a list of chains")
    need = points_needed(kind)  # more chains than that: the best fit through their points (not for pairs)
    if len(chains_data) < need or (kind == "point_pair" and len(chains_data) > need):
        more = "" if kind == "point_pair" else "; more are fitted"
        raise spec.error("chains", f"a {kind} is spanned by {need} chains (one per point{more}), "
                                   f"got {len(chains_data)}")
    snap = data.get("snap", True)
    if not isinstance(snap, bool):
        raise spec.error("snap", f"got {show(snap)}; expected true (snap rpy angles within 1e-9 of a "
                                 f"multiple of π/4 to it, the default) or false (keep the numbers as "
                                 f"written)")
    _within(spec, "chains", len(chains_data), "chains")
    chains = tuple(_chain(spec, c, f"chains[{i}]", snap) for i, c in enumerate(chains_data))
    _within(spec, "joints_per_system", sum(len(c.joints) for c in chains), "chains")
    _check_kernel_names(spec, chains)
    _check_shared_robots(spec, chains)
    _check_measured(spec, chains)
    try:
        system = System(name, kind, chains)
    except ValueError as e:  # the model's own consistency checks (e.g. shared mimic joints)
        raise spec.error("chains", str(e)) from e
    goals_of(spec)  # a goals section is checked with the rest (gagen.robots.goals reads it)
    return system, _configurations(spec, system)
