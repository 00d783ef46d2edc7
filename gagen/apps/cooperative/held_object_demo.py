"""Three iiwa 14 carry a held ring in MuJoCo (issue 30): the ring of ``gagen.dynamics.held_object``
(1.5 kg, the end points' circle, r = 1.55 m, held by three ball joints) is lifted ``LIFT`` and tilted
``TILT`` about the world x axis through its centre over ``MOTION`` s (a minimum-jerk blend), then held
for ``HOLD`` s, along the commanded similarity V_Sd(t) = ``target_from``(V_Sc(q0), s(t) lift, (x, s(t)
tilt)) of the circle task, under

- ``impedance``: the similarity impedance law (``gagen.control.impedance``, K = 100, D = 20: a double
  pole at −10 /s; the posture spring and damper of its default gains) following the moving set-point
  V_Sd(t). It feeds no target velocity forward, so it lags a moving target by about D/K · v;
- ``mpc``: the torque MPC (``gagen.control.torque_mpc``, box-FDDP, N = 20 × 20 ms, 2 iterations a tick
  at 50 Hz).

Neither controller's model has the ring. Its weight is fed forward (``HeldRing.hold_torque``: the
least-norm grasp forces carrying m g, no internal force commanded) unless ``feedforward=False``, which
leaves the controller to absorb it and shows the sag. The record: the ring's pose against the
commanded one (the centre c0 + s lift, the rotation R_x(s tilt) R0), its tilt (the angle between the
ring's axis and the commanded one: what the circle task commands) and its spin about its own axis (no
circle task commands it: the posture term and the grasps hold it), the grasp forces' internal part
and edge tensions, the grasp points' gaps and the cooperative task error ‖e(q; V_Sd(t))‖.

    gagen carry [--out plots/carry] [--duration 2.5] [--no-mpc]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.control.impedance import Gains, ImpedanceController
from gagen.control.ocp import target_from
from gagen.dynamics.held_object import RING_MASS, HeldRing
from gagen.dynamics.mujoco_model import mujoco

Array = NDArray[np.float64]
Policy = Callable[[float, Array, Array], Array]  # (t, q, q̇) -> τ

SYSTEM = "three_iiwas_circle"
LIFT = (0.0, 0.0, 0.10)  # m
TILT = 0.2  # rad about the world x axis through the ring's centre
MOTION, HOLD = 2.0, 0.5  # s
GAINS = Gains(stiffness=(100.0,) * 7, damping=(20.0,) * 7)  # a double pole at −10 /s
# the posture spring pulls toward q0's joint angles, which the carried ring's new pose no longer has: through
# the grasps it loads the ring (a steady offset, internal forces); without it only the posture damper acts
NO_POSTURE_SPRING = Gains(stiffness=GAINS.stiffness, damping=GAINS.damping, posture_stiffness=0.0)
MPC_RATE, MPC_N, MPC_DT, MPC_ITERATIONS = 50.0, 20, 0.02, 2


def blend(t: float, duration: float) -> float:
    """The minimum-jerk blend 10 s³ − 15 s⁴ + 6 s⁵ of s = t / duration, clipped to [0, 1]."""
    s = min(max(t / duration, 0.0), 1.0)
    return s**3 * (10 - 15 * s + 6 * s**2)


def rotation_x(angle: float) -> Array:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


@dataclass(frozen=True)
class Command:
    """The commanded carry: lift (m) and tilt (rad, about world x through the centre) over ``motion`` s."""

    lift: tuple[float, float, float] = LIFT
    tilt: float = TILT
    motion: float = MOTION

    def pose(self, t: float, centre0: Array, rotation0: Array) -> tuple[Array, Array]:
        """The ring's commanded centre and rotation at t, from its start pose."""
        s = blend(t, self.motion)
        return centre0 + s * np.asarray(self.lift), rotation_x(s * self.tilt) @ rotation0

    def target(self, V_Sc0: Array) -> Callable[[float], Array]:
        """V_Sd(t): the circle of V_Sc0 moved as the ring is (``target_from``, the canonical circle),
        computed once per blend value (``target_from`` runs the reference interpreter: ≈ 3 ms)."""
        known: dict[float, Array] = {}

        def V_Sd(t: float) -> Array:
            s = blend(t, self.motion)
            if s not in known:
                known[s] = target_from(V_Sc0, s * np.asarray(self.lift), ((1.0, 0.0, 0.0), s * self.tilt),
                                       1.0, kind="circle")
            return known[s]
        return V_Sd


@dataclass
class CarryRecord:
    """Per simulator step (the state before it, the forces that step applied)."""

    t: Array
    q: Array
    tau: Array
    centre: Array  # (n, 3) the ring's
    rotation: Array  # (n, 3, 3)
    centre_d: Array  # commanded
    rotation_d: Array
    forces: Array  # (n, 3, 3) each arm's force on the ring, N
    internal: Array  # (n,) ‖f_int‖, N
    tensions: Array  # (n, 3) edge tensions t_01, t_12, t_20, N
    gaps: Array  # (n,) the largest end point to grasp point distance, m
    task_error: Array  # (n,) ‖e(q; V_Sd(t))‖
    wall: float = 0.0  # s

    @property
    def position_error(self) -> Array:
        """‖c − c_d‖ (m)."""
        return np.asarray(np.linalg.norm(self.centre - self.centre_d, axis=1))

    @property
    def tilt_error(self) -> Array:
        """The angle between the ring's axis and the commanded one (rad)."""
        cosine = np.einsum("ni,ni->n", self.rotation[:, :, 2], self.rotation_d[:, :, 2])
        return np.asarray(np.arccos(np.clip(cosine, -1.0, 1.0)))

    @property
    def rotation_error(self) -> Array:
        """The angle of R_dᵀ R (rad): the tilt and the spin about the ring's own axis together."""
        trace = np.einsum("nij,nij->n", self.rotation_d, self.rotation)
        return np.asarray(np.arccos(np.clip((trace - 1) / 2, -1.0, 1.0)))


def carry(ring: HeldRing, policy: Policy, command: Command, task: Callable[..., Any],
          V_Sd: Callable[[float], Array], duration: float) -> CarryRecord:
    """Run ``policy`` on the held ring from rest at its q0 for ``duration`` s at MuJoCo's timestep. Each
    step: ``mj_step1`` (the kinematics at the current state, which the policy and ``hold_torque`` read),
    the policy's τ, ``mj_step2`` (the constraint forces of that state and τ, then the integration)."""
    model, data = ring.model, ring.data
    ring.set_state(ring.q0, np.zeros(ring.dof))
    centre0, rotation0 = ring.ring_pose()
    dt = float(model.opt.timestep)
    steps = round(duration / dt)
    rows: dict[str, list[Any]] = {k: [] for k in ("t", "q", "tau", "centre", "rotation", "centre_d",
                                                  "rotation_d", "forces", "internal", "tensions", "gaps",
                                                  "task_error")}
    began = time.perf_counter()
    for i in range(steps):
        t = i * dt
        mujoco.mj_step1(model, data)
        q, qdot = ring.state()
        tau = np.clip(policy(t, q, qdot), -ring.effort, ring.effort)
        data.ctrl[:] = tau
        mujoco.mj_step2(model, data)
        centre, rotation = ring.ring_pose()
        centre_d, rotation_d = command.pose(t, centre0, rotation0)
        split = ring.internal()
        for key, value in (("t", t), ("q", q), ("tau", tau), ("centre", centre), ("rotation", rotation),
                           ("centre_d", centre_d), ("rotation_d", rotation_d),
                           ("forces", ring.grasp_forces()), ("internal", split.magnitude),
                           ("tensions", split.tensions), ("gaps", ring.grasp_gaps().max()),
                           ("task_error", np.linalg.norm(np.asarray(task(q, V_Sd(t))[0])))):
            rows[key].append(value)
        if not np.all(np.isfinite(data.qpos)):
            raise ValueError(f"the held-ring simulation diverged at t = {t:.3f} s")
    arrays = {k: np.array(v) for k, v in rows.items()}
    return CarryRecord(**arrays, wall=time.perf_counter() - began)


def impedance_policy(ring: HeldRing, controller: ImpedanceController, V_Sd: Callable[[float], Array],
                     feedforward: bool = True) -> Policy:
    """The impedance law toward the moving set-point V_Sd(t), plus the ring's weight fed forward."""
    def policy(t: float, q: Array, qdot: Array) -> Array:
        controller.target = np.asarray(V_Sd(t))
        tau: Array = controller(q, qdot).tau
        return tau + ring.hold_torque() if feedforward else tau
    return policy


def mpc_policy(ring: HeldRing, mpc: Any, rate: float = MPC_RATE, feedforward: bool = True) -> Policy:
    """The torque MPC (``TorqueMPC``: a solve every 1/rate s, u₀ − K₀ (x ⊖ x₀) between), plus the ring's
    weight fed forward."""
    dt = float(ring.model.opt.timestep)
    per_tick = max(1, round(1.0 / (rate * dt)))
    step = [0]

    def policy(t: float, q: Array, qdot: Array) -> Array:
        if step[0] % per_tick == 0:
            mpc.solve(t, q, qdot)
        step[0] += 1
        tau: Array = mpc.torque(q, qdot)
        return tau + ring.hold_torque() if feedforward else tau
    return policy


def zero_policy(t: float, q: Array, qdot: Array) -> Array:
    """No torque: the arms and the ring fall."""
    return np.zeros_like(q)


def setup(system: str = SYSTEM, mass: float = RING_MASS) -> tuple[Any, HeldRing, Array]:
    """The system's generated module, its held ring (from the paper's q0) and V_Sc(q0)."""
    from gagen.apps.cooperative.impedance_demo import start
    from gagen.apps.cooperative.scenarios import module, spec_of

    built = module(system)
    if built.manifest["primitive"] != "circle":
        raise ValueError(f"{system}: a ring is carried by a system spanning a circle; this one spans a "
                         f"{built.manifest['primitive']}")
    q0 = start(system)
    return built, HeldRing(spec_of(system), q0, mass), np.asarray(built.c.similarity(q0)[0])


def run_impedance(system: str = SYSTEM, command: Command = Command(), duration: float = MOTION + HOLD,
                  gains: Gains = GAINS, feedforward: bool = True) -> CarryRecord:
    """The impedance carry (see the module docstring)."""
    from gagen.apps.cooperative.scenarios import spec_of
    from gagen.control.differential import CONTROLLABLE_DIMENSION
    from gagen.dynamics.rigid_body import SystemDynamics

    built, ring, V_Sc0 = setup(system)
    V_Sd = command.target(V_Sc0)
    controller = ImpedanceController(built, SystemDynamics(spec_of(system)), V_Sc0, gains, ring.q0,
                                     CONTROLLABLE_DIMENSION[built.manifest["primitive"]])
    return carry(ring, impedance_policy(ring, controller, V_Sd, feedforward), command, built.c.task, V_Sd,
                 duration)


def run_mpc(system: str = SYSTEM, command: Command = Command(), duration: float = MOTION + HOLD,
            feedforward: bool = True) -> CarryRecord:
    """The torque-MPC carry (see the module docstring)."""
    from gagen.apps.cooperative.scenarios import spec_of
    from gagen.control.torque import TorqueOCP
    from gagen.control.torque_mpc import TorqueMPC

    built, ring, V_Sc0 = setup(system)
    V_Sd = command.target(V_Sc0)
    mpc = TorqueMPC(TorqueOCP(spec_of(system), built.c.task, N=MPC_N, dt=MPC_DT), ring.q0, V_Sd,
                    iterations=MPC_ITERATIONS)
    return carry(ring, mpc_policy(ring, mpc, feedforward=feedforward), command, built.c.task, V_Sd, duration)


def summary(record: CarryRecord, settle: float = MOTION) -> dict[str, float]:
    """The figures of a run: worst over the run, and at its end (after ``settle`` s)."""
    late = record.t >= min(settle, record.t[-1])
    return {"position max": float(record.position_error.max()),
            "position end": float(record.position_error[-1]),
            "tilt max": float(record.tilt_error.max()), "tilt end": float(record.tilt_error[-1]),
            "rotation max": float(record.rotation_error.max()),
            "internal max": float(record.internal.max()),
            "internal median": float(np.median(record.internal)),
            "internal end": float(np.median(record.internal[late])),
            "tension max": float(np.abs(record.tensions).max()),
            "task max": float(record.task_error.max()), "task end": float(record.task_error[-1]),
            "gap max": float(record.gaps.max()), "wall": record.wall}


def report(records: dict[str, CarryRecord], command: Command) -> str:
    lines = ["# A held ring carried by three iiwa 14 in MuJoCo", "",
             f"ring {RING_MASS:g} kg, lift {np.linalg.norm(command.lift) * 100:g} cm and tilt "
             f"{command.tilt:g} rad over {command.motion:g} s (minimum jerk), then held", "",
             "| controller | centre error max / end (mm) | tilt error max / end (mrad) | rotation error "
             "max (mrad) | internal ‖f_int‖ max / median (N) | task ‖e‖ max / end | grasp gap max (mm) | "
             "wall (s) |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for name, record in records.items():
        s = summary(record, command.motion)
        lines.append(f"| {name} | {s['position max'] * 1e3:.2f} / {s['position end'] * 1e3:.2f} | "
                     f"{s['tilt max'] * 1e3:.2f} / {s['tilt end'] * 1e3:.2f} | "
                     f"{s['rotation max'] * 1e3:.2f} | "
                     f"{s['internal max']:.3g} / {s['internal median']:.3g} | {s['task max']:.2e} / "
                     f"{s['task end']:.2e} | {s['gap max'] * 1e3:.2f} | {s['wall']:.1f} |")
    return "\n".join(lines) + "\n"


def plot(records: dict[str, CarryRecord], path: Path) -> Path:
    """Centre error, tilt error, internal force and task error over time, one line per controller."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(9, 8), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(4, 1, sharex=True)
    for name, r in records.items():
        axes[0].plot(r.t, r.position_error * 1e3, lw=1, label=name)
        axes[1].plot(r.t, r.tilt_error * 1e3, lw=1, label=name)
        axes[2].plot(r.t, r.internal, lw=1, label=name)
        axes[3].semilogy(r.t, np.maximum(r.task_error, 1e-6), lw=1, label=name)
    for ax, label in zip(axes, ("centre error (mm)", "tilt error (mrad)", "‖f_int‖ (N)", "‖e(q; V_Sd(t))‖"),
                         strict=True):
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].set_title("a 1.5 kg ring carried by three iiwa 14 in MuJoCo (lift 10 cm, tilt 0.2 rad in 2 s)")
    figure.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncol=3, fontsize="small")
    axes[-1].set_xlabel("t (s)")
    figure.savefig(path, dpi=100)
    return path


def animation(record: CarryRecord, path: Path, fps: float = 20.0, system: str = SYSTEM) -> Path | None:
    """The run rendered by MuJoCo: the arms, the commanded ring (magenta) and the held one (teal); None,
    with a line saying why, where MuJoCo's offscreen renderer cannot start."""
    from gagen.dynamics.mujoco_render import RenderUnavailable, render_gif

    _, ring, _ = setup(system)
    every = max(1, round(1.0 / (fps * (record.t[1] - record.t[0]))))
    frames = np.arange(0, len(record.t), every)
    qpos = np.tile(ring.model.qpos0, (len(frames), 1))
    qpos[:, ring.qpos] = record.q[frames]
    s = np.linspace(0, 2 * np.pi, 72)
    circle = ring.radius * np.stack([np.cos(s), np.sin(s), np.zeros_like(s)], axis=1)
    lines = []
    for row, k in enumerate(frames):
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, record.rotation[k].reshape(-1))
        qpos[row, ring.ring_qpos:ring.ring_qpos + 7] = np.concatenate([record.centre[k], quat])
        lines.append([record.centre_d[k] + circle @ record.rotation_d[k].T,
                      record.centre[k] + circle @ record.rotation[k].T])
    try:
        return render_gif(ring.mjspec.to_xml(), qpos, path, polylines=np.array(lines), fps=fps)
    except RenderUnavailable as e:
        print(f"note: {e}; no animation", flush=True)
        return None


def run_command(args: argparse.Namespace) -> int:
    """A held-ring run: ``system`` (a bundled name or a spec file; default three_iiwas_circle), ``--out``,
    ``--duration`` and ``--no-mpc`` (the impedance law only)."""
    command = Command()
    system = args.system or SYSTEM
    records = {"impedance": run_impedance(system, duration=args.duration),
               "impedance, no feed-forward": run_impedance(system, duration=args.duration, feedforward=False),
               "impedance, no posture spring": run_impedance(system, duration=args.duration,
                                                             gains=NO_POSTURE_SPRING)}
    if not args.no_mpc:
        records["torque MPC"] = run_mpc(system, duration=args.duration)
        records["torque MPC, no feed-forward"] = run_mpc(system, duration=args.duration, feedforward=False)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    text = report(records, command)
    (out / "held_object_report.md").write_text(text)
    written = [out / "held_object_report.md", plot(records, out / "held_object.png")]
    shown = records.get("torque MPC", records["impedance"])
    gif = None if args.no_animation else animation(shown, out / "held_object.gif", system=system)
    if gif is not None:
        written.append(gif)
    print(text + "wrote " + ", ".join(map(str, written)))
    return 0

