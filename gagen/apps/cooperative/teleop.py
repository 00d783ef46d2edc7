"""Teleoperation of a cooperative primitive with six input axes [COOP Section 4.4, Figs. 16-17, Eq. 48, 61].

**Axes -> similarity command.** The six device axes (tx, ty, tz, rx, ry, rz; see ``teleop_input``) are
rates: the three translations move the primitive (e1∞, e2∞, e3∞), rz is the dilation e0∞ as in Fig. 16,
and rx, ry turn it where the primitive has rotations (``axis_mapping``): point pairs, lines, circles
and planes; lines and planes have no dilation, so their rz turns about z instead. An axis the kind
cannot use at all (rotations of a point or a sphere, any rz of a point) is listed in ``ignored_axes``
and dropped, never passed on. The dilation follows the paper's reading of Fig. 17 (B_S = ln(d) e0∞:
a negative command closes the hand) and is flipped onto gagen's generator, whose exp (gafro's sign)
scales by e^{−λ} for λ e0∞: rz = δ becomes λ = −δ.

**Frames.** ``frame="world"`` (default): translations in m/s of the primitive's centre (its
origin-image V_Sc e0 V_Sc~, the centre of a round), rotations in rad/s about world axes through that
centre, dilation about it; over one step the commanded similarity is
V_target = T(Δt v) · T_c R(Δt ω) T_c~ · V_Sc(q) · D(e^{Δt δ}). ``frame="body"``: the paper's literal
command in V_Sc's frame, V_target = V_Sc(q) exp(Δt B) (translations then in units of the radius).
Either way the body twist of the step is B = log(V_Sc~ V_target) / Δt.

**Stepping.** Eq. 48 and 61 are the predictor: q̇ = J_G⁺ B (``differential.joint_velocity``, damped
pseudo-inverse), q ← q + Δt q̇. Two choices differ from a literal reading, both measured:

1. Eq. 48 is applied on the primitive's *controllable rows* (``CONTROLLABLE``, the body-frame
   bivectors that move X_u; the others are its stabiliser, Table 1 / ``UNCONTROLLABLE``). The range of
   the 7-row J_G is the tangent of the section X_c -> V_Sc, which for lines and planes mixes rotation
   with the stabiliser's translation (two_iiwas_line at ``ready``: e13 with e1∞), so the 7-row
   least-squares q̇ achieves only part of a commanded rotation; the controllable rows do not have
   that bias (any stabiliser component of J_G q̇ leaves the primitive as it is).
2. The first-order step alone is off by O(Δt²) per step (the map q -> V_Sc is nonlinear): from the
   LEAP hand's ``START`` pose one step of Δt = 0.25 s reaches d = 0.7596 for the command of
   d = 0.3679 (and moves the centre by 2.4 cm); 25 steps of 0.01 s reach 0.3657. So each step is
   *corrected*: it follows the path V_Sc(q) exp(s B), s ∈ [0, Δt], in substeps whose twist has norm
   at most ``max_increment`` (0.05; one substep at Δt = 0.01 s for ordinary rates, 20 for Fig. 17's
   0.25 s step), each a predictor (Eq. 48 and 61 over the substep) followed by damped Gauss-Newton
   (``ik.solve_ik``) on the controllable rows of the task error e(q) = log(V_Sc(q)~ V_goal) (the
   ``task`` kernel) to ``tol``. These rows vanish exactly when X_c(q) is the commanded primitive (the
   rest of e is the stabiliser), so every step moves the primitive as commanded — dilation factor,
   centre, orientation — to ``tol`` (1e-10), with the minimum-norm joint motion from the predictor;
   the substeps keep the joints on a continuous path (a single Gauss-Newton solve from a poor
   predictor can land on a distant branch). ``correct=False`` gives the plain first-order simulation
   of Eq. 61 with one step per Δt (``euler_error`` records its per-step miss either way).

Joint limits from the URDFs bound every corrected step; a step they (or a singular configuration)
block is recorded as not converged (``converged``, ``error``), and the run goes on from there.

    gagen teleop leap_hand_sphere --trace gagen/apps/cooperative/traces/fig17_dilation.csv --out plots/teleop
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.algebra.protocol import Multivector
from gagen.algebra.signature import cga3d
from gagen.apps.cooperative.teleop_input import AXES, Scales, Trace, format_trace, read_trace
from gagen.control.differential import joint_velocity
from gagen.control.ik import solve_ik
from gagen.interp import MultiVector
from gagen.model.conformal import SIMILARITY, SIMILARITY_GENERATOR, e0, location
from gagen.model.versors import (
    decompose_similarity,
    dilator,
    exp_similarity,
    log_dilator,
    log_similarity,
    rotor,
    translator,
)
from gagen.runtime import GeneratedModule

TRACES = Path(__file__).resolve().parent / "traces"
DEFAULT_DT = 0.01
DEFAULT_TOL = 1e-10
FRAMES = ("world", "body")
PLOT_NAME = "teleop.png"
REPORT_NAME = "teleop.txt"

UNCONTROLLABLE: dict[str, tuple[str, ...]] = {
    "point": ("e12", "e13", "e23", "e0inf"),   # rotations and dilations about the point keep it
    "point_pair": ("e23",),                     # the unit pair lies on e1: turning about e1
    "line": ("e23", "e0inf", "e1inf"),          # the unit line is e1 through 0: turn, scale, slide along it
    "circle": ("e12",),                         # unit circle in the e1e2 plane: turning in its plane
    "plane": ("e12", "e0inf", "e1inf", "e2inf"),  # plane z = 0: turn and slide in it, scale about 0
    "sphere": ("e12", "e13", "e23"),            # any rotation about its centre
}
"""Body-frame bivectors (w.r.t. V_Sc) that leave the unit primitive X_u fixed: its stabiliser [Table 1]."""
CONTROLLABLE: dict[str, tuple[str, ...]] = {
    kind: tuple(b for b in SIMILARITY_GENERATOR if b not in stay) for kind, stay in UNCONTROLLABLE.items()}
"""The remaining body-frame bivectors, which move X_u (their count is differential.CONTROLLABLE_DIMENSION)."""

_ROTATING = {"point_pair", "line", "circle", "plane"}


def axis_mapping(kind: str) -> dict[str, str | None]:
    """Device axis -> what it commands for this primitive kind (None: the kind cannot use that axis).

    tx, ty, tz: translation along x, y, z; rz: dilation where the kind has it (point pair, circle,
    sphere), else rotation about z (line, plane); rx, ry: rotation about x, y where it has rotations.
    In the world frame a command may still be partly along the stabiliser at run time (a circle
    turned about its own normal, a plane slid in itself): that part is reported as ``ignored``."""
    if kind not in UNCONTROLLABLE:
        raise ValueError(f"unknown primitive kind {kind!r}; expected one of {', '.join(UNCONTROLLABLE)}")
    rotating = kind in _ROTATING
    dilating = "e0inf" in CONTROLLABLE[kind]
    return {"tx": "translation x", "ty": "translation y", "tz": "translation z",
            "rx": "rotation x" if rotating else None, "ry": "rotation y" if rotating else None,
            "rz": "dilation" if dilating else "rotation z" if rotating else None}


def ignored_axes(kind: str) -> tuple[str, ...]:
    return tuple(axis for axis, role in axis_mapping(kind).items() if role is None)


@dataclass(frozen=True)
class Command:
    """World rates: ``velocity`` (3,) of the centre, ``angular`` (3,) about it, ``dilation`` δ (ln r per s,
    positive opens)."""

    velocity: NDArray[np.float64]
    angular: NDArray[np.float64]
    dilation: float

    @property
    def bivector(self) -> NDArray[np.float64]:
        """The same rates as a gagen generator (7, SIMILARITY_GENERATOR order): rotation ω as
        ω3 e12 − ω2 e13 + ω1 e23, dilation −δ e0∞ (gagen's exp scales by e^{−λ}), translation v ∧ e∞."""
        w, v = self.angular, self.velocity
        return np.array([w[2], -w[1], w[0], -self.dilation, v[0], v[1], v[2]])


def command(kind: str, axes: ArrayLike) -> Command:
    """The ``Command`` of six axis rates for a primitive kind; axes it cannot use are dropped (see
    ``axis_mapping``)."""
    a = np.asarray(axes, dtype=float).ravel()
    if a.shape != (len(AXES),) or not np.all(np.isfinite(a)):
        raise ValueError(f"expected six finite axis rates {AXES}, got {axes!r}")
    roles = axis_mapping(kind)
    angular, dilation = np.zeros(3), 0.0
    for axis, value in zip(AXES[3:], a[3:], strict=True):
        role = roles[axis]
        if role == "dilation":
            dilation = float(value)
        elif role is not None:
            angular["xyz".index(role[-1])] = value
    return Command(velocity=a[:3].copy(), angular=angular, dilation=dilation)


# -- similarity versors on numbers -------------------------------------------------------------------
_ALG = cga3d()


def _versor(coefficients: ArrayLike) -> MultiVector:
    values = np.asarray(coefficients, dtype=float)
    return MultiVector.from_blades(_ALG, dict(zip(SIMILARITY, values, strict=True)))


def _coefficients(v: Multivector, blades: Sequence[str] = SIMILARITY) -> NDArray[np.float64]:
    return np.array([v[b] for b in blades])


def _generator(b: ArrayLike) -> MultiVector:
    values = np.asarray(b, dtype=float)
    return MultiVector.from_blades(_ALG, dict(zip(SIMILARITY_GENERATOR, values, strict=True)))


def geometry(V: ArrayLike) -> tuple[NDArray[np.float64], float]:
    """(centre (3,), scale) of a similarity versor: the image of the origin and the dilation factor,
    i.e. the centre and radius of X_c = V X_u V~ for a round (X_u has radius 1)."""
    v: Multivector = _versor(V)
    centre = _coefficients(location(v.sandwich(e0(v))), ("e1", "e2", "e3"))
    scale = math.exp(-log_dilator(decompose_similarity(v).dilator)["e0inf"])
    return centre, scale


def target(V: ArrayLike, cmd: Command, dt: float, frame: str = "world") -> NDArray[np.float64]:
    """The similarity (12,) commanded dt after V (see the module docstring for the two frames)."""
    v: Multivector = _versor(V)
    if frame == "body":
        return _coefficients(v * exp_similarity(_generator(dt * cmd.bivector)))
    if frame != "world":
        raise ValueError(f"frame must be one of {FRAMES}, got {frame!r}")
    centre = location(v.sandwich(e0(v)))
    angle = float(np.linalg.norm(cmd.angular)) * dt
    if angle > 0:
        unit = cmd.angular / np.linalg.norm(cmd.angular)
        axis = centre.make(dict(zip(("e1", "e2", "e3"), unit, strict=True)))
        t_c = translator(centre)
        v = t_c * rotor(axis, angle) * ~t_c * v
    v = translator(centre.make(dict(zip(("e1", "e2", "e3"), dt * cmd.velocity, strict=True)))) * v
    return _coefficients(v * dilator(v, math.exp(dt * cmd.dilation)))


def body_twist(V: ArrayLike, V_target: ArrayLike, dt: float) -> NDArray[np.float64]:
    """B = log(V~ V_target) / dt (7,): the body twist whose exp over dt reaches V_target."""
    return _coefficients(log_similarity(~_versor(V) * _versor(V_target)), SIMILARITY_GENERATOR) / dt


# -- kernels -----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Kernels:
    """The two generated kernels the loop needs, on numbers: ``similarity(q) -> (V_Sc, cond, J_G)`` and
    ``task(q, V_Sd) -> (e, J_Be)``; ``kind`` the primitive, ``dof``, ``system`` the name."""

    similarity: Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], ...]]
    task: Callable[[NDArray[np.float64], NDArray[np.float64]], tuple[NDArray[np.float64], ...]]
    kind: str
    dof: int
    system: str
    module: GeneratedModule | None = None
    spec: str = ""  # the system as given: a bundled name or a spec file ("": unknown, no URDF limits)


def kernels(module: GeneratedModule, backend: str = "c") -> Kernels:
    """``Kernels`` of a loaded module: its C kernels, or (``backend="casadi"``, no C compiler needed)
    its CasADi Functions."""
    manifest = module.manifest
    if backend == "c":
        sim, task = module.c.similarity, module.c.task

        def similarity(q: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
            return tuple(np.array(x, dtype=float) for x in sim(q))

        def task_(q: NDArray[np.float64], V_Sd: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
            return tuple(np.array(x, dtype=float) for x in task(q, V_Sd))
    elif backend == "casadi":
        sim_f, task_f = module.casadi.similarity, module.casadi.task

        def similarity(q: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
            V, cond, J = sim_f(q)
            return np.array(V).ravel(), np.array(cond).ravel(), np.array(J)

        def task_(q: NDArray[np.float64], V_Sd: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
            e, J = task_f(q, V_Sd)
            return np.array(e).ravel(), np.array(J)
    else:
        raise ValueError(f"backend must be 'c' or 'casadi', got {backend!r}")
    return Kernels(similarity=similarity, task=task_, kind=manifest["primitive"], dof=int(manifest["dof"]),
                   system=manifest["system"], module=module)


@cache
def bundled_kernels(system: str, backend: str = "c") -> Kernels:
    """``Kernels`` of a system: a bundled name or a spec file (its module built on first use:
    ``gagen.modules``)."""
    from gagen.apps.cooperative.scenarios import module

    try:
        loaded = module(system)
    except ValueError as e:  # neither a bundled name nor a spec file
        raise ValueError(f"unknown system {system!r}: {e}") from None
    return dataclasses.replace(kernels(loaded, backend), spec=system)


START: dict[str, tuple[float, ...]] = {
    # a cupped LEAP hand, tips on a sphere of radius 6.3 cm: from here the Fig. 17 commands (d = e^{∓1}:
    # radius 2.3 cm and 17 cm) stay within the joint limits. The spec's ``ready`` pose has nearly
    # coplanar tips (a 14 cm sphere), which cannot shrink by e^{-1} within the limits.
    "leap_hand_sphere": (1.44, 0.365, -0.071, -0.265, 0.857, -0.218, -0.345, 1.587, 0.536, 0.789, 1.221,
                         0.045, 0.625, 1.25, 0.686, 1.796),
}
"""Start configurations for teleoperation where the spec's ``ready`` one does not suit."""


def ready(system: str) -> NDArray[np.float64]:
    """The teleoperation start of a system (a bundled name or a spec file): ``START`` if listed, else the
    spec's ``ready``."""
    from gagen.apps.cooperative.scenarios import ready as spec_ready

    return np.array(START[system], dtype=float) if system in START else spec_ready(system)


# -- simulation --------------------------------------------------------------------------------------
@dataclass
class TeleopResult:
    """One run. Per time (steps + 1): ``t``, ``q``, ``V`` (12), ``centre`` (3), ``scale`` (the radius of a
    round). Per step: ``axes`` (6 rates), ``commanded`` B (7, body twist of the step's target),
    ``achieved`` log(V_k~ V_k+1)/Δt (7), ``euler_error`` ‖e_c‖ of the first-order step, ``error`` ‖e_c‖
    after the step (e_c: the controllable rows of log(V_Sc~ V_target)), ``ignored`` ‖B‖ on the
    stabiliser rows (moves nothing), ``dropped`` Σ|rate| on the axes the kind cannot use (``ignored_axes``),
    ``iterations`` of the correction, ``converged``."""

    system: str
    kind: str
    dt: float
    frame: str
    corrected: bool
    t: NDArray[np.float64]
    q: NDArray[np.float64]
    V: NDArray[np.float64]
    centre: NDArray[np.float64]
    scale: NDArray[np.float64]
    axes: NDArray[np.float64]
    commanded: NDArray[np.float64]
    achieved: NDArray[np.float64]
    euler_error: NDArray[np.float64]
    error: NDArray[np.float64]
    ignored: NDArray[np.float64]
    dropped: NDArray[np.float64]
    iterations: NDArray[np.int64]
    converged: NDArray[np.bool_]
    ignored_axes: tuple[str, ...] = field(default=())
    messages: list[str] = field(default_factory=list)


class Teleoperation:
    """The stepping loop on one system: ``step(axes)`` advances q by dt; ``result()`` collects the run.

    ``limits``: (lower, upper) joint bounds for the correction, default the URDF limits of a bundled
    system (None: unbounded). ``tol``, ``max_iterations``: of the correction; ``damping``: of J_G⁺."""

    def __init__(self, kernels: Kernels, q0: ArrayLike, *, dt: float = DEFAULT_DT, frame: str = "world",
                 correct: bool = True, tol: float = DEFAULT_TOL, max_iterations: int = 50,
                 damping: float = 1e-6, max_increment: float = 0.05,
                 limits: tuple[ArrayLike, ArrayLike] | str | None = "urdf") -> None:
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
        if frame not in FRAMES:
            raise ValueError(f"frame must be one of {FRAMES}, got {frame!r}")
        self.k = kernels
        self.rows = np.array([SIMILARITY_GENERATOR.index(b) for b in CONTROLLABLE[kernels.kind]])
        self.stabiliser = np.array([SIMILARITY_GENERATOR.index(b) for b in UNCONTROLLABLE[kernels.kind]])
        if isinstance(limits, str):
            if limits != "urdf":
                raise ValueError(f"limits must be (lower, upper), 'urdf' or None, got {limits!r}")
            from gagen.apps.cooperative.scenarios import joint_limits

            limits = joint_limits(kernels.spec) if kernels.spec else None
        self.limits = limits
        self.dt, self.frame, self.correct = float(dt), frame, correct
        self.tol, self.max_iterations, self.damping = tol, max_iterations, damping
        self.max_increment = max_increment
        self.q = np.array(q0, dtype=float).ravel()
        if self.q.shape != (kernels.dof,):
            raise ValueError(f"q0 needs {kernels.dof} joint values for {kernels.system}, got {self.q.size}")
        self.time = 0.0
        self._V = self.k.similarity(self.q)[0]
        self._log: dict[str, list[Any]] = {name: [] for name in (
            "axes", "commanded", "achieved", "euler_error", "error", "ignored", "dropped", "iterations",
            "converged")}
        self._unused = np.array([AXES.index(a) for a in ignored_axes(kernels.kind)], dtype=int)
        self._states = [(0.0, self.q.copy(), self._V.copy())]
        self.messages: list[str] = []

    def _reduced_task(self, q: NDArray[np.float64], V_Sd: NDArray[np.float64]
                      ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        e, J = self.k.task(q, V_Sd)
        return e[self.rows], J[self.rows]

    def step(self, axes: ArrayLike) -> None:
        """Advance one step of dt with the six axis rates held over it."""
        cmd = command(self.k.kind, axes)
        V, _, J_G = self.k.similarity(self.q)
        V_target = target(V, cmd, self.dt, self.frame)
        B = body_twist(V, V_target, self.dt)
        q_dot = joint_velocity(J_G[self.rows], B[self.rows], self.damping)  # Eq. 48 (controllable rows)
        predicted = self.q + self.dt * q_dot                                  # Eq. 61
        euler = float(np.linalg.norm(self._reduced_task(predicted, V_target)[0]))
        q, error, iterations, converged = predicted, euler, 0, euler <= self.tol
        if self.correct:  # substeps along V exp(s B), s = Δt j / n: predictor, then Gauss-Newton onto it
            substeps = max(1, math.ceil(float(np.linalg.norm(self.dt * B[self.rows])) / self.max_increment))
            q, J, converged = self.q, J_G[self.rows], True
            for j in range(1, substeps + 1):
                goal = V_target if j == substeps else _coefficients(
                    _versor(V) * exp_similarity(_generator(self.dt * j / substeps * B)))
                guess = q + self.dt / substeps * joint_velocity(J, B[self.rows], self.damping)
                r = solve_ik(self._reduced_task, guess, goal, tol=self.tol,
                             max_iterations=self.max_iterations, limits=self.limits)
                q, error, converged = r.q, r.error_norm, converged and r.converged
                iterations += r.iterations
                if not r.converged:
                    self.messages.append(f"t = {self.time:.4f} s, substep {j}/{substeps}: the commanded "
                                         f"similarity was not reached: {r.message}")
                if j < substeps:
                    J = self.k.similarity(q)[2][self.rows]
        q_next = q
        V_next = self.k.similarity(q_next)[0]
        self.q, self.time = q_next, self.time + self.dt
        for name, value in (("axes", np.asarray(axes, dtype=float)), ("commanded", B),
                            ("achieved", body_twist(V, V_next, self.dt)), ("euler_error", euler),
                            ("error", error), ("ignored", float(np.linalg.norm(B[self.stabiliser]))),
                            ("dropped", float(np.abs(np.asarray(axes, dtype=float)[self._unused]).sum())),
                            ("iterations", iterations), ("converged", converged)):
            self._log[name].append(value)
        self._states.append((self.time, q_next.copy(), V_next.copy()))

    def result(self) -> TeleopResult:
        t, q, V = (np.array(x) for x in zip(*self._states, strict=True))
        geo = [geometry(v) for v in V]
        n = len(self._log["axes"])
        log = {name: np.array(values) if values else np.zeros((0, 7) if name in ("commanded", "achieved")
                                                               else (0, 6) if name == "axes" else 0)
               for name, values in self._log.items()}
        return TeleopResult(
            system=self.k.system, kind=self.k.kind, dt=self.dt, frame=self.frame, corrected=self.correct,
            t=t, q=q, V=V, centre=np.array([c for c, _ in geo]), scale=np.array([s for _, s in geo]),
            axes=log["axes"].reshape(n, 6), commanded=log["commanded"].reshape(n, 7),
            achieved=log["achieved"].reshape(n, 7), euler_error=log["euler_error"],
            error=log["error"], ignored=log["ignored"], dropped=log["dropped"],
            iterations=log["iterations"].astype(np.int64),
            converged=log["converged"].astype(bool), ignored_axes=ignored_axes(self.k.kind),
            messages=list(self.messages))


def run_trace(kernels: Kernels, trace: Trace, q0: ArrayLike | None = None, **options: Any) -> TeleopResult:
    """Replay a trace from ``q0`` (default: the bundled system's ready configuration) in steps of
    ``options['dt']`` (default 0.01 s), each holding the trace's axes at the step's start."""
    loop = Teleoperation(kernels, ready(kernels.spec or kernels.system) if q0 is None else q0, **options)
    for k in range(trace.steps(loop.dt)):
        loop.step(trace.at(k * loop.dt))
    return loop.result()


def intervals(r: TeleopResult, trace: Trace) -> str:
    """Per trace row whose times fall on steps: the dilation factor and the centre's displacement over it."""
    lines = []
    for t0, t1 in zip(trace.times[:-1], trace.times[1:], strict=True):
        i, j = round(t0 / r.dt), round(t1 / r.dt)
        if abs(i * r.dt - t0) > 1e-9 or abs(j * r.dt - t1) > 1e-9 or j >= len(r.t):
            continue
        lines.append(f"  {t0:g}-{t1:g} s: dilation factor {r.scale[j] / r.scale[i]:.6g}, centre moved "
                     f"{np.array2string(r.centre[j] - r.centre[i], precision=5)}")
    return "\n".join(["per trace row:", *lines]) if lines else ""


def run_live(kernels: Kernels, reader: Any, scales: Scales, q0: ArrayLike | None = None,
             duration: float = math.inf, status: Callable[[str], None] | None = None,
             **options: Any) -> TeleopResult:
    """Step in wall-clock time at dt from a live ``reader`` (``read(now)`` -> deflections, ``quit``)
    until it quits or ``duration`` passes; deflections are scaled to rates by ``scales``."""
    loop = Teleoperation(kernels, ready(kernels.spec or kernels.system) if q0 is None else q0, **options)
    start = time.monotonic()
    while not reader.quit and loop.time < duration:
        now = time.monotonic()
        loop.step(scales.apply(reader.read(now)))
        if status is not None and len(loop._log["error"]) % 10 == 1:  # about 10 Hz at dt = 0.01 s
            centre, scale = geometry(loop._states[-1][2])
            status(f"\rt {loop.time:7.2f} s  centre {np.array2string(centre, precision=4)}  "
                   f"scale {scale:.4f}  error {loop._log['error'][-1]:.1e}   ")
        time.sleep(max(0.0, start + loop.time - time.monotonic()))
    return loop.result()


# -- report ------------------------------------------------------------------------------------------
def summary(r: TeleopResult) -> str:
    """A text summary of a run: system, the axis mapping, start and end of the primitive, the errors."""
    steps = len(r.error)
    roles = axis_mapping(r.kind)
    lines = [f"teleoperation of {r.system} ({r.kind}, {r.q.shape[1]} DOF): {steps} steps of {r.dt:g} s "
             f"({r.t[-1]:.4g} s), {r.frame} frame, "
             + ("first-order steps corrected by Gauss-Newton" if r.corrected
                else "first-order steps (Eq. 61)"),
             "axes: " + ", ".join(f"{a} -> {roles[a] or 'ignored'}" for a in AXES)]
    lines.append(f"start: centre {np.array2string(r.centre[0], precision=5)}, scale {r.scale[0]:.6g}")
    lines.append(f"end:   centre {np.array2string(r.centre[-1], precision=5)}, scale {r.scale[-1]:.6g} "
                 f"(factor {r.scale[-1] / r.scale[0]:.6g})")
    if steps:
        lines.append(f"per-step error ‖e_c‖ after the step: max {r.error.max():.3e}; "
                     f"first-order (Euler) step alone: max {r.euler_error.max():.3e}")
        lines.append(f"correction iterations: mean {r.iterations.mean():.2f}, max {r.iterations.max()}; "
                     f"steps not reached: {int(np.count_nonzero(~r.converged))}")
        lines.append("command along the stabiliser (no effect on the primitive): "
                     f"max ‖B‖ {r.ignored.max():.3e}")
        used = np.count_nonzero(r.dropped)
        if used:
            lines.append(f"input on axes a {r.kind} cannot use ({', '.join(r.ignored_axes)}): {used} steps, "
                         f"max Σ|rate| {r.dropped.max():.3g}: dropped")
    lines += [f"  {m}" for m in r.messages[:10]]
    return "\n".join(lines)


LABELS = ("e12", "e13", "e23", "e0∞", "e1∞", "e2∞", "e3∞")


def figure(r: TeleopResult) -> Any:
    """Agg figure: the scale (radius) and the centre's displacement over time, the commanded (solid) vs
    achieved (dashed) body twist on the controllable bivectors, and the per-step errors (log)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 9), layout="constrained")
    FigureCanvasAgg(fig)
    ax_scale, ax_centre, ax_twist, ax_error = fig.subplots(4, 1, sharex=True)
    ax_scale.plot(r.t, r.scale, color="tab:purple", gid="scale")
    ax_scale.set_ylabel("scale (radius)")
    for i, c in enumerate("xyz"):
        ax_centre.plot(r.t, r.centre[:, i] - r.centre[0, i], label=c, gid=f"centre:{c}")
    ax_centre.set_ylabel("centre − start (m)")
    ax_centre.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ts = r.t[:-1]
    colours = [f"C{i}" for i in range(7)]
    for i in (SIMILARITY_GENERATOR.index(b) for b in CONTROLLABLE[r.kind]):
        sign = -1.0 if SIMILARITY_GENERATOR[i] == "e0inf" else 1.0  # the dilation in the paper's sign: δ
        label = "δ = −e0∞ (opens +)" if sign < 0 else LABELS[i]
        ax_twist.step(ts, sign * r.commanded[:, i], where="post", color=colours[i],
                      label=f"{label} commanded", gid=f"commanded:{SIMILARITY_GENERATOR[i]}")
        ax_twist.step(ts, sign * r.achieved[:, i], where="post", color=colours[i], linestyle="--",
                      linewidth=2, alpha=0.6, gid=f"achieved:{SIMILARITY_GENERATOR[i]}")
    ax_twist.set_ylabel("body twist (1/s)")
    ax_twist.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0),
                    title="solid commanded,\ndashed achieved", title_fontsize=7)
    floor = 1e-17
    ax_error.semilogy(ts, np.maximum(r.euler_error, floor), color="tab:red",
                      label="first-order step (Eq. 61)", gid="euler_error")
    ax_error.semilogy(ts, np.maximum(r.error, floor), color="tab:blue", label="after the step", gid="error")
    ax_error.set_ylabel("‖e_c‖ per step")
    ax_error.set_xlabel("t (s)")
    ax_error.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    for ax in (ax_scale, ax_centre, ax_twist, ax_error):
        ax.grid(True, linewidth=0.3)
    fig.suptitle(f"teleoperation of {r.system} ({r.kind}, {r.q.shape[1]} DOF) [COOP Section 4.4]",
                 fontsize=11)
    return fig


def write_report(r: TeleopResult, out: str | Path, trace_text: str | None = None,
                 text: str | None = None) -> list[Path]:
    """Write ``teleop.txt`` (the summary), ``teleop.png`` and, for live runs, ``session.csv`` (the
    commanded rates as a trace, replayable with --trace) into ``out``."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    written = [folder / REPORT_NAME, folder / PLOT_NAME]
    written[0].write_text((text or summary(r)) + "\n", encoding="utf-8")
    figure(r).savefig(written[1], dpi=100)
    if trace_text is not None:
        written.append(folder / "session.csv")
        written[-1].write_text(trace_text, encoding="utf-8")
    return written


def session_trace(r: TeleopResult) -> str:
    """The rates of a run as trace text: a row where they change, and the final all-zero row."""
    keep = [k for k in range(len(r.axes)) if k == 0 or not np.array_equal(r.axes[k], r.axes[k - 1])]
    return format_trace([*r.t[keep], r.t[-1]], [*r.axes[keep], np.zeros(6)],
                        comment=f"recorded by gagen teleop on {r.system}, dt = {r.dt:g} s")


# -- command line ------------------------------------------------------------------------------------
def in_mujoco(system: str, k: Kernels, result: TeleopResult) -> str:
    """The run's joint trajectory tracked by computed torque on MuJoCo's plant (``mujoco_loop.follow``):
    report lines with how far the joints and the primitive end up from the kinematic run's."""
    from gagen.apps.cooperative.scenarios import spec_of
    from gagen.control.mujoco_loop import follow
    from gagen.dynamics.mujoco_model import MujocoSystem

    loop = follow(MujocoSystem(spec_of(system)), result.t, result.q)
    at = np.searchsorted(loop.t, result.t - 1e-9)  # the simulator's states at the run's step times
    joints = np.abs(loop.q[at] - result.q).max(axis=1)
    primitive = np.array([np.linalg.norm(np.asarray(k.task(q, V)[0])) for q, V in zip(loop.q[at], result.V,
                                                                                    strict=True)])
    speed = np.abs(np.diff(result.q, axis=0) / np.diff(result.t)[:, None]).max()
    return "\n".join([
        "In MuJoCo (computed torque at 1 kHz on the run's joint trajectory, the same URDF inertias):",
        f"  the kinematic run's fastest joint: {speed:.2f} rad/s (a jump there is what the plant lags)",
        f"  joints from the kinematic run: max {joints.max():.2e} rad, at the end {joints[-1]:.2e} rad",
        f"  primitive from the kinematic run, ‖log(V_Sc(q_MuJoCo)~ V_Sc(q))‖: max {primitive.max():.2e}, "
        f"at the end {primitive[-1]:.2e}",
        f"  torque: max |τ| {np.abs(loop.tau).max():.1f} N m", ""])


def run_command(args: argparse.Namespace) -> int:
    """``gagen teleop`` on its parsed arguments (``gagen.apps.cooperative.commands``)."""
    trace = read_trace(args.trace) if args.trace is not None else None  # before the module is built
    k = bundled_kernels(args.system)
    options = {"dt": args.dt, "frame": args.frame, "correct": not args.first_order}
    recorded, rows = None, ""
    if trace is not None:
        result = run_trace(k, trace, **options)
        rows = intervals(result, trace)
    else:
        from gagen.apps.cooperative.teleop_input import HELP, KeyboardReader, SpaceMouseReader

        reader = KeyboardReader() if args.keyboard else SpaceMouseReader()
        print(HELP if args.keyboard else "SpaceMouse: push/twist the cap; a button quits")
        print("axes: " + ", ".join(f"{a} -> {role or 'ignored'}" for a, role in axis_mapping(k.kind).items()))
        with reader:
            result = run_live(k, reader, Scales(args.speed, args.turn, args.dilation), duration=args.duration,
                              status=lambda s: print(s, end="", flush=True), **options)
        print()
        recorded = session_trace(result)
    text = summary(result) + (f"\n{rows}" if rows else "")
    if args.mujoco:
        text += "\n" + in_mujoco(args.system, k, result)
    print(text)
    for path in write_report(result, args.out, recorded, text):
        print(f"wrote {path}")
    if args.view:  # the run in a loop until Ctrl-C, the primitive drawn live (gagen.viewer)
        from gagen.apps.cooperative.scenarios import spec_of
        from gagen.robots.spec import load_system
        from gagen.viewer.scene import Scene, serve

        serve(Scene(load_system(spec_of(args.system))[0], result.q[0], port=args.port),
              [(f"{args.system} teleoperation", result.t, result.q)])
    return 0 if bool(np.all(result.converged)) else 1
