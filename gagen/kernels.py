"""CasADi kernels of a cooperative system: X_c, J_c, V_Sc, J_A,Sc, J_G,Sc, J_B, e(q) and J_Be.

The model (``gagen.model.cooperative``) runs once on symbolic multivectors; the Jacobians that are
derivatives of the flat expression are taken with CasADi's AD on that graph (MATH.md §6 allows it;
the closed forms of Appendix B remain a cross-check for later), the geometric one by the product
−2 V_Sc~ J_A,Sc [COOP Eq. 30] on the symbolic columns.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from gagen.algebra.multivector import SparseMultivector
from gagen.algebra.signature import cga3d
from gagen.model.conformal import SIMILARITY, SIMILARITY_GENERATOR
from gagen.model.cooperative import System, cooperative_jacobian, cooperative_primitive, similarity_of
from gagen.model.versors import log_similarity
from gagen.symbolic.casadi_backend import CasadiBackend
from gagen.symbolic.flatten import identifier


@dataclass
class SystemKernels:
    """One CasADi Function with every output; ``blades`` gives the row order of each output."""

    function: ca.Function
    blades: dict[str, tuple[str, ...]]


def build_system_kernels(system: System) -> SystemKernels:
    algebra, backend = cga3d(), CasadiBackend()
    q = ca.SX.sym("q", system.dof)
    qs = [backend.lift(q[i]) for i in range(system.dof)]
    zero = SparseMultivector(algebra, backend, {})
    desired = SparseMultivector.symbolic(algebra, backend, "vsd", SIMILARITY)

    def column(x: SparseMultivector, blades) -> ca.SX:
        return ca.vertcat(*[backend.native(x[b]) for b in blades])

    xc = cooperative_primitive(zero, system, qs)
    xc_blades = tuple(algebra.blade_name(b) for b in xc.support)
    jc = ca.horzcat(*[column(c, xc_blades) for c in cooperative_jacobian(zero, system, qs)])
    v, conditioning = similarity_of(zero, system, qs)
    v_col = column(v, SIMILARITY)
    j_a = ca.jacobian(v_col, q)
    reverse = ~v
    j_g = ca.horzcat(*[
        column((reverse * SparseMultivector(algebra, backend, {
            algebra.blade(b): backend.lift(j_a[r, i]) for r, b in enumerate(SIMILARITY)})) * -2,
            SIMILARITY_GENERATOR)
        for i in range(system.dof)])
    log_v = column(log_similarity(v), SIMILARITY_GENERATOR)
    error = column(log_similarity(reverse * desired), SIMILARITY_GENERATOR)
    outputs = {"X_c": column(xc, xc_blades), "J_c": jc, "V_Sc": v_col,
               "conditioning": backend.native(backend.lift(conditioning)), "J_A": j_a, "J_G": j_g,
               "log_V": log_v, "J_B": ca.jacobian(log_v, q), "e": error, "J_Be": ca.jacobian(error, q)}
    vsd = ca.vertcat(*[backend.native(desired[b]) for b in SIMILARITY])
    shared = ca.cse(list(outputs.values()))  # on all outputs together: they share the whole FK
    f = ca.Function(identifier(system.name), [q, vsd], shared, ["q", "V_Sd"], list(outputs))
    blades = {"X_c": xc_blades, "V_Sc": SIMILARITY, "log_V": SIMILARITY_GENERATOR, "e": SIMILARITY_GENERATOR,
              "J_G": SIMILARITY_GENERATOR}
    return SystemKernels(f, blades)
