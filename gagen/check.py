"""``gagen build --check``: every generated kernel (C single, C batched, CasADi) against the interpreter.

References come from the reference interpreter running the model's formulas on floats: values
directly, the closed-form Jacobians (joint lines, Eq. 15-17) directly, and the Jacobians that the
kernels take by AD (J_A,Sc, J_G,Sc, J_B, J_Be) by step-adapted, Richardson-extrapolated central
differences of the interpreter: R(h) = (4 D(h/2) − D(h)) / 3 with D(h) = (f(q + h) − f(q − h)) / 2h,
whose truncation error is O(h⁴) and rounding error ≈ 3 eps |f| / h. Per joint, R(1e-3) and R(1e-4)
(rad or m) are compared; when they disagree by more than 1e-9 of their magnitude (a function that
turns on a scale below 1e-3, e.g. a small or nearly flat primitive), R(1e-5) is taken too, and the
later of the two consecutive estimates that agree best is used.

Tolerances are relative to the magnitude of what is compared. Per output and sample the error is
max |value − reference| / max(max |reference|, FLOOR), i.e. it passes when
|value − reference| ≤ rtol · max(max |reference|, FLOOR): rtol = 1e-10 against interpreter values
(``--tolerance``), 1e-6 against differences (``FD_RTOL``).

Samples: every configuration the spec names, as given, and ``count`` random ones near them (the
joint-space centre of the limits when the spec names none), each joint within its URDF limits
(±0.4 rad or ±0.05 m around the centre, cut to the limits; prismatic joints in metres).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from gagen.algebra.signature import cga3d
from gagen.interp import MultiVector
from gagen.kernels import TOOL_LINE
from gagen.model import kinematics as K
from gagen.model.conformal import SIMILARITY, SIMILARITY_GENERATOR
from gagen.model.cooperative import System, end_points, primitive_jacobian
from gagen.model.primitives import through
from gagen.model.similarity import cooperative_similarity
from gagen.model.versors import exp_similarity, log_similarity
from gagen.runtime import GeneratedModule

FD_STEPS = (1e-3, 1e-4, 1e-5)  # h of the Richardson-extrapolated central differences (rad or m)
FD_AGREE = 1e-9  # R(h1), R(h2) closer than this (relative): no third step
FD_RTOL = 1e-6  # relative tolerance against those differences
VALUE_RTOL = 1e-10  # default relative tolerance against interpreter values
FLOOR = 1e-6  # magnitudes below this count as this (an all-zero reference is compared absolutely)
SPREAD = {"prismatic": 0.05}  # half-width of the random samples around a centre (m); 0.4 rad otherwise
ANGLE_SPREAD = 0.4
BY_DIFFERENCES = ("J_A", "J_G", "J_B", "J_Be")  # system outputs the kernels differentiate by AD
INTERPRETER, DIFFERENCES = "interpreter", "central differences"


@dataclass
class Discrepancy:
    """Largest relative error of one output over the samples, per evaluation path (see the module
    docstring), the tolerance it is held to and the sample where the worst one occurred."""

    kernel: str
    output: str
    reference: str  # INTERPRETER or DIFFERENCES
    c_single: float
    c_batch: float
    casadi: float
    tolerance: float = VALUE_RTOL
    sample: str = ""
    path: str = ""  # the evaluation path of the worst error

    @property
    def worst(self) -> float:
        return max(self.c_single, self.c_batch, self.casadi)

    @property
    def passed(self) -> bool:
        return bool(self.worst <= self.tolerance)  # (a NaN error fails)

    def message(self) -> str:
        return (f"kernel {self.kernel}, output {self.output}: relative error {self.worst:.2e} above "
                f"{self.tolerance:g} against the {self.reference} ({self.path}, sample {self.sample})")


@dataclass
class Sample:
    label: str  # a configuration's name, or "<name>~<i>" for a random sample near it
    q: np.ndarray
    desired: MultiVector  # a random V_Sd for the task kernel


def relative_error(value, reference: np.ndarray) -> float:
    """max |value − reference| / max(max |reference|, FLOOR); NaN anywhere gives NaN."""
    value = np.reshape(np.asarray(value, dtype=float), reference.shape)
    scale = max(float(np.max(np.abs(reference))) if reference.size else 0.0, FLOOR)
    if not (np.all(np.isfinite(value)) and np.all(np.isfinite(reference))):
        return float("nan")
    return float(np.max(np.abs(value - reference))) / scale if reference.size else 0.0


def _dense(x: MultiVector, rows) -> np.ndarray:
    return np.array([x[b] for b in rows])


def _matrix(columns, rows) -> np.ndarray:
    return np.array([[c[b] for b in rows] for c in columns]).T


class _Reference:
    """The interpreter's values of every kernel output at one (q, V_Sd)."""

    def __init__(self, system: System, q: np.ndarray, desired: MultiVector) -> None:
        self.system, self.q, self.desired = system, q, desired
        self.zero = MultiVector.zero(cga3d())
        self._memo: dict[tuple, object] = {}

    def _once(self, key: tuple, compute: Callable[[], object]) -> object:
        if key not in self._memo:
            self._memo[key] = compute()
        return self._memo[key]

    def chain(self, index: int, port: str, rows) -> np.ndarray:
        chain = self.system.chains[index]
        qc = self.system.split(list(self.q))[index]
        motor, lines = self._once(("chain", index), lambda: K.chain_kinematics(self.zero, chain.joints, qc))
        tool = self.zero.make({TOOL_LINE: 1})
        values = {"M": lambda: _dense(motor, rows), "P": lambda: _dense(K.end_point(motor), rows),
                  "J_S": lambda: _matrix(K.spatial_jacobian(lines), rows),
                  "J_b": lambda: _matrix(K.body_jacobian(motor, lines), rows),
                  "J_A": lambda: _matrix(K.analytic_jacobian(motor, lines), rows),
                  "J_P": lambda: _matrix(K.point_jacobian(motor, lines), rows),
                  "L": lambda: _dense(motor.sandwich(tool), rows),
                  "J_L": lambda: _matrix(K.line_jacobian(motor, lines, tool), rows)}
        return values[port]()

    def task(self, q: np.ndarray) -> dict[str, MultiVector]:
        return self._once(("task", q.tobytes()), lambda: self._task(q))

    def _end_point(self, index: int, qc: list[float]) -> MultiVector:
        # a difference step moves one joint: the chains without it keep their end points (memoised)
        return self._once(("end", index, tuple(qc)), lambda: K.end_point(
            K.forward_kinematics(self.zero, self.system.chains[index].joints, qc)))

    def _task(self, q: np.ndarray) -> dict[str, MultiVector]:
        points = [self._end_point(i, qc) for i, qc in enumerate(self.system.split(list(q)))]
        xc = through(self.system.kind, points)
        v, conditioning = cooperative_similarity(self.system.kind, xc)
        return {"X_c": xc, "V_Sc": v, "conditioning": conditioning, "log_V": log_similarity(v),
                "e": log_similarity(~v * self.desired)}

    def system_output(self, port: str, rows) -> np.ndarray:
        at = self.task(self.q)
        if port == "J_c":
            points = self._once(("points",), lambda: end_points(self.zero, self.system, list(self.q)))
            return _matrix(primitive_jacobian(self.system, points), rows)
        if port == "conditioning":
            return np.array([at["conditioning"]])
        if port in BY_DIFFERENCES:
            return self._differences(port, at["V_Sc"], rows)
        return _dense(at[port], rows)

    def _central(self, of: str, i: int, h: float) -> MultiVector:
        step = np.zeros(self.q.size)
        step[i] = h
        return (self.task(self.q + step)[of] - self.task(self.q - step)[of]) * (0.5 / h)

    def _richardson(self, of: str, i: int, h: float) -> MultiVector:
        # the h² error terms of the two central differences cancel
        return (self._central(of, i, h / 2) * 4 - self._central(of, i, h)) * (1 / 3)

    def _derivative(self, of: str, i: int) -> MultiVector:
        """∂f/∂q_i, step-adapted (see the module docstring)."""
        estimates = [self._richardson(of, i, FD_STEPS[0]), self._richardson(of, i, FD_STEPS[1])]
        gaps = [_size(estimates[1] - estimates[0])]
        if gaps[0] > FD_AGREE * max(_size(estimates[1]), FLOOR):
            for h in FD_STEPS[2:]:
                estimates.append(self._richardson(of, i, h))
                gaps.append(_size(estimates[-1] - estimates[-2]))
        return estimates[1 + int(np.argmin(gaps))]

    def _differences(self, port: str, v: MultiVector, rows) -> np.ndarray:
        of = {"J_A": "V_Sc", "J_G": "V_Sc", "J_B": "log_V", "J_Be": "e"}[port]
        columns = [self._once(("d", of, i), lambda i=i: self._derivative(of, i)) for i in range(self.q.size)]
        return _matrix([~v * d * -2 for d in columns] if port == "J_G" else columns, rows)


def _size(x: MultiVector) -> float:
    return float(np.max(np.abs(x.coeffs)))


def joint_limits(system: System) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Per entry of q: (lower, upper) from the URDF (−inf, inf when none is known) and the joint kind.
    A mimic follower's variable is its leader's, whose limits are used when the leader is in a chain."""
    found: dict[tuple[str, str], K.Joint] = {}
    for chain in system.chains:
        for joint in chain.joints:
            if joint.moves and joint.mimic is None:
                found.setdefault((chain.robot or chain.name, joint.name), joint)
    lower, upper, kinds = [], [], []
    for key in system.joint_keys:
        joint = found.get(key)
        limits = joint.limits if joint is not None and joint.limits is not None else (-np.inf, np.inf)
        lower.append(limits[0])
        upper.append(limits[1])
        kinds.append(joint.kind if joint is not None else "revolute")
    return np.array(lower, dtype=float), np.array(upper, dtype=float), kinds


def samples(system: System, configurations: Mapping[str, Sequence[float]] | Sequence[float] | None,
            count: int, seed: int) -> list[Sample]:
    """Every named configuration as given, then ``count`` random ones near them in turn (near the
    centre of the limits, or 0, when none is named), within the joint limits; each with a random V_Sd."""
    named = _named(configurations)
    rng = np.random.default_rng(seed)
    lower, upper, kinds = joint_limits(system)
    spread = np.array([SPREAD.get(k, ANGLE_SPREAD) for k in kinds])
    limited = np.isfinite(lower) & np.isfinite(upper)
    middle = np.zeros(system.dof)
    middle[limited] = (lower[limited] + upper[limited]) / 2
    centres = list(named.items()) or [("centre", middle)]
    zero = MultiVector.zero(cga3d())

    def desired() -> MultiVector:
        generator = zero.make(dict(zip(SIMILARITY_GENERATOR, rng.uniform(-0.5, 0.5, 7), strict=True)))
        return exp_similarity(generator)

    out = [Sample(name, np.array(q, dtype=float), desired()) for name, q in named.items()]
    for i in range(count):
        name, centre = centres[i % len(centres)]
        lo = np.maximum(centre - spread, lower)
        hi = np.minimum(centre + spread, upper)
        outside = lo > hi  # a centre outside the limits: anywhere within them
        lo, hi = np.where(outside, lower, lo), np.where(outside, upper, hi)
        out.append(Sample(f"{name}~{i}", rng.uniform(lo, hi), desired()))
    return out


def _named(configurations) -> dict[str, np.ndarray]:
    if configurations is None:
        return {}
    if isinstance(configurations, Mapping):
        return {str(k): np.array(v, dtype=float) for k, v in configurations.items()}
    return {"ready": np.array(configurations, dtype=float)}  # one unnamed configuration (older callers)


def check_module(module: GeneratedModule, system: System,
                 configurations: Mapping[str, Sequence[float]] | Sequence[float] | None = None,
                 count: int = 5, seed: int = 0, progress: Callable[[str], None] = lambda _: None,
                 rtol: float = VALUE_RTOL, fd_rtol: float = FD_RTOL) -> list[Discrepancy]:
    """Evaluate every kernel of ``module`` on the samples (see ``samples``); one Discrepancy per output,
    and one progress line per kernel with its worst relative error."""
    chain_index = {c.name: i for i, c in enumerate(system.chains)}
    pairs = samples(system, configurations, count, seed)
    entries = module.manifest["kernels"]
    # one reference per sample for all kernels: its memo keeps the interpreter's values (and the
    # differences' evaluations at q ± h) across the kernels that share them
    sample_references = [_Reference(system, sample.q, sample.desired) for sample in pairs]
    result = []
    for number, entry in enumerate(entries, 1):
        name = entry["name"]
        c_kernel, ca_function = getattr(module.c, name), getattr(module.casadi, name)
        scope = next((c for c in chain_index if name.startswith(c + "_")
                      and name[len(c) + 1:] in ("fk", "fk_jacobian", "jacobians")), None)
        # per output: worst (error, sample label) for C single, C batched, CasADi
        worst: dict[str, list[tuple[float, str]]] = {p["name"]: [(0.0, "")] * 3 for p in entry["outputs"]}

        def note(port: str, path: int, error: float, label: str, worst=worst) -> None:
            current = worst[port][path][0]
            if not np.isnan(current) and (np.isnan(error) or error > current):  # NaN counts as the worst
                worst[port][path] = (error, label)

        batch_inputs, references = [], []
        for sample, reference in zip(pairs, sample_references, strict=True):
            inputs = [sample.q if p["name"] == "q" else np.array([sample.desired[b] for b in SIMILARITY])
                      for p in entry["inputs"]]
            if scope is not None:
                inputs = [np.array(system.split(list(sample.q))[chain_index[scope]])]
            batch_inputs.append(inputs)
            c_out = c_kernel(*inputs)
            c_out = c_out if isinstance(c_out, tuple) else (c_out,)
            ca_out = ca_function(*inputs)
            ca_out = ca_out if isinstance(ca_out, (list, tuple)) else [ca_out]
            refs = []
            for k, port in enumerate(entry["outputs"]):
                rows, shape = port["rows"], (len(port["rows"]), port["cols"])
                ref = (reference.chain(chain_index[scope], port["name"], rows) if scope is not None
                       else reference.system_output(port["name"], rows)).reshape(shape)
                refs.append(ref)
                note(port["name"], 0, relative_error(c_out[k], ref), sample.label)
                note(port["name"], 2, relative_error(ca_out[k], ref), sample.label)
            references.append(refs)
        stacked_inputs = [np.array([b[i] for b in batch_inputs]) for i in range(len(entry["inputs"]))]
        batched = c_kernel.batch(*stacked_inputs)
        batched = batched if isinstance(batched, tuple) else (batched,)
        for k, port in enumerate(entry["outputs"]):
            shape = (len(pairs), len(port["rows"]), port["cols"])
            values = np.reshape(np.asarray(batched[k], dtype=float), shape)
            for s, sample in enumerate(pairs):
                note(port["name"], 1, relative_error(values[s], references[s][k]), sample.label)
        found = []
        for port in entry["outputs"]:
            by_differences = scope is None and port["name"] in BY_DIFFERENCES
            errors = worst[port["name"]]
            path = max(range(3), key=lambda p: (np.isnan(errors[p][0]), errors[p][0]))
            found.append(Discrepancy(name, port["name"], DIFFERENCES if by_differences else INTERPRETER,
                                     *(e for e, _ in errors), fd_rtol if by_differences else rtol,
                                     errors[path][1], ("C single", "C batched", "CasADi")[path]))
        result += found
        progress(_progress_line(number, len(entries), name, found))
    return result


def _progress_line(number: int, total: int, name: str, found: list[Discrepancy]) -> str:
    parts = []
    for reference in (INTERPRETER, DIFFERENCES):
        mine = [d for d in found if d.reference == reference]
        if mine:
            d = max(mine, key=lambda d: (np.isnan(d.worst), d.worst))
            parts.append(f"{d.worst:.1e} vs {reference} ({d.output})")
    status = "ok" if all(d.passed for d in found) else "FAILED"
    return f"  [{number}/{total}] {name}: worst relative error {', '.join(parts)}: {status}"


def failures(discrepancies: list[Discrepancy]) -> list[Discrepancy]:
    return [d for d in discrepancies if not d.passed]


def format_report(discrepancies: list[Discrepancy]) -> str:
    lines = ["| kernel | output | reference | C single | C batched | CasADi | tolerance |",
             "|---|---|---|--:|--:|--:|--:|"]
    lines += [f"| {d.kernel} | {d.output} | {d.reference} | {d.c_single:.1e} | {d.c_batch:.1e} "
              f"| {d.casadi:.1e} | {d.tolerance:g} |" for d in discrepancies]
    return "\n".join(lines)
