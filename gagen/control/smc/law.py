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
REFINEMENTS = 1  # refinement steps of the damped solve: the damping's bias on J J⁺ goes from
# λ²/(σ² + λ²) to its square, so the damping no longer widens the boundary layer (cf. ``damped_solve``)
# Joint limits [Liégeois 1977; Faverjon & Tournassoud 1987]: a nullspace term pushes a joint out of the
# zone within LIMIT_ZONE of a limit (u0 = −LIMIT_GAIN · depth into the zone, projected by the solve), and
# the commanded velocity toward a limit is at most LIMIT_RATE × the distance to it (a velocity damper:
# Euler steps of dt < 1/LIMIT_RATE then never cross the limit; the loops clamp q to the limits as well).
LIMIT_ZONE = 0.1  # ρ, rad (m for a prismatic joint)
LIMIT_GAIN = 100.0  # k_n, 1/s: 10 rad/s of self-motion at the limit itself
LIMIT_RATE = 50.0  # γ, 1/s: at most 5 rad/s toward a limit 0.1 rad away, exact for loops over 50 Hz

Bounds = tuple[tuple[float | None, ...], tuple[float | None, ...]]
"""(lower, upper) per entry of q; None where a variable has no limit."""


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


def damped_solve(J: Sequence[Sequence[Any]], r: Sequence[Any], damping: float,
                 refinements: int = 0, shared: Callable[[Any], Any] = lambda v: v) -> list[Any]:
    """w = (J Jᵀ + λ_d² I)⁻¹ r by an unrolled LDLᵀ factorisation (no pivoting: the matrix is symmetric
    positive definite for λ_d > 0, its eigenvalues ≥ λ_d²; no square roots), on plain scalars: floats,
    the compiler's symbolic scalars or CasADi SX elements. ``J``: k rows of n (``J[i][m]``); ``r``: k.
    Only the upper triangle of J Jᵀ is formed, and each pivot divides (L_ij = C_ij / D_j, z = y / D).

    ``refinements``: that many steps w ← w + λ_d² (J Jᵀ + λ_d² I)⁻¹ w on the same factors (iterated
    Tikhonov): J Jᵀ w = r − λ_d² w, so each step multiplies the damping's residual by λ_d²/(σ² + λ_d²)
    on a direction of singular value σ: J Jᵀ w → r where σ ≫ λ_d, while Jᵀ w stays bounded (≲ 0.8/λ_d
    per unit of r after one step, 0.5/λ_d without) near a singularity. ``shared``: makes a value one
    node (``ga.math.shared`` on the compiler's path), applied to w before each step: the step reads
    every entry several times."""
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

    def substitute(b: Sequence[Any]) -> list[Any]:  # (L D Lᵀ)⁻¹ b
        y: list[Any] = [None] * k
        for i in range(k):
            y[i] = b[i] - _sum([L[i][m] * y[m] for m in range(i)]) if i else b[i]
        w: list[Any] = [None] * k
        for i in reversed(range(k)):
            z = y[i] / D[i]
            w[i] = z - _sum([L[m][i] * w[m] for m in range(i + 1, k)]) if i < k - 1 else z
        return w

    w = substitute(r)
    for _ in range(refinements):
        w = [shared(v) for v in w]  # λ_d² A⁻¹ w, not A⁻¹ (λ_d² w): one scaling per entry, after the solve
        w = [a + damping * damping * c for a, c in zip(w, substitute(w), strict=True)]
    return w


def joint_bounds(joints: Sequence[Joint]) -> Bounds:
    """(lower, upper) per entry of q (``kin.chain_variables``) from the joints' URDF limits (a mimic
    follower's variable is its leader's); None for a variable without one (a continuous joint, a leader
    outside the chain, a spec-defined joint)."""
    by_name = {j.name: j for j in joints}
    lower: list[float | None] = []
    upper: list[float | None] = []
    for name in kin.chain_variables(joints):
        joint = by_name.get(name)
        limits = joint.limits if joint is not None else None
        if limits is not None and all(math.isfinite(v) for v in limits) and limits[0] < limits[1]:
            lower.append(float(limits[0]))
            upper.append(float(limits[1]))
        else:
            lower.append(None)
            upper.append(None)
    return tuple(lower), tuple(upper)


def _clamp(v: Any, a: Any, b: Any, lt: Callable[[Any, Any], Any],
           if_else: Callable[[Any, Any, Any], Any]) -> Any:
    """v clamped to [a, b] (a ≤ b), branch-free on the symbolic paths."""
    return if_else(lt(v, a), a, if_else(lt(b, v), b, v))


def limit_avoidance(q: Sequence[Any], bounds: Bounds, lt: Callable[[Any, Any], Any],
                    if_else: Callable[[Any, Any, Any], Any], zone: float = LIMIT_ZONE,
                    gain: float = LIMIT_GAIN) -> list[Any | None]:
    """u0 = −k_n ∇H with H = ½ Σ_m depth_m², depth_m how far q_m lies inside the zone within ρ of a
    limit: zero away from the limits (no self-motion there, so no effect on the tracking), continuous,
    and finite at and beyond a limit. None for an unlimited variable."""
    u0: list[Any | None] = []
    for qm, lo, hi in zip(q, *bounds, strict=True):
        if lo is None or hi is None:
            u0.append(None)
            continue
        a, b = lo + zone, hi - zone
        u0.append(if_else(lt(qm, a), gain * (a - qm), if_else(lt(b, qm), gain * (b - qm), 0.0)))
    return u0


def limited_law(x: Sequence[Any], J: Sequence[Sequence[Any]], q: Sequence[Any], x_ref: Sequence[Any],
                gains: Sequence[float], epsilon: float, damping: float, bounds: Bounds,
                tanh: Callable[[Any], Any], lt: Callable[[Any, Any], Any],
                if_else: Callable[[Any, Any, Any], Any],
                shared: Callable[[Any], Any] = lambda v: v) -> list[Any]:
    """u on plain scalars (``J``: n columns of k): r = K tanh(ε (x − x_ref)) [Eq. 40], the limit
    avoidance u0 (``limit_avoidance``), w = (J Jᵀ + λ_d² I)⁻¹ (r + J u0) refined ``REFINEMENTS`` times,
    v = u0 − Jᵀ w (= −J⁺ r + (I − J⁺ J) u0: u0 in the task's nullspace [Liégeois 1977]), and each
    limited v_m clamped to [γ (lo_m − q_m), γ (hi_m − q_m)] (γ = ``LIMIT_RATE``). ``tanh``, ``lt``,
    ``if_else`` and ``shared``: the path's (``ga.math``'s, or CasADi's and the identity)."""
    k = len(x)
    r = [g * tanh(epsilon * (xi - ri)) for g, xi, ri in zip(gains, x, x_ref, strict=True)]
    u0 = limit_avoidance(q, bounds, lt, if_else)
    moved = [m for m, v in enumerate(u0) if v is not None]
    if moved:  # r + J u0
        r = [r[i] + _sum([J[m][i] * u0[m] for m in moved]) for i in range(k)]
    w = damped_solve([[column[i] for column in J] for i in range(k)], r, damping, REFINEMENTS, shared)
    u = [-_sum([column[i] * w[i] for i in range(k)]) for column in J]
    for m in moved:
        lo, hi = bounds[0][m], bounds[1][m]
        assert lo is not None and hi is not None
        u[m] = _clamp(u0[m] + u[m], LIMIT_RATE * (lo - q[m]), LIMIT_RATE * (hi - q[m]), lt, if_else)
    return u


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
    pose and Jacobian (``pose_and_jacobian_of``) and u = ``limited_law`` (the sliding-mode law [Eq. 35,
    40] with the joint limits of ``joints``). It runs on the reference interpreter (floats) and on the
    compiler's path (symbolic scalars) alike."""
    joints = tuple(joints)
    bounds = joint_bounds(joints)

    def step(ga: Any, q: Sequence[Any], x_ref: Sequence[Any]) -> dict[str, Any]:
        x, J = pose_and_jacobian_of(ga, joints, q)
        # each pose and Jacobian entry is one value, reused by the solve (on the compiler's path, one
        # node each, as the outputs have them: cheaper than expanding their sums into every product)
        shared = ga.math.shared
        x = [shared(v) for v in x]
        J = [[shared(v) for v in column] for column in J]
        u = limited_law(x, J, q, x_ref, gains, epsilon, damping, bounds, ga.math.tanh, ga.math.lt,
                        ga.math.if_else, shared)
        return {"x": x, "J": J, "u": u}

    return step


def check_finite(name: str, value: Any, unit: str, *, positive: bool) -> None:
    """ValueError unless value is a finite real number > 0 (``positive``) or >= 0."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value < 0 or (positive and value == 0):
        raise ValueError(f"{name} must be a finite number of {unit} {'>' if positive else '>='} 0, "
                         f"got {value!r}")
