"""The robots' looks: each link's URDF ``<visual>`` geometry (meshes and primitive shapes), placed per link.

``load_visuals(spec_path, system)`` reads each URDF chain of a spec (``chains[i].urdf``, relative to the
spec) and returns, per chain, a :class:`ChainVisuals`: the links it draws — the links on the way from
``base_link`` to ``tip_link`` and what hangs rigidly from them (fixed joints: a hand on the flange) — each
with its visuals (box, cylinder, sphere, or a mesh read by trimesh: STL, OBJ, DAE, …, scaled as the URDF
says), their origins and colours. ``ChainVisuals.link_frames(values)`` places the links for the chain's
joint values (the URDF's own joint origins and axes from ``base_link``, after the spec's ``base``
placement), the poses the chain's FK gives its joint frames.

Mesh paths are resolved relative to the URDF file, as ``file://`` URIs, or as ``package://NAME/rest``:
the folder named NAME among the URDF's ancestors (or a NAME folder beside one of them, or in a
``ROS_PACKAGE_PATH`` entry). A mesh that is missing or unreadable is one warning line (``warn``) and that
link is drawn as a stick as well; a chain given by explicit joints, or a URDF without visuals, has no
``ChainVisuals`` (None): the viewer draws it as sticks.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.robots.system import System
from gagen.viewer.geometry import _transform, rotation, rpy_matrix

Array = NDArray[np.float64]
DEFAULT_COLOUR = (150, 160, 175)  # a visual without a material: a blue-grey that shows on white
Warn = Callable[[str], None]


def _stderr(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr)


@dataclass(frozen=True)
class Visual:
    """One ``<visual>``: ``kind`` box (``size`` = x, y, z), cylinder (radius, length, along z), sphere
    (radius,) or mesh (``vertices`` (n, 3), scaled, and ``faces`` (m, 3)); ``origin`` (4, 4) in the link's
    frame; ``colour`` RGB 0–255 and ``opacity`` (None: opaque)."""

    kind: str
    origin: Array
    colour: tuple[int, int, int] = DEFAULT_COLOUR
    opacity: float | None = None
    size: tuple[float, ...] = ()
    vertices: Array | None = None
    faces: NDArray[np.int64] | None = None

    def corners(self) -> Array:
        """(8, 3): the corners of its bounding box, in the link's frame."""
        if self.kind == "mesh":
            assert self.vertices is not None
            low, high = self.vertices.min(axis=0), self.vertices.max(axis=0)
        else:
            if self.kind == "box":
                half = 0.5 * np.asarray(self.size)
            elif self.kind == "cylinder":
                half = np.array([self.size[0], self.size[0], 0.5 * self.size[1]])
            else:
                half = np.full(3, self.size[0])
            low, high = -half, half
        box = np.array([[(low, high)[i][0], (low, high)[j][1], (low, high)[k][2]]
                        for i in (0, 1) for j in (0, 1) for k in (0, 1)])
        placed: Array = box @ self.origin[:3, :3].T + self.origin[:3, 3]
        return placed


@dataclass(frozen=True)
class _Step:
    """One joint crossed on the way from the base link: ``down`` from its parent to its child (else up)."""

    joint: str
    kind: str
    origin: Array
    axis: Array
    down: bool


@dataclass(frozen=True)
class ChainVisuals:
    """A chain's drawn links (see the module docstring). ``links`` maps a link's name to its visuals;
    ``sticks`` holds, per joint of the chain (``Chain.joints`` order), the link whose body the viewer's
    stick from that joint's origin draws (None: no URDF link), and ``missing`` the links drawn as sticks
    because a mesh of theirs could not be read."""

    chain: str
    urdf: Path
    base_link: str
    links: Mapping[str, tuple[Visual, ...]]
    sticks: tuple[str | None, ...]
    missing: frozenset[str]
    base: Array  # base_link's pose in the system's frame (the spec's base placement)
    _paths: Mapping[str, tuple[_Step, ...]] = field(repr=False)
    _mimics: Mapping[str, tuple[str, float, float]] = field(repr=False)

    def covered(self, link: str | None) -> bool:
        """Whether ``link``'s body is drawn from its visuals (so its stick is not)."""
        return link is not None and link in self.links and link not in self.missing

    def link_frames(self, values: Mapping[str, float]) -> dict[str, Array]:
        """Each drawn link's pose (4, 4) in the system's frame, for the joint values by URDF joint name
        (joints not given: their URDF mimic leader's, else 0)."""

        def value(name: str) -> float:
            if name in values:
                return float(values[name])
            if name in self._mimics:
                leader, multiplier, offset = self._mimics[name]
                return multiplier * float(values.get(leader, 0.0)) + offset
            return 0.0

        frames: dict[str, Array] = {}
        for link, path in self._paths.items():
            t = self.base.copy()
            for step in path:
                motion = np.eye(4)
                if step.kind in ("revolute", "continuous"):
                    motion[:3, :3] = rotation(tuple(step.axis), value(step.joint))
                elif step.kind == "prismatic":
                    motion[:3, 3] = value(step.joint) * step.axis
                m = step.origin @ motion
                t = t @ (m if step.down else np.linalg.inv(m))
            frames[link] = t
        return frames


# -- mesh files ------------------------------------------------------------------------------------
def _package_roots() -> list[Path]:
    return [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]


def resolve_mesh_path(uri: str, urdf_path: Path) -> Path | None:
    """The file a URDF mesh ``filename`` names (see the module docstring), or None when none exists."""
    from gagen.robots import urdf as robots_urdf

    shared = getattr(robots_urdf, "resolve_package_uri", None)  # the URDF intake's, where it exists
    if shared is not None and uri.startswith("package://"):
        try:
            found = shared(uri, urdf_path)
        except Exception:  # its own refusal: fall back to the search below
            found = None
        if found is not None and Path(found).is_file():
            return Path(found).resolve()
    here = urdf_path.resolve().parent
    if uri.startswith("file://"):
        candidates = [Path(uri[len("file://"):])]
    elif uri.startswith("package://"):
        package, _, rest = uri[len("package://"):].partition("/")
        ancestors = [here, *here.parents]
        candidates = [a / rest for a in ancestors if a.name == package]
        candidates += [a / package / rest for a in [*ancestors, *_package_roots()]]
    else:
        candidates = [here / uri]
    return next((c.resolve() for c in candidates if c.is_file()), None)


def _file_colour(mesh: Any) -> tuple[int, int, int] | None:
    """The main colour a mesh file gives its triangles (a DAE's material, an OBJ's), if any but trimesh's
    default grey."""
    try:
        visual = mesh.visual
        colour = visual.material.main_color if visual.kind == "texture" else visual.main_color
        rgb = tuple(int(v) for v in np.asarray(colour).reshape(-1)[:3])
    except Exception:  # no visual, or a material without a colour
        return None
    return None if len(rgb) != 3 or rgb == (102, 102, 102) else (rgb[0], rgb[1], rgb[2])


def _mesh(path: Path, scale: Any) -> tuple[Array, NDArray[np.int64], tuple[int, int, int] | None]:
    """(vertices scaled, faces, the file's own colour or None) of a mesh file."""
    import trimesh

    mesh: Any = trimesh.load(str(path), force="mesh")
    vertices: Array = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if vertices.ndim != 2 or len(vertices) == 0 or len(faces) == 0:
        raise ValueError("no triangles")
    if scale is not None:
        vertices = vertices * np.broadcast_to(np.asarray(scale, dtype=np.float64).reshape(-1), (3,))
    return vertices, faces, _file_colour(mesh)


# -- URDF ------------------------------------------------------------------------------------------
def _colour(visual: Any, materials: Mapping[str, Any]) -> tuple[tuple[int, int, int] | None, float | None]:
    """The visual's URDF material colour (RGB 0-255; None: none given) and opacity (None: opaque)."""
    material = getattr(visual, "material", None)
    color = getattr(material, "color", None)
    if color is None and material is not None and getattr(material, "name", None) in materials:
        color = getattr(materials[material.name], "color", None)
    rgba = getattr(color, "rgba", None)
    if rgba is None:
        return None, None
    r, g, b, a = (float(v) for v in np.asarray(rgba, dtype=float).reshape(-1)[:4])
    colour = tuple(round(255 * min(1.0, max(0.0, v))) for v in (r, g, b))
    return (colour[0], colour[1], colour[2]), (None if a >= 0.999 else max(0.05, a))


def _visuals(link: Any, urdf_path: Path, materials: Mapping[str, Any], meshes: dict[tuple[Path, str], Any],
             warn: Warn) -> tuple[list[Visual], bool]:
    """A link's visuals, and whether all of them could be read."""
    drawn: list[Visual] = []
    complete = True
    for visual in getattr(link, "visuals", None) or ():
        geometry = visual.geometry
        origin = np.eye(4) if visual.origin is None else np.asarray(visual.origin, dtype=float)
        colour, opacity = _colour(visual, materials)
        common: dict[str, Any] = {"origin": origin, "colour": colour or DEFAULT_COLOUR, "opacity": opacity}
        if geometry is None:
            continue
        if geometry.box is not None:
            drawn.append(Visual("box", size=tuple(float(v) for v in geometry.box.size), **common))
        elif geometry.cylinder is not None:
            drawn.append(Visual("cylinder", size=(float(geometry.cylinder.radius),
                                                  float(geometry.cylinder.length)), **common))
        elif geometry.sphere is not None:
            drawn.append(Visual("sphere", size=(float(geometry.sphere.radius),), **common))
        elif geometry.mesh is not None:
            uri = str(geometry.mesh.filename)
            path = resolve_mesh_path(uri, urdf_path)
            if path is None:
                warn(f"{urdf_path}: link {link.name!r}: mesh {uri!r} not found; the link is drawn as a stick")
                complete = False
                continue
            key = (path, repr(geometry.mesh.scale))
            if key not in meshes:
                try:
                    meshes[key] = _mesh(path, geometry.mesh.scale)
                except Exception as e:  # trimesh raises many types for unreadable files
                    meshes[key] = None
                    warn(f"{urdf_path}: link {link.name!r}: mesh {path} unreadable "
                         f"({type(e).__name__}: {e}); the link is drawn as a stick")
            if meshes[key] is None:
                complete = False
                continue
            vertices, faces, own = meshes[key]
            if colour is None and own is not None:  # no URDF material: the file's own colour
                common["colour"] = own
            drawn.append(Visual("mesh", vertices=vertices, faces=faces, **common))
    return drawn, complete


def _tree_path(joints: Sequence[Any], base: str, tip: str) -> list[tuple[Any, bool]] | None:
    """The joints from link ``base`` to link ``tip`` (up to their common ancestor, then down), each with
    whether it is crossed from parent to child; None when they are not connected."""
    parent = {j.child: j for j in joints}

    def upward(link: str) -> list[Any]:
        chain: list[Any] = []
        while link in parent and len(chain) <= len(joints):
            chain.append(parent[link])
            link = parent[link].parent
        return chain

    up_base, up_tip = upward(base), upward(tip)
    ancestors_base = [base] + [j.parent for j in up_base]
    ancestors_tip = [tip] + [j.parent for j in up_tip]
    common = next((a for a in ancestors_base if a in ancestors_tip), None)
    if common is None:
        return None
    i, k = ancestors_base.index(common), ancestors_tip.index(common)
    return [(j, False) for j in up_base[:i]] + [(j, True) for j in reversed(up_tip[:k])]


def _step(joint: Any, down: bool) -> _Step:
    origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin, dtype=float)
    axis = np.array([1.0, 0.0, 0.0]) if joint.axis is None else np.asarray(joint.axis, dtype=float)
    norm = float(np.linalg.norm(axis))
    return _Step(joint.name, str(joint.type), origin, axis / norm if norm > 0 else axis, down)


def chain_visuals(system: System, index: int, urdf_path: Path, base_link: str, tip_link: str, *,
                  warn: Warn = _stderr, cache: dict[Any, Any] | None = None) -> ChainVisuals | None:
    """The visuals of chain ``index`` of ``system``, read from the URDF it was built from; None when the
    URDF has no visuals on the chain's links (or its joints do not match the chain's)."""
    import yourdfpy

    cache = {} if cache is None else cache
    chain = system.chains[index]
    key = ("urdf", urdf_path.resolve())
    if key not in cache:
        cache[key] = yourdfpy.URDF.load(str(urdf_path), build_scene_graph=False, load_meshes=False,
                                        build_collision_scene_graph=False, load_collision_meshes=False).robot
    robot = cache[key]
    joints = list(robot.joints)
    path = _tree_path(joints, base_link, tip_link)
    if path is None:
        warn(f"{urdf_path}: no path from {base_link!r} to {tip_link!r}; chain {chain.name} is drawn as "
             f"sticks")
        return None
    # the links drawn: those on the path, and what hangs from them through fixed joints
    paths: dict[str, tuple[_Step, ...]] = {base_link: ()}
    after: dict[str, str] = {}  # URDF joint on the path -> the link it leads to
    for j, down in path:
        here = j.parent if down else j.child
        there = j.child if down else j.parent
        paths[there] = (*paths[here], _step(j, down))
        after[j.name] = there
    children: dict[str, list[Any]] = {}
    for j in joints:
        children.setdefault(j.parent, []).append(j)
    frontier = list(paths)
    while frontier:
        link = frontier.pop()
        for j in children.get(link, ()):
            if j.type == "fixed" and j.child not in paths:
                paths[j.child] = (*paths[link], _step(j, True))
                frontier.append(j.child)
    materials = {m.name: m for m in getattr(robot, "materials", None) or () if getattr(m, "name", None)}
    by_name = {link.name: link for link in robot.links}
    meshes = cache.setdefault("meshes", {})
    links: dict[str, tuple[Visual, ...]] = {}
    missing: set[str] = set()
    for name in paths:
        drawn, complete = _visuals(by_name[name], urdf_path, materials, meshes, warn)
        if drawn:
            links[name] = tuple(drawn)
        if not complete:
            missing.add(name)
    if not links:
        return None
    # each chain joint's stick: the link after it (the spec's base placement: the base link's)
    names = [j.name for j in chain.joints]
    first = next((i for i, n in enumerate(names) if n in after), None)
    if first is None:
        warn(f"{urdf_path}: chain {chain.name}'s joints are not the URDF's; it is drawn as sticks")
        return None
    base = np.eye(4)
    for joint in chain.joints[:first]:  # the spec's base placement (fixed)
        base = base @ _transform(rpy_matrix(joint.rpy), joint.xyz)
    sticks: list[str | None] = []
    current = base_link
    for i, n in enumerate(names):
        current = after.get(n, current) if i >= first else base_link
        sticks.append(current)
    mimics = {j.name: (j.mimic.joint, float(j.mimic.multiplier or 1.0), float(j.mimic.offset or 0.0))
              for j in joints if getattr(j, "mimic", None) is not None}
    return ChainVisuals(chain.name, urdf_path, base_link, links, tuple(sticks), frozenset(missing), base,
                        {n: p for n, p in paths.items() if n in links}, mimics)


def load_visuals(spec_path: str | Path, system: System, *, warn: Warn = _stderr) -> list[ChainVisuals | None]:
    """Per chain of ``system`` (loaded from ``spec_path``), its visuals, or None (drawn as sticks)."""
    import yaml

    spec_path = Path(spec_path)
    data = yaml.safe_load(spec_path.read_text(encoding="utf-8"))
    chains = data.get("chains", []) if isinstance(data, dict) else []
    result: list[ChainVisuals | None] = []
    cache: dict[Any, Any] = {}
    for i in range(len(system.chains)):
        entry = chains[i] if i < len(chains) and isinstance(chains[i], dict) else {}
        if not all(isinstance(entry.get(k), str) for k in ("urdf", "base_link", "tip_link")):
            result.append(None)
            continue
        try:
            result.append(chain_visuals(system, i, spec_path.parent / entry["urdf"], entry["base_link"],
                                        entry["tip_link"], warn=warn, cache=cache))
        except Exception as e:  # a look is never worth a crash: sticks, and say why
            warn(f"{spec_path}: chains[{i}]: visuals not read ({type(e).__name__}: {e}); drawn as sticks")
            result.append(None)
    return result


def chain_joint_values(system: System, q: Sequence[float]) -> list[dict[str, float]]:
    """Per chain, each moving joint's value by name (mimic followers included), for ``link_frames``."""
    per_chain = system.joint_values(list(q))
    return [{j.name: float(v) for j, v in zip([j for j in chain.joints if j.moves], values, strict=True)}
            for chain, values in zip(system.chains, per_chain, strict=True)]

