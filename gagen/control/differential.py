"""Differential kinematics, nullspace projection and manipulability [COOP Eq. 48, 58, 59].

All three are built on the singular value decomposition J = U diag(s) Vᵀ of a Jacobian (rows = the
coefficients of a bivector or multivector, columns = joints). The cooperative Jacobians are rank
deficient by construction: the geometric similarity Jacobian J_G,Sc has 7 rows but only as many
independent ones as the primitive has controllable bivectors (Table 1: 3 for a point, 6 for a
circle, …), and J_c of a circle has 10 rows but rank 7. So every inverse here is a (damped)
pseudo-inverse, never (J Jᵀ)⁻¹ itself: singular values at or below ``rcond`` · s_max are treated as
exact zeros, and a damping λ > 0 replaces 1/s by the Tikhonov filter s / (s² + λ²).

Norms are those of the coefficient vectors (the Euclidean metric on the blade coordinates), as in
the paper's pseudo-inverse.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

RCOND = 1e-12
"""Singular values at or below RCOND · (largest singular value) count as zero."""

CONTROLLABLE_DIMENSION: dict[str, int] = {
    "point": 3, "point_pair": 6, "line": 4, "circle": 6, "plane": 3, "sphere": 4,
}
"""Controllable similarity bivectors per primitive [COOP Table 1]: the rank of J_G,Sc away from
singular configurations, and the default rank of ``manipulability_index`` for that primitive."""


def _svd(J: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    matrix = np.asarray(J, dtype=float)
    if matrix.ndim != 2:
        raise ValueError(f"a Jacobian is a matrix (rows, joints), got shape {matrix.shape}")
    return np.linalg.svd(matrix, full_matrices=False)


def _kept(s: NDArray[np.float64], rcond: float) -> NDArray[np.bool_]:
    """Mask of the singular values above rcond · s_max (all False for a zero matrix)."""
    return s > rcond * s[0] if s.size and s[0] > 0 else np.zeros(s.shape, dtype=bool)


def damped_pseudo_inverse(J: ArrayLike, damping: float = 0.0, rcond: float = RCOND) -> NDArray[np.float64]:
    """The damped pseudo-inverse J⁺_λ = Jᵀ (J Jᵀ + λ² I)⁻¹ = V diag(s / (s² + λ²)) Uᵀ (m × k for a k × m J).

    With ``damping`` λ = 0 this is the Moore-Penrose pseudo-inverse (numpy.linalg.pinv with the
    same ``rcond``). With λ > 0 it is the damped-least-squares (Levenberg) inverse: J⁺_λ b minimises
    ‖J x − b‖² + λ² ‖x‖², which stays bounded near singular configurations. It is evaluated through
    the SVD rather than by solving with J Jᵀ + λ² I, which is singular for λ = 0 and as badly
    conditioned as (s_max / λ)² otherwise.
    """
    if damping < 0:
        raise ValueError(f"damping must be >= 0, got {damping}")
    u, s, vt = _svd(J)
    keep = _kept(s, rcond)
    filtered = np.zeros_like(s)
    filtered[keep] = s[keep] / (s[keep] ** 2 + damping**2)
    return (vt.T * filtered) @ u.T


def joint_velocity(J_G: ArrayLike, B: ArrayLike, damping: float = 1e-6,
                   rcond: float = RCOND) -> NDArray[np.float64]:
    """Differential kinematics q̇ = J_G,Sc⁺ B [COOP Eq. 48] with the damped pseudo-inverse.

    ``J_G`` is the geometric similarity Jacobian (7 × m, rows e12 e13 e23 e0∞ e1∞ e2∞ e3∞ as the
    ``similarity`` kernel returns it) and ``B`` the similarity twist (7 coefficients in the same order,
    or a 7 × k array of k twists). q̇ = J_Gᵀ (J_G J_Gᵀ + λ² I)⁻¹ B is the joint velocity of least norm
    (damped by λ = ``damping``) whose similarity twist is closest to B: for an achievable B
    (B = J_G v) it reproduces B up to a relative O(λ² / s_min²), and the part of B along bivectors the
    primitive cannot control (Table 1) is ignored.
    """
    return damped_pseudo_inverse(J_G, damping, rcond) @ np.asarray(B, dtype=np.float64)


def nullspace_projector(J: ArrayLike, damping: float = 0.0, rcond: float = RCOND) -> NDArray[np.float64]:
    """The nullspace projector N = I − J⁺ J [COOP Eq. 58] (m × m).

    For ``damping`` = 0, N = I − V_r V_rᵀ with V_r the right singular vectors of the r singular values
    above ``rcond`` · s_max: the orthogonal (symmetric, idempotent) projector onto ker J, so J N = 0
    and a joint velocity N v leaves the task of J unchanged to first order. The paper takes
    J = J_G,Sc (the primitive's similarity, Section 4.3); passing J_c of the ``primitive`` kernel
    instead keeps the coefficients of X_c themselves (scale included) fixed. With damping λ > 0 it is
    I − J⁺_λ J = I − V diag(s² / (s² + λ²)) Vᵀ, still symmetric but only approximately a projector.
    """
    if damping < 0:
        raise ValueError(f"damping must be >= 0, got {damping}")
    _, s, vt = _svd(J)
    keep = _kept(s, rcond)
    weights = np.zeros_like(s)
    weights[keep] = s[keep] ** 2 / (s[keep] ** 2 + damping**2)
    m = vt.shape[1]
    return np.eye(m) - (vt.T * weights) @ vt


def manipulability(J_G: ArrayLike) -> NDArray[np.float64]:
    """The similarity manipulability ellipsoid M_S = J_G,Sc J_G,Scᵀ [COOP Eq. 59] (7 × 7, symmetric PSD).

    Its eigenvectors are the principal axes of the set of similarity twists reached by unit joint
    velocities, the square roots of its eigenvalues their lengths. The e0∞ direction is the dilation:
    how fast the primitive can grow or shrink (the radius of a circle or sphere).
    """
    matrix = np.asarray(J_G, dtype=np.float64)
    return matrix @ matrix.T


def manipulability_index(J_G: ArrayLike, rank: int | None = None, rcond: float = RCOND) -> float:
    """A scalar manipulability: the product of the ``rank`` largest singular values of J_G,Sc.

    This is √(pdet M_S), Yoshikawa's √det(J Jᵀ) restricted to the controllable directions: det M_S
    itself is always 0, since J_G has only as many independent rows as the primitive has
    controllable bivectors, and those are not fixed rows of J_G (Table 1 states them w.r.t. V_Sc).
    Pass ``rank = CONTROLLABLE_DIMENSION[primitive]`` to get a measure that falls continuously to 0
    at a singular configuration; by default the numerical rank (singular values above ``rcond`` ·
    s_max) is used, which jumps instead.
    """
    _, s, _ = _svd(J_G)
    if rank is None:
        rank = int(np.count_nonzero(_kept(s, rcond)))
    if not 0 <= rank <= s.size:
        raise ValueError(f"rank must be between 0 and {s.size}, got {rank}")
    return float(np.prod(s[:rank]))
