"""Similarity task-space dynamics [COOP Eq. 33-38; MATH.md §7].

With V_S = J_G q̇ (the similarity twist, ``similarity_rate``) and V̇_S = J_G q̈ + J̇_G q̇ (Eq. 34 with
its last factor read as q̇), the joint-space dynamics M q̈ + C q̇ + g = τ become, for τ = J_Gᵀ W,

    M_Sc V̇_S + C_Sc + g_Sc = W,   M_Sc = (J_G M⁻¹ J_Gᵀ)⁻¹,
    C_Sc = M_Sc (J_G M⁻¹ C q̇ − J̇_G q̇),   g_Sc = M_Sc J_G M⁻¹ g.

**Which inverse.** J_G has 7 rows but only as many independent ones as the primitive has controllable
bivectors (Table 1: 6 for a circle, 3 for a plane, …), and those are not fixed rows: A = J_G M⁻¹ J_Gᵀ
is singular by construction. M_Sc is therefore the pseudo-inverse of A on its range: A = U diag(a) Uᵀ
(a symmetric eigendecomposition), M_Sc = Σ_{k ≤ r} u_k u_kᵀ / a_k over the ``rank`` = r largest
eigenvalues (r = the primitive's controllable dimension by default), which is the exact inverse on
the twists the system can produce and zero on the others. Where the configuration itself loses rank
(a_r ≤ ``RCOND`` a_1) that direction is dropped too and ``TaskSpace.rank`` says so; a ``damping``
λ > 0 replaces 1/a by a/(a² + λ²) instead.

J̄ = M⁻¹ J_Gᵀ M_Sc is the dynamically consistent (inertia-weighted) inverse of J_G: q̇ = J̄ V_S is the
joint velocity of least kinetic energy with J_G q̇ = V_S, and its kinetic energy is ½ V_Sᵀ M_Sc V_S.
N = I − J̄ J_G projects joint motions that leave the similarity at rest; Nᵀ torques do not accelerate
it (J_G M⁻¹ Nᵀ = 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

RCOND = 1e-10
"""Eigenvalues of J_G M⁻¹ J_Gᵀ at or below RCOND · (the largest) count as zero."""


@dataclass(frozen=True)
class TaskSpace:
    """The similarity task-space quantities at one (q, q̇)."""

    inertia: NDArray[np.float64]  # M_Sc (7 × 7, symmetric PSD, rank ``rank``)
    coriolis: NDArray[np.float64]  # C_Sc (7)
    gravity: NDArray[np.float64]  # g_Sc (7)
    consistent_inverse: NDArray[np.float64]  # J̄ = M⁻¹ J_Gᵀ M_Sc (m × 7)
    rank: int  # the directions kept

    def nullspace_torque(self, J_G: ArrayLike, tau: ArrayLike) -> NDArray[np.float64]:
        """Nᵀ τ = τ − J_Gᵀ J̄ᵀ τ: the part of τ that does not accelerate the similarity."""
        torque = np.asarray(tau, dtype=np.float64)
        return torque - np.asarray(J_G, dtype=np.float64).T @ (self.consistent_inverse.T @ torque)


def task_space(J_G: ArrayLike, Jdot_qdot: ArrayLike, M: ArrayLike, bias: ArrayLike, gravity: ArrayLike,
               rank: int, damping: float = 0.0, rcond: float = RCOND) -> TaskSpace:
    """M_Sc, C_Sc and g_Sc (Eq. 36-38) from the generated J_G and J̇_G q̇ and the joint-space M, the bias
    C q̇ + g and g (see the module docstring for the inverse)."""
    J = np.asarray(J_G, dtype=float)
    rows, joints = J.shape
    if damping < 0:
        raise ValueError(f"damping must be >= 0, got {damping}")
    if not 0 < rank <= rows:
        raise ValueError(f"rank must be between 1 and {rows}, got {rank}")
    g = np.asarray(gravity, dtype=float)
    rhs = np.empty((joints, rows + 2))  # one solve with M for M⁻¹ J_Gᵀ, M⁻¹ C q̇ and M⁻¹ g
    rhs[:, :rows] = J.T
    np.subtract(bias, g, out=rhs[:, rows])
    rhs[:, rows + 1] = g
    solved = np.linalg.solve(np.asarray(M, dtype=float), rhs)
    projected = J @ solved  # [A | J M⁻¹ C q̇ | J M⁻¹ g]
    a, u = np.linalg.eigh(projected[:, :rows])  # ascending: the kept directions are the last ``rank``
    a, u = a[rows - rank:], u[:, rows - rank:]
    keep = a > rcond * max(a[-1], 0.0)
    safe = np.where(keep, a, 1.0)
    inverse = np.where(keep, safe / (safe * safe + damping * damping) if damping > 0 else 1.0 / safe, 0.0)
    inertia = (u * inverse) @ u.T
    forces = inertia @ (projected[:, rows:] - np.column_stack([Jdot_qdot, np.zeros(rows)]))
    return TaskSpace(inertia=inertia, coriolis=forces[:, 0], gravity=forces[:, 1],
                     consistent_inverse=solved[:, :rows] @ inertia, rank=int(keep.sum()))
