"""Torque-level cooperative optimal control with Crocoddyl: gagen kernels as Crocoddyl residuals, and
the cooperative reaching OCP with rigid-body dynamics.

**Residuals.** ``KernelResidual`` is a Crocoddyl residual r(x) = f(q) of any generated kernel that gives
a value and its Jacobian with respect to the joint vector: the cooperative task error e(q) = log(V_Sc(q)~
V_Sd) with J_Be (``task_residual``), a chain's kernels, a user's formula. q is read from the state's
configuration and the Jacobian written into the configuration columns of R_x, through the map from
the system's joint order (the kernels') to Pinocchio's (``SystemDynamics.order``). This is the
prototyping version: Crocoddyl calls it through Python, and the kernel itself is the compiled C.

**The OCP** (``torque_reach``): the state x = (q, q̇) of the system's Pinocchio model (its URDFs'
inertias, ``gagen.dynamics``), the control τ, free forward dynamics (ABA) integrated by symplectic
Euler. The running cost, at node k with t = k dt, is
    w_task ‖e(q_k; V_Sd(t))‖² + w_u ‖τ_k − g(q_k)‖² + w_v ‖q̇_k‖² + w_limit barrier(q_k, q̇_k).
The terminal cost is w_terminal ‖e(q_N; V_Sd(t_N))‖² + w_v,N ‖q̇_N‖² + w_limit barrier. The barrier is a
quadratic outside the URDF's position and velocity limits (Crocoddyl's quadratic barrier on the
state). The torques are boxed by the URDF's effort limits, which box-FDDP enforces. V_Sd may move:
give a function of t.

Crocoddyl's wheels need a Pinocchio of the same release: ``gagen[ocp]`` pins crocoddyl 3.2.1 with pin
4.0.0, because with pin 4.1.0 Crocoddyl's dynamics models fail (MemoryError, wrong accelerations).
"""

from __future__ import annotations

import sys
import threading
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.dynamics.rigid_body import SystemDynamics
from gagen.extras import require

crocoddyl: Any = require("crocoddyl", "gagen.control.torque (torque-level optimal control)")

Array = NDArray[np.float64]
Target = ArrayLike | Callable[[float], ArrayLike]  # V_Sd, or V_Sd(t)
Points = list[tuple[str, Array]]  # (Pinocchio frame name, target position) per chain end


class KernelResidual(crocoddyl.ResidualModelAbstract):  # type: ignore[misc]
    """r(x) = f(q) with ∂r/∂q from a kernel: ``evaluate(q) -> (r, J)``, or ``evaluate(q, parameter)``
    when a ``parameter`` vector is given (the task kernel's V_Sd; set it anew to move the target), q and
    J's columns in the system's joint order; ``order[i]`` is the Pinocchio velocity index of joint i."""

    def __init__(self, state: Any, nu: int, nr: int, evaluate: Callable[..., Any], order: NDArray[np.intp],
                 parameter: ArrayLike | None = None) -> None:
        crocoddyl.ResidualModelAbstract.__init__(self, state, nr, nu, True, False, False)
        self.function, self.order = evaluate, np.asarray(order)
        self.parameter = None if parameter is None else np.asarray(parameter, dtype=float)

    def evaluate(self, q: Array) -> tuple[ArrayLike, ArrayLike]:
        result: tuple[ArrayLike, ArrayLike] = self.function(q) if self.parameter is None else \
            self.function(q, self.parameter)
        return result

    def _q(self, x: Array) -> Array:
        return np.asarray(x)[self.order]  # (revolute and prismatic joints: Pinocchio's q is the angle)

    def calc(self, data: Any, x: Array, u: Array | None = None) -> None:
        r, _ = self.evaluate(self._q(x))
        data.r[:] = np.asarray(r, dtype=float).reshape(-1)

    def calcDiff(self, data: Any, x: Array, u: Array | None = None) -> None:
        _, jacobian = self.evaluate(self._q(x))
        data.Rx[:, self.order] = np.asarray(jacobian, dtype=float).reshape(self.nr, -1)


NATIVE_SOURCE = Path(__file__).with_name("crocoddyl_residual.cpp")
_NATIVE_LOCK = threading.Lock()
_NATIVE: dict[str, Any] = {}


THREADS = 1  # Crocoddyl's threads per shooting problem (see ``TorqueOCP.problem``)


def native_residuals() -> Any:
    """The C++ residual (``crocoddyl_residual.cpp``) compiled against the installed Crocoddyl, Pinocchio
    and Boost.Python headers into gagen's cache (once per source and library versions) and imported: its
    ``KernelResidual(state, nu, nr, address, parameter, order, has_parameter)`` calls a generated C
    kernel from Crocoddyl's loop. A CompileError when no C++ compiler or header is found."""
    with _NATIVE_LOCK:
        if "module" not in _NATIVE:
            _NATIVE["module"] = _compile_native()
        return _NATIVE["module"]


def _compile_native() -> Any:
    import importlib.util
    import sysconfig

    import pinocchio

    from gagen.control.native_build import cmeel_prefix, compile_cached

    prefix = cmeel_prefix()
    include = prefix / "include"
    python = sysconfig.get_paths()["include"]
    boost_python = f"boost_python{sys.version_info.major}{sys.version_info.minor}"
    # (Crocoddyl 3.2.1's headers include Pinocchio's 3.x paths, which Pinocchio 4 keeps under deprecated/)
    includes = [include, include / "pinocchio" / "deprecated", include / "eigen3", python]
    flags = ["-std=c++17", "-O2", "-fPIC", "-shared", "-w", *(f"-I{path}" for path in includes)]
    libraries = [f"-L{prefix / 'lib'}", "-lcrocoddyl", f"-l{boost_python}", "-lpinocchio_default",
                 f"-Wl,-rpath,{prefix / 'lib'}"]  # (after the source: the linker drops unneeded libraries)
    module, target = compile_cached(NATIVE_SOURCE, "crocoddyl", flags, libraries,
                                    f"{crocoddyl.__version__} {pinocchio.__version__}", extension=True)
    spec = importlib.util.spec_from_file_location(module, target)
    assert spec is not None and spec.loader is not None
    loaded = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(loaded)
    return loaded


def _circle_function() -> Any:
    """(p1, p2, p3) -> (centre, unit normal, radius) of their circle by 3-vector algebra, and its Jacobian
    (9 columns): what a Crocoddyl user writes for a circle, here with CasADi's AD for the derivatives."""
    import casadi as ca

    p = ca.SX.sym("p", 9)
    p1, p2, p3 = p[0:3], p[3:6], p[6:9]
    a, b = p1 - p3, p2 - p3
    axb = ca.cross(a, b)
    area2 = ca.dot(axb, axb)
    centre = p3 + ca.cross(ca.dot(a, a) * b - ca.dot(b, b) * a, axb) / (2 * area2)
    radius = ca.norm_2(a) * ca.norm_2(b) * ca.norm_2(a - b) / (2 * ca.sqrt(area2))
    value = ca.vertcat(centre, axb / ca.sqrt(area2), radius)
    return ca.Function("circle", [p], [value, ca.jacobian(value, p)])


class CircleResidual(crocoddyl.ResidualModelAbstract):  # type: ignore[misc]
    """The conventional circle error: (c − c_d, n − n_d, ρ − ρ_d) of the circle through three frames'
    origins (Pinocchio's placements and LOCAL_WORLD_ALIGNED Jacobians), by 3-vector algebra (7 rows)."""

    def __init__(self, state: Any, nu: int, frames: list[int], centre: ArrayLike, normal: ArrayLike,
                 radius: float) -> None:
        crocoddyl.ResidualModelAbstract.__init__(self, state, 7, nu, True, False, False)
        self.frames = frames
        self.reference = np.concatenate([np.asarray(centre, float), np.asarray(normal, float), [radius]])
        self.circle = _circle_function()
        self.pinocchio = require("pinocchio", "gagen.control.torque")
        self.data = state.pinocchio.createData()

    def _points(self, x: Array, jacobians: bool) -> tuple[Array, Array | None]:
        pin, model, data = self.pinocchio, self.state.pinocchio, self.data
        q = np.asarray(x)[:model.nq]
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        points = np.concatenate([data.oMf[f].translation for f in self.frames])
        if not jacobians:
            return points, None
        pin.computeJointJacobians(model, data, q)
        frame = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        rows = [pin.getFrameJacobian(model, data, f, frame)[:3] for f in self.frames]
        return points, np.vstack(rows)

    def calc(self, data: Any, x: Array, u: Array | None = None) -> None:
        points, _ = self._points(x, False)
        value, _ = self.circle(points)
        data.r[:] = np.asarray(value).reshape(-1) - self.reference

    def calcDiff(self, data: Any, x: Array, u: Array | None = None) -> None:
        points, jacobian = self._points(x, True)
        _, d_points = self.circle(points)
        data.Rx[:, :self.state.nv] = np.asarray(d_points) @ jacobian


def circle_through(points: Points) -> tuple[Array, Array, float]:
    """(centre, unit normal, radius) of the circle through three (frame, position) points."""
    value, _ = _circle_function()(np.concatenate([p for _, p in points]))
    value = np.asarray(value).reshape(-1)
    return value[:3], value[3:6], float(value[6])


def _plain_joints(dynamics: SystemDynamics) -> None:
    """Crocoddyl's state is Pinocchio's (q, q̇); a continuous joint's q there is (cos, sin)."""
    if dynamics.model.nq != dynamics.model.nv:
        raise ValueError("torque-level control supports revolute and prismatic joints; this system has "
                         "continuous joints (Pinocchio's (cos q, sin q) configuration)")


def _check_task(task: Any, dof: int, target: Array) -> None:
    """A ``task`` kernel of this system and a finite V_Sd of its size: the C++ residual calls the kernel's
    raw address, so a wrong size would read or write out of bounds. Kernels of a generated module carry
    their shapes; a plain function is held to V_Sd's size only."""
    inputs, outputs = getattr(task, "_in_shapes", None), getattr(task, "_out_shapes", None)
    if inputs is not None and outputs is not None:
        expected = ([(dof, 1), (12, 1)], [(7, 1), (7, dof)])
        if [tuple(s) for s in inputs] != expected[0] or [tuple(s) for s in outputs] != expected[1]:
            names = getattr(task, "inputs", ())
            shown = ", ".join(f"{n}[{s[0]}]" for n, s in zip(names, inputs, strict=False))
            raise ValueError(f"the kernel {getattr(task, 'name', '?')} takes ({shown}) and gives "
                             f"{[tuple(s) for s in outputs]}; a task residual needs (q[{dof}], V_Sd[12]) -> "
                             f"(e[7], J_Be[7 x {dof}]): the system's task kernel")
    if target.size != 12:
        raise ValueError(f"V_Sd: expected 12 values (a similarity versor), got {target.size}")
    if not np.all(np.isfinite(target)):
        raise ValueError("V_Sd: expected finite values")


def task_residual(state: Any, dynamics: SystemDynamics, task: Any, V_Sd: ArrayLike, *,
                  native: bool = False) -> Any:
    """The cooperative task error e(q) = log(V_Sc(q)~ V_Sd) and J_Be of a module's ``task`` kernel
    (usually ``module.c.task``) as a residual of ``state``'s model (7 rows): ``KernelResidual`` (Python),
    or with ``native`` the C++ one (``native_residuals``), which calls the kernel's C function itself."""
    _plain_joints(dynamics)
    target = np.asarray(V_Sd, dtype=float).reshape(-1)
    _check_task(task, dynamics.dof, target)
    if native:
        address = int(getattr(task, "address", 0) or 0)
        if not address:
            raise ValueError("the C++ residual needs a compiled kernel of a generated module (module.c.task)")
        return native_residuals().KernelResidual(state, dynamics.dof, 7, address, target,
                                                 np.asarray(dynamics.order, dtype=np.int32), True)
    return KernelResidual(state, dynamics.dof, 7, task, dynamics.order, target)


@dataclass(frozen=True)
class Weights:
    """The cost weights (see the module docstring)."""

    task: float = 1e2
    terminal: float = 1e5
    torque: float = 1e-4  # on τ − g(q)
    velocity: float = 1e-1
    terminal_velocity: float = 1e2
    limits: float = 1e6


@dataclass
class TorqueResult:
    """The solution: states xs (N+1 rows: q, q̇ in the system's order), torques us (N rows), the task
    error at every node, and the solver's account."""

    t: Array
    q: Array
    qdot: Array
    tau: Array
    errors: Array  # ‖e(q_k; V_Sd(t_k))‖
    iterations: int
    wall_time: float
    converged: bool
    cost: float
    torque_limit: Array
    position_limits: tuple[Array, Array]

    @property
    def error_norm(self) -> float:
        return float(self.errors[-1])


def _targets(target: Target, times: Array) -> list[Array]:
    if callable(target):
        return [np.asarray(target(float(t)), dtype=float) for t in times]
    fixed = np.asarray(target, dtype=float)
    return [fixed] * len(times)


def _limits(dynamics: SystemDynamics) -> tuple[Array, Array, Array, Array]:
    """(lower, upper, velocity, effort) of the model in Pinocchio's order: ±inf where the URDF has none."""
    model = dynamics.model

    def bounded(values: Any) -> Array:
        array = np.array(values, dtype=float)
        array[np.abs(array) >= 1e300] = np.inf  # Pinocchio's "no limit"
        return array

    return (-bounded(-np.asarray(model.lowerPositionLimit)), bounded(model.upperPositionLimit),
            bounded(model.velocityLimit), bounded(model.effortLimit))


def _native_possible(task: Any) -> bool:
    if not getattr(task, "address", 0):
        return False
    from gagen.codegen.compiler import CompileError

    try:
        native_residuals()
    except CompileError as e:
        warnings.warn(f"the task residual runs through Python: the C++ one did not compile ({e})",
                      stacklevel=3)
        return False
    return True


def _tip_links(spec: str | Path) -> dict[str, str]:
    """Each URDF chain's tip link by chain name (the frame of its end point in the Pinocchio model)."""
    import yaml

    return {c["name"]: c["tip_link"] for c in yaml.safe_load(Path(spec).read_text())["chains"]
            if isinstance(c, dict) and "tip_link" in c}


class TorqueOCP:
    """The cooperative reaching OCP of a system at the torque level (see the module docstring)."""

    def __init__(self, spec: str | Path, task: Any, *, N: int = 50, dt: float = 0.02,
                 weights: Weights = Weights(), torque_limits: bool = True, joint_limits: bool = True,
                 native: bool | None = None) -> None:
        self.dynamics = SystemDynamics(spec)
        _plain_joints(self.dynamics)
        self.task, self.N, self.dt, self.weights = task, int(N), float(dt), weights
        self.state = crocoddyl.StateMultibody(self.dynamics.model)
        self.actuation = crocoddyl.ActuationModelFull(self.state)
        self.lower, self.upper, self.velocity_limit, self.effort = _limits(self.dynamics)
        self.torque_limits, self.joint_limits = torque_limits, joint_limits
        self.tips = _tip_links(spec)
        self.solver: Any = None
        # the C++ residual where the kernel is compiled C and a C++ compiler is found, else the Python one
        self.native = _native_possible(task) if native is None else native

    def _model(self, V_Sd: Array, terminal: bool, points: Points | None = None, circle: bool = False) -> Any:
        w, nu, state = self.weights, self.actuation.nu, self.state
        costs = crocoddyl.CostModelSum(state, nu)
        weight = w.terminal if terminal else w.task
        if points is None:
            costs.addCost("task", crocoddyl.CostModelResidual(
                state, task_residual(state, self.dynamics, self.task, V_Sd, native=self.native)), weight)
        elif circle:  # the conventional circle error of the end points, by 3-vector algebra
            frames = [self.dynamics.model.getFrameId(frame) for frame, _ in points]
            costs.addCost("circle", crocoddyl.CostModelResidual(
                state, CircleResidual(state, nu, frames, *circle_through(points))), weight)
        else:  # the conventional formulation: each end point pinned to its target by Crocoddyl's residual
            for frame, position in points:
                residual = crocoddyl.ResidualModelFrameTranslation(
                    state, self.dynamics.model.getFrameId(frame), np.asarray(position, dtype=float), nu)
                costs.addCost(frame, crocoddyl.CostModelResidual(state, residual), weight)
        nq = self.dynamics.model.nq
        velocity = crocoddyl.ActivationModelWeightedQuad(np.concatenate([np.zeros(nq), np.ones(nq)]))
        costs.addCost("velocity", crocoddyl.CostModelResidual(
            state, velocity, crocoddyl.ResidualModelState(state, state.zero(), nu)),
            w.terminal_velocity if terminal else w.velocity)
        if not terminal:
            costs.addCost("torque", crocoddyl.CostModelResidual(
                state, crocoddyl.ResidualModelControlGrav(state, nu)), w.torque)
        if self.joint_limits:
            bounds = crocoddyl.ActivationBounds(
                np.concatenate([np.maximum(self.lower, -1e10), -np.minimum(self.velocity_limit, 1e10)]),
                np.concatenate([np.minimum(self.upper, 1e10), np.minimum(self.velocity_limit, 1e10)]))
            costs.addCost("limits", crocoddyl.CostModelResidual(
                state, crocoddyl.ActivationModelQuadraticBarrier(bounds),
                crocoddyl.ResidualModelState(state, state.zero(), nu)), w.limits)
        dam = crocoddyl.DifferentialActionModelFreeFwdDynamics(state, self.actuation, costs)
        model = crocoddyl.IntegratedActionModelEuler(dam, 0.0 if terminal else self.dt)
        if self.torque_limits and not terminal:
            model.u_lb, model.u_ub = -np.minimum(self.effort, 1e10), np.minimum(self.effort, 1e10)
        return model

    def problem(self, q0: ArrayLike, target: Target, qdot0: ArrayLike | None = None,
                points: Points | None = None, circle: bool = False) -> tuple[Any, Array]:
        """Crocoddyl's shooting problem from (q0, q̇0) toward ``target`` (V_Sd or V_Sd(t)), and the times;
        with ``points`` ((Pinocchio frame, target position) per chain end) a conventional formulation
        instead of the task error: each point pinned by a frame-translation residual, or with ``circle``
        (three points) the error of the circle through the ends from the circle through ``points``."""
        d = self.dynamics
        times = np.arange(self.N + 1, dtype=np.float64) * self.dt
        targets = _targets(target, times)
        x0 = np.concatenate([d._to_pin(q0), d._to_pin(np.zeros(d.dof) if qdot0 is None else qdot0)])
        running = [self._model(v, False, points, circle) for v in targets[:-1]]
        problem = crocoddyl.ShootingProblem(x0, running, self._model(targets[-1], True, points, circle))
        # one thread: the wheel's default (OpenMP, every core) made calc and calcDiff 30× slower on a
        # 2-core machine with MuJoCo and Python beside it (6.3 against 0.21 ms for 10 nodes)
        problem.nthreads = THREADS
        return problem, times

    def solve(self, q0: ArrayLike, target: Target, *, qdot0: ArrayLike | None = None,
              max_iterations: int = 200, warm: tuple[list[Array], list[Array]] | None = None,
              points: Points | None = None, circle: bool = False) -> TorqueResult:
        """Solve by box-FDDP from rest at q0 (or ``warm`` = (xs, us) in Crocoddyl's layout); ``points``,
        ``circle``: see ``problem`` (the result's errors are still the task error toward ``target``)."""
        problem, times = self.problem(q0, target, qdot0, points, circle)
        solver = crocoddyl.SolverBoxFDDP(problem)
        if warm is None:
            xs = [problem.x0] * (self.N + 1)
            us = list(problem.quasiStatic([problem.x0] * self.N))
        else:
            xs, us = warm
        start = time.perf_counter()
        converged = bool(solver.solve(xs, us, max_iterations, False))
        wall = time.perf_counter() - start
        self.solver = solver
        return self._result(solver, times, target, converged, wall)

    def end_points(self, q: ArrayLike) -> Points:
        """(Pinocchio frame, position) of every chain's end at q: the conventional formulation's targets
        when q reaches the goal (each chain's tip link; chains with a tool offset are not supported)."""
        d = self.dynamics
        data = d.model.createData()
        pinocchio = require("pinocchio", "gagen.control.torque")
        pinocchio.framesForwardKinematics(d.model, data, d._config(q))
        points = []
        for chain in d.system.chains:
            if chain.joints[-1].name == f"{chain.name}_tool":
                raise ValueError(f"chain {chain.name} has a tool offset: no Pinocchio frame at its end point")
            frame = f"{chain.robot or chain.name}/{self.tips[chain.name]}"
            points.append((frame, np.array(data.oMf[d.model.getFrameId(frame)].translation)))
        return points

    def _result(self, solver: Any, times: Array, target: Target, converged: bool,
                wall: float) -> TorqueResult:
        d, n = self.dynamics, self.dynamics.dof
        xs = np.array(solver.xs)
        q, qdot = xs[:, :n][:, d.order], xs[:, n:][:, d.order]
        tau = np.array(solver.us)[:, d.order]
        errors = np.array([np.linalg.norm(np.asarray(self.task(qk, v)[0]))
                           for qk, v in zip(q, _targets(target, times), strict=True)])
        return TorqueResult(times, q, qdot, tau, errors, int(solver.iter), wall, converged,
                            float(solver.cost), self.effort[d.order],
                            (self.lower[d.order], self.upper[d.order]))


def resimulate(dynamics: SystemDynamics, q0: ArrayLike, qdot0: ArrayLike, tau: ArrayLike,
               dt: float) -> tuple[Array, Array]:
    """The states the torques ``tau`` (N rows) give from (q0, q̇0) by Pinocchio's ABA through
    ``SystemDynamics.forward`` and symplectic Euler (q̇ += q̈ dt, then q += q̇ dt): an integration of
    our own, to hold a solver's trajectory to."""
    q, qdot = np.array(q0, dtype=float), np.array(qdot0, dtype=float)
    qs, qdots = [q.copy()], [qdot.copy()]
    for torque in np.asarray(tau, dtype=float):
        qdot = qdot + dynamics.forward(q, qdot, torque) * dt
        q = q + qdot * dt
        qs.append(q.copy())
        qdots.append(qdot.copy())
    return np.array(qs), np.array(qdots)
