"""The cooperative dual task space of two chains [COOP Section 2.5, Eq. 10-11], as kernels.

With M_1, M_2 the end-effector motors of the two chains in the system's base frame:

- relative motor M_r = M_2~ M_1 [Eq. 10] (chain 1's frame seen from chain 2's);
- absolute motor M_a = M_2 exp(½ log M_r) [Eq. 11], in gagen's decoupled charts (``versors``):
  exp(½ log M_r) = H = T(t/2) S with M_r = T(t) R and S the half-angle rotor (1 + R)/|1 + R|.
  dqrobotics' pow(x_r, ½) uses the same decoupled log (½θn + ε½t), so the two agree.

Geometric (body) Jacobians J = −2 M~ ∂M/∂q [COOP Eq. 8], rows MOTOR_GENERATOR, one column per joint
of the system (a joint both chains share sums its two contributions), in closed form from the
chains' spatial joint lines L'_j (∂M_i/∂q_j = −½ L'_j M_i):

- J_r,j = M_1~ Λ_j M_1 with Λ_j = L'_1,j − L'_2,j (each where the chain has joint j);
- J_a,j = M_a~ L'_2,j M_a + G_H(J_r,j), G_H = −2 H~ ∂H from the body generator of M_r = T(t) R
  (see ``half_motor_generator``): ½ S g_∞ S~ + ½(ω + ⟨R ω⟩₂)/(1 + r₀) for J_r,j = ω + g_∞;
- the analytic Jacobians ∂M/∂q = −½ M J (exact for unit motors).

H is singular where R = −1 (r₀ = −1: the two frames have the same orientation but opposite lifts,
a relative angle of 2π in the chart), like dqrobotics' pow there: its axis is undefined and ∂H grows
like 1/(1 + r₀). The kernels stay finite there (``SINGULAR``), and (1 + ⟨M_r⟩₀)/2 ∈ [0, 1], readable
from M_r, is the conditioning to watch (1 at R = 1, 0 at R = −1).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

from gagen.algebra.signature import cga3d
from gagen.frontend import KernelFunction, scalars
from gagen.model import kinematics as K
from gagen.model.conformal import MOTOR, MOTOR_GENERATOR, ROTATION, TRANSLATION, part
from gagen.model.versors import ROTOR, exp_motor, log_motor
from gagen.robots.system import System


def relative_motor(m1: Any, m2: Any) -> Any:
    """M_r = M_2~ M_1 [COOP Eq. 10]."""
    return ~m2 * m1


def absolute_motor(m1: Any, m2: Any) -> Any:
    """M_a = M_2 exp(½ log M_r) [COOP Eq. 11], literally, through the motor exp and log charts."""
    return m2 * exp_motor(log_motor(relative_motor(m1, m2)) * 0.5)


# 1 + r₀ is floored here: within ~3e-8 rad of the singular relative angle 2π, S stays bounded (|S| <= 1)
# and the Jacobians below ~1e16, finite, where the exact ones grow without bound
SINGULAR = 1e-16


class HalfMotor(NamedTuple):
    """H = exp(½ log M) = (1 + τ) S for a unit motor M = T(t) R, and what its derivative needs."""

    versor: Any  # H
    rotor: Any  # R, the rotor of M
    half_rotor: Any  # S = (1 + R)/|1 + R|, the rotor of half R's angle
    reciprocal: Any  # 1/(1 + r₀) (floored at SINGULAR)


def half_motor(m: Any) -> HalfMotor:
    """exp(½ log M) in closed form: T(t/2) with t the translation of M = T(t) R, times the half-angle
    rotor (1 + R)/|1 + R|, |1 + R|² = 2(1 + r₀). It is the chart's square root for every rotation
    angle θ ∈ [0, 2π) of R (log_rotor's range), with no trigonometry."""
    r = part(m, ROTOR)
    tau = part(m * ~r, TRANSLATION) * 0.5  # T(t) = M R~ = 1 − ½ t e∞, so T(t/2) = 1 + ½⟨M R~⟩_{e∞}
    math = m.math
    d = 1 + r.scalar()  # = |1 + R|²/2, from 2 (R = 1) down to 0 (R = −1)
    reciprocal = math.shared(1 / math.if_else(math.lt(d, SINGULAR), SINGULAR, d))
    s = _shared((1 + r) * math.sqrt(reciprocal * 0.5), ROTOR)
    return HalfMotor(_shared((1 + tau) * s, MOTOR), r, s, reciprocal)


def half_motor_generator(half: HalfMotor, g: Any) -> Any:
    """G_H = −2 H~ ∂H for H = exp(½ log M), from M's body generator g = −2 M~ ∂M = ω + g_∞.

    With ∂R = −½ R ω and ∂τ = −¼ R g_∞ R~ (T = 1 + 2τ, its body part R~(−4 ∂τ)R = g_∞), and S² = R:
    G_H = S~(−2 ∂τ)S − ⟨(1 + R~)∂R⟩₂/(1 + r₀) = ½ S g_∞ S~ + ½(ω + ⟨R ω⟩₂)/(1 + r₀)."""
    omega = part(g, ROTATION)
    rotation = (omega + part(half.rotor * omega, ROTATION)) * (half.reciprocal * 0.5)
    return part(half.half_rotor.sandwich(part(g, TRANSLATION)), TRANSLATION) * 0.5 + rotation


def _shared(x: Any, blades: Sequence[str]) -> Any:
    """x with each coefficient one node (products with it stay binary instead of expanding its terms)."""
    return x.make({b: x.math.shared(x[b]) for b in blades})


def _is_zero(value: Any) -> bool:
    return isinstance(value, (int, float)) and value == 0


def _adjoint(versor: Any) -> Callable[[Any], Any]:
    """The linear map B ↦ V B V~ on the MOTOR_GENERATOR bivectors, from the images of the six basis
    bivectors, built once: each column costs a 6 × 6 product instead of two multivector products."""
    images = {b: _shared(part(versor.sandwich(versor.make({b: 1})), MOTOR_GENERATOR), MOTOR_GENERATOR)
              for b in MOTOR_GENERATOR}

    def apply(x: Any) -> Any:
        total = versor.make({})
        for b in MOTOR_GENERATOR:
            if not _is_zero(x[b]):
                total = total + images[b] * versor.math.shared(x[b])
        return total

    return apply


def _columns(system: System, lines: Sequence[Sequence[Any]], zero: Any) -> list[list[Any]]:
    """Per chain, its joint lines as system columns (zero where the chain lacks the joint)."""
    found = []
    for indices, chain_lines in zip(system.chain_indices(), lines, strict=True):
        columns = [zero] * system.dof
        for j, line in zip(indices, chain_lines, strict=True):
            columns[j] = columns[j] + line
        found.append(columns)
    return found


NAMES = ("M_r", "M_a", "J_r", "J_a", "J_Ar", "J_Aa")


def dual_task(ga: Any, system: System, q: Sequence[Any], names: Sequence[str] = NAMES) -> dict[str, Any]:
    """The dual task space of a two-chain system at q: M_r, M_a, their geometric Jacobians J_r, J_a
    and analytic Jacobians J_Ar = ∂M_r/∂q, J_Aa = ∂M_a/∂q (the ones in ``names``)."""
    if len(system.chains) != 2:
        raise ValueError(f"system {system.name!r}: the dual task space takes two chains, "
                         f"got {len(system.chains)}")
    poses = [K.chain_kinematics(ga, chain.joints, qc) for chain, qc in zip(system.chains, system.split(q),
                                                                           strict=True)]
    m1, m2 = (_shared(m, MOTOR) for m, _ in poses)
    lines1, lines2 = _columns(system, [lines for _, lines in poses], ga)
    mr = _shared(relative_motor(m1, m2), MOTOR)
    half = half_motor(mr)
    ma = _shared(m2 * half.versor, MOTOR)
    memo: dict[str, list[Any]] = {}

    def jr() -> list[Any]:  # M_1~ Λ_j M_1, Λ_j = L'_1,j − L'_2,j
        if "J_r" not in memo:
            carry = _adjoint(~m1)
            memo["J_r"] = [carry(a - b) for a, b in zip(lines1, lines2, strict=True)]
        return memo["J_r"]

    def ja() -> list[Any]:  # M_a~ L'_2,j M_a + G_H(J_r,j)
        if "J_a" not in memo:
            carry = _adjoint(~ma)
            memo["J_a"] = [carry(line) + half_motor_generator(half, g) for line, g in zip(lines2, jr(),
                                                                                           strict=True)]
        return memo["J_a"]

    values: dict[str, Callable[[], Any]] = {
        "M_r": lambda: mr, "M_a": lambda: ma, "J_r": jr, "J_a": ja,
        "J_Ar": lambda: [part(mr * _shared(g, MOTOR_GENERATOR), MOTOR) * -0.5 for g in jr()],
        "J_Aa": lambda: [part(ma * _shared(g, MOTOR_GENERATOR), MOTOR) * -0.5 for g in ja()]}
    return {name: values[name]() for name in names}


def _generator_column(v: Any, derivative: Any) -> Any:
    """A column of J = −2 M~ ∂M from one of ∂M (on the interpreter, for the difference checks)."""
    return ~v * derivative * -2


KERNELS = (  # (names as gagen.names.DUAL_TASK_KERNELS, which the spec checks chain names against)
    ("dual_task", "cooperative dual task space: relative and absolute motors M_r, M_a and their "
                  "geometric Jacobians J_r, J_a", ("M_r", "M_a", "J_r", "J_a")),
    ("dual_task_jacobians", "cooperative dual task space: M_r, M_a and their analytic Jacobians "
                            "J_Ar = dM_r/dq, J_Aa = dM_a/dq", ("M_r", "M_a", "J_Ar", "J_Aa")),
)
JACOBIANS: dict[str, tuple[str, str] | tuple[str, str, Callable[[Any, Any], Any]]] = {
    "J_r": ("M_r", "q", _generator_column), "J_a": ("M_a", "q", _generator_column),
    "J_Ar": ("M_r", "q"), "J_Aa": ("M_a", "q")}


def _values(system: System, names: Sequence[str]) -> Callable[..., dict[str, Any]]:
    def values(ga: Any, q: Sequence[Any]) -> dict[str, Any]:
        return dual_task(ga, system, q, names)

    return values


def dual_task_kernel_functions(system: System) -> dict[str, KernelFunction]:
    """``dual_task`` and ``dual_task_jacobians`` of a system with exactly two chains (none otherwise):
    the function gives its Jacobians itself (closed forms), held against differences by the checks."""
    if len(system.chains) != 2:
        return {}
    labels = [f"{robot}/{joint}" for robot, joint in system.joint_keys]
    functions = {}
    for name, doc, names in KERNELS:
        outputs = {n: MOTOR if n.startswith("M") else (MOTOR if n.startswith("J_A") else MOTOR_GENERATOR,
                                                       system.dof) for n in names}
        functions[name] = KernelFunction(
            _values(system, names), algebra=cga3d(), name=name, doc=doc,
            inputs={"ga": "algebra", "q": scalars(system.dof, labels)}, outputs=outputs,
            jacobians={k: v for k, v in JACOBIANS.items() if k in names})
    return functions
