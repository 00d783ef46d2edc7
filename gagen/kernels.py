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
- ``similarity``: q → V_Sc, its conditioning, J_A,Sc and J_G,Sc = −2 V_Sc~ J_A,Sc [Eq. 28-30];
- ``task``: (q, V_Sd) → e = log(V_Sc~ V_Sd) and J_Be = ∂e/∂q [Eq. 40-44];
- ``system``: (q, V_Sd) → all of the above plus log V_Sc and J_B.

Jacobians of the similarity part use the chain rule through the similarity construction: with x
the coefficients of X_c, ∂V_Sc/∂q = (∂V_S(X_u, x)/∂x) J_c, where ∂/∂x is CasADi AD on the similarity
alone (ten inputs, no kinematics in it) and J_c comes from the point Jacobians.

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
from gagen.model.conformal import MOTOR, MOTOR_GENERATOR, POINT, SIMILARITY, SIMILARITY_GENERATOR
from gagen.model.cooperative import System, primitive_jacobian
from gagen.model.primitives import through
from gagen.model.similarity import cooperative_similarity
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
        motor, lines = K.chain_kinematics(graph.zero, chain.joints, [graph.backend.lift(graph.q[i])
                                                                    for i in indices])
        point, point_jac = K.end_point(motor), K.point_jacobian(motor, lines)
        points.append((point, point_jac))
        tool = graph.zero.make({TOOL_LINE: 1})
        n = len(indices)
        q_port = Port("q", tuple(graph.joint_labels[i] for i in indices))
        fk = [(Port("M", MOTOR), graph.column(motor, MOTOR)), (Port("P", POINT), graph.column(point, POINT))]
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


def build_kernels(system: System) -> dict[str, Kernel]:
    """Every kernel of ``system`` by name, in catalogue order (chains first)."""
    graph = _Graph(system)
    kernels, points = _chain_kernels(graph)
    algebra, backend, n = graph.algebra, graph.backend, system.dof

    xc = through(system.kind, [p for p, _ in points])
    xc_blades = tuple(algebra.blade_name(b) for b in xc.support)
    x_q, jc = graph.column(xc, xc_blades), graph.matrix(primitive_jacobian(system, points), xc_blades)

    # the similarity part as a function of the primitive's coefficients x (and of V_Sd)
    x = ca.SX.sym("x", len(xc_blades))
    vsd = ca.SX.sym("V_Sd", len(SIMILARITY))
    v, conditioning = cooperative_similarity(system.kind, graph.multivector(x, xc_blades))
    v_col = graph.column(v, SIMILARITY)
    log_v = graph.column(log_similarity(v), SIMILARITY_GENERATOR)
    error = graph.column(log_similarity(~v * graph.multivector(vsd, SIMILARITY)), SIMILARITY_GENERATOR)
    similarity_part = ca.Function("similarity_part", [x, vsd], [
        v_col, backend.native(backend.lift(conditioning)), log_v, error,
        ca.jacobian(v_col, x), ca.jacobian(log_v, x), ca.jacobian(error, x)])
    v_q, cond_q, log_q, error_q, dv_dx, dlog_dx, derror_dx = similarity_part(x_q, vsd)
    j_a = ca.mtimes(dv_dx, jc)
    reverse = ~graph.multivector(v_q, SIMILARITY)  # J_G = −2 V~ J_A, column by column
    j_g = graph.matrix([(reverse * graph.multivector(j_a[:, i], SIMILARITY)) * -2 for i in range(n)],
                       SIMILARITY_GENERATOR)

    q_port, vsd_port = (Port("q", graph.joint_labels), graph.q), (Port("V_Sd", SIMILARITY), vsd)
    out = {
        "X_c": (Port("X_c", xc_blades), x_q),
        "J_c": (Port("J_c", xc_blades, n), jc),
        "V_Sc": (Port("V_Sc", SIMILARITY), v_q),
        "conditioning": (Port("conditioning", ("conditioning",)), cond_q),
        "J_A": (Port("J_A", SIMILARITY, n), j_a),
        "J_G": (Port("J_G", SIMILARITY_GENERATOR, n), j_g),
        "log_V": (Port("log_V", SIMILARITY_GENERATOR), log_q),
        "J_B": (Port("J_B", SIMILARITY_GENERATOR, n), ca.mtimes(dlog_dx, jc)),
        "e": (Port("e", SIMILARITY_GENERATOR), error_q),
        "J_Be": (Port("J_Be", SIMILARITY_GENERATOR, n), ca.mtimes(derror_dx, jc)),
    }

    def pick(*names: str) -> list[tuple[Port, ca.SX]]:
        return [out[k] for k in names]

    kernels += [
        _kernel("primitive", f"the cooperative {system.kind} X_c(q) and J_c", [q_port], pick("X_c", "J_c")),
        _kernel("similarity", "V_Sc(q), its conditioning, J_A,Sc and J_G,Sc", [q_port],
                pick("V_Sc", "conditioning", "J_A", "J_G")),
        _kernel("task", "task error e = log(V_Sc~ V_Sd) and J_Be", [q_port, vsd_port], pick("e", "J_Be")),
        _kernel("system", "every system output", [q_port, vsd_port], list(out.values())),
    ]
    return {k.name: k for k in kernels}
