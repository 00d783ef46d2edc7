"""The joint-space dynamics of a cooperative system from Pinocchio [COOP Eq. 32].

A system's chains are read again from its spec (their URDFs, base links and placements); every
robot (a chain, or the chains sharing a ``robot`` label) becomes one subtree of a single Pinocchio
model, placed at its chain's ``base``, with the robot's joints that no chain uses locked at 0. The
model's configuration order is Pinocchio's; ``SystemDynamics`` maps it to and from the system's q
(``System.joint_keys``), so every quantity here is in the order of the generated kernels. A continuous
joint is Pinocchio's (cos q, sin q) pair; here, as in the kinematics, it is its angle q.

M(q) comes from CRBA, C(q, q̇)q̇ + g(q) from RNEA with zero acceleration, g(q) from RNEA at rest, the
forward dynamics q̈ = M⁻¹(τ − C q̇ − g) from ABA; gravity is −9.81 m/s² along the system frame's z.
Inertial parameters are the URDF's: a robot whose moving links have no ``<inertial>`` is refused,
naming its URDF, rather than given Pinocchio's massless defaults.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.robots.spec import load_system
from gagen.robots.system import System
from gagen.yaml_document import Document

GRAVITY = 9.81  # m/s², along −z of the system frame


class DynamicsError(ValueError):
    """A system whose dynamics cannot be built: names the spec or URDF and what is missing."""


def _pinocchio() -> Any:
    try:
        import pinocchio
    except ImportError as e:  # an optional extra: say how to get it
        raise DynamicsError("the dynamics need Pinocchio: pip install 'gagen[dynamics]' (package pin)") from e
    return pinocchio


@dataclass(frozen=True)
class RobotSource:
    """One robot of a system: its URDF, the link its chains start from, and where that link is placed."""

    label: str
    urdf: Path
    base_link: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]


def _triple(values: Sequence[Any]) -> tuple[float, float, float]:
    """Three numbers as floats (``load_system`` has checked that there are three)."""
    x, y, z = (float(v) for v in values)
    return x, y, z


def robot_sources(spec_path: str | Path) -> tuple[System, list[RobotSource]]:
    """The system of a spec and its robots, in order of first appearance. The spec is validated by
    ``load_system`` first; here only what the dynamics need beyond it is checked: chains given by URDF,
    and the chains of one robot sharing its URDF, base link and placement."""
    spec_path = Path(spec_path)
    system, _ = load_system(spec_path)
    spec = Document(spec_path)
    robots: dict[str, RobotSource] = {}
    for i, (chain, entry) in enumerate(zip(system.chains, spec.data["chains"], strict=True)):
        if "urdf" not in entry:
            raise DynamicsError(f"{spec_path}: chains[{i}]: dynamics need a URDF with inertial parameters; "
                                f"this chain lists its joints")
        base = entry.get("base", {})
        source = RobotSource(chain.robot or chain.name, spec_path.parent / entry["urdf"], entry["base_link"],
                             _triple(base.get("xyz", (0, 0, 0))), _triple(base.get("rpy", (0, 0, 0))))
        known = robots.setdefault(source.label, source)
        if known != source:
            raise DynamicsError(f"{spec_path}: chains[{i}]: robot {source.label!r} is placed or described "
                                f"differently by another chain ({known}); one robot has one URDF and base")
    return system, list(robots.values())


def _check_inertias(urdf: Path, model: Any) -> None:
    moving = [model.names[j] for j in range(1, model.njoints)]
    massless = [name for j, name in enumerate(moving, 1) if model.inertias[j].mass <= 0.0]
    if massless:
        raise DynamicsError(f"{urdf}: the links moved by joints {', '.join(massless)} have no <inertial> "
                            f"(mass); dynamics need the robot's inertial parameters")


def _placement(pin: Any, source: RobotSource) -> Any:
    roll, pitch, yaw = source.rpy
    rotation = pin.rpy.rpyToMatrix(roll, pitch, yaw)
    return pin.SE3(rotation, np.array(source.xyz, dtype=float))


def _robot_model(pin: Any, source: RobotSource, used: set[str]) -> Any:
    """The robot's Pinocchio model from its URDF, with the joints no chain uses locked at 0."""
    try:
        ET.parse(source.urdf)  # a malformed file is named here, not deep inside the C++ parser
        model = pin.buildModelFromUrdf(str(source.urdf))
    except (OSError, ET.ParseError, ValueError, RuntimeError) as e:
        raise DynamicsError(f"{source.urdf}: cannot build a Pinocchio model ({e})") from e
    root = model.frames[model.getFrameId(source.base_link)] if model.existFrame(source.base_link) else None
    if root is None or root.parentJoint != 0 or not root.placement.isIdentity():
        raise DynamicsError(f"{source.urdf}: the chains start at {source.base_link!r}; dynamics need them to "
                            f"start at the URDF's root link")
    locked = [j for j in range(1, model.njoints) if model.names[j] not in used]
    if locked:
        model = pin.buildReducedModel(model, locked, pin.neutral(model))
    if any(model.joints[j].nv != 1 or model.joints[j].nq not in (1, 2) for j in range(1, model.njoints)):
        raise DynamicsError(f"{source.urdf}: only revolute, continuous and prismatic joints are supported")
    _check_inertias(source.urdf, model)
    return model


def _append(pin: Any, world: Any, robot: Any, placement: Any, prefix: str) -> None:
    """Add a robot's joints and bodies to ``world`` under the universe at ``placement``, names prefixed."""
    index = {0: 0}
    for j in range(1, robot.njoints):
        parent = index[robot.parents[j]]
        joint_placement = placement * robot.jointPlacements[j] if robot.parents[j] == 0 \
            else robot.jointPlacements[j]
        v, q, nq = robot.idx_vs[j], robot.idx_qs[j], robot.nqs[j]  # the URDF's limits go along (Crocoddyl)
        new = world.addJoint(parent, robot.joints[j], joint_placement, f"{prefix}/{robot.names[j]}",
                             robot.effortLimit[v:v + 1], robot.velocityLimit[v:v + 1],
                             robot.lowerPositionLimit[q:q + nq], robot.upperPositionLimit[q:q + nq])
        world.appendBodyToJoint(new, robot.inertias[j], pin.SE3.Identity())
        index[j] = new
    for frame in robot.frames:  # the links (tips included), to compare with the generated kinematics
        if frame.type == pin.FrameType.BODY and frame.parentJoint > 0:
            world.addFrame(pin.Frame(f"{prefix}/{frame.name}", index[frame.parentJoint], frame.placement,
                                     pin.FrameType.BODY))


class SystemDynamics:
    """M(q), C(q, q̇)q̇, g(q), forward dynamics and energies of a cooperative system, in its q order."""

    def __init__(self, spec_path: str | Path) -> None:
        pin = self._pin = _pinocchio()
        self.system, robots = robot_sources(spec_path)
        world = pin.Model()
        world.gravity = pin.Motion(np.array([0.0, 0.0, -GRAVITY]), np.zeros(3))
        for source in robots:
            used = {joint for robot, joint in self.system.joint_keys if robot == source.label}
            _append(pin, world, _robot_model(pin, source, used), _placement(pin, source), source.label)
        self.model = world
        self.data = world.createData()
        joint = {world.names[j]: j for j in range(1, world.njoints)}
        missing = [f"{r}/{j}" for r, j in self.system.joint_keys if f"{r}/{j}" not in joint]
        if missing or world.nv != self.system.dof:
            raise DynamicsError(f"{spec_path}: joints {', '.join(missing) or '?'} of the system are not "
                                f"moving joints of its URDFs' Pinocchio models")
        ids = [joint[f"{r}/{j}"] for r, j in self.system.joint_keys]
        # system index i ↔ Pinocchio velocity index order[i]; most systems need no permutation (then
        # none is made). A continuous joint's configuration is (cos q, sin q) in Pinocchio (nq = 2,
        # nv = 1): its angle is the system's q and its velocity and torque are the system's.
        self.order: NDArray[np.intp] = np.array([world.idx_vs[i] for i in ids], dtype=np.intp)
        self._same_order = bool(np.all(self.order == np.arange(self.dof)))
        self._angle = np.array([world.idx_qs[i] for i in ids if world.nqs[i] == 1], dtype=np.intp)
        self._linear = np.array([i for i, j in enumerate(ids) if world.nqs[j] == 1], dtype=np.intp)
        self._cos = np.array([world.idx_qs[i] for i in ids if world.nqs[i] == 2], dtype=np.intp)
        self._unbounded = np.array([i for i, j in enumerate(ids) if world.nqs[j] == 2], dtype=np.intp)
        self._lower = np.tril_indices(self.dof, -1)

    @property
    def dof(self) -> int:
        return self.system.dof

    def _to_pin(self, x: ArrayLike) -> NDArray[np.float64]:
        x = np.asarray(x, dtype=float)
        if self._same_order:
            return x
        out = np.empty(self.dof)
        out[self.order] = x
        return out

    def _config(self, q: ArrayLike) -> NDArray[np.float64]:
        """Pinocchio's configuration vector of the system's q (continuous joints as cos, sin)."""
        q = np.asarray(q, dtype=float)
        if not self._unbounded.size:
            return self._to_pin(q)
        out = np.empty(self.model.nq)
        out[self._angle] = q[self._linear]
        out[self._cos] = np.cos(q[self._unbounded])
        out[self._cos + 1] = np.sin(q[self._unbounded])
        return out

    def _from_pin(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        x = np.array(x)  # a copy: Pinocchio's results live in its data, which the next call overwrites
        if self._same_order:
            return x
        return x[self.order] if x.ndim == 1 else x[np.ix_(self.order, self.order)]

    def mass_matrix(self, q: ArrayLike) -> NDArray[np.float64]:
        """M(q), symmetric positive definite (CRBA fills the upper triangle; mirrored here)."""
        m = np.array(self._pin.crba(self.model, self.data, self._config(q)))
        m[self._lower] = m.T[self._lower]
        return self._from_pin(m) if not self._same_order else m

    def bias(self, q: ArrayLike, qd: ArrayLike) -> NDArray[np.float64]:
        """C(q, q̇)q̇ + g(q) (RNEA with q̈ = 0)."""
        return self._from_pin(self._pin.nonLinearEffects(self.model, self.data, self._config(q),
                                                         self._to_pin(qd)))

    def gravity(self, q: ArrayLike) -> NDArray[np.float64]:
        """g(q), the joint torques that hold the system at rest."""
        return self._from_pin(self._pin.computeGeneralizedGravity(self.model, self.data, self._config(q)))

    def forward(self, q: ArrayLike, qd: ArrayLike, tau: ArrayLike) -> NDArray[np.float64]:
        """q̈ from the applied joint torques τ (ABA)."""
        return self._from_pin(self._pin.aba(self.model, self.data, self._config(q), self._to_pin(qd),
                                            self._to_pin(tau)))

    def kinetic_energy(self, q: ArrayLike, qd: ArrayLike) -> float:
        return float(self._pin.computeKineticEnergy(self.model, self.data, self._config(q), self._to_pin(qd)))

    def potential_energy(self, q: ArrayLike) -> float:
        """The gravitational potential energy (zero at z = 0 of the system frame)."""
        return float(self._pin.computePotentialEnergy(self.model, self.data, self._config(q)))

    def link_position(self, q: ArrayLike, robot: str, link: str) -> NDArray[np.float64]:
        """The origin of ``link`` of ``robot`` in the system frame at q."""
        name = f"{robot}/{link}"
        if not self.model.existFrame(name):
            raise DynamicsError(f"no link {link!r} on robot {robot!r}")
        frame = self.model.getFrameId(name)
        self._pin.framesForwardKinematics(self.model, self.data, self._config(q))
        return np.array(self.data.oMf[frame].translation)

    def total_mass(self) -> float:
        return float(sum(inertia.mass for inertia in self.model.inertias))


def check_finite(name: str, value: NDArray[np.float64]) -> NDArray[np.float64]:
    """``value``, or a DynamicsError naming it where it is not finite (a degenerate configuration)."""
    if not np.all(np.isfinite(value)):
        raise DynamicsError(f"{name} is not finite (a degenerate configuration)")
    return value

