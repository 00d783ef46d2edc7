"""The hexapod's tripod gait played in MuJoCo: a model written from the spec and the mass model, its 18
joints position-controlled along the kinematic gait's joint trajectories (the generated IK), on flat
ground or a slope, and what physics makes of it: the body's drift from the planned path, the stance
feet's slip, the static stability margin along the walk and the contact forces against the friction
cones.

The model (:func:`mjcf`), every number stated here:

- a free-floating ``base`` (the body box of :mod:`gagen.apps.hexapod.mass`), per leg ``<leg>_coxa``,
  ``<leg>_femur`` and ``<leg>_tibia`` bodies with the URDF's chain (:mod:`gagen.apps.hexapod.urdf`:
  the coxa at the mount, hinge joints about the spec's axes through the joint centres), inertials from
  the mass model (uniform rods), a site ``<leg>_toe`` at (l3, 0, 0) of the tibia;
- a sphere foot of ``FOOT_RADIUS`` centred on each toe: the only geoms but the body box that touch
  the ground (the leg links do not collide), friction ``FRICTION`` (sliding), elliptic cones;
- the ground, a plane tilted by the gait's :class:`~gagen.apps.hexapod.gait.Ground` and lowered by
  the foot radius along its normal, so a sphere resting on it has its centre, the toe, on the gait's
  plane;
- a position actuator per joint, torque = KP (q_cmd − q) − KV q̇, clipped at ±EFFORT; joint armature
  ARMATURE (the servos' reflected rotor inertia); the implicitfast integrator at TIMESTEP.

The run (:func:`simulate`): the body placed at the plan's first pose with the joints at the first
sample, held there for SETTLE s, then the commands follow the plan's samples (linear between them).
Recorded at RECORD_RATE: the body pose, the toes, the whole robot's centre of mass (MuJoCo's
``subtree_com`` of the base) and each foot's contact force in its contact frame (``mj_contactForce``).

The report (:class:`SimReport`): the body's position and yaw error against the plan (yaw: the angle
about the body z of R_planᵀ R_sim), end and max; the slip (how far a toe's projection on the ground
moves from where its contact began, while it stays in contact); the stability margin of the feet in
contact (``gagen.apps.hexapod.statics.stability_margin``; −inf while they span no area);
the cone ratio |f_t| / f_n of every contact against the friction coefficient.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape

import numpy as np
from numpy.typing import NDArray

from gagen.apps.hexapod import gait
from gagen.apps.hexapod.mass import MassModel, box_inertia, default_mass_model, rod_inertia, total_mass
from gagen.apps.hexapod.spec import Hexapod
from gagen.apps.hexapod.statics import DegenerateSupport, stability_margin

Array = NDArray[np.float64]

FOOT_RADIUS = 0.01  # m
FRICTION = 0.8  # sliding friction coefficient of foot and ground (rubber on wood)
ROLLING = 0.02  # m: rolling friction (a rubber pad resists rolling up to ROLLING × normal force)
FRICTIONS = (FRICTION, 0.005, ROLLING)  # MuJoCo's sliding, torsional (m) and rolling (m) coefficients
CONDIM = 6  # contact dimensions: normal, 2 sliding, torsional, 2 rolling
KP = 200.0  # N m / rad: position gain of every joint (a stiff servo)
KV = 1.0  # N m s / rad: its velocity gain
EFFORT = 8.0  # N m: actuator torque limit
ARMATURE = 0.002  # kg m²: reflected rotor inertia per joint
TIMESTEP = 0.001  # s
SOLREF = (0.02, 1.0)  # the ground contact's time constant (s) and damping ratio
SOLIMP = (0.9, 0.95, 0.001)  # its impedance: MuJoCo's defaults
IMPRATIO = 10.0  # frictional to normal constraint impedance: stiffer friction, less creep (elliptic cones)
SETTLE = 0.5  # s: standing at the first pose before the walk
RECORD_RATE = 200.0  # Hz
GRAVITY = 9.81  # m/s²
CONTACT_FORCE = 1e-6  # N: a foot pressing less is not in contact
DRIFT_BOUND = 0.025  # m: the largest body position error the walk may have (the CLI's exit status)
YAW_BOUND = math.radians(2.0)  # rad: and yaw error


def _num(value: float) -> str:
    return repr(float(value))


def _vec(values: Any) -> str:
    return " ".join(_num(v) for v in np.ravel(values))


def _quat(r: Array) -> str:
    return _vec(gait.quaternion(r)[0])


def _rpy(rpy: tuple[float, float, float]) -> Array:
    roll, pitch, yaw = rpy
    z, y, x = (np.array(a, dtype=float) for a in ((0, 0, 1), (0, 1, 0), (1, 0, 0)))
    r: Array = gait.rotation(z, yaw) @ gait.rotation(y, pitch) @ gait.rotation(x, roll)
    return r


def _inertial(mass: float, centre: Any, moments: tuple[float, float, float]) -> str:
    return f'<inertial pos="{_vec(centre)}" mass="{_num(mass)}" diaginertia="{_vec(moments)}"/>'


def _attr(text: str) -> str:
    """``text`` escaped for a double-quoted XML attribute."""
    return escape(text, {'"': "&quot;"})


def mjcf(hexapod: Hexapod, mass: MassModel | None = None, ground: gait.Ground | None = None) -> str:
    """The MuJoCo model (MJCF text) of ``hexapod`` with ``mass`` (default: the documented one) on
    ``ground`` (default flat): see the module docstring."""
    mass = mass or default_mass_model(hexapod)
    ground = ground or gait.Ground()
    if len(mass.link_masses) != len(hexapod.legs):
        raise ValueError(f"mass model has {len(mass.link_masses)} legs, the hexapod {len(hexapod.legs)}")
    rad = mass.link_radius
    legs, actuators = [], []
    for leg, masses in zip(hexapod.legs, mass.link_masses, strict=True):
        parts = ("coxa", "femur", "tibia")
        starts = [leg.xyz, (leg.lengths[0], 0.0, 0.0), (leg.lengths[1], 0.0, 0.0)]
        quats = [f' quat="{_quat(_rpy(leg.rpy))}"', "", ""]
        opened = []
        name = _attr(leg.name)  # a spec's names are identifiers; a Hexapod built in code may hold any
        for j, (part, length, m) in enumerate(zip(parts, leg.lengths, masses, strict=True)):
            joint = _attr(leg.joint_names[j])
            lo, hi = leg.limits[j]
            opened.append(
                f'<body name="{name}_{part}" pos="{_vec(starts[j])}"{quats[j]}>'
                f'<joint name="{joint}" axis="{_vec(leg.axes[j])}" range="{_num(lo)} {_num(hi)}"/>'
                f'{_inertial(m, (length / 2, 0.0, 0.0), rod_inertia(m, length, rad))}'
                f'<geom type="capsule" fromto="0 0 0 {_num(length)} 0 0" size="{_num(rad)}" '
                f'contype="0" conaffinity="0" rgba="{"0.35 0.4 0.5 1" if j else "0.2 0.2 0.25 1"}"/>')
            actuators.append(f'<position name="{joint}" joint="{joint}" kp="{_num(KP)}" kv="{_num(KV)}" '
                             f'forcerange="{_num(-EFFORT)} {_num(EFFORT)}"/>')
        toe = f"{_num(leg.lengths[2])} 0 0"
        opened.append(f'<site name="{name}_toe" pos="{toe}" size="0.004"/>'
                      f'<geom name="{name}_foot" type="sphere" pos="{toe}" size="{_num(FOOT_RADIUS)}" '
                      f'contype="1" conaffinity="0" condim="{CONDIM}" friction="{_vec(FRICTIONS)}" '
                      f'rgba="0.9 0.45 0.1 1"/>')
        legs.append("".join(opened) + "</body>" * 3)
    normal = ground.normal
    body = (f'<body name="base"><freejoint name="base"/>'
            f'{_inertial(mass.body_mass, mass.body_centre, box_inertia(mass.body_mass, mass.body_size))}'
            f'<geom name="base" type="box" pos="{_vec(mass.body_centre)}" '
            f'size="{_vec(np.array(mass.body_size) / 2)}" contype="1" conaffinity="0" rgba="0.3 0.5 0.8 1"/>'
            f'{"".join(legs)}</body>')
    return "\n".join([
        f'<mujoco model="{hexapod.name}">',
        '<compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
        f'<option timestep="{_num(TIMESTEP)}" integrator="implicitfast" cone="elliptic" '
        f'impratio="{_num(IMPRATIO)}" gravity="0 0 {_num(-GRAVITY)}"/>',
        f'<default><joint armature="{_num(ARMATURE)}" damping="0.01"/></default>',
        '<asset><texture type="skybox" builtin="gradient" rgb1="0.75 0.82 0.9" rgb2="0.98 0.98 0.98" '
        'width="32" height="32"/><texture name="grid" type="2d" builtin="checker" rgb1="0.82 0.82 0.8" '
        'rgb2="0.68 0.7 0.72" width="256" height="256"/>'
        '<material name="grid" texture="grid" texrepeat="8 8"/></asset>',
        '<worldbody>',
        '<light directional="true" pos="0 0 3" dir="0.3 0.3 -1" diffuse="0.7 0.7 0.7"/>',
        f'<geom name="ground" type="plane" size="3 3 0.1" pos="{_vec(-FOOT_RADIUS * normal)}" '
        f'quat="{_quat(ground.tilt)}" material="grid" contype="1" conaffinity="1" condim="{CONDIM}" '
        f'friction="{_vec(FRICTIONS)}" solref="{_vec(SOLREF)}" solimp="{_vec(SOLIMP)}"/>',
        body,
        '</worldbody>',
        f'<actuator>{"".join(actuators)}</actuator>',
        '</mujoco>', ""])


def load_model(hexapod: Hexapod, mass: MassModel | None = None, ground: gait.Ground | None = None) -> Any:
    """The compiled ``mujoco.MjModel`` of :func:`mjcf`."""
    from gagen.extras import require

    mujoco = require("mujoco", "the hexapod's MuJoCo walk")
    return mujoco.MjModel.from_xml_string(mjcf(hexapod, mass, ground))


def joint_qpos(model: Any, hexapod: Hexapod) -> NDArray[np.int64]:
    """The qpos addresses of the 18 joints, spec order."""
    from gagen.extras import require

    mujoco = require("mujoco", "the hexapod's MuJoCo walk")
    return np.array([model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)]
                     for name in hexapod.joint_names])


# -- stability margin -----------------------------------------------------------------------------------

def _margin(feet: Array, com: Array, gravity: Array) -> float:
    """``statics.stability_margin`` of the feet in contact; −inf where they span no area (fewer than
    three, or in a line): no static support at that instant, so the walk's minimum margin says so."""
    try:
        return stability_margin(feet, com, gravity)
    except DegenerateSupport:
        return -math.inf


# -- the run ------------------------------------------------------------------------------------------

@dataclass
class SimRecord:
    """What the simulation recorded at ``t`` (n, s from the walk's start; the settling before it is
    not recorded): the full ``qpos`` (n×nq, for the animation), the body's position (n×3) and
    rotation (n×3×3), the toes (n×6×3, the sites), the robot's centre of mass (n×3) and per foot the
    contact force (n×6×3: normal, then the two tangential components; zeros without contact)."""

    t: Array
    qpos: Array
    position: Array
    rotation: Array
    toes: Array
    com: Array
    force: Array


def _contact_forces(mujoco: Any, model: Any, data: Any, feet: dict[int, int]) -> Array:
    out = np.zeros((len(feet), 3))
    wrench = np.zeros(6)
    for k in range(data.ncon):
        contact = data.contact[k]
        leg = feet.get(int(contact.geom1), feet.get(int(contact.geom2), -1))
        if leg < 0:
            continue
        mujoco.mj_contactForce(model, data, k, wrench)
        out[leg] += wrench[:3]  # a sphere on a plane: one contact, its frame's x along the normal
    return out


def simulate(hexapod: Hexapod, plan: gait.GaitResult, mass: MassModel | None = None,
             progress: Callable[[str], None] = lambda _: None) -> tuple[Any, SimRecord]:
    """Play ``plan``'s joint trajectories in MuJoCo (module docstring): the model and the record."""
    from gagen.extras import require

    mujoco = require("mujoco", "the hexapod's MuJoCo walk")
    model = load_model(hexapod, mass, plan.ground)
    data = mujoco.MjData(model)
    qadr = joint_qpos(model, hexapod)
    base = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "base")
    sites = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{leg.name}_toe") for leg in hexapod.legs]
    feet = {mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{leg.name}_foot"): i
            for i, leg in enumerate(hexapod.legs)}
    data.qpos[:3] = plan.body.position[0]
    data.qpos[3:7] = gait.quaternion(plan.body.rotation[0])[0]
    data.qpos[qadr] = plan.q[0]
    data.ctrl[:] = plan.q[0]  # the actuators are in spec order, like the joints
    mujoco.mj_forward(model, data)
    for _ in range(round(SETTLE / TIMESTEP)):
        mujoco.mj_step(model, data)
    steps = round(plan.t[-1] / TIMESTEP)
    every = max(1, round(1 / (RECORD_RATE * TIMESTEP)))
    names = ("t", "qpos", "position", "rotation", "toes", "com", "force")
    rows: dict[str, list[Array]] = {k: [] for k in names}
    progress(f"MuJoCo: {steps} steps of {TIMESTEP * 1e3:g} ms after {SETTLE:g} s standing")
    # the command at the end of each step, linear between the plan's samples
    times = np.arange(1, steps + 1) * TIMESTEP
    # plus KV/KP times the plan's joint velocity: the position actuator's damping KV q̇ then acts on
    # the velocity error, KP (q_cmd − q) + KV (q̇_cmd − q̇), and the joints do not lag the plan
    qdot = np.gradient(plan.q, plan.t, axis=0)
    commands = np.column_stack([np.interp(times, plan.t, plan.q[:, j] + KV / KP * qdot[:, j])
                                for j in range(hexapod.dof)])
    for k in range(steps + 1):
        if k % every == 0:
            mujoco.mj_forward(model, data)  # the derived quantities (poses, contacts) of this state
            rows["t"].append(np.array(k * TIMESTEP))
            rows["qpos"].append(data.qpos.copy())
            rows["position"].append(data.xpos[base].copy())
            rows["rotation"].append(data.xmat[base].reshape(3, 3).copy())
            rows["toes"].append(data.site_xpos[sites].copy())
            rows["com"].append(data.subtree_com[base].copy())
            rows["force"].append(_contact_forces(mujoco, model, data, feet))
        if k == steps:
            break
        data.ctrl[:] = commands[k]
        mujoco.mj_step(model, data)
    record = SimRecord(**{k: np.array(v) for k, v in rows.items()})
    return model, record


# -- the report -----------------------------------------------------------------------------------------

def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the runs of True."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def yaw_error(planned: Array, simulated: Array) -> Array:
    """The angles (n, rad) about the body z of R_planᵀ R_sim (n×3×3 each)."""
    relative = np.einsum("nji,njk->nik", planned, simulated)
    return np.asarray(np.arctan2(relative[:, 1, 0], relative[:, 0, 0]))


def slip(toes: Array, contact: NDArray[np.bool_], normal: Array) -> Array:
    """Per sample and foot (n×6): how far the toe's projection on the ground has moved since its
    contact began, while the contact lasts (0 out of contact)."""
    out = np.zeros(contact.shape)
    for i in range(contact.shape[1]):
        for a, b in _runs(contact[:, i]):
            d = toes[a:b, i] - toes[a, i]
            d = d - (d @ normal)[:, None] * normal
            out[a:b, i] = np.linalg.norm(d, axis=1)
    return out


@dataclass
class SimReport:
    """The simulated walk against its plan, per recorded sample (``t``, s): the body's position error
    (n, m) and yaw error (n, rad), the stance slip (n×6, m), the stability margin of the feet in
    contact (n, m) and of the plan's stance feet with the plan's CoM (``planned_margin``, n), the
    feet in contact (n×6) and each contact's ratio |f_t| / f_n (``cone``, n×6, NaN without contact)."""

    slope: float  # rad
    t: Array
    position_error: Array
    yaw_error: Array
    slip: Array
    margin: Array
    planned_margin: Array
    contact: NDArray[np.bool_]
    cone: Array
    mass: float  # kg
    step_time: float  # s

    @property
    def drift_end(self) -> float:
        return float(self.position_error[-1])

    @property
    def drift_max(self) -> float:
        return float(self.position_error.max())

    @property
    def yaw_end(self) -> float:
        return float(self.yaw_error[-1])

    @property
    def yaw_max(self) -> float:
        return float(np.abs(self.yaw_error).max())

    @property
    def slip_max(self) -> float:
        return float(self.slip.max())

    @property
    def margin_min(self) -> float:
        return float(self.margin.min())

    @property
    def cone_inside(self) -> float:
        """The fraction of contact samples strictly inside the cone, |f_t| ≤ 0.99 μ f_n: sticking.
        (MuJoCo's elliptic cones never let a force out; at the edge the foot slides.)"""
        ratios = self.cone[self.contact]
        return float((ratios <= 0.99 * FRICTION).mean()) if ratios.size else 1.0

    @property
    def cone_max(self) -> float:
        ratios = self.cone[self.contact]
        return float(ratios.max()) if ratios.size else 0.0

    @property
    def sliding_near_step_change(self) -> float:
        """The largest time (s) from a sliding contact (|f_t| > 0.99 μ f_n) to the nearest step change
        (lift-off and touch-down of the tripods); 0 without sliding."""
        k = np.flatnonzero((self.contact & (self.cone > 0.99 * FRICTION)).any(axis=1))
        if not k.size:
            return 0.0
        phase = np.mod(self.t[k], self.step_time)
        return float(np.minimum(phase, self.step_time - phase).max())

    @property
    def ok(self) -> bool:
        return self.margin_min > 0 and self.drift_max <= DRIFT_BOUND and self.yaw_max <= YAW_BOUND

    def table(self) -> str:
        rows = [("slope", f"{math.degrees(self.slope):.1f}°", ""),
                ("robot mass", f"{self.mass:.3f} kg", ""),
                ("body drift, end / max", f"{self.drift_end * 1e3:.1f} / {self.drift_max * 1e3:.1f} mm",
                 f"bound {DRIFT_BOUND * 1e3:g} mm"),
                ("yaw error, end / max",
                 f"{math.degrees(self.yaw_end):.2f} / {math.degrees(self.yaw_max):.2f}°",
                 f"bound {math.degrees(YAW_BOUND):g}°"),
                ("stance slip, max", f"{self.slip_max * 1e3:.2f} mm", "toe along the ground, in contact"),
                ("stability margin, min", f"{self.margin_min * 1e3:.1f} mm",
                 f"plan: {self.planned_margin.min() * 1e3:.1f} mm"),
                ("friction cone, inside", f"{100 * self.cone_inside:.1f} %",
                 f"μ = {FRICTION:g}; sliding only within {self.sliding_near_step_change * 1e3:.0f} ms "
                 f"of a step change"),
                ("|f_t| / f_n, max", f"{self.cone_max:.3f}", f"tan(slope) = {math.tan(self.slope):.3f}")]
        width = max(len(r[0]) for r in rows) + 2
        return "\n".join(f"{name:<{width}}{value:>18}   {note}".rstrip() for name, value, note in rows)


def report(hexapod: Hexapod, plan: gait.GaitResult, record: SimRecord, mass: MassModel | None = None
           ) -> SimReport:
    """The simulated walk ``record`` measured against ``plan`` (module docstring)."""
    from gagen.apps.hexapod.mass import centre_of_mass

    mass = mass or default_mass_model(hexapod)
    ground = plan.ground
    planned = gait.body_trajectory(plan.params, ground, record.t)
    position_error = np.linalg.norm(record.position - planned.position, axis=1)
    contact = record.force[:, :, 0] > CONTACT_FORCE
    feet = record.toes - FOOT_RADIUS * ground.normal  # a sphere touches the plane below its centre
    gravity = np.array([0.0, 0.0, -GRAVITY])
    margin = np.array([_margin(feet[k, contact[k]], record.com[k], gravity) for k in range(len(record.t))])
    # the plan at its own samples nearest the record's (the plan's rate divides the record's)
    nearest = np.clip(np.searchsorted(plan.t, record.t - 0.5 / plan.params.rate), 0, len(plan.t) - 1)
    planned_margin = np.empty(len(record.t))
    for k, j in enumerate(nearest):
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = plan.body.rotation[j], plan.body.position[j]
        com = centre_of_mass(hexapod, mass, pose, plan.q[j])
        planned_margin[k] = _margin(plan.targets[j, plan.stance[j]], com, gravity)
    normal_force = np.where(contact, record.force[:, :, 0], 1.0)
    cone = np.where(contact, np.linalg.norm(record.force[:, :, 1:3], axis=2) / normal_force, np.nan)
    return SimReport(ground.slope, record.t, position_error, yaw_error(planned.rotation, record.rotation),
                     slip(record.toes, contact, ground.normal), margin, planned_margin, contact, cone,
                     total_mass(mass), plan.params.step_time)


def run(hexapod: Hexapod, module: Any, ground: gait.Ground | None = None,
        params: gait.GaitParameters | None = None, mass: MassModel | None = None,
        progress: Callable[[str], None] = lambda _: None
        ) -> tuple[gait.GaitResult, Any, SimRecord, SimReport]:
    """Plan the tripod gait (``gait.walk`` with the generated ``module``) on ``ground`` (default flat),
    play it in MuJoCo and measure it: (plan, model, record, report)."""
    plan = gait.walk(module, hexapod, params, ground or gait.Ground(), progress=progress)
    if not plan.ok:
        raise ValueError(f"the planned walk is not feasible: {plan.flags()[0]}")
    model, record = simulate(hexapod, plan, mass, progress)
    return plan, model, record, report(hexapod, plan, record, mass)


# -- plot and command ---------------------------------------------------------------------------------

def plot(report_: SimReport, path: str | Path) -> Path:
    """``walk_sim.png``: the body's drift and yaw error, the stability margin (simulated and planned)
    and the stance slip over the walk."""
    from gagen.apps.hexapod.plots import _figure

    fig = _figure((8, 7))
    t = report_.t
    ax = fig.add_subplot(3, 1, 1)
    ax.plot(t, report_.position_error * 1e3, label="position error (mm)")
    ax.plot(t, np.degrees(report_.yaw_error) * 10, label="yaw error (0.1°)")
    ax.axhline(DRIFT_BOUND * 1e3, color="tab:red", ls="--", lw=1, label="drift bound")
    ax.set_title(f"hexapod in MuJoCo, slope {math.degrees(report_.slope):g}°: body against the plan")
    ax.legend(fontsize=8, loc="upper left")
    ax = fig.add_subplot(3, 1, 2)
    ax.plot(t, report_.margin * 1e3, label="simulated (feet in contact, MuJoCo CoM)")
    ax.plot(t, report_.planned_margin * 1e3, ls="--", label="planned (stance feet, mass model CoM)")
    ax.axhline(0, color="k", lw=0.8)
    ax.set_ylabel("stability margin (mm)")
    ax.legend(fontsize=8, loc="lower left")
    ax = fig.add_subplot(3, 1, 3)
    ax.plot(t, report_.slip.max(axis=1) * 1e3, color="tab:purple")
    ax.set_ylabel("stance slip, max (mm)")
    ax.set_xlabel("t (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    return Path(path)


def walk_sim(args: Any, hexapod: Hexapod, module: Any, params: gait.GaitParameters,
             ground: gait.Ground) -> int:
    """``gagen walk-sim`` (the command line's ``args``: out, fps, no_animation): plan, simulate, print
    the report, write the plot and (unless --no-animation) the GIF; exit 1 when the margin goes
    negative, the drift passes its bound or the planned walk is not feasible."""
    import time

    start = time.perf_counter()

    def say(line: str) -> None:
        print(line, flush=True)

    try:
        plan, _, record, result = run(hexapod, module, ground, params, progress=say)
    except ValueError as e:  # the plan is not feasible: as `gagen walk`, exit 1
        print(f"error: {e}", file=sys.stderr)
        return 1
    print(result.table())
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    say(f"  wrote {plot(result, out / 'walk_sim.png')}")
    if not args.no_animation:
        from gagen.apps.hexapod.mujoco_animation import render_walk
        from gagen.dynamics.mujoco_render import RenderUnavailable

        every = max(1, round(RECORD_RATE / args.fps))
        say(f"rendering {len(record.t[::every])} frames offscreen (MuJoCo, Pillow GIF)")
        try:
            gif = render_walk(mjcf(hexapod, None, plan.ground), record.qpos[::every], out / "walk_sim.gif",
                              fps=args.fps, still=out / "walk_sim_frame.png")
            say(f"  wrote {gif} ({gif.stat().st_size / 1e6:.2f} MB) and {out / 'walk_sim_frame.png'}")
        except RenderUnavailable as e:
            say(f"note: {e}; no animation")
    say(f"done in {time.perf_counter() - start:.1f} s")
    if not result.ok:
        print(f"error: the simulated walk fails its bounds: margin min {result.margin_min * 1e3:.1f} mm, "
              f"drift max {result.drift_max * 1e3:.1f} mm (bound {DRIFT_BOUND * 1e3:g}), yaw max "
              f"{math.degrees(result.yaw_max):.2f}° (bound {math.degrees(YAW_BOUND):g}°)", file=sys.stderr)
        return 1
    return 0
