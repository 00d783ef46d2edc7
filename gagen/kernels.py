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
from gagen.model.cooperative import System, cooperative_jacobian, cooperative_primitive
from gagen.model.similarity import cooperative_similarity
from gagen.model.versors import log_similarity
from gagen.symbolic.casadi_backend import CasadiBackend
from gagen.symbolic.flatten import identifier


@dataclass
class SystemKernels:
    """One CasADi Function with every output; ``blades`` gives the row order of each output."""

    function: ca.Function
    blades: dict[str, tuple[str, ...]]


def build_system_kernels(system: System) -> SystemKernels:
    """All kernels of a system as one CasADi Function (inputs q and V_Sd).

    Jacobians by the chain rule through the similarity construction: with x the coefficients of
    X_c, ∂V_Sc/∂q = (∂V_S(X_u, x)/∂x) J_c, where J_c comes from the point Jacobians [Eq. 15-17] and
    ∂/∂x is CasADi AD on the similarity alone (a few inputs, no kinematics in it).
    """
    algebra, backend = cga3d(), CasadiBackend()
    q = ca.SX.sym("q", system.dof)
    qs = [backend.lift(q[i]) for i in range(system.dof)]
    zero = SparseMultivector(algebra, backend, {})

    def column(x: SparseMultivector, blades) -> ca.SX:
        return ca.vertcat(*[backend.native(x[b]) for b in blades])

    xc = cooperative_primitive(zero, system, qs)
    xc_blades = tuple(algebra.blade_name(b) for b in xc.support)
    jc = ca.horzcat(*[column(c, xc_blades) for c in cooperative_jacobian(zero, system, qs)])

    # the similarity part as a function of the primitive's coefficients x (and of V_Sd)
    x = ca.SX.sym("x", len(xc_blades))
    vsd = ca.SX.sym("vsd", len(SIMILARITY))
    x_mv = SparseMultivector(algebra, backend, {algebra.blade(b): backend.lift(x[i])
                                                for i, b in enumerate(xc_blades)})
    desired = SparseMultivector(algebra, backend, {algebra.blade(b): backend.lift(vsd[i])
                                                   for i, b in enumerate(SIMILARITY)})
    v, conditioning = cooperative_similarity(system.kind, x_mv)
    v_col = column(v, SIMILARITY)
    log_v = column(log_similarity(v), SIMILARITY_GENERATOR)
    error = column(log_similarity(~v * desired), SIMILARITY_GENERATOR)
    similarity_part = ca.Function("similarity_part", [x, vsd], [
        v_col, backend.native(backend.lift(conditioning)), log_v, error,
        ca.jacobian(v_col, x), ca.jacobian(log_v, x), ca.jacobian(error, x)])
    v_q, cond_q, log_q, error_q, dv_dx, dlog_dx, derror_dx = similarity_part(column(xc, xc_blades), vsd)
    j_a = ca.mtimes(dv_dx, jc)

    # J_G = −2 V~ J_A, column by column on the symbolic multivectors
    v_at_q = SparseMultivector(algebra, backend, {algebra.blade(b): backend.lift(v_q[r])
                                                  for r, b in enumerate(SIMILARITY)})
    reverse = ~v_at_q
    j_g = ca.horzcat(*[
        column((reverse * SparseMultivector(algebra, backend, {
            algebra.blade(b): backend.lift(j_a[r, i]) for r, b in enumerate(SIMILARITY)})) * -2,
            SIMILARITY_GENERATOR)
        for i in range(system.dof)])
    outputs = {"X_c": column(xc, xc_blades), "J_c": jc, "V_Sc": v_q, "conditioning": cond_q, "J_A": j_a,
               "J_G": j_g, "log_V": log_q, "J_B": ca.mtimes(dlog_dx, jc), "e": error_q,
               "J_Be": ca.mtimes(derror_dx, jc)}
    shared = ca.cse(list(outputs.values()))  # on all outputs together: they share the whole FK
    f = ca.Function(identifier(system.name), [q, vsd], shared, ["q", "V_Sd"], list(outputs))
    blades = {"X_c": xc_blades, "V_Sc": SIMILARITY, "log_V": SIMILARITY_GENERATOR, "e": SIMILARITY_GENERATOR,
              "J_G": SIMILARITY_GENERATOR}
    return SystemKernels(f, blades)
