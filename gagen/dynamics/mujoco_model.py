"""A cooperative system as a MuJoCo model: every robot of the spec loaded from its URDF (its inertias),
placed at its chain's base, each of the system's joints driven by a torque motor with the URDF's effort
limit. The joint damping, friction and armature are zero, as in the Pinocchio model of
``gagen.dynamics.rigid_body``, so the two describe the same rigid bodies and a controller designed on one
runs on the other. Gravity is −9.81 m/s² along z.

``MujocoSystem`` maps the system's q order (the generated kernels') to MuJoCo's qpos, qvel and ctrl, and
puts a site ``<robot>/<chain>/end`` at each chain's end point (``end_points``). ``mjspec`` keeps the
model's specification: add bodies to it (a held object, ``gagen.dynamics.held_object``) and ``compile``.
A URDF whose inertias MuJoCo refuses (the triangle inequality, e.g. the published Panda's link 4) is
refused with its name; MuJoCo's ``balanceinertia`` would change the robot.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.dynamics.rigid_body import GRAVITY, DynamicsError, robot_sources
from gagen.extras import require
from gagen.yaml_document import Document

mujoco: Any = require("mujoco", "gagen.dynamics.mujoco_model (MuJoCo simulation)")

Array = NDArray[np.float64]


def _quaternion(rpy: tuple[float, float, float]) -> Array:
    """(w, x, y, z) of the URDF's fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    half = np.asarray(rpy, dtype=float) / 2
    cr, cp, cy = np.cos(half)
    sr, sp, sy = np.sin(half)
    return np.array([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])


def _robot_spec(urdf: Path, sites: list[tuple[str, str, list[float]]]) -> Any:
    try:
        spec = mujoco.MjSpec.from_file(str(urdf))
        spec.compiler.balanceinertia = False
        for link, name, pos in sites:  # before compiling, which fuses a massless tip link into its parent
            spec.body(link).add_site(name=name, pos=pos)
        spec.compile()  # (a bad inertia is refused here, naming the robot's URDF below)
    except ValueError as e:
        raise DynamicsError(f"{urdf}: MuJoCo cannot load it ({' '.join(str(e).split())})") from e
    return spec


def _end_sites(spec_path: str | Path, system: Any) -> dict[str, list[tuple[str, str, list[float]]]]:
    """Per robot label, a site for each of its chains: (tip link, site name, position in the tip link's
    frame). The site ``<chain>/end`` is the chain's end point: its tip link's origin plus the spec's
    ``tool`` offset, the point the generated kinematics give."""
    sites: dict[str, list[tuple[str, str, list[float]]]] = {}
    for chain, entry in zip(system.chains, Document(Path(spec_path)).data["chains"], strict=True):
        tool = entry.get("tool", {}).get("xyz", (0.0, 0.0, 0.0))
        sites.setdefault(chain.robot or chain.name, []).append(
            (str(entry["tip_link"]), f"{chain.name}/end", [float(v) for v in tool]))
    return sites


class MujocoSystem:
    """The MuJoCo model and data of a system's spec, and its q order (see the module docstring)."""

    def __init__(self, spec_path: str | Path, timestep: float = 1e-3) -> None:
        self.system, robots = robot_sources(spec_path)
        world = mujoco.MjSpec()
        world.option.timestep = float(timestep)
        world.option.gravity = [0.0, 0.0, -GRAVITY]
        sites = _end_sites(spec_path, self.system)
        for source in robots:
            robot = _robot_spec(source.urdf, sites.get(source.label, []))
            frame = world.worldbody.add_frame(pos=list(source.xyz), quat=list(_quaternion(source.rpy)))
            frame.attach_body(robot.worldbody.first_body(), f"{source.label}/", "")
        self.end_site_names = [f"{c.robot or c.name}/{c.name}/end" for c in self.system.chains]
        effort: dict[str, float] = {}
        for joint in world.joints:
            joint.damping, joint.frictionloss, joint.armature = np.zeros(3), 0.0, 0.0
            high = float(joint.actfrcrange[1])  # the URDF's <limit effort> (0: none)
            effort[joint.name] = high if high > 0 else np.inf
        names = [f"{robot}/{joint}" for robot, joint in self.system.joint_keys]
        missing = [n for n in names if n not in effort]
        if missing:
            raise DynamicsError(f"{spec_path}: joints {', '.join(missing)} are not joints of the MuJoCo "
                                f"model")
        for name in names:
            limit = effort[name]
            world.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT,
                               ctrllimited=bool(np.isfinite(limit)),
                               ctrlrange=[-limit, limit] if np.isfinite(limit) else [0.0, 0.0])
        locked = [joint.name for joint in world.joints if joint.name not in set(names)]
        for name in locked:  # the robots' joints no chain uses, held at 0 as in the Pinocchio model
            world.add_equality(type=mujoco.mjtEq.mjEQ_JOINT, name1=name, data=[0.0] * 11)
        self.mjspec = world
        self.joint_names = names
        self.effort = np.array([effort[n] for n in names])
        self.compile()

    def compile(self) -> None:
        """(Re)compile ``mjspec`` (after adding bodies to it: a held object) into ``model`` and a fresh
        ``data``, and map the system's joints, and its chains' end sites, into them."""
        self.model = self.mjspec.compile()
        self.data = mujoco.MjData(self.model)
        ids = [mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in self.joint_names]
        self.qpos = np.array([self.model.jnt_qposadr[i] for i in ids], dtype=np.intp)
        self.qvel = np.array([self.model.jnt_dofadr[i] for i in ids], dtype=np.intp)
        self.end_sites = np.array([mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, n)
                                   for n in self.end_site_names], dtype=np.intp)

    @property
    def dof(self) -> int:
        return self.system.dof

    def set_state(self, q: ArrayLike, qdot: ArrayLike) -> None:
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self.qpos] = np.asarray(q, dtype=float)
        self.data.qvel[self.qvel] = np.asarray(qdot, dtype=float)
        mujoco.mj_forward(self.model, self.data)

    def state(self) -> tuple[Array, Array]:
        return np.array(self.data.qpos[self.qpos]), np.array(self.data.qvel[self.qvel])

    def end_points(self) -> Array:
        """The chains' end points (world frame, one row per chain) at the last computed kinematics."""
        return np.array(self.data.site_xpos[self.end_sites])

    def step(self, tau: ArrayLike) -> None:
        """One timestep with the joint torques τ (clipped by MuJoCo to the effort limits)."""
        self.data.ctrl[:] = np.asarray(tau, dtype=float)
        mujoco.mj_step(self.model, self.data)

    def bias_now(self) -> Array:
        """C(q, q̇) q̇ + g(q) at the current state, in the system's order."""
        return np.array(self.data.qfrc_bias[self.qvel])

    def current_mass_matrix(self) -> Array:
        """M at the current state (computed by the last step), in the system's order."""
        full = np.zeros((self.model.nv, self.model.nv))
        mujoco.mj_fullM(self.model, self.data, full)
        return full[np.ix_(self.qvel, self.qvel)]

    def mass_matrix(self, q: ArrayLike) -> Array:
        """M(q) in the system's order (MuJoCo's composite rigid body algorithm)."""
        self.set_state(q, np.zeros(self.dof))
        full = np.zeros((self.model.nv, self.model.nv))
        mujoco.mj_fullM(self.model, self.data, full)
        return full[np.ix_(self.qvel, self.qvel)]

    def bias(self, q: ArrayLike, qdot: ArrayLike) -> Array:
        """C(q, q̇) q̇ + g(q) in the system's order (MuJoCo's RNE)."""
        self.set_state(q, qdot)
        return np.array(self.data.qfrc_bias[self.qvel])
