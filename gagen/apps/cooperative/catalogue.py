"""The kernel catalogue of a cooperative system: named CasADi Functions with labelled ports.

The model (``gagen.model``) runs once on symbolic multivectors; every kernel is a CasADi Function
over that one graph, with its own common-subexpression elimination, so it carries only what its
outputs need. Per chain (in the system's base frame):

- ``<chain>_fk``: q_i → motor M, end point P;
- ``<chain>_fk_jacobian``: q_i → M, P and the spatial (geometric) Jacobian J_S;
- ``<chain>_jacobians``: q_i → M, P, spatial J_S (= the joint lines L'_j), body J_b, analytic
  J_A = ∂M/∂q, point J_P = ∂P/∂q [COOP Eq. 17], the tool's z-axis line L and its Jacobian J_L [SMC Eq. 20].

Per system:

- ``primitive``: q → X_c, J_c [COOP Eq. 14-17];
- ``similarity``: q → V_Sc, its conditioning and J_G,Sc = −2 V_Sc~ J_A,Sc [Eq. 28-30];
- ``similarity_jacobians``: q → J_A,Sc = ∂V_Sc/∂q, log V_Sc and J_B = ∂ log V_Sc/∂q [Eq. 29, 31];
- ``task``: (q, V_Sd) → e = log(V_Sc~ V_Sd) and J_Be = ∂e/∂q [Eq. 40-44];
- ``similarity_rate``: (q, q̇) → the similarity twist V_S = J_G,Sc q̇ and J̇_G,Sc q̇, the derivative of J_G
  along q̇ [Eq. 33-34], which the task-space dynamics need (C_Sc, Eq. 37): J_G q̇ differentiated along
  q̇ by forward-mode AD (``casadi.jtimes``) on J_G's graph, no second derivative matrix formed;
- with exactly two chains, the cooperative dual task space [Eq. 10-11] (``dual_task`` module):
  ``dual_task``: q → the relative and absolute motors M_r, M_a and their geometric Jacobians;
  ``dual_task_jacobians``: q → M_r, M_a and ∂M_r/∂q, ∂M_a/∂q (both carry the motors, as every chain
  kernel carries M and P).

With measured chains (``measured: true``: a leader's hand, ``docs/leader-follower.md``) every system
kernel also takes the measured joints q_m after q, its Jacobians stay with respect to the robot's q,
and each (but ``similarity_rate``'s, which holds q_m fixed) has a twin ``<J>_m`` with respect to q_m
(J_c_m, J_G_m, J_A_m, J_B_m, J_Be_m: the leader's feed-forward J_m q̇_m); the dual task space is left out.
Systems without measured chains are unchanged.

No kernel is the union of the others: each output is computed by exactly one kernel, which keeps
the generated C (and its compile time) proportional to what is asked.

System Jacobians use the chain rule through the chains' end positions (see ``build_kernels``):
AD on the task-space formulas alone (3 inputs per chain, no kinematics in them), times each
chain's position Jacobian from its joint lines.

Matrices are (rows = blades, columns = joints), stored column-major as CasADi does.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, TypeAlias, TypeVar, cast

import casadi as ca

from gagen.algebra.multivector import SparseMultivector
from gagen.algebra.protocol import Multivector
from gagen.algebra.signature import cga3d
from gagen.apps.cooperative.dual_task import dual_task_kernel_functions
from gagen.codegen.ir import Kernel
from gagen.frontend import Along, KernelFunction, along, scalars, split_derivative
from gagen.model import kinematics as K
from gagen.model.conformal import (
    EUCLID,
    MOTOR,
    MOTOR_GENERATOR,
    POINT,
    SIMILARITY,
    SIMILARITY_GENERATOR,
    part,
    point,
    vector,
)
from gagen.model.fitting import span
from gagen.model.primitives import points_needed, through, unit_primitive
from gagen.model.similarity import cooperative_similarity, similarity_factors
from gagen.model.versors import log_similarity
from gagen.robots.system import Chain, System
from gagen.symbolic.casadi_backend import CasadiBackend
from gagen.symbolic.flatten import identifier

_T = TypeVar("_T")


class _Graph:
    """The system's model on CasADi symbols, built once; kernels select from it."""

    def __init__(self, system: System) -> None:
        self.system = system
        self.algebra = algebra = cga3d()
        self.backend = CasadiBackend()
        self.q = ca.SX.sym("q", system.dof)
        self.q_m = ca.SX.sym("q_m", system.measured_dof)
        # the chains' indices point into (q, q_m) joined; without measured chains that is q itself
        self.joined = ca.vertcat(self.q, self.q_m) if system.measured_dof else self.q
        self.zero = SparseMultivector(algebra, self.backend, {})
        self.joint_labels = _labels(system)

    def column(self, x: Multivector, blades: Sequence[str]) -> ca.SX:
        column: ca.SX = ca.vertcat(*[self.backend.native(x[b]) for b in blades])
        return column

    def matrix(self, columns: Sequence[Multivector], blades: Sequence[str]) -> ca.SX:
        return ca.horzcat(*[self.column(c, blades) for c in columns])

    def multivector(self, values: ca.SX, blades: Sequence[str]) -> SparseMultivector:
        return SparseMultivector(self.algebra, self.backend, {
            self.algebra.blade(b): self.backend.lift(values[r]) for r, b in enumerate(blades)})


def _labels(system: System) -> tuple[str, ...]:
    """The row labels of (q, q_m) joined, "robot/joint" each."""
    return tuple(f"{robot}/{joint}" for robot, joint in system.joint_keys + system.measured_keys)


CHAIN_KERNELS = (
    ("fk", "motor and end point", ("M", "P")),
    ("fk_jacobian", "motor, end point and spatial (geometric) Jacobian", ("M", "P", "J_S")),
    ("jacobians", "motor, end point, every Jacobian and the tool z-axis line",
     ("M", "P", "J_S", "J_b", "J_A", "J_P", "L", "J_L")),
)


def _chain_function(chain: Chain, names: Sequence[str]) -> Callable[..., dict[str, Any]]:
    """The chain's kinematics as one function over the multivector protocol (the compiler's and the
    interpreter's path alike): the Jacobians are the closed forms from the joint lines [COOP Eq. 15-17]."""

    def kinematics(ga: Any, q: Sequence[Any]) -> dict[str, Any]:
        motor, lines, position = K.chain_pose(ga, chain.joints, q)
        end = point(position)  # = V_M e0 V_M~, from the position the chain carries
        tool = ga.make({K.TOOL_LINE: 1})
        values: dict[str, Callable[[], Any]] = {
            "M": lambda: motor, "P": lambda: end, "J_S": lambda: K.spatial_jacobian(lines),
            "J_b": lambda: K.body_jacobian(motor, lines),
            "J_A": lambda: K.analytic_jacobian(motor, lines),
            "J_P": lambda: K.point_jacobian(motor, lines, end),
            "L": lambda: part(motor.sandwich(tool), MOTOR_GENERATOR),
            "J_L": lambda: K.line_jacobian(motor, lines, tool)}
        return {name: values[name]() for name in names}

    return kinematics


def _chain_outputs(n: int) -> dict[str, Any]:
    return {"M": MOTOR, "P": POINT, "J_S": (MOTOR_GENERATOR, n), "J_b": (MOTOR_GENERATOR, n),
            "J_A": (MOTOR, n), "J_P": (POINT, n), "L": MOTOR_GENERATOR, "J_L": (MOTOR_GENERATOR, n)}


def chain_kernel_functions(system: System) -> dict[str, KernelFunction]:
    """``<chain>_fk``, ``<chain>_fk_jacobian`` and ``<chain>_jacobians`` of every chain, as front-end
    kernels (J_A = ∂M/∂q and J_P = ∂P/∂q are the function's own, cheaper than AD)."""
    labels = _labels(system)
    functions = {}
    for chain, indices in zip(system.chains, system.chain_indices(), strict=True):
        n = len(indices)
        declared = _chain_outputs(n)
        for suffix, doc, names in CHAIN_KERNELS:
            jacobians = {j: (of, "q") for j, of in (("J_A", "M"), ("J_P", "P")) if j in names}
            name = identifier(f"{chain.name}_{suffix}")  # (a System built directly may carry any chain name)
            functions[name] = KernelFunction(
                _chain_function(chain, names), algebra=cga3d(), name=name, doc=f"chain {chain.name}: {doc}",
                inputs={"ga": "algebra", "q": scalars(n, [labels[i] for i in indices])},
                outputs={k: declared[k] for k in names}, jacobians=jacobians)
    return functions


def _task_space(graph: _Graph, positions: ca.SX, vsd: ca.SX) -> dict[str, ca.SX]:
    """X_c, V_Sc, conditioning, log V_Sc and e as functions of the end positions (3 per chain), and
    their derivatives with respect to them. Points are rebuilt as P(p) = e0 + p + ½|p|² e∞.

    ∂X_c/∂p is CasADi AD. The similarity's derivatives all come from G = −2 V_Sc~ ∂V_Sc/∂p, taken by
    the product rule over its factors (``_generator_jacobian``); then ∂V_Sc = −½ V_Sc G and, with
    W = V_Sc~ V_Sd, ∂W = ½ G W; the logarithms are differentiated locally (AD of log at its argument,
    applied to those directions), never through the whole construction."""
    system, algebra = graph.system, graph.algebra
    points = [point(vector(graph.zero, [graph.backend.lift(positions[3 * i + k]) for k in range(3)]))
              for i in range(len(system.chains))]
    # (the model's formulas return the multivector type they are given: symbolic points, a symbolic X_c)
    spanned = span(system.kind, points)  # X_c through the points, or their best fit beyond the needed count
    xc = cast(SparseMultivector, spanned.primitive)
    xc_blades = tuple(algebra.blade_name(b) for b in xc.support)
    factored = similarity_factors(system.kind, unit_primitive(system.kind, xc), xc)
    factors, conditioning, degenerate = factored
    if spanned.fitted:  # the fit's own conditioning too (gagen.model.fitting)
        conditioning = conditioning * spanned.conditioning
    v = factored.versor()
    g = _masked(_generator_jacobian(graph, factors, positions), degenerate)
    directions = [graph.multivector(g[:, k], SIMILARITY_GENERATOR) for k in range(positions.numel())]
    w = ~v * graph.multivector(vsd, SIMILARITY)
    if len(factors) == 1:  # V_Sc is its one factor (flats, points): its own AD derivative is ∂V_Sc
        blades = tuple(algebra.blade_name(b) for b in factors[0].support)
        derivative = ca.jacobian(graph.column(factors[0], blades), positions)
        dv = _masked(graph.matrix([graph.multivector(derivative[:, k], blades)
                                   for k in range(positions.numel())], SIMILARITY), degenerate)
    else:
        dv = graph.matrix([(v * d) * -0.5 for d in directions], SIMILARITY)
    dw = graph.matrix([(d * w) * 0.5 for d in directions], SIMILARITY)
    values = {"X_c": graph.column(xc, xc_blades), "V_Sc": graph.column(v, SIMILARITY),
              "conditioning": graph.backend.native(graph.backend.lift(conditioning)),
              "log_V": graph.column(log_similarity(v), SIMILARITY_GENERATOR),
              "e": graph.column(log_similarity(w), SIMILARITY_GENERATOR)}
    return {"blades": xc_blades, **values, "dX_c": ca.jacobian(values["X_c"], positions), "dV_Sc": dv,
            "dG": g, "dlog_V": _log_derivative(graph, values["V_Sc"], dv),
            "de": _log_derivative(graph, graph.column(w, SIMILARITY), dw)}


def _masked(derivative: ca.SX, degenerate: bool | ca.SX) -> ca.SX:
    """Zero where the spanning points are degenerate, like the identity that replaces V_Sc there,
    whatever the guarded factors' derivatives give."""
    if isinstance(degenerate, bool):
        return ca.SX.zeros(derivative.shape) if degenerate else derivative
    return ca.if_else(degenerate, ca.SX.zeros(derivative.shape), derivative)


def _generator_jacobian(graph: _Graph, factors: Sequence[SparseMultivector], wrt: ca.SX) -> ca.SX:
    """G = −2 V~ ∂V/∂x (7 × len(x)) for V = V_1 V_2 ⋯ V_k, by the product rule at the group level:
    G = Σ_j U_j~ g_j U_j with g_j = −2 V_j~ ∂V_j/∂x and U_j = V_{j+1} ⋯ V_k.

    Each factor is differentiated alone (AD on its few coefficients), and each sandwich is applied as
    a linear map: the images U_j~ e_b U_j of the generator blades are built once and combined per
    direction, as the chains carry their frames."""
    n = wrt.numel()
    columns = [graph.zero] * n
    trailing = None
    for factor in reversed(factors):
        blades = tuple(graph.algebra.blade_name(b) for b in factor.support)
        derivative = ca.jacobian(graph.column(factor, blades), wrt)
        reverse = ~factor
        local = [part((reverse * graph.multivector(derivative[:, k], blades)) * -2, SIMILARITY_GENERATOR)
                 for k in range(n)]
        used = [b for b in SIMILARITY_GENERATOR if any(not graph.backend.is_zero(g[b]) for g in local)]
        if trailing is None:
            moved = local
        else:
            inverse = ~trailing
            images = {b: inverse * graph.zero.make({b: 1}) * trailing for b in used}
            moved = []
            for g in local:
                total = graph.zero
                for b in used:
                    if not graph.backend.is_zero(g[b]):
                        total = total + images[b] * graph.zero.math.shared(g[b])
                moved.append(part(total, SIMILARITY_GENERATOR))
        columns = [c + m for c, m in zip(columns, moved, strict=True)]
        trailing = factor if trailing is None else factor * trailing
    return graph.matrix(columns, SIMILARITY_GENERATOR)


def _log_derivative(graph: _Graph, at: ca.SX, directions: ca.SX) -> ca.SX:
    """∂ log(X)·dX for each column dX of ``directions``: the Jacobian of the similarity logarithm at a
    free argument (CasADi AD on the log alone), evaluated at ``at``, times the directions. (Forward
    sweeps per direction instead cost ~15 % more flops and ~50 % more selects here.)"""
    x = ca.SX.sym("x", len(SIMILARITY))
    log = graph.column(log_similarity(graph.multivector(x, SIMILARITY)), SIMILARITY_GENERATOR)
    return ca.mtimes(ca.substitute(ca.jacobian(log, x), x, at), directions)


def _chain_rule(system: System, by_position: ca.SX, position_jacobians: Sequence[ca.SX]) -> ca.SX:
    """∂y/∂q from ∂y/∂p (3 columns per chain) and each chain's 3 × n_i position Jacobian; a joint
    shared by several chains sums their contributions. With measured chains the columns are those of
    (q, q_m) joined."""
    columns: list[ca.SX | None] = [None] * (system.dof + system.measured_dof)
    for i, (indices, jp) in enumerate(zip(system.chain_indices(), position_jacobians, strict=True)):
        block = ca.mtimes(by_position[:, 3 * i:3 * i + 3], jp)
        for c, j in enumerate(indices):
            current = columns[j]
            columns[j] = block[:, c] if current is None else current + block[:, c]
    return ca.horzcat(*cast(list[ca.SX], columns))  # (every joint is in a chain: no column is left None)


class _SystemGraph:
    """The system kernels' expressions, built once on CasADi symbols (q, V_Sd) and shared by their rules.

    The system Jacobians use the chain rule through the end positions: with p = (p_1 … p_n),
    ∂y/∂q = Σ_i (∂y/∂p_i) J_p,i, where ∂y/∂p_i (3 columns) is CasADi AD on the task-space formulas
    alone (X_c from the points, the similarity construction, the logarithms) and J_p,i is chain i's
    position Jacobian from its joint lines (the e1, e2, e3 rows of [COOP Eq. 17]). For J_G,Sc the
    product −2 V_Sc~ ∂V_Sc/∂p is taken before the chain rule (7 × 3n instead of 7 × m columns).
    """

    NAMES = ("X_c", "J_c", "V_Sc", "conditioning", "J_A", "J_G", "log_V", "J_B", "e", "J_Be")
    JACOBIANS = ("J_c", "J_A", "J_G", "J_B", "J_Be")  # with measured chains also each <J>_m (q_m's columns)

    def __init__(self, system: System) -> None:
        self.system = system
        self.names = self.NAMES + (tuple(f"{j}_m" for j in self.JACOBIANS) if system.measured_dof else ())
        self._function: ca.Function | None = None

    @property
    def function(self) -> ca.Function:
        if self._function is None:
            self._function = self._build()
        return self._function

    def _build(self) -> ca.Function:
        system = self.system
        graph = _Graph(system)
        points = []
        for indices, chain in zip(system.chain_indices(), system.chains, strict=True):
            qi = [graph.backend.lift(graph.joined[i]) for i in indices]
            # the system kernels need positions and lines only: turn the frame by cos q, sin q directly
            _, free_lines, free_position = K.chain_pose(graph.zero, chain.joints, qi, with_motor=False)
            free_end = point(free_position)
            points.append((free_end, K.point_jacobian(None, free_lines, free_end)))
        positions_q = ca.vertcat(*[graph.column(p, EUCLID) for p, _ in points])
        jps = [graph.matrix(jac, EUCLID) for _, jac in points]
        # the task space as a function of the end positions (and of V_Sd), differentiated there
        positions = ca.SX.sym("p", 3 * len(system.chains))
        vsd = ca.SX.sym("V_Sd", len(SIMILARITY))
        task = _task_space(graph, positions, vsd)
        names = ("X_c", "V_Sc", "conditioning", "log_V", "e", "dX_c", "dV_Sc", "dG", "dlog_V", "de")
        task_function = ca.Function("task_space", [positions, vsd], [task[k] for k in names])
        at_q = dict(zip(names, task_function(positions_q, vsd), strict=True))
        values = {
            "X_c": at_q["X_c"], "J_c": _chain_rule(system, at_q["dX_c"], jps),
            "V_Sc": at_q["V_Sc"], "conditioning": at_q["conditioning"],
            "J_A": _chain_rule(system, at_q["dV_Sc"], jps), "J_G": _chain_rule(system, at_q["dG"], jps),
            "log_V": at_q["log_V"], "J_B": _chain_rule(system, at_q["dlog_V"], jps),
            "e": at_q["e"], "J_Be": _chain_rule(system, at_q["de"], jps)}
        if not system.measured_dof:
            return ca.Function("system", [graph.q, vsd], [values[k] for k in self.names], ["q", "V_Sd"],
                               list(self.names))
        for j in self.JACOBIANS:  # the robot's columns, and the measured joints' as the twin
            values[f"{j}_m"] = values[j][:, system.dof:]
            values[j] = values[j][:, :system.dof]
        return ca.Function("system", [graph.q, graph.q_m, vsd], [values[k] for k in self.names],
                           ["q", "q_m", "V_Sd"], list(self.names))

    def rule(self, names: Sequence[str]) -> Callable[[dict[str, ca.SX]], dict[str, ca.SX]]:
        def expressions(inputs: dict[str, ca.SX]) -> dict[str, ca.SX]:
            vsd = inputs.get("V_Sd", ca.SX.zeros(len(SIMILARITY)))
            measured = [inputs[MEASURED_INPUT]] if self.system.measured_dof else []
            values = dict(zip(self.names, self.function(inputs["q"], *measured, vsd), strict=True))
            if RATE_INPUT in inputs:  # V_S = J_G q̇ and its derivative along q̇ (J̇_G q̇) by forward AD
                qd = inputs[RATE_INPUT]
                values["V_S"] = ca.mtimes(values["J_G"], qd)
                values["Jdot_qdot"] = ca.jtimes(values["V_S"], inputs["q"], qd)
            return {name: values[name] for name in names}

        return expressions


def primitive_blades(kind: str) -> tuple[str, ...]:
    """The blades X_c may have (its proven support from symbolic points)."""
    zero = SparseMultivector(cga3d(), CasadiBackend(), {})
    points = [point(vector(zero, [zero.backend.lift(s) for s in ca.SX.sym(f"p{i}", 3).nz]))
              for i in range(points_needed(kind))]
    x = cast(SparseMultivector, through(kind, points))  # (symbolic points: a symbolic X_c)
    return tuple(x.algebra.blade_name(b) for b in x.support)


class _SystemValues:
    """The system kernels' values as functions over the multivector protocol: the end points from each
    chain's forward kinematics, X_c through them, V_Sc = V_S(X_u, X_c) and the logarithms
    [COOP Eq. 14, 28-31, 40]. On the interpreter (float joint values) one memo serves all four
    kernels: the end points per chain (a difference step moves one joint; the other chains keep
    theirs) and the task-space values per q (the kernels' differences revisit the same q ± h)."""

    LIMIT = 4096

    def __init__(self, system: System) -> None:
        self.system = system
        self._ends: dict[tuple[Any, ...], Any] = {}
        self._task: dict[tuple[Any, ...], dict[str, Any]] = {}

    def _remember(self, memo: dict[tuple[Any, ...], _T], key: tuple[Any, ...] | None,
                  compute: Callable[[], _T]) -> _T:
        if key is None:
            return compute()
        if key not in memo:
            if len(memo) > self.LIMIT:
                memo.clear()
            memo[key] = compute()
        return memo[key]

    def _at(self, ga: Any, q: Sequence[Any], q_m: Sequence[Any] = ()) -> dict[str, Any]:
        numeric = all(isinstance(v, float) for v in [*q, *q_m])
        system = self.system

        def end_point(index: int, qc: list[Any]) -> Any:
            return self._remember(self._ends, (index, tuple(qc)) if numeric else None, lambda: K.end_point(
                K.forward_kinematics(ga, system.chains[index].joints, qc)))

        def task() -> dict[str, Any]:
            points = [end_point(i, qc) for i, qc in enumerate(system.split(list(q), list(q_m)))]
            spanned = span(system.kind, points)
            xc = spanned.primitive
            v, conditioning = cooperative_similarity(system.kind, xc)
            if spanned.fitted:
                conditioning = conditioning * spanned.conditioning
            return {"X_c": xc, "V_Sc": v, "conditioning": conditioning}

        return self._remember(self._task, (*q, *q_m) if numeric else None, task)

    def function(self, names: Sequence[str], extra: Sequence[str] = ()) -> Callable[..., dict[str, Any]]:
        def values(ga: Any, q: Sequence[Any], V_Sd: Any = None, q_m: Sequence[Any] = ()) -> dict[str, Any]:
            at = self._at(ga, q, q_m)
            found: dict[str, Callable[[], Any]] = {
                "X_c": lambda: at["X_c"], "V_Sc": lambda: at["V_Sc"],
                "conditioning": lambda: at["conditioning"],
                "log_V": lambda: at["log_V"] if "log_V" in at else
                at.setdefault("log_V", log_similarity(at["V_Sc"])),
                "e": lambda: log_similarity(~at["V_Sc"] * V_Sd)}
            return {name: found[name]() for name in names}

        extra = list(extra)
        if extra[:1] == [MEASURED_INPUT]:  # (q, q_m, ...): the argument names are the kernel's inputs
            if extra[1:] == ["V_Sd"]:
                return lambda ga, q, q_m, V_Sd: values(ga, q, V_Sd, q_m)
            if extra[1:] == [RATE_INPUT]:
                return lambda ga, q, q_m, qd: values(ga, q, None, q_m)
            return lambda ga, q, q_m: values(ga, q, None, q_m)
        if extra == ["V_Sd"]:
            return lambda ga, q, V_Sd: values(ga, q, V_Sd)
        if extra == [RATE_INPUT]:  # q̇ is read by the compiler's rule only: the rates' reference is
            return lambda ga, q, qd: values(ga, q)  # differences of V_Sc along it
        return lambda ga, q: values(ga, q)


def _generator_column(v: Any, derivative: Any) -> Any:
    """A column of J_G = −2 V~ ∂V from one of ∂V (on the interpreter, for the checks)."""
    return ~v * derivative * -2


# a Jacobian declaration (gagen.frontend): (output, input), optionally with a post-map and/or along(input)
_Post = Callable[[Any, Any], Any]
Jacobian: TypeAlias = (tuple[str, str] | tuple[str, str, _Post] | tuple[str, str, _Post, Along]
                       | tuple[str, str, Along])

SYSTEM_KERNELS: tuple[tuple[str, str, dict[str, str], dict[str, Jacobian]], ...] = (
    ("primitive", "the cooperative {kind} X_c(q) and J_c", {"X_c": "X_c", "J_c": "X_c"},
     {"J_c": ("X_c", "q")}),
    ("similarity", "V_Sc(q), its conditioning and J_G,Sc",
     {"V_Sc": "similarity", "conditioning": "scalar", "J_G": "similarity_generator"},
     {"J_G": ("V_Sc", "q", _generator_column)}),
    ("similarity_jacobians", "J_A,Sc = dV_Sc/dq, log V_Sc and J_B = d log V_Sc/dq",
     {"J_A": "similarity", "log_V": "similarity_generator", "J_B": "similarity_generator"},
     {"J_A": ("V_Sc", "q"), "J_B": ("log_V", "q")}),
    ("task", "task error e = log(V_Sc~ V_Sd) and J_Be",
     {"e": "similarity_generator", "J_Be": "similarity_generator"},
     {"J_Be": ("e", "q")}),
    ("similarity_rate", "similarity twist V_S = J_G,Sc q' and the rate term J_G,Sc' q'",
     {"V_S": "similarity_generator", "Jdot_qdot": "similarity_generator"},
     {"V_S": ("V_Sc", "q", _generator_column, along("qd")), "Jdot_qdot": ("V_S", "q", along("qd"))}),
)
RATE_INPUT = "qd"  # the joint velocities of ``similarity_rate``
MEASURED_INPUT = "q_m"  # the measured chains' joints, of a system with measured chains


def _measured_twins(outputs: dict[str, str], jacobians: dict[str, Jacobian]
                    ) -> tuple[dict[str, str], dict[str, Jacobian]]:
    """A kernel's declaration with a twin ``<J>_m`` (the same derivative with respect to q_m) of every
    Jacobian with respect to q but the directional ones (``similarity_rate``'s hold q_m fixed)."""
    twins = {f"{name}_m": (declaration[0], MEASURED_INPUT, *declaration[2:])
             for name, declaration in jacobians.items() if split_derivative(declaration)[3] is None}
    return ({**outputs, **{name: outputs[name[:-2]] for name in twins}},
            {**jacobians, **cast(dict[str, Jacobian], twins)})


def system_kernel_functions(system: System) -> dict[str, KernelFunction]:
    """``primitive``, ``similarity``, ``similarity_jacobians`` and ``task`` as front-end kernels: the
    model's formulas are their reference; the compiler's expressions come from one shared graph
    (``_SystemGraph``) by rules, with the chain rule through the end positions."""
    graph, reference = _SystemGraph(system), _SystemValues(system)
    labels = tuple(f"{robot}/{joint}" for robot, joint in system.joint_keys)
    columns = {"q": system.dof, MEASURED_INPUT: system.measured_dof}
    functions = {}
    for name, doc, outputs, jacobians in SYSTEM_KERNELS:
        if system.measured_dof:
            outputs, jacobians = _measured_twins(outputs, jacobians)
        declared: dict[str, Any] = {k: (primitive_blades(system.kind) if d == "X_c" else d)
                                    for k, d in outputs.items()}
        declared = {k: (d, columns[jacobians[k][1]]) if k in jacobians and split_derivative(jacobians[k])[3]
                    is None else d for k, d in declared.items()}
        inputs = {"ga": "algebra", "q": scalars(system.dof, labels)}
        if system.measured_dof:
            inputs[MEASURED_INPUT] = scalars(system.measured_dof, _labels(system)[system.dof:])
        if name == "task":
            inputs["V_Sd"] = "similarity"
        if name == "similarity_rate":
            inputs[RATE_INPUT] = scalars(system.dof, labels)
        # a Jacobian taken of an output the kernel does not return (J_A of V_Sc) is still declared on it
        hidden = sorted({of for of, *_ in jacobians.values()} - set(declared))
        values = [*(k for k in declared if k not in jacobians), *hidden]
        extra = [k for k in inputs if k not in ("ga", "q")]  # (q_m first, then V_Sd or qd)
        functions[name] = KernelFunction(
            reference.function(values, extra), algebra=cga3d(), name=name, doc=doc.format(kind=system.kind),
            inputs=inputs, outputs=declared, jacobians=jacobians, rule=graph.rule(list(declared)))
    return functions


def kernel_functions(system: System) -> dict[str, KernelFunction]:
    """Every kernel of ``system`` as a front-end kernel, in catalogue order (chains first, the dual task
    space last)."""
    dual_task = dual_task_kernel_functions(system) if not system.measured_dof else {}  # (robots only)
    return {**chain_kernel_functions(system), **system_kernel_functions(system), **dual_task}


def build_kernels(system: System) -> dict[str, Kernel]:
    """Every kernel of ``system`` by name, traced (see ``kernel_functions``)."""
    return {name: f.trace() for name, f in kernel_functions(system).items()}
