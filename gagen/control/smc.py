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
λ_d > 0), unrolled in CasADi SX. K = diag(k_1 … k_6) is in task space as in Eq. 36 (the paper's
K = diag{7.5, …} multiplies tanh(ε s); with equal gains K J⁺ = J⁺ K). Inside the boundary layer
(tanh(ε s) ≈ ε s) the error obeys ṡ ≈ −K ε s − ẋ_ref + λ, so it settles at |s_i| ≲ (|ẋ_ref| + |λ|)/(k ε)
(0.2 / (7.5 · 50) = 5.3e-4 for the paper's reference at the default ε = 50), after a transient in which
tanh saturates and each coordinate closes at up to k per second (Eq. 38: k > |ẋ_ref| + |λ|).
At the loop's rate the Euler-discretised boundary layer is stable for k ε dt < 2 (0.375 at 1 kHz).

Pieces:

- ``smc_step_function``: the CasADi SX Function q, x_ref -> x, J, u;
- ``write_step_c`` / ``build``: its C (``smc_step.c``/``.h`` through gagen's emitter), a shared library
  and the real-time loop runner ``smc_loop`` (``smc_loop.c`` next to this module);
- ``CompiledStep``: the shared library through ctypes; ``simulate``: the same loop in Python/numpy,
  tick for tick identical to the C runner (the runner uses nominal tick times);
- ``run_loop`` / ``bench_step``: run the C loop at a fixed rate, or the step in a tight loop;
- ``read_log`` / ``plot_run``: the per-tick CSV and plots like the paper's Figs. 6-8.
"""

from __future__ import annotations

import ctypes
import hashlib
import json
import math
import os
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.algebra.multivector import SparseMultivector
from gagen.algebra.signature import cga3d
from gagen.codegen.c_emitter import emit_body
from gagen.codegen.compiler import FLAGS, CompileError, compile_shared, find_compiler, library_name
from gagen.kernels import TOOL_LINE
from gagen.model import kinematics as kin
from gagen.model.conformal import EUCLID, point
from gagen.model.kinematics import Joint
from gagen.symbolic.casadi_backend import CasadiBackend
from gagen.symbolic.flatten import casadi_op_count

POSE = ("px", "py", "pz", "dx", "dy", "dz")
"""The pose coordinates: end point position, then the tool line's direction."""
GAIN = 7.5  # [SMC VI]: K = diag{7.5, …, 7.5}
EPSILON = 50.0  # tanh slope (Eq. 40); the paper does not state it
DAMPING = 1e-2  # λ_d of J⁺ = Jᵀ(J Jᵀ + λ_d² I)⁻¹
PANDA_Q0 = (2.5, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
"""Default start for the 7-DOF Panda: its ``ready`` pose with joint 1 turned to 2.5 rad (within its
±2.8973 limit), facing the paper's reference, which lies behind the base at azimuth 143°."""
LOOP_SOURCE = Path(__file__).with_name("smc_loop.c")
STEP_NAME = "smc_step"


# -- the reference trajectory [SMC Eq. 43] -----------------------------------------------------------
def reference(t: float) -> NDArray[np.float64]:
    """x_ref(t) = [−0.3 + 0.1 cos 2t, 0.15, 0.25, 0, 1, 0] [SMC Eq. 43] (the C runner's ``reference``,
    with the same operations: math.cos is the C library's cos)."""
    return np.array([-0.3 + 0.1 * math.cos(2.0 * t), 0.15, 0.25, 0.0, 1.0, 0.0])


def reference_rate(t: float) -> NDArray[np.float64]:
    """ẋ_ref(t) = [−0.2 sin 2t, 0, 0, 0, 0, 0] [SMC Eq. 43]."""
    return np.array([-0.2 * math.sin(2.0 * t), 0.0, 0.0, 0.0, 0.0, 0.0])


# -- the symbolic step -------------------------------------------------------------------------------
def _direction(line: Any, native: Callable[[Any], Any]) -> list[Any]:
    """Direction n of a line bivector n3 e12 − n2 e13 + n1 e23 + moment."""
    return [native(line["e23"]), -native(line["e13"]), native(line["e12"])]


def pose_and_jacobian(joints: Sequence[Joint], q: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(x, J) on CasADi symbols: the pose [x_p; d] (6) and its Jacobian (6 × n) from the joint lines
    [SMC Eq. 17-20]."""
    backend = CasadiBackend()
    zero = SparseMultivector(cga3d(), backend, {})
    n = q.numel()
    motor, lines, position = kin.chain_pose(zero, joints, [backend.lift(q[i]) for i in range(n)])
    point_columns = kin.point_jacobian(motor, lines, point(position))  # P × L'_j  (Eq. 18)
    tool = zero.make({TOOL_LINE: 1})
    line_columns = kin.line_jacobian(motor, lines, tool)  # α_j = ½(L'_p L'_j − L'_j L'_p)  (Eq. 20)
    native = backend.native
    x = ca.vertcat(*[native(position[b]) for b in EUCLID], *_direction(motor.sandwich(tool), native))
    J = ca.horzcat(*[ca.vertcat(*[native(p[b]) for b in EUCLID], *_direction(a, native))
                     for p, a in zip(point_columns, line_columns, strict=True)])
    return x, J


def _sum(terms: Sequence[ca.SX]) -> ca.SX:
    total = terms[0]
    for t in terms[1:]:
        total = total + t
    return total


def damped_solve(J: ca.SX, r: ca.SX, damping: float) -> ca.SX:
    """w = (J Jᵀ + λ_d² I)⁻¹ r on SX by an unrolled LDLᵀ factorisation (no pivoting: the matrix is
    symmetric positive definite for λ_d > 0, its eigenvalues ≥ λ_d²; no square roots). Only the upper
    triangle of J Jᵀ is formed."""
    if not damping > 0:
        raise ValueError(f"damping must be > 0 (J Jᵀ of a pose with a unit direction is singular), "
                         f"got {damping}")
    k, n = J.shape
    rows = [[J[i, m] for m in range(n)] for i in range(k)]
    A = [[None] * k for _ in range(k)]
    for i in range(k):
        for j in range(i, k):
            A[i][j] = _sum([rows[i][m] * rows[j][m] for m in range(n)])
        A[i][i] = A[i][i] + damping * damping
    L: list[list[Any]] = [[None] * k for _ in range(k)]
    C: list[list[Any]] = [[None] * k for _ in range(k)]  # C_ij = L_ij D_j
    inverse = [None] * k
    for j in range(k):
        d = A[j][j] - _sum([C[j][m] * L[j][m] for m in range(j)]) if j else A[j][j]
        inverse[j] = 1 / d
        for i in range(j + 1, k):
            C[i][j] = A[j][i] - _sum([C[i][m] * L[j][m] for m in range(j)]) if j else A[j][i]
            L[i][j] = C[i][j] * inverse[j]
    y: list[Any] = [None] * k
    for i in range(k):
        y[i] = r[i] - _sum([L[i][m] * y[m] for m in range(i)]) if i else r[i]
    w: list[Any] = [None] * k
    for i in reversed(range(k)):
        z = y[i] * inverse[i]
        w[i] = z - _sum([L[m][i] * w[m] for m in range(i + 1, k)]) if i < k - 1 else z
    return ca.vertcat(*w)


def _gains(K: float | Sequence[float], k: int) -> list[float]:
    gains = [float(K)] * k if np.isscalar(K) else [float(g) for g in K]  # type: ignore[arg-type]
    if len(gains) != k or not all(g > 0 for g in gains):
        raise ValueError(f"K must be a positive scalar or {k} positive task-space gains, got {K}")
    return gains


def smc_step_function(joints: Sequence[Joint], *, K: float | Sequence[float] = GAIN, epsilon: float = EPSILON,
                      damping: float = DAMPING) -> ca.Function:
    """The sliding-mode step as a CasADi SX Function ``smc_step``: (q[n], x_ref[6]) -> (x[6], J[6×n], u[n])
    with x the pose, J its Jacobian [SMC Eq. 17-20] and u = −J⁺ K tanh(ε (x − x_ref)) [Eq. 35, 40],
    J⁺ = Jᵀ(J Jᵀ + λ_d² I)⁻¹ (λ_d = ``damping``). ``K``: a scalar or 6 task-space gains."""
    if not epsilon > 0:
        raise ValueError(f"epsilon must be > 0, got {epsilon}")
    n = len(kin.chain_variables(joints))  # mimic joints follow their leader: no entry of their own
    q = ca.SX.sym("q", n)
    x_ref = ca.SX.sym("x_ref", len(POSE))
    x, J = pose_and_jacobian(joints, q)
    gains = _gains(K, len(POSE))
    r = ca.vertcat(*[gains[i] * ca.tanh(epsilon * (x[i] - x_ref[i])) for i in range(len(POSE))])
    u = -ca.mtimes(J.T, damped_solve(J, r, damping))
    outputs = ca.cse([x, J, u])
    return ca.Function(STEP_NAME, [q, x_ref], outputs, ["q", "x_ref"], ["x", "J", "u"])


# -- C ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SmcBuild:
    """A built step: the folder, its C files, the shared library and the loop runner, and the
    parameters (``meta``: n, k, K, epsilon, damping, q0, op count)."""

    folder: Path
    source: Path
    header: Path
    library: Path
    runner: Path
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def q0(self) -> NDArray[np.float64]:
        return np.array(self.meta["q0"], dtype=float)

    def step(self) -> CompiledStep:
        return CompiledStep(self.library, self.meta["n"], self.meta["k"])


def _atomic_write(path: Path, text: str) -> None:
    partial = path.with_name(path.name + f".{os.getpid()}.partial")
    partial.write_text(text)
    partial.replace(path)


def _c_array(values: Sequence[float]) -> str:
    return "{" + ", ".join(repr(float(v)) for v in values) + "}"


def write_step_c(function: ca.Function, folder: str | Path, *, q0: Sequence[float] | None = None,
                 compile: bool = True, meta: dict[str, Any] | None = None) -> SmcBuild:
    """Emit ``smc_step.c``/``smc_step.h`` for ``function`` (from ``smc_step_function``) with gagen's
    emitter: ``void smc_step(const double *q, const double *x_ref, double *x, double *J, double *u)``
    (J dense column-major, 6 × n). With ``compile``: the shared library ``libsmc_step.so`` and the
    loop runner ``smc_loop`` (gagen's compiler flags, so both give CasADi's doubles).
    ``q0``: the runner's default start (the Panda's ``PANDA_Q0`` for 7 joints)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    n, k = function.numel_in(0), function.numel_in(1)
    if function.name_in() != ["q", "x_ref"] or function.name_out() != ["x", "J", "u"]:
        raise ValueError("write_step_c needs a smc_step_function: inputs (q, x_ref), outputs (x, J, u)")
    if q0 is None:
        q0 = PANDA_Q0 if n == len(PANDA_Q0) else (0.0,) * n
    if len(q0) != n:
        raise ValueError(f"q0 needs {n} joint values, got {len(q0)}")
    ops = casadi_op_count(function)
    body = emit_body(function, ["q", "x_ref"], ["x", "J", "u"])
    declarations = [f"  double {', '.join(body.locals[i:i + 16])};" for i in range(0, len(body.locals), 16)]
    signature = "void smc_step(const double *q, const double *x_ref, double *x, double *J, double *u)"
    header = "\n".join([
        "/* smc_step.h: sliding-mode pose tracking step [SMC Eq. 17-20, 35, 40], generated by",
        " * gagen.control.smc. Do not edit.",
        " *   in  q[N]       joint values",
        f" *   in  x_ref[K]   reference pose ({', '.join(POSE)})",
        " *   out x[K]       pose: end point position, tool z-axis direction",
        " *   out J[K*N]     its Jacobian, dense column-major",
        " *   out u[N]       joint velocities u = -J+ K tanh(eps (x - x_ref)), J+ = J^T (J J^T + l^2 I)^-1",
        f" * Operation counts: {ops}",
        " */",
        "#ifndef SMC_STEP_H", "#define SMC_STEP_H",
        f"#define SMC_STEP_N {n}", f"#define SMC_STEP_K {k}", f"#define SMC_STEP_Q0 {_c_array(q0)}",
        f"{signature};", "#endif", ""])
    source = "\n".join([
        "/* smc_step.c: generated by gagen.control.smc (one C statement per CasADi instruction). */",
        "#include <math.h>", "", '#include "smc_step.h"', "",
        f"{signature} {{", *declarations, *[f"  {s}" for s in body.statements], "}", ""])
    paths = {"header": folder / "smc_step.h", "source": folder / "smc_step.c",
             "library": folder / library_name(STEP_NAME), "runner": folder / "smc_loop"}
    _atomic_write(paths["header"], header)
    _atomic_write(paths["source"], source)
    info = {**(meta or {}), "n": n, "k": k, "q0": [float(v) for v in q0], "op_count": str(ops),
            "flops": ops.flops, "calls": ops.calls}
    _atomic_write(folder / "smc_step.json", json.dumps(info, indent=1))
    if compile:
        compile_shared(paths["source"], paths["library"])
        _compile_runner(folder, paths["source"], paths["runner"])
    return SmcBuild(folder, paths["source"], paths["header"], paths["library"], paths["runner"], info)


def _compile_runner(folder: Path, step_source: Path, runner: Path) -> None:
    loop = folder / "smc_loop.c"
    shutil.copyfile(LOOP_SOURCE, loop)
    flags = [f for f in FLAGS if f not in ("-shared", "-fPIC")]
    partial = runner.with_name(runner.name + f".{os.getpid()}.partial")
    command = [*find_compiler(), *flags, f"-I{folder}", "-o", str(partial), str(loop), str(step_source),
               "-lm"]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        partial.unlink(missing_ok=True)
        raise CompileError(f"{' '.join(command)} failed:\n{result.stderr.strip()}")
    partial.replace(runner)


def _panda_joints() -> tuple[Joint, ...]:
    from gagen.robots.systems import bundled_systems

    return tuple(bundled_systems()["panda_point"].chains[0].joints)


def _sources_digest() -> str:
    """Digest of the code the step is generated from (model, algebra, symbolic, emitter), so a cached
    build is not reused after any of it changes."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for package in ("algebra", "model", "symbolic", "codegen"):
        for path in sorted((root / package).glob("*.py")):
            digest.update(path.name.encode() + path.read_bytes())
    return digest.hexdigest()


def build(joints: Sequence[Joint] | None = None, *, K: float | Sequence[float] = GAIN,
          epsilon: float = EPSILON, damping: float = DAMPING, q0: Sequence[float] | None = None,
          folder: str | Path | None = None) -> SmcBuild:
    """Build (or reuse) the step and the runner for ``joints`` (default: the bundled Panda,
    ``panda_point``'s arm). Without ``folder`` the build is cached in the temporary directory under a
    key of the joints, the parameters and the sources."""
    joints = tuple(joints) if joints is not None else _panda_joints()
    params = {"K": K if np.isscalar(K) else list(K), "epsilon": epsilon, "damping": damping}
    key = hashlib.sha256(json.dumps(
        [repr(joints), params, None if q0 is None else list(q0), LOOP_SOURCE.read_text(),
         Path(__file__).read_text(), _sources_digest(), list(FLAGS), find_compiler()],
        default=str).encode()).hexdigest()[:16]
    target = Path(folder) if folder is not None else Path(tempfile.gettempdir()) / "gagen-smc" / key
    meta_path = target / "smc_step.json"
    if folder is None and meta_path.is_file() and (target / "smc_loop").is_file() \
            and (target / library_name(STEP_NAME)).is_file():
        meta = json.loads(meta_path.read_text())
        return SmcBuild(target, target / "smc_step.c", target / "smc_step.h",
                        target / library_name(STEP_NAME), target / "smc_loop", meta)
    function = smc_step_function(joints, K=K, epsilon=epsilon, damping=damping)
    return write_step_c(function, target, q0=q0, meta={**params, "key": key})


# -- the step from Python --------------------------------------------------------------------------
class CompiledStep:
    """The compiled ``smc_step`` through ctypes: ``step(q, x_ref) -> (x, J (k × n), u)`` (fresh arrays)."""

    def __init__(self, library: str | Path, n: int, k: int = len(POSE)) -> None:
        self.library = ctypes.CDLL(str(library))
        self.n, self.k = n, k
        self._f = self.library.smc_step
        pointer = ctypes.POINTER(ctypes.c_double)
        self._f.argtypes = [pointer] * 5
        self._f.restype = None

    def __call__(self, q: ArrayLike, x_ref: ArrayLike) -> tuple[NDArray, NDArray, NDArray]:
        q = np.ascontiguousarray(q, dtype=np.float64)
        x_ref = np.ascontiguousarray(x_ref, dtype=np.float64)
        if q.shape != (self.n,) or x_ref.shape != (self.k,):
            raise ValueError(f"smc_step takes q[{self.n}] and x_ref[{self.k}], got {q.shape}, {x_ref.shape}")
        x, J, u = np.empty(self.k), np.empty(self.k * self.n), np.empty(self.n)
        ptr = ctypes.POINTER(ctypes.c_double)
        self._f(*(a.ctypes.data_as(ptr) for a in (q, x_ref, x, J, u)))
        return x, J.reshape((self.n, self.k)).T.copy(), u


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
    "read_log",
    "reference",
    "reference_rate",
    "run_loop",
    "simulate",
    "smc_step_function",
    "write_step_c",
]
