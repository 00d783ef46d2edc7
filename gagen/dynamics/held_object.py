"""A rigid ring held by a circle system's three arms in MuJoCo (``gagen.dynamics.mujoco_model``).

The ring is a free body (a thin hoop: mass m, radius r of the circle through the arms' end points at
the start configuration, I = m r² about its axis, m r²/2 about a diameter, its centre of mass at its
centre) joined to each chain's end point by a MuJoCo ``connect`` equality: a ball joint at the grasp
point. Three ball joints fix the ring's six degrees of freedom through the three points alone (9
constraint rows, 6 of them carrying the ring), which is what the circle task controls: the arms' end
points, not their flange orientations. A ``weld`` would also fix each flange's orientation to the ring
(18 rows, 12 internal), fighting the wrist motions the circle task leaves to the posture term.

**Forces.** ``grasp_forces`` reads MuJoCo's constraint forces (``efc_force`` of the three equality
rows, world frame): the force f_i each arm applies to the ring at its grasp point p_i. The grasp map
G (6 × 9) sends them to the net wrench on the ring about its centre c: (Σ f_i, Σ (p_i − c) × f_i).
Its nullspace (3-dimensional for three points not on a line) holds the *internal* forces: they
squeeze or stretch the ring and do no work on its motion. ``internal_forces`` splits the forces into
G⁺ G f (the least-norm forces giving the same wrench) and f_int = (I − G⁺ G) f, and writes f_int as
tensions t_ij along the triangle's edges (f_i = −t_ij u_ij, f_j = t_ij u_ij, u_ij the unit vector from
p_i to p_j: t > 0 stretches the ring), the basis of the nullspace that reads as newtons along a bar.

MuJoCo's equality constraints are soft (its default ``solref`` 0.02 s, ``solimp`` 0.9-0.95): a grasp
point drifts from its end point by a fraction of a millimetre under load (``grasp_gaps``). The ring has
no geom, so no contact touches it: gravity and the three grasp forces are all that act on it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.dynamics.mujoco_model import MujocoSystem, mujoco
from gagen.dynamics.rigid_body import GRAVITY, DynamicsError

Array = NDArray[np.float64]

RING_MASS = 1.5  # kg: a light tube hoop (≈ 150 g/m at the iiwa circle's 1.55 m radius)
EDGES = ((0, 1), (1, 2), (2, 0))


def ring_frame(points: ArrayLike) -> tuple[Array, float, Array]:
    """Centre, radius and rotation (columns: x toward the first point, y, z the normal of the points'
    plane, right-handed in the points' order) of the circle through three points."""
    p = np.asarray(points, dtype=float)
    a, b = p[1] - p[0], p[2] - p[0]
    normal = np.cross(a, b)
    area2 = normal @ normal
    if area2 <= 1e-24 * (a @ a) * (b @ b):
        raise DynamicsError(f"the three end points are on a line: no ring through them ({p.tolist()})")
    centre = p[0] + np.cross((a @ a) * b - (b @ b) * a, normal) / (2 * area2)
    x = (p[0] - centre) / np.linalg.norm(p[0] - centre)
    z = normal / np.sqrt(area2)
    return centre, float(np.linalg.norm(p[0] - centre)), np.column_stack([x, np.cross(z, x), z])


def grasp_map(points: ArrayLike, centre: ArrayLike) -> Array:
    """G (6 × 9): the forces at the points (stacked) to the net force and the torque about the centre."""
    r = np.asarray(points, dtype=float) - np.asarray(centre, dtype=float)
    G = np.zeros((6, 3 * len(r)))
    for i, ri in enumerate(r):
        G[:3, 3 * i:3 * i + 3] = np.eye(3)
        G[3:, 3 * i:3 * i + 3] = [[0, -ri[2], ri[1]], [ri[2], 0, -ri[0]], [-ri[1], ri[0], 0]]
    return G


@dataclass(frozen=True)
class Internal:
    """Grasp forces split by the grasp map (see the module docstring)."""

    manipulating: Array  # (3, 3) G⁺ G f: the least-norm forces with the same net wrench
    internal: Array  # (3, 3) (I − G⁺ G) f
    tensions: Array  # (3,) t_01, t_12, t_20 in N (> 0 stretches the ring)

    @property
    def magnitude(self) -> float:
        """‖f_int‖ over the three points (N)."""
        return float(np.linalg.norm(self.internal))


def internal_forces(forces: ArrayLike, points: ArrayLike, centre: ArrayLike) -> Internal:
    """The internal part of the forces on a body at three points, and its edge tensions."""
    f = np.asarray(forces, dtype=float).reshape(-1)
    p = np.asarray(points, dtype=float)
    G = grasp_map(p, centre)
    manipulating = np.linalg.pinv(G) @ (G @ f)
    internal = f - manipulating
    basis = np.zeros((9, 3))  # one column per edge: −u on its first point, +u on its second
    for k, (i, j) in enumerate(EDGES):
        u = (p[j] - p[i]) / np.linalg.norm(p[j] - p[i])
        basis[3 * i:3 * i + 3, k], basis[3 * j:3 * j + 3, k] = -u, u
    tensions = np.linalg.lstsq(basis, internal, rcond=None)[0]
    return Internal(manipulating.reshape(3, 3), internal.reshape(3, 3), tensions)


class HeldRing(MujocoSystem):
    """A circle system's MuJoCo model with a ring held at its end points from the configuration q0 on
    (see the module docstring). ``mass`` in kg; the radius is the circle's at q0."""

    def __init__(self, spec_path: str | Path, q0: ArrayLike, mass: float = RING_MASS,
                 timestep: float = 1e-3) -> None:
        super().__init__(spec_path, timestep)
        if len(self.end_sites) != 3:
            raise DynamicsError(f"{spec_path}: a ring is held by three chains, this system has "
                                f"{len(self.end_sites)}")
        if not mass > 0:
            raise ValueError(f"the ring's mass must be > 0, got {mass}")
        self.q0 = np.array(q0, dtype=float)
        MujocoSystem.set_state(self, self.q0, np.zeros(self.dof))
        points = self.end_points()
        centre, self.radius, rotation = ring_frame(points)
        self.mass = float(mass)
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rotation.reshape(-1))
        r2 = self.mass * self.radius**2
        # (ipos is given: MjSpec's unset one (NaN) would not put the centre of mass at the centre)
        body = self.mjspec.worldbody.add_body(name="ring", pos=list(centre), quat=list(quat), mass=self.mass,
                                              ipos=[0.0, 0.0, 0.0], iquat=[1.0, 0.0, 0.0, 0.0],
                                              inertia=[r2 / 2, r2 / 2, r2], explicitinertial=True)
        body.add_freejoint(name="ring")
        self.grasp_local = (points - centre) @ rotation  # the grasp points in the ring's frame
        for i, local in enumerate(self.grasp_local):
            body.add_site(name=f"ring/grasp{i}", pos=list(local))
            self.mjspec.add_equality(type=mujoco.mjtEq.mjEQ_CONNECT, objtype=mujoco.mjtObj.mjOBJ_SITE,
                                     name=f"grasp{i}", name1=self.end_site_names[i], name2=f"ring/grasp{i}")
        self.compile()
        model = self.model
        self.ring_body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "ring")
        joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "ring")
        self.ring_qpos = int(model.jnt_qposadr[joint])
        self.ring_qvel = int(model.jnt_dofadr[joint])
        self.grasp_sites = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"ring/grasp{i}")
                                     for i in range(3)], dtype=np.intp)
        self.grasps = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, f"grasp{i}")
                                for i in range(3)], dtype=np.intp)
        self.set_state(self.q0, np.zeros(self.dof))

    def set_state(self, q: ArrayLike, qdot: ArrayLike) -> None:
        """The arms at (q, q̇) and the ring at rest where their end points are (its first grasp point on
        the first end point, its plane through all three)."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self.qpos] = np.asarray(q, dtype=float)
        self.data.qvel[self.qvel] = np.asarray(qdot, dtype=float)
        mujoco.mj_kinematics(self.model, self.data)
        points = self.end_points()
        centre, _, rotation = ring_frame(points)
        # align the ring's first grasp point, whatever the three points' circle's radius
        centre = points[0] - rotation @ self.grasp_local[0]
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rotation.reshape(-1))
        self.data.qpos[self.ring_qpos:self.ring_qpos + 7] = np.concatenate([centre, quat])
        mujoco.mj_forward(self.model, self.data)

    def ring_pose(self) -> tuple[Array, Array]:
        """The ring's centre and rotation (world frame) at the last computed kinematics."""
        body = self.ring_body
        return np.array(self.data.xpos[body]), np.array(self.data.xmat[body]).reshape(3, 3)

    def grasp_points(self) -> Array:
        """The grasp points on the ring (world frame, one row per chain)."""
        return np.array(self.data.site_xpos[self.grasp_sites])

    def grasp_gaps(self) -> Array:
        """The distance between each end point and its grasp point (m): the constraints' softness."""
        return np.asarray(np.linalg.norm(self.end_points() - self.grasp_points(), axis=1))

    def grasp_forces(self) -> Array:
        """(3, 3): the force each arm applies to the ring at its grasp point (world frame, N), from the
        last ``mj_forward`` or ``mj_step``. A connect row's residual is (end point − grasp point), so the
        arm receives +efc_force and the ring −efc_force."""
        d = self.data
        equality = np.asarray(d.efc_type) == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        forces = np.empty((3, 3))
        for i, eq in enumerate(self.grasps):
            rows = np.flatnonzero(equality & (np.asarray(d.efc_id) == eq))
            if len(rows) != 3:
                raise DynamicsError(f"grasp {i}: {len(rows)} constraint rows, expected 3 (a connect)")
            forces[i] = -d.efc_force[rows]
        return forces

    def internal(self) -> Internal:
        """The grasp forces' internal part at the last computed state (``internal_forces``)."""
        centre, _ = self.ring_pose()
        return internal_forces(self.grasp_forces(), self.grasp_points(), centre)

    def hold_torque(self, wrench: ArrayLike | None = None) -> Array:
        """Joint torques (system order) with which the arms apply to the ring the least-norm grasp forces
        G⁺ w giving the wrench w (net force, torque about the centre; default: the ring's weight carried,
        (0, 0, m g, 0, 0, 0)), at the last computed kinematics: τ = Σ J_iᵀ f_i with J_i the Jacobian of
        chain i's end point. A feed-forward for the load: it commands no internal force."""
        weight = [0.0, 0.0, self.mass * GRAVITY, 0.0, 0.0, 0.0]
        w = np.asarray(weight if wrench is None else wrench, dtype=float)
        centre, _ = self.ring_pose()
        points = self.end_points()
        forces = (np.linalg.pinv(grasp_map(points, centre)) @ w).reshape(3, 3)
        jacobian = np.zeros((3, self.model.nv))
        tau = np.zeros(self.model.nv)
        for site, force in zip(self.end_sites, forces, strict=True):
            mujoco.mj_jacSite(self.model, self.data, jacobian, None, int(site))
            tau += jacobian.T @ force
        return tau[self.qvel]
