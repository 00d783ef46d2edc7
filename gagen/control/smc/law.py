"""The sliding-mode step law [SMC Eq. 17-20, 32-40, 43]: the reference, the pose and its Jacobian on either
path (the multivector protocol or CasADi SX), the damped least-squares solve and the law itself."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, cast

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from gagen.algebra.multivector import SparseMultivector
from gagen.algebra.signature import cga3d
from gagen.model import kinematics as kin
from gagen.model.conformal import EUCLID, point
from gagen.model.kinematics import TOOL_LINE, Joint
from gagen.symbolic.casadi_backend import CasadiBackend

POSE = ("px", "py", "pz", "dx", "dy", "dz")
"""The pose coordinates: end point position, then the tool line's direction."""
GAIN = 7.5  # [SMC VI]: K = diag{7.5, …, 7.5}
EPSILON = 50.0  # tanh slope (Eq. 40); the paper does not state it
DAMPING = 1e-2  # λ_d of J⁺ = Jᵀ(J Jᵀ + λ_d² I)⁻¹


# -- the reference trajectory [SMC Eq. 43] -----------------------------------------------------------
def reference(t: float) -> NDArray[np.float64]:
    """x_ref(t) = [−0.3 + 0.1 cos 2t, 0.15, 0.25, 0, 1, 0] [SMC Eq. 43] (the C runner's ``reference``,
    with the same operations: math.cos is the C library's cos)."""
    return np.array([-0.3 + 0.1 * math.cos(2.0 * t), 0.15, 0.25, 0.0, 1.0, 0.0])


def reference_rate(t: float) -> NDArray[np.float64]:
    """ẋ_ref(t) = [−0.2 sin 2t, 0, 0, 0, 0, 0] [SMC Eq. 43]."""
    return np.array([-0.2 * math.sin(2.0 * t), 0.0, 0.0, 0.0, 0.0, 0.0])


# -- the step, on both paths -------------------------------------------------------------------------
def _direction(line: Any) -> list[Any]:
    """Direction n of a line bivector n3 e12 − n2 e13 + n1 e23 + moment."""
    return [line["e23"], -line["e13"], line["e12"]]


def pose_and_jacobian_of(ga: Any, joints: Sequence[Joint],
                         q: Sequence[Any]) -> tuple[list[Any], list[list[Any]]]:
    """(x, J) on any path (``ga``: the zero multivector of the interpreter's or the compiler's path):
    the pose [x_p; d] (6 scalars) and its Jacobian as n columns of 6 scalars, from the joint lines
    [SMC Eq. 17-20]."""
    motor, lines, position = kin.chain_pose(ga, joints, q)
    point_columns = kin.point_jacobian(motor, lines, point(position))  # P × L'_j  (Eq. 18)
    tool = ga.make({TOOL_LINE: 1})
    line_columns = kin.line_jacobian(motor, lines, tool)  # α_j = ½(L'_p L'_j − L'_j L'_p)  (Eq. 20)
    x = [position[b] for b in EUCLID] + _direction(motor.sandwich(tool))
    J = [[p[b] for b in EUCLID] + _direction(a) for p, a in zip(point_columns, line_columns, strict=True)]
    return x, J


def pose_and_jacobian(joints: Sequence[Joint], q: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(x, J) on CasADi symbols: the pose (6) and its Jacobian (6 × n), as gagen built them before the
    front-end kernel (each coefficient made one SX node, the signs taken in SX): the baseline of
    ``sx_step_function``."""
    backend = CasadiBackend()
    zero = SparseMultivector(cga3d(), backend, {})
    motor, lines, position = kin.chain_pose(zero, joints, [backend.lift(q[i]) for i in range(q.numel())])
    point_columns = kin.point_jacobian(motor, lines, point(position))
    tool = zero.make({TOOL_LINE: 1})
    line_columns = kin.line_jacobian(motor, lines, tool)
    native = backend.native

    def direction(line: Any) -> list[ca.SX]:
        return [native(line["e23"]), -native(line["e13"]), native(line["e12"])]

    x = ca.vertcat(*[native(position[b]) for b in EUCLID], *direction(motor.sandwich(tool)))
    J = ca.horzcat(*[ca.vertcat(*[native(p[b]) for b in EUCLID], *direction(a))
                     for p, a in zip(point_columns, line_columns, strict=True)])
    return x, J


def _sum(terms: Sequence[Any]) -> Any:
    total = terms[0]
    for t in terms[1:]:
        total = total + t
    return total


def damped_solve(J: Sequence[Sequence[Any]], r: Sequence[Any], damping: float) -> list[Any]:
    """w = (J Jᵀ + λ_d² I)⁻¹ r by an unrolled LDLᵀ factorisation (no pivoting: the matrix is symmetric
    positive definite for λ_d > 0, its eigenvalues ≥ λ_d²; no square roots), on plain scalars: floats,
    the compiler's symbolic scalars or CasADi SX elements. ``J``: k rows of n (``J[i][m]``); ``r``: k.
    Only the upper triangle of J Jᵀ is formed, and each pivot divides (L_ij = C_ij / D_j, z = y / D)."""
    if not damping > 0:
        raise ValueError(f"damping must be > 0 (J Jᵀ of a pose with a unit direction is singular), "
                         f"got {damping}")
    k, n = len(J), len(J[0])
    A: list[list[Any]] = [[None] * k for _ in range(k)]
    for i in range(k):
        for j in range(i, k):
            A[i][j] = _sum([J[i][m] * J[j][m] for m in range(n)])
        A[i][i] = A[i][i] + damping * damping
    L: list[list[Any]] = [[None] * k for _ in range(k)]
    C: list[list[Any]] = [[None] * k for _ in range(k)]  # C_ij = L_ij D_j
    D: list[Any] = [None] * k
    for j in range(k):
        D[j] = A[j][j] - _sum([C[j][m] * L[j][m] for m in range(j)]) if j else A[j][j]
        for i in range(j + 1, k):
            C[i][j] = A[j][i] - _sum([C[i][m] * L[j][m] for m in range(j)]) if j else A[j][i]
            L[i][j] = C[i][j] / D[j]
    y: list[Any] = [None] * k
    for i in range(k):
        y[i] = r[i] - _sum([L[i][m] * y[m] for m in range(i)]) if i else r[i]
    w: list[Any] = [None] * k
    for i in reversed(range(k)):
        z = y[i] / D[i]
        w[i] = z - _sum([L[m][i] * w[m] for m in range(i + 1, k)]) if i < k - 1 else z
    return w


def _gains(K: float | Sequence[float], k: int) -> list[float]:
    # (np.isscalar narrows only its True branch, to numbers and strings; a float is a scalar)
    gains = [float(cast(float, K))] * k if np.isscalar(K) else [float(g) for g in cast("Sequence[float]", K)]
    if len(gains) != k or not all(g > 0 for g in gains):
        raise ValueError(f"K must be a positive scalar or {k} positive task-space gains, got {K}")
    return gains


def _checked(K: float | Sequence[float], epsilon: float, damping: float) -> list[float]:
    if not (math.isfinite(float(epsilon)) and epsilon > 0):
        raise ValueError(f"epsilon must be > 0, got {epsilon}")
    if not (math.isfinite(float(damping)) and damping > 0):
        raise ValueError(f"damping must be > 0 (J Jᵀ of a pose with a unit direction is singular), "
                         f"got {damping}")
    return _gains(K, len(POSE))


def step_law(joints: Sequence[Joint], gains: Sequence[float], epsilon: float,
             damping: float) -> Callable[[Any, Sequence[Any], Sequence[Any]], dict[str, Any]]:
    """The step as one function over the multivector protocol, ``step(ga, q, x_ref) -> {x, J, u}``: the
    pose and Jacobian (``pose_and_jacobian_of``), r = K tanh(ε (x − x_ref)) [Eq. 40] and
    u = −Jᵀ (J Jᵀ + λ_d² I)⁻¹ r [Eq. 35]. It runs on the reference interpreter (floats) and on the
    compiler's path (symbolic scalars) alike."""
    joints = tuple(joints)

    def step(ga: Any, q: Sequence[Any], x_ref: Sequence[Any]) -> dict[str, Any]:
        x, J = pose_and_jacobian_of(ga, joints, q)
        # each pose and Jacobian entry is one value, reused by the solve (on the compiler's path, one
        # node each, as the outputs have them: cheaper than expanding their sums into every product)
        shared = ga.math.shared
        x = [shared(v) for v in x]
        J = [[shared(v) for v in column] for column in J]
        r = [g * ga.math.tanh(epsilon * (xi - ri)) for g, xi, ri in zip(gains, x, x_ref, strict=True)]
        w = damped_solve([[column[i] for column in J] for i in range(len(POSE))], r, damping)
        u = [-_sum([column[i] * w[i] for i in range(len(POSE))]) for column in J]
        return {"x": x, "J": J, "u": u}

    return step


def check_finite(name: str, value: Any, unit: str, *, positive: bool) -> None:
    """ValueError unless value is a finite real number > 0 (``positive``) or >= 0."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value < 0 or (positive and value == 0):
        raise ValueError(f"{name} must be a finite number of {unit} {'>' if positive else '>='} 0, "
                         f"got {value!r}")
