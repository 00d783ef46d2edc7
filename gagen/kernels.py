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
- ``task``: (q, V_Sd) → e = log(V_Sc~ V_Sd) and J_Be = ∂e/∂q [Eq. 40-44].

No kernel is the union of the others: each output is computed by exactly one kernel, which keeps
the generated C (and its compile time) proportional to what is asked.

System Jacobians use the chain rule through the chains' end positions (see ``build_kernels``):
AD on the task-space formulas alone (3 inputs per chain, no kinematics in them), times each
chain's position Jacobian from its joint lines.

Matrices are (rows = blades, columns = joints), stored column-major as CasADi does.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import casadi as ca

from gagen.algebra.multivector import SparseMultivector
from gagen.algebra.signature import cga3d
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
from gagen.model.cooperative import System
from gagen.model.primitives import through, unit_primitive
from gagen.model.similarity import similarity_factors
from gagen.model.versors import log_similarity
from gagen.symbolic.casadi_backend import CasadiBackend
from gagen.symbolic.flatten import OpCount, casadi_op_count, identifier

TOOL_LINE = "e12"  # the tool's z axis through its origin, as a line bivector (rotation about z)


@dataclass(frozen=True)
class Port:
    """A named input or output: one label per row (blade or joint) and a column count."""

    name: str
    rows: tuple[str, ...]
    cols: int = 1

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.rows), self.cols

    @property
    def size(self) -> int:
        return len(self.rows) * self.cols


@dataclass
class Kernel:
    """One generated computation: a CasADi SX Function and the meaning of its ports."""

    name: str
    doc: str
    inputs: tuple[Port, ...]
    outputs: tuple[Port, ...]
    function: ca.Function

    @cached_property
    def op_count(self) -> OpCount:
        return casadi_op_count(self.function)


def _kernel(name: str, doc: str, inputs: Sequence[tuple[Port, ca.SX]],
            outputs: Sequence[tuple[Port, ca.SX]]) -> Kernel:
    # one CSE per kernel, over all its outputs together (they share the kinematics)
    values = ca.cse([value for _, value in outputs])
    function = ca.Function(identifier(name), [s for _, s in inputs], values,
                           [p.name for p, _ in inputs], [p.name for p, _ in outputs])
    return Kernel(identifier(name), doc, tuple(p for p, _ in inputs), tuple(p for p, _ in outputs), function)


class _Graph:
    """The system's model on CasADi symbols, built once; kernels select from it."""

    def __init__(self, system: System) -> None:
        self.system = system
        self.algebra = algebra = cga3d()
        self.backend = CasadiBackend()
        self.q = ca.SX.sym("q", system.dof)
        self.zero = SparseMultivector(algebra, self.backend, {})
        self.joint_labels = tuple(f"{robot}/{joint}" for robot, joint in system.joint_keys)

    def column(self, x: SparseMultivector, blades: Sequence[str]) -> ca.SX:
        return ca.vertcat(*[self.backend.native(x[b]) for b in blades])

    def matrix(self, columns: Sequence[SparseMultivector], blades: Sequence[str]) -> ca.SX:
        return ca.horzcat(*[self.column(c, blades) for c in columns])

    def multivector(self, values: ca.SX, blades: Sequence[str]) -> SparseMultivector:
        return SparseMultivector(self.algebra, self.backend, {
            self.algebra.blade(b): self.backend.lift(values[r]) for r, b in enumerate(blades)})


def _chain_kernels(graph: _Graph) -> tuple[list[Kernel], list[tuple[SparseMultivector, list]]]:
    kernels, points = [], []
    for chain, indices in zip(graph.system.chains, graph.system.chain_indices(), strict=True):
        qc = ca.vertcat(*[graph.q[i] for i in indices])
        qi = [graph.backend.lift(graph.q[i]) for i in indices]
        motor, lines, position = K.chain_pose(graph.zero, chain.joints, qi)
        end = point(position)  # = V_M e0 V_M~, from the position the chain carries
        point_jac = K.point_jacobian(motor, lines, end)
        # the system kernels need positions and lines only: turn the frame by cos q, sin q directly
        _, free_lines, free_position = K.chain_pose(graph.zero, chain.joints, qi, with_motor=False)
        free_end = point(free_position)
        points.append((free_end, K.point_jacobian(None, free_lines, free_end)))
        tool = graph.zero.make({TOOL_LINE: 1})
        n = len(indices)
        q_port = Port("q", tuple(graph.joint_labels[i] for i in indices))
        fk = [(Port("M", MOTOR), graph.column(motor, MOTOR)), (Port("P", POINT), graph.column(end, POINT))]
        spatial = (Port("J_S", MOTOR_GENERATOR, n), graph.matrix(K.spatial_jacobian(lines), MOTOR_GENERATOR))
        rest = [
            (Port("J_b", MOTOR_GENERATOR, n), graph.matrix(K.body_jacobian(motor, lines), MOTOR_GENERATOR)),
            (Port("J_A", MOTOR, n), graph.matrix(K.analytic_jacobian(motor, lines), MOTOR)),
            (Port("J_P", POINT, n), graph.matrix(point_jac, POINT)),
            (Port("L", MOTOR_GENERATOR), graph.column(motor.sandwich(tool), MOTOR_GENERATOR)),
            (Port("J_L", MOTOR_GENERATOR, n),
             graph.matrix(K.line_jacobian(motor, lines, tool), MOTOR_GENERATOR)),
        ]
        for suffix, doc, outputs in (
                ("fk", "motor and end point", fk),
                ("fk_jacobian", "motor, end point and spatial (geometric) Jacobian", [*fk, spatial]),
                ("jacobians", "motor, end point, every Jacobian and the tool z-axis line",
                 [*fk, spatial, *rest])):
            kernels.append(_kernel(f"{chain.name}_{suffix}", f"chain {chain.name}: {doc}", [(q_port, qc)],
                                   outputs))
    return kernels, points


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
    xc = through(system.kind, points)
    xc_blades = tuple(algebra.blade_name(b) for b in xc.support)
    factored = similarity_factors(system.kind, unit_primitive(system.kind, xc), xc)
    factors, conditioning, degenerate = factored
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


def _masked(derivative: ca.SX, degenerate: object) -> ca.SX:
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
    shared by several chains sums their contributions."""
    columns: list[ca.SX | None] = [None] * system.dof
    for i, (indices, jp) in enumerate(zip(system.chain_indices(), position_jacobians, strict=True)):
        block = ca.mtimes(by_position[:, 3 * i:3 * i + 3], jp)
        for c, j in enumerate(indices):
            columns[j] = block[:, c] if columns[j] is None else columns[j] + block[:, c]
    return ca.horzcat(*columns)


def build_kernels(system: System) -> dict[str, Kernel]:
    """Every kernel of ``system`` by name, in catalogue order (chains first).

    The system Jacobians use the chain rule through the end positions: with p = (p_1 … p_n),
    ∂y/∂q = Σ_i (∂y/∂p_i) J_p,i, where ∂y/∂p_i (3 columns) is CasADi AD on the task-space formulas
    alone (X_c from the points, the similarity construction, the logarithms) and J_p,i is chain i's
    position Jacobian from its joint lines (the e1, e2, e3 rows of [COOP Eq. 17]). For J_G,Sc the
    product −2 V_Sc~ ∂V_Sc/∂p is taken before the chain rule (7 × 3n instead of 7 × m columns).
    """
    graph = _Graph(system)
    kernels, points = _chain_kernels(graph)
    n = system.dof
    positions_q = ca.vertcat(*[graph.column(p, EUCLID) for p, _ in points])
    jps = [graph.matrix(jac, EUCLID) for _, jac in points]

    # the task space as a function of the end positions (and of V_Sd), differentiated there
    positions = ca.SX.sym("p", 3 * len(system.chains))
    vsd = ca.SX.sym("V_Sd", len(SIMILARITY))
    task = _task_space(graph, positions, vsd)
    names = ("X_c", "V_Sc", "conditioning", "log_V", "e", "dX_c", "dV_Sc", "dG", "dlog_V", "de")
    task_function = ca.Function("task_space", [positions, vsd], [task[k] for k in names])
    at_q = dict(zip(names, task_function(positions_q, vsd), strict=True))
    xc_blades = task["blades"]

    q_port, vsd_port = (Port("q", graph.joint_labels), graph.q), (Port("V_Sd", SIMILARITY), vsd)
    out = {
        "X_c": (Port("X_c", xc_blades), at_q["X_c"]),
        "J_c": (Port("J_c", xc_blades, n), _chain_rule(system, at_q["dX_c"], jps)),
        "V_Sc": (Port("V_Sc", SIMILARITY), at_q["V_Sc"]),
        "conditioning": (Port("conditioning", ("conditioning",)), at_q["conditioning"]),
        "J_A": (Port("J_A", SIMILARITY, n), _chain_rule(system, at_q["dV_Sc"], jps)),
        "J_G": (Port("J_G", SIMILARITY_GENERATOR, n), _chain_rule(system, at_q["dG"], jps)),
        "log_V": (Port("log_V", SIMILARITY_GENERATOR), at_q["log_V"]),
        "J_B": (Port("J_B", SIMILARITY_GENERATOR, n), _chain_rule(system, at_q["dlog_V"], jps)),
        "e": (Port("e", SIMILARITY_GENERATOR), at_q["e"]),
        "J_Be": (Port("J_Be", SIMILARITY_GENERATOR, n), _chain_rule(system, at_q["de"], jps)),
    }

    def pick(*names: str) -> list[tuple[Port, ca.SX]]:
        return [out[k] for k in names]

    kernels += [
        _kernel("primitive", f"the cooperative {system.kind} X_c(q) and J_c", [q_port], pick("X_c", "J_c")),
        _kernel("similarity", "V_Sc(q), its conditioning and J_G,Sc", [q_port],
                pick("V_Sc", "conditioning", "J_G")),
        _kernel("similarity_jacobians", "J_A,Sc = dV_Sc/dq, log V_Sc and J_B = d log V_Sc/dq", [q_port],
                pick("J_A", "log_V", "J_B")),
        _kernel("task", "task error e = log(V_Sc~ V_Sd) and J_Be", [q_port, vsd_port], pick("e", "J_Be")),
    ]
    return {k.name: k for k in kernels}
