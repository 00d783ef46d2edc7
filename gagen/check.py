"""``gagen build --check``: every generated kernel (C single, C batched, CasADi) against the interpreter.

One mechanism for every module: each kernel is a front-end kernel (``gagen.frontend.KernelFunction``)
whose function, run on the reference interpreter, is its reference (``check_kernels``). Outputs the
function returns are compared with its values; the Jacobians it leaves to the compiler (AD or a rule:
J_c, J_A,Sc, J_G,Sc, J_B, J_Be of the robots; the AD Jacobians of user kernels), and at the first
point (``FD_SAMPLES``) also the Jacobians it gives itself (J_A, J_P of the chains, a hexapod leg's
J), with step-adapted, Richardson-extrapolated central differences of the interpreter:
R(h) = (4 D(h/2) − D(h)) / 3 with D(h) = (f(q + h) − f(q − h)) / 2h, whose truncation error is
O(h⁴) and rounding error ≈ 3 eps |f| / h. Per joint, R(1e-3) and R(1e-4) (rad or m) are compared;
when they disagree by more than 1e-9 of their magnitude (a function that turns on a scale below
1e-3, e.g. a small or nearly flat primitive), R(1e-5) is taken too, and the later of the two
consecutive estimates that agree best is used.

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
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from gagen.algebra.protocol import Multivector
from gagen.algebra.signature import Algebra, cga3d
from gagen.frontend import KernelFunction, split_derivative
from gagen.interp import MultiVector
from gagen.model import kinematics as K
from gagen.model.conformal import SIMILARITY_GENERATOR
from gagen.model.versors import exp_similarity
from gagen.robots.system import System
from gagen.runtime import GeneratedModule

FD_STEPS = (1e-3, 1e-4, 1e-5)  # h of the Richardson-extrapolated central differences (rad or m)
FD_AGREE = 1e-9  # R(h1), R(h2) closer than this (relative): no third step
FD_RTOL = 1e-6  # relative tolerance against those differences
FD_SAMPLES = 1  # a Jacobian the function gives itself is held against differences at this many points
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
    desired: Multivector  # a random V_Sd for the task kernel
    velocity: np.ndarray  # a random q̇ (rad/s or m/s, each in [−1, 1]) for the rate kernel


def relative_error(value: ArrayLike, reference: np.ndarray) -> float:
    """max |value − reference| / max(max |reference|, FLOOR); NaN anywhere gives NaN."""
    value = np.reshape(np.asarray(value, dtype=float), reference.shape)
    scale = max(float(np.max(np.abs(reference))) if reference.size else 0.0, FLOOR)
    if not (np.all(np.isfinite(value)) and np.all(np.isfinite(reference))):
        return float("nan")
    return float(np.max(np.abs(value - reference))) / scale if reference.size else 0.0


class _Entry:
    """A port as the manifest lists it (name, rows, cols)."""

    def __init__(self, entry: Mapping[str, Any]) -> None:
        self.name, self.rows, self.cols = entry["name"], tuple(entry["rows"]), int(entry["cols"])


def _dense_value(value: Any, algebra: Algebra) -> np.ndarray:
    """The interpreter's value of an output as one dense array (multivectors: every coefficient)."""
    if isinstance(value, MultiVector):
        return np.array(value.coeffs, dtype=float)
    if isinstance(value, list):  # a vector of scalars, or a matrix: a list of columns
        if any(isinstance(v, (list, MultiVector)) for v in value):
            return np.concatenate([_dense_value(v, algebra) for v in value])
        return np.array([float(v) for v in value])
    return np.array([float(value)])


def _rows(dense: np.ndarray, rows: Sequence[str], algebra: Algebra, is_multivector: bool) -> np.ndarray:
    if is_multivector:
        return np.array([dense[algebra.blade(b)] for b in rows])
    return dense[:len(rows)] if len(dense) >= len(rows) else dense


class _Differences:
    """Step-adapted Richardson central differences of a kernel function's interpreter values (see the
    module docstring), memoised per input point."""

    def __init__(self, function: KernelFunction, in_ports: Sequence[_Entry]) -> None:
        self.function, self.in_ports = function, in_ports
        self._memo: dict[bytes, dict[str, Any]] = {}
        self._inner: dict[str, float] = {}  # the step of a derived output's differences, when nested

    def values(self, arrays: Sequence[np.ndarray]) -> dict[str, Any]:
        key = b"".join(np.asarray(a, dtype=float).tobytes() for a in arrays)
        if key not in self._memo:
            self._memo[key] = self.function.values(arrays, self.in_ports)
        return self._memo[key]

    def _value(self, of: str, arrays: Sequence[np.ndarray]) -> np.ndarray:
        values = self.values(arrays)
        if of in values:
            return _dense_value(values[of], self.function.algebra)
        # a Jacobian the function does not give, differentiated again (J̇ q̇ from J_G q̇): by differences
        # with the step chosen once at the outer difference's point, so that it is a smooth function of
        # the outer difference's input
        return np.concatenate(self._columns(self.function.jacobians[of], arrays, self._inner[of])[0])

    def _central(self, of: str, arrays: Sequence[np.ndarray], port: int, step: np.ndarray,
                 h: float) -> np.ndarray:
        plus = [np.array(a, dtype=float) for a in arrays]
        minus = [np.array(a, dtype=float) for a in arrays]
        plus[port] = plus[port] + h * step.reshape(plus[port].shape)
        minus[port] = minus[port] - h * step.reshape(minus[port].shape)
        difference: np.ndarray = (self._value(of, plus) - self._value(of, minus)) * (0.5 / h)
        return difference

    def _richardson(self, of: str, arrays: Sequence[np.ndarray], port: int, step: np.ndarray,
                    h: float) -> np.ndarray:
        # the h² error terms of the two central differences cancel
        half, full = (self._central(of, arrays, port, step, s) for s in (h / 2, h))
        estimate: np.ndarray = (4 * half - full) / 3
        return estimate

    def _adaptive(self, of: str, arrays: Sequence[np.ndarray], port: int, step: np.ndarray,
                  larger: bool = False) -> tuple[np.ndarray, float]:
        """The derivative of output ``of`` along ``step`` (a vector of input ``port``'s size), and the
        step h whose Richardson estimate it is: of the two consecutive steps whose estimates agree best,
        the smaller (``larger``: the larger, when the two agree to ``FD_AGREE``)."""
        if of not in self.values(arrays):  # a derived output: its own differences' step, chosen here (the
            # larger of an agreeing pair: the smoother function of the outer step, as accurate)
            self._inner[of] = self._columns(self.function.jacobians[of], arrays, larger=True)[2]
        estimates = [self._richardson(of, arrays, port, step, FD_STEPS[0]),
                     self._richardson(of, arrays, port, step, FD_STEPS[1])]
        gaps = [_size(estimates[1] - estimates[0])]
        if gaps[0] > FD_AGREE * max(_size(estimates[1]), FLOOR):
            for h in FD_STEPS[2:]:
                estimates.append(self._richardson(of, arrays, port, step, h))
                gaps.append(_size(estimates[-1] - estimates[-2]))
        pair = int(np.argmin(gaps))
        agree = gaps[pair] <= FD_AGREE * max(_size(estimates[pair + 1]), FLOOR)
        best = pair if larger and agree else pair + 1
        return estimates[best], FD_STEPS[best]

    def derivative(self, of: str, arrays: Sequence[np.ndarray], port: int, step: np.ndarray) -> np.ndarray:
        """The derivative of output ``of`` along ``step`` (a vector of input ``port``'s size)."""
        return self._adaptive(of, arrays, port, step)[0]

    def _is_multivector(self, of: str, arrays: Sequence[np.ndarray]) -> bool:
        values = self.values(arrays)
        if of in values:
            return isinstance(values[of], MultiVector)
        source, _, post, _ = split_derivative(self.function.jacobians[of])
        return post is not None or self._is_multivector(source, arrays)

    def _columns(self, derivative: tuple[Any, ...], arrays: Sequence[np.ndarray], fixed: float | None = None,
                 larger: bool = False) -> tuple[list[np.ndarray], bool, float]:
        """The dense columns of a declared Jacobian by differences, whether they are multivectors, and
        the largest step used: one column per entry of the input, or one along the direction input of a
        directional Jacobian; with ``fixed``, one Richardson estimate at that step."""
        of, wrt, post, direction = split_derivative(derivative)
        port = next(k for k, p in enumerate(self.in_ports) if p.name == wrt)
        size = len(self.in_ports[port].rows)
        if direction is None:
            steps = list(np.eye(size))
        else:
            along = next(k for k, p in enumerate(self.in_ports) if p.name == direction)
            steps = [np.asarray(arrays[along], dtype=float).reshape(size)]
        value = self.values(arrays).get(of)
        is_multivector = post is not None or self._is_multivector(of, arrays)
        columns, used = [], 0.0
        for step in steps:
            if fixed is None:
                column, h = self._adaptive(of, arrays, port, step, larger)
            else:
                column, h = self._richardson(of, arrays, port, step, fixed), fixed
            used = max(used, h)
            if post is not None:
                column = post(value, MultiVector(self.function.algebra, column)).coeffs
            columns.append(np.asarray(column, dtype=float))
        return columns, is_multivector, used

    def jacobian(self, derivative: tuple[Any, ...], arrays: Sequence[np.ndarray],
                 rows: Sequence[str]) -> np.ndarray:
        """The Jacobian output (rows × entries of the input, or rows × 1 along a direction) from
        differences: ∂of/∂wrt, each column passed through ``post(value, column)`` when the Jacobian is a
        transformed one."""
        columns, is_multivector, _ = self._columns(derivative, arrays)
        algebra = self.function.algebra
        return np.array([_rows(c, rows, algebra, is_multivector) for c in columns]).T


def _size(x: np.ndarray) -> float:
    return float(np.max(np.abs(x))) if x.size else 0.0


def _in_domain(function: KernelFunction, differences: _Differences, rng: np.random.Generator,
               tries: int = 50) -> list[np.ndarray]:
    """A random input where the function is defined on the interpreter (finite values, no error):
    random coefficients of a kind (a circle, say) can be imaginary or degenerate; they are drawn
    again. A kernel with a narrow domain should give ``sample=`` to ``gagen.kernel``."""
    from gagen.frontend import KernelError

    for _ in range(tries):
        arrays = function.sample(rng)
        try:
            values = differences.values(arrays)
        except KernelError:
            continue
        if all(np.all(np.isfinite(_dense_value(v, function.algebra))) for v in values.values()):
            return arrays
    raise ValueError(f"kernel {function.name}: no random input out of {tries} is in its domain; "
                     "give gagen.kernel a sample= function")


def check_kernels(module: GeneratedModule, functions: Mapping[str, KernelFunction],
                  inputs: Mapping[str, list[tuple[str, list[np.ndarray]]]] | None = None, *,
                  count: int = 5, seed: int = 0, progress: Callable[[str], None] = lambda _: None,
                  rtol: float = VALUE_RTOL, fd_rtol: float = FD_RTOL) -> list[Discrepancy]:
    """Evaluate every kernel of ``module`` (C single, C batched, CasADi) on labelled input samples
    (``inputs[kernel]``, else ``count`` draws of the function's ``sample``) against its function on
    the interpreter; one Discrepancy per output and one progress line per kernel."""
    rng = np.random.default_rng(seed)
    entries = module.manifest["kernels"]
    result = []
    for number, entry in enumerate(entries, 1):
        name = entry["name"]
        function = functions[name]
        in_ports = [_Entry(p) for p in entry["inputs"]]
        out_ports = [_Entry(p) for p in entry["outputs"]]
        derivatives = function.jacobians
        differences = _Differences(function, in_ports)
        points = list(inputs[name]) if inputs is not None and name in inputs else \
            [(f"random~{i}", _in_domain(function, differences, rng)) for i in range(count)]
        c_kernel, ca_function = getattr(module.c, name), getattr(module.casadi, name)
        worst: dict[str, list[tuple[float, str]]] = {p.name: [(0.0, "")] * 3 for p in out_ports}

        def note(port: str, path: int, error: float, label: str,
                 worst: dict[str, list[tuple[float, str]]] = worst) -> None:
            current = worst[port][path][0]
            if not np.isnan(current) and (np.isnan(error) or error > current):  # NaN counts as the worst
                worst[port][path] = (error, label)

        # a Jacobian the function gives itself (an author's rule) is held against its values and,
        # at the first FD_SAMPLES points, against differences too: its formula is the one at risk
        authored: dict[str, list[tuple[float, str]]] = {}
        references = []
        for number_of_point, (label, arrays) in enumerate(points):
            values = differences.values(arrays)
            given = function.layout(values, out_ports)
            refs = [ref if ref is not None else differences.jacobian(derivatives[p.name], arrays, p.rows)
                    for p, ref in zip(out_ports, given, strict=True)]
            c_out = c_kernel(*arrays)
            c_out = c_out if isinstance(c_out, tuple) else (c_out,)
            ca_out = ca_function(*arrays)
            ca_out = ca_out if isinstance(ca_out, (list, tuple)) else [ca_out]
            for k, port in enumerate(out_ports):
                ref = np.reshape(refs[k], (len(port.rows), port.cols))
                refs[k] = ref
                note(port.name, 0, relative_error(c_out[k], ref), label)
                note(port.name, 2, relative_error(ca_out[k], ref), label)
                if port.name in derivatives and given[k] is not None and number_of_point < FD_SAMPLES:
                    fd = differences.jacobian(derivatives[port.name], arrays, port.rows).reshape(ref.shape)
                    errors = authored.setdefault(port.name, [(0.0, "")] * 3)
                    for path, value in ((0, c_out[k]), (2, ca_out[k])):
                        error = relative_error(value, fd)
                        if not np.isnan(errors[path][0]) and (np.isnan(error) or error > errors[path][0]):
                            errors[path] = (error, label)
            references.append(refs)
        if points:
            stacked = [np.array([arrays[i] for _, arrays in points]) for i in range(len(in_ports))]
            batched = c_kernel.batch(*stacked)
            batched = batched if isinstance(batched, tuple) else (batched,)
            for k, port in enumerate(out_ports):
                shape = (len(points), len(port.rows), port.cols)
                batch_values = np.reshape(np.asarray(batched[k], dtype=float), shape)
                for s, (label, _) in enumerate(points):
                    note(port.name, 1, relative_error(batch_values[s], references[s][k]), label)
        found = []
        for port in out_ports:
            by_differences = port.name in derivatives and port.name not in function.returned(
                differences.values(points[0][1]) if points else {})
            errors = worst[port.name]
            path = max(range(3), key=lambda p: (np.isnan(errors[p][0]), errors[p][0]))
            found.append(Discrepancy(name, port.name, DIFFERENCES if by_differences else INTERPRETER,
                                     errors[0][0], errors[1][0], errors[2][0],
                                     fd_rtol if by_differences else rtol,
                                     errors[path][1], ("C single", "C batched", "CasADi")[path]))
            if port.name in authored:  # (C batched equals C single to the interpreter's tolerance)
                errors = authored[port.name]
                path = max((0, 2), key=lambda p: (np.isnan(errors[p][0]), errors[p][0]))
                found.append(Discrepancy(name, port.name, DIFFERENCES, errors[0][0], errors[0][0],
                                         errors[2][0], fd_rtol, errors[path][1],
                                         ("C single", "C batched", "CasADi")[path]))
        result += found
        progress(_progress_line(number, len(entries), name, found))
    return result


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
        known = found.get(key)
        limits = known.limits if known is not None and known.limits is not None else (-np.inf, np.inf)
        lower.append(limits[0])
        upper.append(limits[1])
        kinds.append(known.kind if known is not None else "revolute")
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

    def desired() -> Multivector:
        generator = zero.make(dict(zip(SIMILARITY_GENERATOR, rng.uniform(-0.5, 0.5, 7), strict=True)))
        return exp_similarity(generator)

    def velocity() -> np.ndarray:
        return rng.uniform(-1.0, 1.0, system.dof)

    out = [Sample(name, np.array(q, dtype=float), desired(), velocity()) for name, q in named.items()]
    for i in range(count):
        name, centre = centres[i % len(centres)]
        lo = np.maximum(centre - spread, lower)
        hi = np.minimum(centre + spread, upper)
        outside = lo > hi  # a centre outside the limits: anywhere within them
        lo, hi = np.where(outside, lower, lo), np.where(outside, upper, hi)
        out.append(Sample(f"{name}~{i}", rng.uniform(lo, hi), desired(), velocity()))
    return out


def _named(configurations: Mapping[str, Sequence[float]] | Sequence[float] | None) -> dict[str, np.ndarray]:
    if configurations is None:
        return {}
    if isinstance(configurations, Mapping):
        return {str(k): np.array(v, dtype=float) for k, v in configurations.items()}
    return {"ready": np.array(configurations, dtype=float)}  # one unnamed configuration (older callers)


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
