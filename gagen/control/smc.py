"""Sliding-mode pose tracking of a serial arm [SMC Sections V-VI], as a generated C step and a 1 kHz loop.

Pose [SMC V.A, Eq. 16-20, 43]: x = [x_p; d] ∈ R⁶, the end point's position x_p (the e1, e2, e3
coefficients of P = V_M e0 V_M~) and the direction d of the tool line L'_p = V_M L_p V_M~, with L_p the
tool's z axis through its origin (the bivector e12, gagen's ``TOOL_LINE``). A line bivector
n3 e12 − n2 e13 + n1 e23 + (moment) has direction n, so d = (L'_p[e23], −L'_p[e13], L'_p[e12]).
The reference of the paper's simulation is exactly such a pair, x_ref = [x_Mref, L_Mref]
(Eq. 33, 43): x_ref(t) = [−0.3 + 0.1 cos 2t, 0.15, 0.25, 0, 1, 0].

Jacobian [SMC Eq. 17-20]: with the joint lines L'_j (the generators carried by the motors before
joint j, from ``kinematics.chain_pose``), the point rows are the Euclidean part of the commutators
P × L'_j (Eq. 18, [COOP Eq. 17]) and the direction rows the direction of α_j = ½(L'_p L'_j − L'_j L'_p)
(Eq. 19-20). d is a unit vector, so ḋ ⊥ d and J (6 × n) has rank at most 5: J Jᵀ is singular, and the
pseudo-inverse must be damped.

Controller [SMC Eq. 32-40]: ẋ = J u + λ, s = x − x_ref, u = −J⁺ K tanh(ε s) with the sign function
replaced by tanh (Eq. 39-40) and J⁺ = Jᵀ(J Jᵀ + λ_d² I)⁻¹ the damped pseudo-inverse, solved in the
step kernel by an explicit LDLᵀ factorisation of the 6 × 6 J Jᵀ + λ_d² I (positive definite for
λ_d > 0), unrolled on plain scalars. K = diag(k_1 … k_6) is in task space as in Eq. 36 (the paper's
K = diag{7.5, …} multiplies tanh(ε s); with equal gains K J⁺ = J⁺ K). Inside the boundary layer
(tanh(ε s) ≈ ε s) the error obeys ṡ ≈ −K ε s − ẋ_ref + λ, so it settles at |s_i| ≲ (|ẋ_ref| + |λ|)/(k ε)
(0.2 / (7.5 · 50) = 5.3e-4 for the paper's reference at the default ε = 50), after a transient in which
tanh saturates and each coordinate closes at up to k per second (Eq. 38: k > |ẋ_ref| + |λ|).
At the loop's rate the Euler-discretised boundary layer is stable for k ε dt < 2 (0.375 at 1 kHz).

Pieces:

- ``step_law`` / ``step_kernel``: the step as one function over the multivector protocol (pose and
  Jacobian from ``kinematics``, the law on plain scalars, ``damped_solve``), declared as the
  front-end kernel ``step`` (q, x_ref -> x, J, u): traced for the compiler, and the same function on
  the reference interpreter is its reference; ``smc_step_function`` is its CasADi Function and
  ``sx_step_function`` the step built directly in CasADi SX (the earlier construction, kept as the
  op-count baseline);
- ``build``: the module ``smc`` (``smc.h``/``smc.c`` with ``smc_step``, library, CPython binding)
  through ``gagen.build.build_source``, as every module is built, and the real-time loop runner
  ``smc_loop`` (``smc_loop.c`` next to this module, compiled with the module's C);
- ``CompiledStep``: the compiled step from Python (``gagen.load(module).c.step``); ``simulate``: the
  same loop in Python/numpy, tick for tick identical to the C runner (the runner uses nominal tick
  times);
- ``run_loop`` / ``bench_step``: run the C loop at a fixed rate, or the step in a tight loop;
- ``read_log`` / ``plot_run``: the per-tick CSV and plots like the paper's Figs. 6-8.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import subprocess
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.algebra.multivector import SparseMultivector
from gagen.algebra.signature import cga3d
from gagen.apps.cooperative.catalogue import TOOL_LINE
from gagen.codegen.backends.c import library as c_library
from gagen.codegen.compiler import (
    FLAGS,
    CompileError,
    find_compiler,
    vector_math_defines,
    vector_math_libraries,
)
from gagen.codegen.ir import ModuleSource
from gagen.frontend import KernelFunction, cache_root, matrix, scalars, source_of
from gagen.model import kinematics as kin
from gagen.model.conformal import EUCLID, point
from gagen.model.kinematics import Joint
from gagen.symbolic.casadi_backend import CasadiBackend

POSE = ("px", "py", "pz", "dx", "dy", "dz")
"""The pose coordinates: end point position, then the tool line's direction."""
GAIN = 7.5  # [SMC VI]: K = diag{7.5, …, 7.5}
EPSILON = 50.0  # tanh slope (Eq. 40); the paper does not state it
DAMPING = 1e-2  # λ_d of J⁺ = Jᵀ(J Jᵀ + λ_d² I)⁻¹
PANDA_Q0 = (2.5, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
"""Default start for the 7-DOF Panda: its ``ready`` pose with joint 1 turned to 2.5 rad (within its
±2.8973 limit), facing the paper's reference, which lies behind the base at azimuth 143°."""
LOOP_SOURCE = Path(__file__).with_name("smc_loop.c")
MODULE = "smc"  # the generated module: smc.h / smc.c
KERNEL = "step"  # its one kernel: the C function smc_step


# -- the reference trajectory [SMC Eq. 43] -----------------------------------------------------------
def reference(t: float) -> NDArray[np.float64]:
    """x_ref(t) = [−0.3 + 0.1 cos 2t, 0.15, 0.25, 0, 1, 0] [SMC Eq. 43] (the C runner's ``reference``,
    with the same operations: math.cos is the C library's cos)."""
    return np.array([-0.3 + 0.1 * math.cos(2.0 * t), 0.15, 0.25, 0.0, 1.0, 0.0])


def reference_rate(t: float) -> NDArray[np.float64]:
    """ẋ_ref(t) = [−0.2 sin 2t, 0, 0, 0, 0, 0] [SMC Eq. 43]."""
    return np.array([-0.2 * math.sin(2.0 * t), 0.0, 0.0, 0.0, 0.0, 0.0])


# -- the step, on both paths -------------------------------------------------------------------------
def _direction(line: Any) -> list[Any]:
    """Direction n of a line bivector n3 e12 − n2 e13 + n1 e23 + moment."""
    return [line["e23"], -line["e13"], line["e12"]]


def pose_and_jacobian_of(ga: Any, joints: Sequence[Joint],
                         q: Sequence[Any]) -> tuple[list[Any], list[list[Any]]]:
    """(x, J) on any path (``ga``: the zero multivector of the interpreter's or the compiler's path):
    the pose [x_p; d] (6 scalars) and its Jacobian as n columns of 6 scalars, from the joint lines
    [SMC Eq. 17-20]."""
    motor, lines, position = kin.chain_pose(ga, joints, q)
    point_columns = kin.point_jacobian(motor, lines, point(position))  # P × L'_j  (Eq. 18)
    tool = ga.make({TOOL_LINE: 1})
    line_columns = kin.line_jacobian(motor, lines, tool)  # α_j = ½(L'_p L'_j − L'_j L'_p)  (Eq. 20)
    x = [position[b] for b in EUCLID] + _direction(motor.sandwich(tool))
    J = [[p[b] for b in EUCLID] + _direction(a) for p, a in zip(point_columns, line_columns, strict=True)]
    return x, J


def pose_and_jacobian(joints: Sequence[Joint], q: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(x, J) on CasADi symbols: the pose (6) and its Jacobian (6 × n), as gagen built them before the
    front-end kernel (each coefficient made one SX node, the signs taken in SX): the baseline of
    ``sx_step_function``."""
    backend = CasadiBackend()
    zero = SparseMultivector(cga3d(), backend, {})
    motor, lines, position = kin.chain_pose(zero, joints, [backend.lift(q[i]) for i in range(q.numel())])
    point_columns = kin.point_jacobian(motor, lines, point(position))
    tool = zero.make({TOOL_LINE: 1})
    line_columns = kin.line_jacobian(motor, lines, tool)
    native = backend.native

    def direction(line: Any) -> list[ca.SX]:
        return [native(line["e23"]), -native(line["e13"]), native(line["e12"])]

    x = ca.vertcat(*[native(position[b]) for b in EUCLID], *direction(motor.sandwich(tool)))
    J = ca.horzcat(*[ca.vertcat(*[native(p[b]) for b in EUCLID], *direction(a))
                     for p, a in zip(point_columns, line_columns, strict=True)])
    return x, J


def _sum(terms: Sequence[Any]) -> Any:
    total = terms[0]
    for t in terms[1:]:
        total = total + t
    return total


def damped_solve(J: Sequence[Sequence[Any]], r: Sequence[Any], damping: float) -> list[Any]:
    """w = (J Jᵀ + λ_d² I)⁻¹ r by an unrolled LDLᵀ factorisation (no pivoting: the matrix is symmetric
    positive definite for λ_d > 0, its eigenvalues ≥ λ_d²; no square roots), on plain scalars: floats,
    the compiler's symbolic scalars or CasADi SX elements. ``J``: k rows of n (``J[i][m]``); ``r``: k.
    Only the upper triangle of J Jᵀ is formed, and each pivot divides (L_ij = C_ij / D_j, z = y / D)."""
    if not damping > 0:
        raise ValueError(f"damping must be > 0 (J Jᵀ of a pose with a unit direction is singular), "
                         f"got {damping}")
    k, n = len(J), len(J[0])
    A: list[list[Any]] = [[None] * k for _ in range(k)]
    for i in range(k):
        for j in range(i, k):
            A[i][j] = _sum([J[i][m] * J[j][m] for m in range(n)])
        A[i][i] = A[i][i] + damping * damping
    L: list[list[Any]] = [[None] * k for _ in range(k)]
    C: list[list[Any]] = [[None] * k for _ in range(k)]  # C_ij = L_ij D_j
    D: list[Any] = [None] * k
    for j in range(k):
        D[j] = A[j][j] - _sum([C[j][m] * L[j][m] for m in range(j)]) if j else A[j][j]
        for i in range(j + 1, k):
            C[i][j] = A[j][i] - _sum([C[i][m] * L[j][m] for m in range(j)]) if j else A[j][i]
            L[i][j] = C[i][j] / D[j]
    y: list[Any] = [None] * k
    for i in range(k):
        y[i] = r[i] - _sum([L[i][m] * y[m] for m in range(i)]) if i else r[i]
    w: list[Any] = [None] * k
    for i in reversed(range(k)):
        z = y[i] / D[i]
        w[i] = z - _sum([L[m][i] * w[m] for m in range(i + 1, k)]) if i < k - 1 else z
    return w


def _gains(K: float | Sequence[float], k: int) -> list[float]:
    gains = [float(K)] * k if np.isscalar(K) else [float(g) for g in K]  # type: ignore[arg-type]
    if len(gains) != k or not all(g > 0 for g in gains):
        raise ValueError(f"K must be a positive scalar or {k} positive task-space gains, got {K}")
    return gains


def _checked(K: float | Sequence[float], epsilon: float, damping: float) -> list[float]:
    if not (math.isfinite(float(epsilon)) and epsilon > 0):
        raise ValueError(f"epsilon must be > 0, got {epsilon}")
    if not (math.isfinite(float(damping)) and damping > 0):
        raise ValueError(f"damping must be > 0 (J Jᵀ of a pose with a unit direction is singular), "
                         f"got {damping}")
    return _gains(K, len(POSE))


def step_law(joints: Sequence[Joint], gains: Sequence[float], epsilon: float,
             damping: float) -> Callable[[Any, Sequence[Any], Sequence[Any]], dict[str, Any]]:
    """The step as one function over the multivector protocol, ``step(ga, q, x_ref) -> {x, J, u}``: the
    pose and Jacobian (``pose_and_jacobian_of``), r = K tanh(ε (x − x_ref)) [Eq. 40] and
    u = −Jᵀ (J Jᵀ + λ_d² I)⁻¹ r [Eq. 35]. It runs on the reference interpreter (floats) and on the
    compiler's path (symbolic scalars) alike."""
    joints = tuple(joints)

    def step(ga: Any, q: Sequence[Any], x_ref: Sequence[Any]) -> dict[str, Any]:
        x, J = pose_and_jacobian_of(ga, joints, q)
        # each pose and Jacobian entry is one value, reused by the solve (on the compiler's path, one
        # node each, as the outputs have them: cheaper than expanding their sums into every product)
        shared = ga.math.shared
        x = [shared(v) for v in x]
        J = [[shared(v) for v in column] for column in J]
        r = [g * ga.math.tanh(epsilon * (xi - ri)) for g, xi, ri in zip(gains, x, x_ref, strict=True)]
        w = damped_solve([[column[i] for column in J] for i in range(len(POSE))], r, damping)
        u = [-_sum([column[i] * w[i] for i in range(len(POSE))]) for column in J]
        return {"x": x, "J": J, "u": u}

    return step


def step_kernel(joints: Sequence[Joint] | None = None, *, K: float | Sequence[float] = GAIN,
                epsilon: float = EPSILON, damping: float = DAMPING) -> KernelFunction:
    """The sliding-mode step as a front-end kernel ``step`` over cga3d: (q[n], x_ref[6]) -> (x[6],
    J[6×n], u[n]) with x the pose, J its Jacobian [SMC Eq. 17-20] and u = −J⁺ K tanh(ε (x − x_ref))
    [Eq. 35, 40], J⁺ = Jᵀ(J Jᵀ + λ_d² I)⁻¹ (λ_d = ``damping``). ``K``: a scalar or 6 task-space gains.
    Its function (``step_law``) is also its reference on the interpreter. ``joints``: default the
    bundled Panda (``panda_point``'s arm)."""
    joints = tuple(joints) if joints is not None else _panda_joints()
    gains = _checked(K, epsilon, damping)
    variables = tuple(kin.chain_variables(joints))  # mimic joints follow their leader: no entry of their own
    n = len(variables)

    def sample(rng: np.random.Generator) -> list[np.ndarray]:
        return [rng.uniform(-2.5, 2.5, n), reference(rng.uniform(0.0, math.pi))]

    return KernelFunction(
        step_law(joints, gains, float(epsilon), float(damping)), algebra=cga3d(), name=KERNEL,
        doc="sliding-mode pose tracking step [SMC Eq. 17-20, 35, 40]: pose x, its Jacobian J and "
            "u = -J+ K tanh(eps (x - x_ref))",
        inputs={"ga": "algebra", "q": scalars(n, variables), "x_ref": scalars(len(POSE), POSE)},
        outputs={"x": scalars(len(POSE), POSE), "J": matrix(scalars(len(POSE), POSE), n),
                 "u": scalars(n, variables)},
        sample=sample)


def smc_step_function(joints: Sequence[Joint] | None = None, *, K: float | Sequence[float] = GAIN,
                      epsilon: float = EPSILON, damping: float = DAMPING) -> ca.Function:
    """The compiled step's CasADi SX Function (``step_kernel(...).trace().function``):
    (q[n], x_ref[6]) -> (x[6], J[6×n], u[n])."""
    return step_kernel(joints, K=K, epsilon=epsilon, damping=damping).trace().function


def sx_step_function(joints: Sequence[Joint] | None = None, *, K: float | Sequence[float] = GAIN,
                     epsilon: float = EPSILON, damping: float = DAMPING) -> ca.Function:
    """The step built directly in CasADi SX, as gagen did before the front-end kernel: the pose and
    Jacobian as SX, then the law in SX operations. Kept as a cross-check and as the op-count baseline
    the kernel must not exceed."""
    joints = tuple(joints) if joints is not None else _panda_joints()
    gains = _checked(K, epsilon, damping)
    q = ca.SX.sym("q", len(kin.chain_variables(joints)))
    x_ref = ca.SX.sym("x_ref", len(POSE))
    x, J = pose_and_jacobian(joints, q)
    r = ca.vertcat(*[gains[i] * ca.tanh(epsilon * (x[i] - x_ref[i])) for i in range(len(POSE))])
    rows = [[J[i, m] for m in range(J.shape[1])] for i in range(len(POSE))]
    w = damped_solve(rows, [r[i] for i in range(len(POSE))], damping)
    u = -ca.mtimes(J.T, ca.vertcat(*w))
    return ca.Function("smc_step_sx", [q, x_ref], ca.cse([x, J, u]), ["q", "x_ref"], ["x", "J", "u"])


# -- C: the module and the runner --------------------------------------------------------------------
@dataclass(frozen=True)
class SmcBuild:
    """A built step: the folder, the generated module (``module``: ``smc.h``/``smc.c`` with
    ``smc_step``, its library and CPython binding, built by ``gagen.build.build_source``), the loop
    runner, and the parameters (``meta``: n, k, K, epsilon, damping, q0, op count)."""

    folder: Path
    source: Path
    header: Path
    library: Path
    runner: Path
    meta: dict[str, Any] = field(default_factory=dict)
    module: Path | None = None

    @property
    def q0(self) -> NDArray[np.float64]:
        return np.array(self.meta["q0"], dtype=float)

    def step(self) -> CompiledStep:
        return CompiledStep(self.module or self.source.parent)


def _panda_joints() -> tuple[Joint, ...]:
    from gagen.apps.cooperative.bundled import bundled_systems

    return tuple(bundled_systems()["panda_point"].chains[0].joints)


def step_source(joints: Sequence[Joint] | None = None, *, K: float | Sequence[float] = GAIN,
                epsilon: float = EPSILON, damping: float = DAMPING) -> ModuleSource:
    """The module ``smc`` of the one kernel ``step`` (C function ``smc_step``), for
    ``gagen.build.build_source``; its manifest records the parameters under ``"smc"``."""
    joints = tuple(joints) if joints is not None else _panda_joints()
    kernel = step_kernel(joints, K=K, epsilon=epsilon, damping=damping)
    params = {"joints": [j.name for j in joints], "K": _gains(K, len(POSE)), "epsilon": float(epsilon),
              "damping": float(damping)}
    source = source_of([kernel], MODULE, "gagen.control.smc",
                       json.dumps([repr(joints), params]).encode(), "gagen smc")
    source.title = "sliding-mode pose tracking step [SMC Eq. 17-20, 35, 40]"
    source.meta["smc"] = params
    return source


def _start(q0: Sequence[float] | None, n: int) -> list[float]:
    if q0 is None:
        q0 = PANDA_Q0 if n == len(PANDA_Q0) else (0.0,) * n
    values = [float(v) for v in q0]
    if len(values) != n:
        raise ValueError(f"q0 needs {n} joint values, got {len(values)}")
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"q0 must be finite, got {values}")
    return values


def _compile_runner(module: Path, manifest: dict[str, Any], q0: Sequence[float], runner: Path) -> None:
    """``smc_loop.c`` with the module's C (``smc.c`` and its SIMD companion) into the executable
    ``runner`` (gagen's compiler flags, so the step gives the library's doubles); the start q0 comes
    as ``-DSMC_LOOP_Q0=a,b,…`` (finite doubles, Python's repr: numbers only)."""
    c_source = module / manifest["c_source"]
    units = [LOOP_SOURCE, c_source]
    simd = c_source.with_name(f"{c_source.stem}_simd.c")
    if simd.is_file():
        units.append(simd)
    flags = [f for f in FLAGS if f not in ("-shared", "-fPIC")]
    partial = runner.with_name(runner.name + f".{os.getpid()}.partial")
    command = [*find_compiler(), *flags, *vector_math_defines(), f"-I{module}",
               f"-DSMC_LOOP_Q0={','.join(map(repr, q0))}",
               "-o", str(partial), *map(str, units), *vector_math_libraries(), "-lm"]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        partial.unlink(missing_ok=True)
        raise CompileError(f"{' '.join(command)} failed:\n{result.stderr.strip()}")
    partial.replace(runner)


def build(joints: Sequence[Joint] | None = None, *, K: float | Sequence[float] = GAIN,
          epsilon: float = EPSILON, damping: float = DAMPING, q0: Sequence[float] | None = None,
          folder: str | Path | None = None, force: bool = False,
          progress: Callable[[str], None] | None = None) -> SmcBuild:
    """Build (or reuse) the step module and the loop runner for ``joints`` (default: the bundled Panda,
    ``panda_point``'s arm) in ``folder``: the module ``smc/`` through ``gagen.build.build_source`` (its
    cache: rebuilt only when out of date) and the executable ``smc_loop`` beside it. Without ``folder``:
    ``gagen.frontend.cache_root() / "smc-<key>"``, keyed by the kernel's content, the start q0 and the
    loop's source; the runner is compiled when the module was (re)built or it is missing (and always
    with ``force`` or in a ``folder`` given here, which no key names). ``q0``: the runner's default
    start (the Panda's ``PANDA_Q0`` for 7 joints, else zeros)."""
    from gagen.build import build_source

    find_compiler()  # CompilerNotFound before anything is built: the runner needs the compiler
    source = step_source(joints, K=K, epsilon=epsilon, damping=damping)
    kernel = source.kernels[KERNEL]
    n, k = kernel.inputs[0].size, kernel.inputs[1].size
    start = _start(q0, n)
    key = hashlib.sha256(json.dumps([source.key, source.source_hash, start,
                                     hashlib.sha256(LOOP_SOURCE.read_bytes()).hexdigest()]).encode())
    root = Path(folder) if folder is not None else cache_root() / f"smc-{key.hexdigest()[:16]}"
    root.mkdir(parents=True, exist_ok=True)
    module, runner = root / MODULE, root / "smc_loop"
    result = build_source(source, module, force=force, compile_c=True, progress=progress or (lambda _: None))
    manifest = json.loads((result.folder / "manifest.json").read_text())
    if not result.compiled:
        raise CompileError(f"the step module in {result.folder} was written but not compiled")
    if force or folder is not None or not result.cached or not runner.is_file():
        _compile_runner(result.folder, manifest, start, runner)
    ops = kernel.op_count
    meta = {**source.meta["smc"], "n": n, "k": k, "q0": start, "op_count": str(ops), "flops": ops.flops,
            "calls": ops.calls, "key": key.hexdigest()[:16]}
    return SmcBuild(root, result.folder / manifest["c_source"], result.folder / manifest["c_header"],
                    result.folder / c_library(manifest), runner, meta, result.folder)


# -- the step from Python --------------------------------------------------------------------------
class CompiledStep:
    """The compiled ``smc_step`` of a built module (``gagen.load(module).c.step``, the CPython
    binding): ``step(q, x_ref) -> (x, J (k × n), u)`` (fresh arrays)."""

    def __init__(self, module: str | Path) -> None:
        import gagen

        self.module = gagen.load(module)
        self._f = self.module.c.step
        entry = self.module.entry(KERNEL)
        self.n = len(entry["inputs"][0]["rows"])
        self.k = len(entry["inputs"][1]["rows"])

    def __call__(self, q: ArrayLike, x_ref: ArrayLike) -> tuple[NDArray, NDArray, NDArray]:
        q = np.asarray(q, dtype=np.float64)
        x_ref = np.asarray(x_ref, dtype=np.float64)
        if q.shape != (self.n,) or x_ref.shape != (self.k,):
            raise ValueError(f"smc_step takes q[{self.n}] and x_ref[{self.k}], got {q.shape}, {x_ref.shape}")
        x, J, u = self._f(q, x_ref)
        return x, J, u


def casadi_step(function: ca.Function) -> Callable[[ArrayLike, ArrayLike], tuple[NDArray, NDArray, NDArray]]:
    """``smc_step_function``'s Function as a step callable for ``simulate`` (CasADi's VM)."""

    def step(q: ArrayLike, x_ref: ArrayLike) -> tuple[NDArray, NDArray, NDArray]:
        x, J, u = function(np.asarray(q, dtype=float), np.asarray(x_ref, dtype=float))
        return np.asarray(x).ravel(), np.asarray(J), np.asarray(u).ravel()

    return step


@dataclass
class Simulation:
    """A closed-loop run, one row per tick k (t_k = k dt): the state q_k before the step, the pose x_k,
    the reference, the control u_k and s_k = x_k − x_ref(t_k)."""

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    x: NDArray[np.float64]
    x_ref: NDArray[np.float64]
    u: NDArray[np.float64]

    @property
    def s(self) -> NDArray[np.float64]:
        return self.x - self.x_ref

    def error_after(self, transient: float) -> float:
        """max |s_i| over the ticks with t ≥ ``transient``."""
        return float(np.abs(self.s[self.t >= transient]).max())

    def write_csv(self, path: str | Path) -> Path:
        """The runner's CSV layout (lateness and work 0)."""
        s = self.s
        columns = np.column_stack([self.t, self.q, self.x, self.x_ref, self.u,
                                   np.linalg.norm(s[:, :3], axis=1), np.linalg.norm(s[:, 3:], axis=1),
                                   np.abs(s).max(axis=1), np.zeros((len(self.t), 2))])
        path = Path(path)
        np.savetxt(path, columns, delimiter=",", fmt="%.17g", header=",".join(_csv_header(self.q.shape[1])),
                   comments="")
        return path


def simulate(step: Callable[[ArrayLike, ArrayLike], tuple[Any, Any, Any]], q0: ArrayLike, duration: float,
             dt: float, *, reference: Callable[[float], NDArray] = reference,
             disturbance: Callable[[float], ArrayLike] | None = None) -> Simulation:
    """The C runner's loop in Python: round(duration / dt) ticks of x_ref(t_k), (x, J, u) = step(q, x_ref),
    q += u dt, with t_k = k dt. With the compiled step (``CompiledStep``) and dt = 1/rate it gives the
    runner's log bit for bit. ``disturbance(t)``: an optional joint-velocity disturbance d added to u
    in the integration (q += (u + d) dt), i.e. λ = J d in ẋ = J u + λ [SMC Eq. 32]."""
    q = np.array(q0, dtype=float)
    if not np.all(np.isfinite(q)):
        raise ValueError(f"q0 must be finite, got {q}")
    _finite("duration", duration, "s", positive=True)
    _finite("dt", dt, "s", positive=True)
    ticks = round(duration / dt)
    if ticks < 1:
        raise ValueError(f"a duration of {duration:g} s is less than one tick of {dt:g} s")
    rows: dict[str, list] = {"t": [], "q": [], "x": [], "x_ref": [], "u": []}
    for k in range(ticks):
        t = k * dt
        xr = reference(t)
        x, _, u = step(q, xr)
        for name, value in (("t", t), ("q", q.copy()), ("x", x), ("x_ref", xr), ("u", u)):
            rows[name].append(value)
        q = q + (u if disturbance is None else u + np.asarray(disturbance(t), dtype=float)) * dt
    return Simulation(*(np.array(rows[name], dtype=float) for name in ("t", "q", "x", "x_ref", "u")))


# -- the real-time loop ----------------------------------------------------------------------------
def _csv_header(n: int) -> list[str]:
    return ["t", *[f"q{i + 1}" for i in range(n)], *POSE, *[f"ref_{p}" for p in POSE],
            *[f"u{i + 1}" for i in range(n)], "position_error", "direction_error", "error_max", "lateness",
            "work"]


@dataclass(frozen=True)
class LoopSummary:
    """What ``smc_loop`` printed: timing (rates in Hz, times in µs) and the tracking error after the
    transient (max |s_i|, its RMS, and the norms of the position and direction errors)."""

    scheduler: str
    rate_hz: float
    ticks: int
    wall_s: float
    achieved_rate_hz: float
    deadline_misses: int
    jitter_mean_us: float
    jitter_std_us: float
    jitter_max_us: float
    work_mean_us: float
    work_max_us: float
    transient_s: float
    settled_ticks: int
    error_max: float
    error_rms: float
    position_error_max: float
    direction_error_max: float
    final_q: tuple[float, ...]
    csv: Path | None = None


def _parse(output: str) -> dict[str, str]:
    return dict(line.split("=", 1) for line in output.splitlines() if "=" in line)


def _finite(name: str, value: Any, unit: str, *, positive: bool) -> None:
    """ValueError unless value is a finite real number > 0 (``positive``) or >= 0."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value < 0 or (positive and value == 0):
        raise ValueError(f"{name} must be a finite number of {unit} {'>' if positive else '>='} 0, "
                         f"got {value!r}")


def loop_ticks(duration: float, rate: float, transient: float = 0.0) -> int:
    """The number of ticks of a ``duration`` s run at ``rate`` Hz, as the C loop counts them
    (round half away from zero); ValueError for a non-finite or non-positive duration or rate, a run
    shorter than one tick, or a ``transient`` (s) that is negative, non-finite or leaves no tick after it."""
    _finite("duration", duration, "s", positive=True)
    _finite("rate", rate, "Hz", positive=True)
    _finite("transient", transient, "s", positive=False)
    ticks = math.floor(duration * rate + 0.5)
    if ticks < 1:
        raise ValueError(f"a duration of {duration:g} s at {rate:g} Hz is less than one tick: give at least "
                         f"{0.5 / rate:g} s (one tick is {1 / rate:g} s)")
    if transient > (ticks - 1) * (1.0 / rate):  # the last tick's t, as the C loop computes it
        raise ValueError(f"transient {transient:g} s leaves no tick to measure the tracking error in a "
                         f"run of {ticks} ticks ({duration:g} s at {rate:g} Hz): give a shorter transient")
    return ticks


def run_loop(duration: float = 10.0, rate: float = 1000.0, csv: str | Path | None = None, *,
             q0: Sequence[float] | None = None, transient: float = 0.5, fifo: bool = False,
             smc: SmcBuild | None = None, timeout: float | None = None) -> LoopSummary:
    """Build (cached) and run the C loop for ``duration`` s at ``rate`` Hz; log to ``csv`` if given.
    ``fifo``: ask for SCHED_FIFO and locked memory (best effort, reported in ``scheduler``). The
    arguments are checked first (``loop_ticks``), before anything is built."""
    loop_ticks(duration, rate, transient)
    if q0 is not None and not all(math.isfinite(float(v)) for v in q0):
        raise ValueError(f"q0 must be finite, got {list(q0)}")
    smc = smc or build()
    command = [str(smc.runner), "--rate", repr(float(rate)), "--duration", repr(float(duration)),
               "--transient", repr(float(transient))]
    if q0 is not None:
        command += ["--q0", ",".join(repr(float(v)) for v in q0)]
    if csv is not None:
        command += ["--csv", str(csv)]
    if fifo:
        command.append("--fifo")
    result = subprocess.run(command, capture_output=True, text=True,
                            timeout=timeout if timeout is not None else duration * 3 + 30)
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed ({result.returncode}):\n{result.stderr}")
    v = _parse(result.stdout)
    floats = ("rate_hz", "wall_s", "achieved_rate_hz", "jitter_mean_us", "jitter_std_us", "jitter_max_us",
              "work_mean_us", "work_max_us", "transient_s", "error_max", "error_rms", "position_error_max",
              "direction_error_max")
    return LoopSummary(scheduler=v["scheduler"], ticks=int(v["ticks"]),
                       deadline_misses=int(v["deadline_misses"]), settled_ticks=int(v["settled_ticks"]),
                       final_q=tuple(float(a) for a in v["final_q"].split(",")),
                       csv=Path(csv) if csv is not None else None, **{k: float(v[k]) for k in floats})


def bench_step(steps: int = 200_000, repeats: int = 21, smc: SmcBuild | None = None) -> dict[str, float]:
    """Steps per second of the C step (+ the Euler update) in a tight loop: the median over ``repeats``
    loops of ``steps`` (also ns_per_step, min and max)."""
    smc = smc or build()
    result = subprocess.run([str(smc.runner), "--bench", str(steps), "--repeats", str(repeats)],
                            capture_output=True, text=True, check=True)
    v = _parse(result.stdout)
    return {k: float(v[k]) for k in ("steps_per_second", "ns_per_step", "steps_per_second_min",
                                     "steps_per_second_max")}


# -- logs and plots --------------------------------------------------------------------------------
def read_log(csv: str | Path) -> dict[str, NDArray[np.float64]]:
    """The runner's (or ``Simulation.write_csv``'s) CSV as column name -> array."""
    path = Path(csv)
    with path.open() as f:
        names = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {name: data[:, i] for i, name in enumerate(names)}


def plot_run(csv: str | Path, out_folder: str | Path, *, transient: float | None = 0.5) -> list[Path]:
    """Plots of a run like the paper's Figs. 6-8 (matplotlib, Agg): ``pose.png`` (the point and the
    direction with their references, Fig. 6), ``error.png`` (position and direction error norms, log
    scale), ``joint_velocities.png`` (u = q̇, Fig. 7) and ``joint_positions.png`` (q, Fig. 8)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    log = read_log(csv)
    out = Path(out_folder)
    out.mkdir(parents=True, exist_ok=True)
    t = log["t"]
    n = sum(1 for name in log if name.startswith("u") and name[1:].isdigit())
    written = []

    def save(fig: Figure, name: str) -> None:
        FigureCanvasAgg(fig)
        fig.tight_layout()
        path = out / name
        fig.savefig(path, dpi=110)
        written.append(path)

    fig = Figure(figsize=(11, 6))
    labels = ("x [m]", "y [m]", "z [m]", "direction x", "direction y", "direction z")
    for i, (name, label) in enumerate(zip(POSE, labels, strict=True)):
        ax = fig.add_subplot(2, 3, i + 1)
        ax.plot(t, log[name], label="end effector")
        ax.plot(t, log[f"ref_{name}"], "--", label="reference")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        if i == 0:
            ax.legend(fontsize=8)
    fig.suptitle("Pose tracking: end point and tool line direction (cf. [SMC] Fig. 6)")
    save(fig, "pose.png")

    fig = Figure(figsize=(8, 4))
    ax = fig.add_subplot(1, 1, 1)
    floor = 1e-12
    ax.semilogy(t, np.maximum(log["position_error"], floor), label="|x_p − x_p,ref| [m]")
    ax.semilogy(t, np.maximum(log["direction_error"], floor), label="|d − d_ref|")
    ax.semilogy(t, np.maximum(log["error_max"], floor), ":", label="max |s_i|")
    if transient is not None:
        ax.axvline(transient, color="gray", lw=0.8)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("tracking error")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.suptitle("Tracking error s = x − x_ref")
    save(fig, "error.png")

    for name, prefix, ylabel, title in (
            ("joint_velocities.png", "u", "q̇ [rad/s]", "Control: joint velocities u (cf. [SMC] Fig. 7)"),
            ("joint_positions.png", "q", "q [rad]", "Joint positions (cf. [SMC] Fig. 8)")):
        fig = Figure(figsize=(8, 4))
        ax = fig.add_subplot(1, 1, 1)
        for i in range(n):
            ax.plot(t, log[f"{prefix}{i + 1}"], label=f"{prefix}{i + 1}")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, ncol=min(n, 7))
        fig.suptitle(title)
        save(fig, name)
    return written


def op_count(smc: SmcBuild) -> str:
    """The step kernel's operation count, as recorded at build time."""
    return str(smc.meta["op_count"])


__all__ = [
    "DAMPING",
    "EPSILON",
    "GAIN",
    "KERNEL",
    "MODULE",
    "PANDA_Q0",
    "POSE",
    "CompiledStep",
    "LoopSummary",
    "Simulation",
    "SmcBuild",
    "bench_step",
    "build",
    "casadi_step",
    "damped_solve",
    "plot_run",
    "pose_and_jacobian",
    "pose_and_jacobian_of",
    "read_log",
    "reference",
    "reference_rate",
    "run_loop",
    "simulate",
    "smc_step_function",
    "step_kernel",
    "step_law",
    "step_source",
    "sx_step_function",
]
