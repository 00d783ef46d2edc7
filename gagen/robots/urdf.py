"""URDF import: the serial chain between two links, as gagen ``Joint``s.

Parsing is yourdfpy's (a maintained URDF library; meshes are not loaded). yourdfpy keeps each
joint origin as a 4×4 matrix, so the rpy angles are read back from it; ``Joint``'s exact-constant
folding then snaps them to multiples of π/4 where they are within 1e-9 of one, as URDF files'
90° turns are. Translations keep the exact doubles of the file.
"""

from __future__ import annotations

import math
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from gagen.errors import SpecError
from gagen.model.kinematics import Joint

_KINDS = {"revolute": "revolute", "continuous": "continuous", "prismatic": "prismatic", "fixed": "fixed"}


def rpy_from_matrix(r: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw with R = Rz(yaw) Ry(pitch) Rx(roll); yaw = 0 at gimbal lock."""
    pitch = math.atan2(-r[2, 0], math.hypot(r[0, 0], r[1, 0]))
    if math.hypot(r[0, 0], r[1, 0]) < 1e-12:  # pitch = ±π/2: only roll ∓ yaw is defined
        return math.atan2(-r[1, 2], r[1, 1]), pitch, 0.0
    return math.atan2(r[2, 1], r[2, 2]), pitch, math.atan2(r[1, 0], r[0, 0])


def _load(path: Path):
    import yourdfpy

    if not path.is_file():
        raise SpecError(path, "urdf", "file not found")
    try:  # yourdfpy's parser recovers from broken XML silently; refuse it first, with its position
        ElementTree.parse(path)
    except ElementTree.ParseError as e:
        line, column = e.position
        raise SpecError(path, "urdf",
                        f"not a readable URDF: malformed XML at line {line}, column {column}") from e
    try:
        return yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False,
                                  build_collision_scene_graph=False, load_collision_meshes=False)
    except Exception as e:  # yourdfpy/lxml raise many types for malformed XML
        raise SpecError(path, "urdf", f"not a readable URDF ({type(e).__name__}: {e})") from e


def load_chain(path: str | Path, base_link: str, tip_link: str) -> list[Joint]:
    """The joints from ``base_link`` to ``tip_link`` (fixed joints included), in order."""
    path = Path(path)
    robot = _load(path).robot
    links = {link.name for link in robot.links}
    for field, link in (("base_link", base_link), ("tip_link", tip_link)):
        if link not in links:
            raise SpecError(path, field, f"no link named {link!r}; links are: {', '.join(sorted(links))}")
    parent_joint = {j.child: j for j in robot.joints}
    chain = []
    link = tip_link
    while link != base_link:
        if link not in parent_joint:
            raise SpecError(path, "tip_link",
                            f"{tip_link!r} is not below {base_link!r} in the kinematic tree")
        joint = parent_joint[link]
        chain.append(joint)
        link = joint.parent
    joints = []
    for j in reversed(chain):
        if j.type not in _KINDS:
            raise SpecError(path, f"joint {j.name}", f"type {j.type!r} is not supported; expected one of "
                                                      f"{', '.join(_KINDS)}")
        origin = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float)
        axis = (1.0, 0.0, 0.0) if j.axis is None else tuple(float(a) for a in j.axis)  # URDF default
        if j.type != "fixed":
            norm = math.sqrt(sum(a * a for a in axis))
            if norm == 0:
                raise SpecError(path, f"joint {j.name}: axis", "a non-zero axis vector")
            axis = tuple(a / norm for a in axis)
        joints.append(Joint(j.name, _KINDS[j.type], tuple(float(v) for v in origin[:3, 3]),
                            rpy_from_matrix(origin[:3, :3]), axis))
    return joints
