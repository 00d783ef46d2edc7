"""URDF import: the serial chain between two links, as gagen ``Joint``s.

Parsing is yourdfpy's (a maintained URDF library; meshes are not loaded). yourdfpy keeps each
joint origin as a 4×4 matrix, so the rpy angles are read back from it; ``Joint``'s exact-constant
folding then snaps them to multiples of π/4 where they are within 1e-9 of one, as URDF files'
90° turns are (``1.57079632679`` becomes exactly π/2). Translations keep the exact doubles of the
file. ``load_chain(..., snap=False)`` (a spec's ``snap: false``) keeps the file's xyz and rpy as
written, unsnapped.

Before yourdfpy sees a file it is checked here: UTF-8 (or declared) XML without entity declarations
(no entity bombs), not a xacro source (no element in the xacro namespace and no ``${...}``
substitution: expand it first; xacro's output, which keeps the ``xmlns:xacro`` declaration, is a
plain URDF and accepted), a ``<robot>`` root, joint and link names
each defined once, and every joint's origin ``xyz``/``rpy`` and ``axis`` three finite numbers with
coordinates within ±``MAX_COORDINATE`` m and angles within ±``MAX_ANGLE`` rad. A chain goes from any
link to any link of the tree: up from the base link to the nearest link above both, each joint
walked against its direction (its inverse: the motion about the reversed axis by the same variable,
then the inverse of its origin as a fixed ``<joint>_inverse``), then down to the tip link. The walks
up from both links refuse links with two parents and kinematic loops (they are bounded by the
number of joints); the chain's joints must be revolute, continuous, prismatic or fixed (a fixed
joint's ``<mimic>`` is ignored), and their names (which become row labels ``robot/joint``) follow
``gagen.names.LABEL_RULE``. Each problem is a ``SpecError`` naming the file, the joint and its line.

``resolve_package_uri`` finds the file a mesh filename (``package://``, ``file://``, relative) names.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from lxml import etree

from gagen.errors import SpecError, read_input
from gagen.limits import check_limit
from gagen.model.kinematics import Joint
from gagen.names import LABEL_RULE, label_problem
from gagen.yaml_document import MAX_ANGLE, MAX_COORDINATE, MIN_AXIS

if TYPE_CHECKING:
    import yourdfpy

Origin = tuple[tuple[float, float, float], tuple[float, float, float]]  # (xyz, rpy) of a joint
_KINDS = {"revolute": "revolute", "continuous": "continuous", "prismatic": "prismatic", "fixed": "fixed"}


def resolve_package_uri(uri: str, urdf_path: str | Path) -> Path | None:
    """The file a URDF's mesh ``filename`` names, or None where it cannot be found.

    ``package://PKG/REL`` (also ``package:///PKG/REL``, as some files write it) is looked for, first,
    beside the URDF: in each folder above it, as ``<folder>/REL`` where the folder is named ``PKG`` (a ROS
    package's own tree: ``ur_description/urdf/ur5.urdf`` names ``package://ur_description/meshes/…``)
    and as ``<folder>/PKG/REL`` (a share folder holding the package: example-robot-data's
    ``package://example-robot-data/robots/…``); then under each root of ``ROS_PACKAGE_PATH`` (as
    ``<root>/PKG/REL``) and each prefix of ``AMENT_PREFIX_PATH`` and ``CMAKE_PREFIX_PATH`` (as
    ``<prefix>/share/PKG/REL``). ``file://PATH`` is that absolute path; a plain filename is relative to
    the URDF's folder. A path with a ``..`` part is not followed (None)."""
    urdf_path = Path(urdf_path)
    if uri.startswith("file://"):
        found = Path(uri[len("file://"):])
        return found if found.is_absolute() and ".." not in found.parts and found.is_file() else None
    if not uri.startswith("package://"):
        if "://" in uri or ".." in Path(uri).parts:
            return None
        found = urdf_path.parent / uri
        return found if found.is_file() else None
    package, _, rest = uri[len("package://"):].lstrip("/").partition("/")
    relative = Path(rest)
    if not package or not rest or relative.is_absolute() or ".." in relative.parts:
        return None
    candidates = []
    here = urdf_path.resolve().parent
    for folder in (here, *here.parents):
        if folder.name == package:
            candidates.append(folder / relative)
        candidates.append(folder / package / relative)
    for variable, share in (("ROS_PACKAGE_PATH", ""), ("AMENT_PREFIX_PATH", "share"),
                            ("CMAKE_PREFIX_PATH", "share")):
        for root in filter(None, os.environ.get(variable, "").split(os.pathsep)):
            candidates.append(Path(root) / share / package / relative)
    return next((c for c in candidates if c.is_file()), None)


def rpy_from_matrix(r: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw with R = Rz(yaw) Ry(pitch) Rx(roll); yaw = 0 at gimbal lock."""
    pitch = math.atan2(-r[2, 0], math.hypot(r[0, 0], r[1, 0]))
    if math.hypot(r[0, 0], r[1, 0]) < 1e-12:  # pitch = ±π/2: only roll ∓ yaw is defined
        return math.atan2(-r[1, 2], r[1, 1]), pitch, 0.0
    return math.atan2(r[2, 1], r[2, 2]), pitch, math.atan2(r[1, 0], r[0, 0])


def _joint_field(name: str) -> str:
    """``joint NAME``, the name quoted when it is not a plain label (it may hold anything)."""
    return f"joint {name}" if label_problem(name) is None else f"joint {name!r}"


def _numbers(path: Path, element: Any, attribute: str, default: str, field: str,
             bound: float) -> tuple[float, float, float]:
    """An ``xyz``/``rpy`` attribute's three numbers; refused unless finite and within ±bound."""
    text = element.get(attribute, default)
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) and abs(v) <= bound for v in values):
        raise SpecError(path, field, f"line {element.sourceline}: {attribute}={text!r}; expected three "
                                     f"finite numbers within ±{bound:g}")
    return values[0], values[1], values[2]


def _xacro(path: Path, found: str) -> SpecError:
    stem = path.name.removesuffix(".xacro").removesuffix(".urdf")
    target = f"{stem}.urdf" if f"{stem}.urdf" != path.name else f"{stem}_expanded.urdf"
    return SpecError(path, "urdf", f"a xacro file, not a URDF ({found}): expand it first, e.g. "
                                   f"`xacro {path.name} > {target}`, and name the result in the spec")


def _refuse_xacro(path: Path, root: Any) -> None:
    """Refuse an unexpanded xacro source: an element in the xacro namespace, or a ``${...}`` left in an
    attribute. xacro's *output* keeps the ``xmlns:xacro`` declaration (and may keep comments naming
    xacro elements); it is a plain URDF and passes."""
    for element in root.iter():
        if not isinstance(element.tag, str):  # comments and processing instructions
            continue
        namespace = etree.QName(element).namespace or ""
        if "xacro" in namespace or element.prefix == "xacro":
            raise _xacro(path, f"line {element.sourceline}: <xacro:{etree.QName(element).localname}>")
        for attribute, value in element.attrib.items():
            if "${" in value or "$(" in value:
                raise _xacro(path, f"line {element.sourceline}: {attribute}={value!r}, a xacro substitution")


def _check_xml(path: Path, data: bytes) -> tuple[dict[str, int], dict[str, Origin]]:
    """Check the raw file (see the module docstring); the line and the origin (xyz, rpy as written) of
    each joint by name."""
    if b"<!ENTITY" in data:
        raise SpecError(path, "urdf", "XML entity declarations (<!ENTITY) are not supported in URDF files")
    parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False)
    try:
        root = etree.fromstring(data, parser)
    except etree.XMLSyntaxError as e:
        if b"<xacro:" in data:  # an element of the undeclared xacro prefix
            raise _xacro(path, "a <xacro:...> element") from e
        line, column = e.position
        raise SpecError(path, "urdf", f"not a readable URDF: malformed XML at line {line}, column {column} "
                                      f"({e.msg})") from e
    except (ValueError, etree.LxmlError) as e:
        raise SpecError(path, "urdf", f"not a readable URDF ({type(e).__name__}: {e})") from e
    if root.tag != "robot":
        raise SpecError(path, "urdf", f"the root element is <{root.tag}>; expected <robot>")
    _refuse_xacro(path, root)
    lines: dict[str, int] = {}
    for kind in ("link", "joint"):
        seen: dict[str, int] = {}
        for element in root.findall(kind):
            name = element.get("name")
            if name is None:
                raise SpecError(path, kind, f"line {element.sourceline}: a <{kind}> without a name")
            if name in seen:
                raise SpecError(path, f"{kind} {name!r}" if kind == "link" else _joint_field(name),
                                f"defined twice (lines {seen[name]} and {element.sourceline}); "
                                f"{kind} names must differ")
            seen[name] = element.sourceline
        if kind == "joint":
            lines = seen
    origins: dict[str, Origin] = {}
    for element in root.findall("joint"):
        field = _joint_field(element.get("name"))
        origin = element.find("origin")
        if origin is not None:
            origins[element.get("name")] = (
                _numbers(path, origin, "xyz", "0 0 0", f"{field}: origin", MAX_COORDINATE),
                _numbers(path, origin, "rpy", "0 0 0", f"{field}: origin", MAX_ANGLE))
        axis = element.find("axis")
        if axis is not None:
            _numbers(path, axis, "xyz", "1 0 0", f"{field}: axis", MAX_COORDINATE)
    return lines, origins


def _check_label(path: Path, name: Any, line: int | None) -> None:
    if not isinstance(name, str) or label_problem(name):
        raise SpecError(path, _joint_field(str(name)),
                        f"line {line}: the joint name {name!r} becomes a row label (robot/joint) in the "
                        f"generated code; expected {LABEL_RULE}")


def _load(path: Path) -> tuple[yourdfpy.URDF, dict[str, int], dict[str, Origin]]:
    """The yourdfpy model of a checked file, and each joint's line and origin as written."""
    import yourdfpy

    data = read_input(path, "urdf")
    lines, origins = _check_xml(path, data)  # yourdfpy's parser recovers from broken XML silently
    try:
        urdf = yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False,
                                  build_collision_scene_graph=False, load_collision_meshes=False)
    except Exception as e:  # yourdfpy/lxml raise many types for malformed XML
        raise SpecError(path, "urdf", f"not a readable URDF ({type(e).__name__}: {e})") from e
    return urdf, lines, origins


def load_chain(path: str | Path, base_link: str, tip_link: str, snap: bool = True) -> list[Joint]:
    """The joints from ``base_link`` to ``tip_link`` (fixed joints included), in order: down the tree, or
    up it and down again (see the module docstring).

    ``snap`` (the default) lets the kinematics snap rpy angles within 1e-9 of a multiple of π/4 to
    it (``gagen.model.kinematics.exact_angle``); ``snap=False`` keeps every origin number as the file
    writes it (the rpy angles are then the file's, not read back from yourdfpy's matrix)."""
    path = Path(path)
    urdf, lines, origins = _load(path)
    robot = urdf.robot
    links = {link.name for link in robot.links}
    for field, link in (("base_link", base_link), ("tip_link", tip_link)):
        if link not in links:
            raise SpecError(path, field, f"no link named {link!r}; links are: {', '.join(sorted(links))}")
    parent_joint: dict[str, yourdfpy.Joint] = {}
    for j in robot.joints:
        if j.child in parent_joint:
            other = parent_joint[j.child]
            raise SpecError(path, _joint_field(j.name),
                            f"line {lines.get(j.name)}: link {j.child!r} already has the parent joint "
                            f"{other.name!r} (line {lines.get(other.name)}); a URDF is a tree, each link "
                            f"has at most one parent")
        parent_joint[j.child] = j

    def ancestry(link: str) -> list[yourdfpy.Joint]:
        """The joints from ``link`` up to its tree's root (each joint visited once: the walk is bounded)."""
        chain: list[yourdfpy.Joint] = []
        while link in parent_joint:
            joint = parent_joint[link]
            if any(joint is seen for seen in chain):
                first = next(i for i, seen in enumerate(chain) if seen is joint)
                loop = " -> ".join(j.name for j in [*chain[first:], joint])
                raise SpecError(path, _joint_field(joint.name), f"line {lines.get(joint.name)}: a kinematic "
                                                                f"loop ({loop}); a URDF is a tree")
            chain.append(joint)
            link = joint.parent
        return chain

    # the chain goes up from base_link to the nearest link above both, then down to tip_link
    above_tip, above_base = ancestry(tip_link), ancestry(base_link)
    tip_links = [tip_link, *(j.parent for j in above_tip)]
    base_links = [base_link, *(j.parent for j in above_base)]
    common = next((link for link in base_links if link in tip_links), None)
    if common is None:
        raise SpecError(path, "tip_link", f"{tip_link!r} and {base_link!r} are not connected in the "
                                          f"kinematic tree (they have no common ancestor link)")
    up, down = above_base[:base_links.index(common)], above_tip[:tip_links.index(common)]
    check_limit("joints_per_chain", len(up) + len(down), path, "tip_link")
    joints = []
    for j in up:  # traversed from child to parent: the inverse of each joint's transform
        joints += _inverse(_joint(path, robot, j, lines, origins, snap))
    for j in reversed(down):
        joints.append(_joint(path, robot, j, lines, origins, snap))
    return joints


def _joint(path: Path, robot: yourdfpy.Robot, j: yourdfpy.Joint, lines: dict[str, int],
           origins: dict[str, Origin], snap: bool) -> Joint:
    """One URDF joint as a checked ``Joint``."""
    field = _joint_field(j.name)
    _check_label(path, j.name, lines.get(j.name))
    if j.type in ("floating", "planar"):
        raise SpecError(path, field, f"line {lines.get(j.name)}: floating/planar joints are not "
                                     f"supported; a chain is made of 1-DOF joints (revolute, continuous, "
                                     f"prismatic) and fixed ones: choose base_link below it")
    if j.type not in _KINDS:
        raise SpecError(path, field, f"type {j.type!r} is not supported; expected one of "
                                     f"{', '.join(_KINDS)}")
    origin = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float)
    axis = (1.0, 0.0, 0.0) if j.axis is None else tuple(float(a) for a in j.axis)  # URDF default
    if origin.shape != (4, 4) or not np.isfinite(origin).all() or len(axis) != 3:
        raise SpecError(path, field, f"line {lines.get(j.name)}: origin and axis must be finite "
                                     f"(three numbers each)")
    if j.type != "fixed":
        norm = math.sqrt(sum(a * a for a in axis))
        if norm < MIN_AXIS:
            raise SpecError(path, f"{field}: axis", f"line {lines.get(j.name)}: a non-zero axis vector "
                                                    f"(length at least {MIN_AXIS:g})")
        axis = (axis[0] / norm, axis[1] / norm, axis[2] / norm)
    try:  # Joint's own checks (e.g. on a mimic), as an error naming the file and the joint
        xyz = (float(origin[0, 3]), float(origin[1, 3]), float(origin[2, 3]))
        rpy = rpy_from_matrix(origin[:3, :3])
        if not snap:  # the numbers as written (the same transform: R = Rz(yaw) Ry(pitch) Rx(roll))
            xyz, rpy = origins.get(j.name, ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
        # a fixed joint has no value to follow: its <mimic> (left by tools that weld joints, as in
        # example-robot-data's talos_reduced.urdf) is ignored, as Pinocchio and urdfdom do
        mimic = _mimic(path, robot, j) if j.type != "fixed" else None
        joint = Joint(j.name, _KINDS[j.type], xyz, rpy, axis, mimic=mimic, limits=_limits(j), snap=snap)
    except ValueError as e:
        raise SpecError(path, field, f"line {lines.get(j.name)}: {e}") from e
    if joint.mimic is not None:  # the leader's name labels the chain's joint variable
        _check_label(path, joint.mimic[0], lines.get(joint.mimic[0]))
    return joint


def _rotation(rpy: tuple[float, float, float]) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll)."""
    (cr, cp, cy), (sr, sp, sy) = np.cos(rpy), np.sin(rpy)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _inverse(joint: Joint) -> list[Joint]:
    """A joint walked from its child link to its parent: (F M(q))⁻¹ = M(q)⁻¹ F⁻¹, the motion about (along)
    the reversed axis by the same variable, then the fixed transform F⁻¹ (named ``<joint>_inverse`` after
    a moving joint, whose name stays the variable's)."""
    r = _rotation(joint.rpy)
    p = -r.T @ np.array(joint.xyz)
    fixed = Joint(joint.name if not joint.moves else f"{joint.name}_inverse", "fixed",
                  (float(p[0]), float(p[1]), float(p[2])), rpy_from_matrix(r.T), snap=joint.snap)
    if not joint.moves:
        return [fixed]
    reversed_axis = (-joint.axis[0], -joint.axis[1], -joint.axis[2])
    return [Joint(joint.name, joint.kind, axis=reversed_axis, mimic=joint.mimic, limits=joint.limits,
                  snap=joint.snap), fixed]


def _limits(joint: yourdfpy.Joint) -> tuple[float, float] | None:
    """(lower, upper) of a revolute or prismatic joint's <limit>, when both are finite and ordered."""
    limit = getattr(joint, "limit", None)
    if joint.type not in ("revolute", "prismatic") or limit is None:
        return None
    lower, upper = getattr(limit, "lower", None), getattr(limit, "upper", None)
    if lower is None or upper is None:
        return None
    if not (math.isfinite(lower) and math.isfinite(upper) and lower < upper):
        return None
    return float(lower), float(upper)


def _mimic(path: Path, robot: yourdfpy.Robot, joint: yourdfpy.Joint) -> tuple[str, float, float] | None:
    """A joint's ``<mimic>`` as (leader, multiplier, offset), a chain of mimics resolved to its first
    leader (q = m1 (m2 q_leader + o2) + o1); a missing, fixed or cyclic leader is a SpecError."""
    by_name = {j.name: j for j in robot.joints}
    multiplier, offset, seen, current = 1.0, 0.0, [joint.name], joint
    while current.mimic is not None:
        m = 1.0 if current.mimic.multiplier is None else float(current.mimic.multiplier)
        o = 0.0 if current.mimic.offset is None else float(current.mimic.offset)
        field = f"joint {joint.name}: mimic"
        if not (math.isfinite(m) and math.isfinite(o)):
            raise SpecError(path, field, f"finite multiplier and offset, got {m} and {o}")
        multiplier, offset = multiplier * m, multiplier * o + offset
        leader = by_name.get(current.mimic.joint)
        if leader is None:
            raise SpecError(path, field, f"the name of a joint of this robot; there is no joint "
                                         f"{current.mimic.joint!r}")
        if leader.name in seen:
            raise SpecError(path, field, f"a mimic leader, but mimics form a loop: "
                                         f"{' -> '.join([*seen, leader.name])}")
        if leader.type not in ("revolute", "continuous", "prismatic"):
            raise SpecError(path, field, f"a revolute, continuous or prismatic leader; {leader.name!r} "
                                         f"is {leader.type}")
        seen.append(leader.name)
        current = leader
    return None if current is joint else (current.name, multiplier, offset)
