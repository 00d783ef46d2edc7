"""A cooperative system in the browser: its robots and its primitive, live, through a viser server.

``Scene(system)`` starts a viser server (on the loopback interface only, and only to the holder of the
per-run token in ``scene.url``: ``gagen.viewer.access``) and draws every chain of the system — a link
as a grey cylinder between consecutive joint origins, a moving joint as an orange ball, the base and
end frames as small axes — and the primitive through the chains' end points (``gagen.viewer.geometry``)
in ``PRIMITIVE_COLOUR``, a colour nothing else in the scene uses. ``update(q)`` redraws for a
configuration; ``play(times, qs)`` plays a joint trajectory in real time (the one mechanism the demos
share: the reach OCP's optimal trajectory, the nullspace runs, teleoperation and impedance simulations
alike). Open ``scene.url`` in a browser, or take a headless render with ``gagen.viewer.browser``.

Given ``visuals`` (``gagen.viewer.visuals.load_visuals``: the URDFs' ``<visual>`` meshes and shapes), a
link with visuals is drawn from them, placed at the link's pose along its chain, and its stick and joint
ball are left out; links without visuals (or whose mesh files could not be read) stay sticks. Given a
``goal`` (a ``geometry.Shape``: ``geometry.goal_shape``, ``geometry.moved``), its target primitive is
drawn too, in ``GOAL_COLOUR``.

    with Scene(system, port=8080) as scene:
        scene.play(result.t, result.q, loop=True)
"""

from __future__ import annotations

import contextlib
import ipaddress
import math
import threading
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.extras import MissingExtra
from gagen.robots.system import System
from gagen.viewer import DEFAULT_PORT, access
from gagen.viewer.camera import Camera, framing
from gagen.viewer.geometry import (
    ChainPose,
    Shape,
    aligning,
    basis,
    polylines,
    quaternion,
    segments,
    shape,
    system_pose,
)
from gagen.viewer.visuals import ChainVisuals, Visual, chain_joint_values

if TYPE_CHECKING:
    from viser import SceneNodeHandle  # the optional dependency: imported where it is needed

PRIMITIVE_COLOUR = (255, 0, 255)  # magenta: no robot part uses it (frames are red, green, blue)
GOAL_COLOUR = (0, 170, 200)  # cyan-blue: the target primitive, apart from the current one
LINK_COLOUR = (205, 210, 220)
JOINT_COLOUR = (245, 140, 40)
BASE_COLOUR = (70, 70, 80)
FPS = 30.0  # play() shows at most this many configurations per second, whatever the trajectory's rate
Frames = Literal["none", "ends", "all"]


def loopback(host: str) -> str:
    """``host`` if it is a loopback address (or ``localhost``); ValueError otherwise: the viewer's
    server has no authentication beyond its URL's token, so it must not listen where other machines
    can reach it."""
    if host == "localhost":
        return host
    try:
        if ipaddress.ip_address(host).is_loopback:
            return host
    except ValueError:
        pass
    raise ValueError(f"viewer host {host!r}: the server only listens on a loopback address "
                     f"(127.0.0.1, ::1 or localhost)")


def _sizes(poses: Sequence[ChainPose]) -> tuple[float, float]:
    """(link radius, frame axes length), scaled to the robots: a hand's links are centimetres long."""
    lengths = [float(d) for pose in poses for d in np.linalg.norm(np.diff(pose.origins, axis=0), axis=1)
               if d > 1e-6]
    typical = float(np.median(lengths)) if lengths else 0.1
    radius = min(0.03, max(0.002, 0.12 * typical))
    return radius, 6.0 * radius


class Scene:
    """The viewer of one system; see the module docstring. ``port`` 0 picks a free one (``url`` says
    which); ``frames``: draw axes at each chain's base and end ("ends"), at every joint ("all") or none."""

    def __init__(self, system: System, q: ArrayLike | None = None, *, host: str = "127.0.0.1",
                 port: int = DEFAULT_PORT, frames: Frames = "ends", label: str | None = None,
                 visuals: Sequence[ChainVisuals | None] | None = None, goal: Shape | None = None) -> None:
        try:  # the optional dependency, imported where it is needed
            import viser
        except ModuleNotFoundError as e:
            raise MissingExtra("viser", "gagen.viewer") from e

        if frames not in ("none", "ends", "all"):
            raise ValueError(f"frames {frames!r}: expected 'none', 'ends' or 'all'")
        if not 0 <= port <= 65535:
            raise ValueError(f"port {port}: expected 0 (any free port) to 65535")
        self.system = system
        self.host = loopback(host)
        self.frames = frames
        self.q = np.zeros(system.dof) if q is None else self._check(q)
        if visuals is not None and len(visuals) != len(system.chains):
            raise ValueError(f"visuals: one entry (or None) per chain of {system.name}, "
                             f"{len(system.chains)}; got {len(visuals)}")
        self.visuals: list[ChainVisuals | None] = list(visuals) if visuals is not None else \
            [None] * len(system.chains)
        # a token-guarded server (gagen.viewer.access): loopback alone leaves it open to any web page
        self.token = access.new_token()
        with access.guarded(access.Guard(self.token)) as wrapped:
            self.server = viser.ViserServer(host=self.host, port=port, label=label or system.name,
                                            verbose=False)
        if not wrapped:  # this viser starts its server some other way: refuse to serve unguarded
            self.server.stop()
            raise RuntimeError(f"viser {viser.__version__}: cannot put the viewer's access check in front "
                               f"of its server (gagen.viewer.access)")
        self.server.scene.set_up_direction("+z")
        self._lock = threading.Lock()  # update() from a play thread and a GUI callback
        self._primitive_visible = True
        self._goal: list[SceneNodeHandle] = []
        self.goal: Shape | None = None
        self._build()
        self.show_goal(goal)
        self.camera = self.default_camera()
        self.set_camera(self.camera)
        self._status = self.server.gui.add_markdown(f"**{system.name}**: {system.kind}, {system.dof} DOF")
        self._toggle = self.server.gui.add_checkbox("primitive", initial_value=True)
        self._toggle.on_update(lambda _: self._set_primitive_visible(bool(self._toggle.value)))

    # -- lifecycle -----------------------------------------------------------------------------------
    @property
    def port(self) -> int:
        return self.server.get_port()

    @property
    def url(self) -> str:
        """The page's address, with the token that lets a browser in (``gagen.viewer.access``)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/?token={self.token}"

    def close(self) -> None:
        self.server.stop()

    def __enter__(self) -> Scene:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def wait_for_client(self, timeout: float) -> Any:
        """The first connected browser's ``viser.ClientHandle``; TimeoutError after ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            clients = self.server.get_clients()
            if clients:
                return clients[min(clients)]
            time.sleep(0.05)
        raise TimeoutError(f"no browser connected to {self.url} within {timeout:g} s")

    # -- drawing -------------------------------------------------------------------------------------
    def _check(self, q: ArrayLike) -> NDArray[np.float64]:
        v = np.asarray(q, dtype=float).reshape(-1)
        if v.shape != (self.system.dof,) or not np.all(np.isfinite(v)):
            raise ValueError(f"system {self.system.name!r}: expected {self.system.dof} finite joint values, "
                             f"got {v.shape[0]}" + ("" if np.all(np.isfinite(v)) else " (not all finite)"))
        return v

    def _build(self) -> None:
        scene = self.server.scene
        poses = system_pose(self.system, self.q)
        self.link_radius, axes = _sizes(poses)
        r = self.link_radius
        # a grid on the floor, its cells a round length in proportion to the robots
        origins = np.vstack([pose.origins for pose in poses])
        extent = max(0.05, float(np.max(np.linalg.norm(origins - origins.mean(axis=0), axis=1))))
        cell = 10.0 ** math.floor(math.log10(extent / 2.0))
        size = cell * math.ceil(5.0 * extent / cell)
        scene.add_grid("/grid", width=size, height=size, cell_size=cell, section_size=5.0 * cell,
                       position=(*np.round(origins.mean(axis=0)[:2] / cell) * cell, 0.0))
        self._links: list[tuple[int, int, Any]] = []  # (chain, frame index) -> cylinder from there
        self._joints: list[tuple[int, int, Any]] = []
        self._axes: list[tuple[int, int, Any]] = []
        self._bodies: list[tuple[int, str, Any]] = []  # (chain, link name) -> the link's frame node
        for c, pose in enumerate(poses):
            root = f"/robots/{pose.name}"
            looks = self.visuals[c]

            def stick(i: int, looks: ChainVisuals | None = looks) -> bool:  # the link after joint i: a stick?
                return looks is None or not looks.covered(looks.sticks[i] if i < len(looks.sticks) else None)

            if looks is not None:
                for k, (link, drawn) in enumerate(looks.links.items()):
                    body = scene.add_frame(f"{root}/body{k}", show_axes=False)
                    self._bodies.append((c, link, body))
                    for m, visual in enumerate(drawn):
                        self._add_visual(f"{root}/body{k}/visual{m}", visual)
            if stick(0):
                scene.add_icosphere(f"{root}/base", radius=1.6 * r, color=BASE_COLOUR,
                                    position=pose.origins[0])
            for i in range(len(pose.frames) - 1):
                if not stick(i):
                    continue
                length = float(np.linalg.norm(pose.origins[i + 1] - pose.origins[i]))
                if length > 1e-6 or pose.moving[i]:  # rigid: a zero-length link stays so (prismatic aside)
                    self._links.append((c, i, scene.add_cylinder(f"{root}/link{i}", radius=r, height=1.0,
                                                                 color=LINK_COLOUR, radial_segments=16)))
                if pose.moving[i]:
                    self._joints.append((c, i, scene.add_icosphere(f"{root}/joint{i}", radius=1.35 * r,
                                                                   color=JOINT_COLOUR, subdivisions=2)))
            ends = range(len(pose.frames)) if self.frames == "all" else (0, len(pose.frames) - 1)
            if self.frames != "none":
                for i in ends:
                    self._axes.append((c, i, scene.add_frame(f"{root}/frame{i}", axes_length=axes,
                                                             axes_radius=0.08 * axes, origin_radius=0.0)))
        self._point_radius = 1.8 * r
        self._primitive: list[SceneNodeHandle] = []
        self._draw(poses)

    def _add_visual(self, name: str, visual: Visual) -> None:
        """One URDF visual as a child node of its link's frame node (placed by its origin)."""
        scene = self.server.scene
        wxyz, position, opacity = quaternion(visual.origin[:3, :3]), visual.origin[:3, 3], visual.opacity
        if visual.kind == "box":
            x, y, z = visual.size
            scene.add_box(name, color=visual.colour, dimensions=(x, y, z), flat_shading=False,
                          opacity=opacity, wxyz=wxyz, position=position)
        elif visual.kind == "cylinder":
            scene.add_cylinder(name, radius=visual.size[0], height=visual.size[1], color=visual.colour,
                               radial_segments=32, opacity=opacity, wxyz=wxyz, position=position)
        elif visual.kind == "sphere":
            scene.add_icosphere(name, radius=visual.size[0], color=visual.colour, subdivisions=3,
                                opacity=opacity, wxyz=wxyz, position=position)
        else:
            assert visual.vertices is not None and visual.faces is not None
            scene.add_mesh_simple(name, visual.vertices.astype(np.float32), visual.faces.astype(np.uint32),
                                  color=visual.colour, opacity=opacity, wxyz=wxyz, position=position)

    def _body_frames(self) -> list[tuple[int, str, NDArray[np.float64]]]:
        """(chain, link, pose) of every link drawn from its visuals, at the configuration ``self.q``."""
        if not self._bodies:
            return []
        values = chain_joint_values(self.system, list(self.q))
        frames = [looks.link_frames(values[c]) if looks is not None else {} for c, looks in
                  enumerate(self.visuals)]
        return [(c, link, frames[c][link]) for c, link, _ in self._bodies]

    def _draw(self, poses: Sequence[ChainPose]) -> None:
        for (_, _, frame), (_, _, handle) in zip(self._body_frames(), self._bodies, strict=True):
            handle.position = frame[:3, 3]
            handle.wxyz = quaternion(frame[:3, :3])
        for c, i, handle in self._links:
            a, b = poses[c].origins[i], poses[c].origins[i + 1]
            d = b - a
            length = float(np.linalg.norm(d))
            handle.visible = length > 1e-6
            if length > 1e-6:
                handle.position = 0.5 * (a + b)
                handle.wxyz = quaternion(aligning(d))
                handle.scale = (1.0, 1.0, length)
        for c, i, handle in self._joints:
            handle.position = poses[c].origins[i]
        for c, i, handle in self._axes:
            handle.position = poses[c].frames[i][:3, 3]
            handle.wxyz = quaternion(poses[c].frames[i][:3, :3])
        self._draw_primitive(np.array([pose.end_point for pose in poses]))

    def _draw_primitive(self, points: NDArray[np.float64]) -> None:
        """The primitive's nodes are replaced as a whole: their number and kind change with degeneracy."""
        for handle in self._primitive:
            handle.remove()
        s = shape(self.system.kind, points)
        self._primitive = self._shape_nodes("/primitive", s, PRIMITIVE_COLOUR, self._primitive_visible,
                                            spanning=True)
        self.shape = s

    def _shape_nodes(self, root: str, s: Shape, colour: tuple[int, int, int], visible: bool,
                     spanning: bool) -> list[SceneNodeHandle]:
        """The nodes drawing a primitive: its polylines, a translucent surface for a sphere or a plane,
        and (``spanning``) a ball at each of its points."""
        scene = self.server.scene
        width = 0.35 * self.link_radius  # in proportion to the robots: a hand is centimetres across
        handles: list[SceneNodeHandle] = [
            scene.add_line_segments(f"{root}/lines", segments(polylines(s)), colour,
                                    thickness=width, visible=visible)]
        for k, p in enumerate(s.points if spanning else ()):
            handles.append(scene.add_icosphere(f"{root}/point{k}", radius=self._point_radius,
                                               color=colour, position=p, visible=visible))
        if not s.degenerate and s.kind == "sphere":
            handles.append(scene.add_icosphere(f"{root}/surface", radius=s.radius, color=colour,
                                               position=s.centre, opacity=0.15, subdivisions=4,
                                               cast_shadow=False, receive_shadow=False, visible=visible))
        elif not s.degenerate and s.kind == "plane":
            assert s.normal is not None  # set for every plane that is not degenerate
            a, b = basis(s.normal)
            h = 1.5 * s.size
            corners = np.array([s.centre + h * (i * a + j * b)
                                for i, j in ((1, 1), (-1, 1), (-1, -1), (1, -1))])
            faces = np.array([[0, 1, 2], [0, 2, 3]])
            handles.append(scene.add_mesh_simple(f"{root}/surface", corners, faces,
                                                 color=colour, opacity=0.15, side="double",
                                                 cast_shadow=False, receive_shadow=False, visible=visible))
        return handles

    def show_goal(self, goal: Shape | None) -> None:
        """Draw the goal (target) primitive in ``GOAL_COLOUR`` (``geometry.goal_shape`` makes one from a
        spec's goal parameters), replacing any drawn before; None removes it."""
        with self._lock, self.server.atomic():
            for handle in self._goal:
                handle.remove()
            self.goal = goal
            self._goal = [] if goal is None else self._shape_nodes("/goal", goal, GOAL_COLOUR, True,
                                                                   spanning=False)

    def update(self, q: ArrayLike) -> None:
        """Redraw robots and primitive at the configuration q (the system's joint vector)."""
        v = self._check(q)
        with self._lock, self.server.atomic():
            self.q = v
            self._draw(system_pose(self.system, v))

    def show_primitive(self, visible: bool = True) -> None:
        """Show or hide the primitive (lines, spanning points, surface), as the panel's checkbox does."""
        if self._toggle.value != visible:
            self._toggle.value = visible  # type: ignore[misc]  # viser: mypy takes the generic property as read-only
        self._set_primitive_visible(visible)

    def _set_primitive_visible(self, visible: bool) -> None:
        with self._lock, self.server.atomic():
            self._primitive_visible = visible
            for handle in self._primitive:
                handle.visible = visible

    def status(self, text: str) -> None:
        """A line of text in the viewer's panel (which run is playing, the time)."""
        self._status.content = text

    # -- camera --------------------------------------------------------------------------------------
    def points(self) -> NDArray[np.float64]:
        """Every drawn joint origin, the corners of the links' visuals and the primitive's points, for
        framing a camera."""
        poses = system_pose(self.system, self.q)
        corners = []
        for c, link, frame in self._body_frames():
            looks = self.visuals[c]
            assert looks is not None
            for visual in looks.links[link]:
                corners.append(visual.corners() @ frame[:3, :3].T + frame[:3, 3])
        goal = polylines(self.goal) if self.goal is not None else []
        return np.vstack([pose.origins for pose in poses] + corners + polylines(self.shape) + goal)

    def default_camera(self, aspect: float = 4.0 / 3.0) -> Camera:
        return framing(self.points(), aspect=aspect)

    def set_camera(self, camera: Camera) -> None:
        """The camera new browsers start from ("reset view" returns to it), also applied to connected ones."""
        self.camera = camera
        self.server.initial_camera.position = camera.position
        self.server.initial_camera.look_at = camera.look_at
        self.server.initial_camera.up = camera.up
        self.server.initial_camera.fov = camera.fov
        for client in self.server.get_clients().values():
            client.camera.position = camera.position
            client.camera.look_at = camera.look_at
            client.camera.up_direction = camera.up
            client.camera.fov = camera.fov

    # -- playing -------------------------------------------------------------------------------------
    def play(self, times: ArrayLike, qs: ArrayLike, *, speed: float = 1.0,
             loop: bool = False, stop: threading.Event | None = None, label: str = "") -> None:
        """Play a joint trajectory (qs[k] at times[k], seconds, increasing) in real time × ``speed``,
        showing at most ``FPS`` configurations a second (each the latest sample due). Blocks until the
        end (forever with ``loop``, until ``stop`` is set or KeyboardInterrupt)."""
        t = np.asarray(times, dtype=float).reshape(-1)
        Q = np.asarray(qs, dtype=float)
        if Q.ndim != 2 or Q.shape[0] != t.shape[0] or t.shape[0] == 0:
            count = Q.shape[0] if Q.ndim == 2 else "?"
            raise ValueError(f"play: {t.shape[0]} times for {count} configurations")
        if np.any(np.diff(t) < 0) or not speed > 0:
            raise ValueError("play: times must increase and speed must be positive")
        for q in Q:
            self._check(q)
        stop = stop or threading.Event()
        duration = (t[-1] - t[0]) / speed
        while not stop.is_set():
            start = time.monotonic()
            while not stop.is_set():
                elapsed = time.monotonic() - start
                k = min(int(np.searchsorted(t, t[0] + elapsed * speed, side="right")) - 1, len(t) - 1)
                self.update(Q[max(k, 0)])
                self.status(f"{label + ': ' if label else ''}t = {t[max(k, 0)]:.2f} s of {t[-1]:.2f} s")
                if elapsed >= duration:
                    break
                stop.wait(max(0.0, min(1.0 / FPS, duration - elapsed)))
            if not loop:
                return
            stop.wait(0.5)  # a pause on the final configuration before it starts again


def serve(scene: Scene, runs: Sequence[tuple[str, ArrayLike, ArrayLike]], *,
          speed: float = 1.0, stop: threading.Event | None = None) -> None:
    """Play (label, times, qs) runs one after another in a loop until Ctrl-C (or ``stop`` is set), then
    close the scene: the ``--view`` of the command-line demos."""
    if not runs:
        raise ValueError("serve: no trajectory to play")
    stop = stop or threading.Event()
    print(f"viewer: open {scene.url} in a browser (Ctrl-C to stop)", flush=True)
    with contextlib.suppress(KeyboardInterrupt), scene:
        while not stop.is_set():
            for label, times, qs in runs:
                scene.play(times, qs, speed=speed, label=label, stop=stop)
                if stop.wait(0.5):
                    break
