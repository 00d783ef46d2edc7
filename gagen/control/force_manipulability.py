"""Velocity and force manipulability of the cooperative similarity, and its nullspace optimisation
[COOP Section 3.11, Eq. 59].

J_G = J_G,Sc is the geometric similarity Jacobian (7 × n, rows e12 e13 e23 e0∞ e1∞ e2∞ e3∞, the
``similarity`` kernel's third output); it maps joint velocities to the similarity twist B = J_G q̇.

- **Velocity ellipsoid** M_S = J_G J_Gᵀ [Eq. 59]: {J_G q̇ : ‖q̇‖ ≤ 1} = {B ∈ range J_G : Bᵀ M_S⁺ B ≤ 1},
  principal axes the left singular vectors u_i of J_G, semi-axes σ_i.
- **Force ellipsoid** M_S⁺ (the paper's M_S⁻¹): by virtual work a generalised force F on the
  primitive (a covector on the twist coordinates) needs the joint torques τ = J_Gᵀ F, so unit torques
  reach {F : Fᵀ M_S F ≤ 1}, semi-axes 1/σ_i along the same u_i. J_G has rank r < 7 (the primitive's
  controllable dimension, Table 1), so M_S is singular: along ker J_Gᵀ (twists the primitive cannot
  make, e.g. a circle turning about its own normal) a force costs no torque and the set is
  unbounded. The force ellipsoid is therefore taken **on the controllable subspace range J_G**: M_S⁺
  = U_r diag(σ_i⁻²) U_rᵀ, the Moore-Penrose pseudo-inverse truncated at rank r. It is *not* the
  restriction to fixed generator rows: range J_G is a configuration-dependent 6-plane of R⁷ (for
  three Pandas on a circle the e12 row is 0 at ``ready`` but not elsewhere).
- **Dilation force index** β_D = (e_Dᵀ M_S e_D)^(−1/2) = 1/‖J_Gᵀ e_D‖ (e_D the e0∞ row): Chiu's force
  transmission ratio along the dilation, the largest *pure* dilation force F = f e_D that unit joint
  torques produce (τ = f J_Gᵀ e_D), i.e. the force ellipsoid's radius along e_D — the squeeze three
  arms can put on a held ring without pushing it anywhere else. Chosen over (M_S⁺)_DD because it
  needs no rank decision (it is smooth wherever the dilation row is non-zero; M_S⁺ jumps where
  rank J_G drops) and it measures a force that does no work on the other twist directions; the two
  agree exactly when e_D is an eigenvector of M_S (three symmetric prismatic points: β_D = √3 r).
  It exists only for primitives that dilate (point pair, circle, sphere: ``DILATING``); a zero
  dilation row gives ∞, the singular stretch where the size can no longer change.
- **Gradients** of log β_D and of the log force-ellipsoid volume with respect to q are formed from
  ∂J_G/∂q_k by central differences of the ``similarity`` kernel (2n calls; error O(h²) ≈ 1e-10 at the
  default h = 1e-5): the analytic route would need the kernel's second derivatives, which no kernel
  carries. ``tests/control/test_manipulability.py`` holds them against CasADi AD of the kernel.
- **Nullspace optimisation** (``maximise``): gradient ascent of the objective inside the self-motion
  manifold {q : e(q) = 0} of the primary task: each step moves along N ∇w with N = I − J_G⁺ J_G
  [Eq. 58] (predictor), then Gauss-Newton steps q ← q − J_Be⁺ e on the ``task`` kernel bring ‖e‖ back
  below ``tol`` (corrector), so the primitive stays on its target while the index grows.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.control.differential import RCOND, damped_pseudo_inverse, nullspace_projector

Array = NDArray[np.float64]
Similarity = Callable[[Array], Sequence[Any]]  # q -> (V_Sc, conditioning, J_G): module.c.similarity
Task = Callable[[Array, Array], Sequence[Any]]  # (q, V_Sd) -> (e, J_Be): module.c.task

DILATION_ROW = 3
"""The e0∞ row of J_G (``gagen.model.conformal.SIMILARITY_GENERATOR``)."""
DILATING = frozenset({"point_pair", "circle", "sphere"})
"""Primitives whose similarity includes a dilation (Table 1): the dilation force index exists for these."""
OBJECTIVES = ("dilation", "volume")
DEFAULT_STEP = 1e-5
HALVINGS = 10  # a step is halved at most this often before the ascent counts as converged


def _jacobian(J_G: ArrayLike) -> Array:
    matrix = np.asarray(J_G, dtype=np.float64)
    if matrix.ndim != 2 or matrix.shape[0] != 7:
        raise ValueError(f"J_G: expected the 7 × n geometric similarity Jacobian, got shape {matrix.shape}")
    if not np.all(np.isfinite(matrix)):
        raise ValueError("J_G: expected finite entries")
    return matrix


def _rank(s: Array, rank: int | None, rcond: float) -> int:
    if rank is None:
        return int(np.count_nonzero(s > rcond * s[0])) if s.size and s[0] > 0 else 0
    if isinstance(rank, bool) or not 1 <= rank <= s.size:
        raise ValueError(f"rank: expected an integer between 1 and {s.size}, got {rank!r}")
    return int(rank)


@dataclass(frozen=True)
class Ellipsoids:
    """The velocity and force ellipsoids of one J_G: ``axes`` (7, r) their common principal directions
    (J_G's left singular vectors), ``velocity_lengths`` σ_1 ≥ … ≥ σ_r and ``force_lengths`` 1/σ_i (∞ at a
    zero σ_i); ``conditioning`` σ_r/σ_1 (0 at a singular configuration, where the force ellipsoid is
    unbounded)."""

    axes: Array
    velocity_lengths: Array
    force_lengths: Array
    rank: int

    @property
    def conditioning(self) -> float:
        s = self.velocity_lengths
        return float(s[-1] / s[0]) if s.size and s[0] > 0 else 0.0


def velocity_ellipsoid(J_G: ArrayLike) -> Array:
    """M_S = J_G J_Gᵀ [COOP Eq. 59] (7 × 7, symmetric positive semi-definite, rank r)."""
    matrix = _jacobian(J_G)
    return matrix @ matrix.T


def ellipsoids(J_G: ArrayLike, rank: int | None = None, rcond: float = RCOND) -> Ellipsoids:
    """Principal axes and semi-axes of both ellipsoids, on the first ``rank`` singular directions (default:
    the numerical rank, singular values above ``rcond`` · σ_1; pass min(CONTROLLABLE_DIMENSION[kind], n)
    for a measure that is continuous through singular configurations)."""
    u, s, _ = np.linalg.svd(_jacobian(J_G), full_matrices=False)
    r = _rank(s, rank, rcond)
    kept = s[:r]
    with np.errstate(divide="ignore"):
        force = np.where(kept > 0, 1.0 / np.where(kept > 0, kept, 1.0), np.inf)
    return Ellipsoids(u[:, :r], kept, force, r)


def force_ellipsoid(J_G: ArrayLike, rank: int | None = None, rcond: float = RCOND) -> Array:
    """M_S⁺ = U_r diag(σ_i⁻²) U_rᵀ: the force ellipsoid {F ∈ range J_G : Fᵀ M_S F ≤ 1} has shape matrix
    M_S⁺ (the paper's M_S⁻¹ on the controllable subspace). A ValueError at a singular configuration
    (σ_r ≤ rcond · σ_1), where the force ellipsoid is unbounded."""
    found = ellipsoids(J_G, rank, rcond)
    s = found.velocity_lengths
    if found.rank == 0 or s[-1] <= rcond * s[0]:
        raise ValueError(f"J_G: singular configuration (σ_{found.rank} / σ_1 = {found.conditioning:.3g}): "
                         "the force ellipsoid is unbounded there")
    return (found.axes / s**2) @ found.axes.T


def force_volume(J_G: ArrayLike, rank: int | None = None, rcond: float = RCOND) -> float:
    """The r-dimensional volume of the force ellipsoid, V_r / Π σ_i (V_r the unit r-ball's; ∞ at a
    singular configuration)."""
    found = ellipsoids(J_G, rank, rcond)
    product = float(np.prod(found.velocity_lengths))
    return _ball(found.rank) / product if product > 0 else math.inf


def _ball(r: int) -> float:
    return float(math.pi ** (r / 2) / math.gamma(r / 2 + 1))


def dilation_force_index(J_G: ArrayLike) -> float:
    """β_D = (e_Dᵀ M_S e_D)^(−1/2) = 1/‖J_Gᵀ e_D‖: the largest pure dilation force per unit joint torque
    (∞ where the dilation row is zero)."""
    norm = float(np.linalg.norm(_jacobian(J_G)[DILATION_ROW]))
    return 1.0 / norm if norm > 0 else math.inf


# -- derivatives ---------------------------------------------------------------------------------------
def jacobian_derivatives(similarity: Similarity, q: ArrayLike,
                         step: float = DEFAULT_STEP) -> tuple[Array, Array]:
    """(J_G(q), dJ) with dJ[k] = ∂J_G/∂q_k (n, 7, n) by central differences of ``similarity`` (q →
    (V_Sc, conditioning, J_G), e.g. ``module.c.similarity`` or a CasADi Function on numbers)."""
    x = np.array(q, dtype=np.float64).ravel()
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"step: expected a finite difference step > 0, got {step!r}")
    if not np.all(np.isfinite(x)):
        raise ValueError("q: expected finite joint values")

    def at(y: Array) -> Array:
        return np.asarray(similarity(y)[2], dtype=np.float64).reshape(7, x.size)

    J = at(x)
    dJ = np.empty((x.size, 7, x.size))
    for k in range(x.size):
        e = np.zeros_like(x)
        e[k] = step
        dJ[k] = (at(x + e) - at(x - e)) / (2.0 * step)
    return J, dJ


def dilation_force_gradient(J_G: ArrayLike, dJ: ArrayLike) -> Array:
    """∇_q β_D = −β_D³ gᵀ ∂g/∂q with g = J_Gᵀ e_D (``dJ`` from ``jacobian_derivatives``); a ValueError
    where the dilation row is zero (β_D = ∞, no gradient)."""
    g = _jacobian(J_G)[DILATION_ROW]
    norm2 = float(g @ g)
    if norm2 == 0:
        raise ValueError("J_G: the dilation row is zero (β_D = ∞): no gradient")
    dg = np.asarray(dJ, dtype=np.float64)[:, DILATION_ROW, :]  # (k, j) = ∂g_j/∂q_k
    gradient: Array = -(dg @ g) / norm2**1.5
    return gradient


def objective(name: str, J_G: ArrayLike, dJ: ArrayLike | None = None,
              rank: int | None = None) -> tuple[float, Array | None]:
    """(w, ∇w) of an objective to maximise: ``dilation``, w = log β_D; ``volume``, w = log of the force
    ellipsoid's volume = −Σ log σ_i (+ const), ∂σ_i/∂q_k = u_iᵀ (∂J_G/∂q_k) v_i. ∇w only with ``dJ``."""
    matrix = _jacobian(J_G)
    if name == "dilation":
        beta = dilation_force_index(matrix)
        if not math.isfinite(beta):
            raise ValueError("J_G: the dilation row is zero (β_D = ∞): nothing to maximise")
        grad = None if dJ is None else dilation_force_gradient(matrix, dJ) / beta
        return math.log(beta), grad
    if name == "volume":
        u, s, vt = np.linalg.svd(matrix, full_matrices=False)
        r = _rank(s, rank, RCOND)
        if s[r - 1] <= 0:
            raise ValueError("J_G: singular configuration: the force ellipsoid's volume is unbounded")
        value = -float(np.sum(np.log(s[:r])))
        if dJ is None:
            return value, None
        d = np.asarray(dJ, dtype=np.float64)
        # ∂σ_i/∂q_k = u_iᵀ ∂J/∂q_k v_i for the r kept singular values
        dsigma = np.einsum("ai,kab,ib->ki", u[:, :r], d, vt[:r])
        return value, -(dsigma / s[:r]).sum(axis=1)
    raise ValueError(f"objective: expected one of {', '.join(OBJECTIVES)}, got {name!r}")


# -- nullspace optimisation ------------------------------------------------------------------------------
@dataclass(frozen=True)
class OptimisationResult:
    """One nullspace ascent: per iterate (steps + 1) ``q``, the ``objective`` w, the ``dilation`` index
    β_D (NaN-free: ∞ where undefined), the force ellipsoid ``volume`` and the task error ``error_norm``
    ‖e(q)‖ with respect to the start's V_Sc (after the corrector); ``corrections`` Gauss-Newton steps
    per step."""

    name: str
    q: Array
    objective: Array
    dilation: Array
    volume: Array
    error_norm: Array
    corrections: NDArray[np.int64]


def maximise(similarity: Similarity, task: Task, q0: ArrayLike, *, name: str = "dilation",
             rank: int | None = None, steps: int = 60, step_size: float = 0.02, tol: float = 1e-12,
             max_corrections: int = 10, fd_step: float = DEFAULT_STEP,
             progress: Callable[[int, float], None] | None = None) -> OptimisationResult:
    """Gradient ascent of objective ``name`` in the nullspace of the primary task e(q) = log(V_Sc(q)~ V_Sd),
    V_Sd = V_Sc(q0): each step q ← q + α N ∇w/‖N ∇w‖ (α = ``step_size`` rad in joint space, N = I −
    J_G⁺ J_G), then Gauss-Newton corrections q ← q − J_Be⁺ e until ‖e‖ ≤ ``tol`` (at most
    ``max_corrections``); α is halved (up to ``HALVINGS`` times) until w increases, and the ascent
    stops early at a local maximum (no such α). ``progress(step, w)`` is called after each step."""
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 0:
        raise ValueError(f"steps: expected an integer >= 0, got {steps!r}")
    if not (math.isfinite(step_size) and step_size > 0):
        raise ValueError(f"step_size: expected a finite step > 0 rad, got {step_size!r}")
    if name not in OBJECTIVES:
        raise ValueError(f"objective: expected one of {', '.join(OBJECTIVES)}, got {name!r}")
    q = np.array(q0, dtype=np.float64).ravel()
    V_Sd = np.asarray(similarity(q)[0], dtype=np.float64).ravel()

    def error(x: Array) -> tuple[Array, Array]:
        e, J_Be = task(x, V_Sd)
        return np.asarray(e, dtype=np.float64).ravel(), np.asarray(J_Be, dtype=np.float64).reshape(7, x.size)

    qs, values, dilations, volumes, errors, corrections = [], [], [], [], [], []

    def correct(x: Array) -> tuple[Array, int]:
        count = 0
        e, J_Be = error(x)
        while float(np.linalg.norm(e)) > tol and count < max_corrections:
            x = x - damped_pseudo_inverse(J_Be) @ e
            e, J_Be = error(x)
            count += 1
        return x, count

    def record(x: Array, count: int) -> tuple[float, Array]:
        J, dJ = jacobian_derivatives(similarity, x, fd_step)
        w, grad = objective(name, J, dJ, rank)
        assert grad is not None
        qs.append(x.copy())
        values.append(w)
        dilations.append(dilation_force_index(J))
        volumes.append(force_volume(J, rank))
        errors.append(float(np.linalg.norm(error(x)[0])))
        corrections.append(count)
        return w, nullspace_projector(J) @ grad

    w, direction = record(q, 0)
    for k in range(steps):
        norm = float(np.linalg.norm(direction))
        length = step_size
        while norm > 0 and length >= step_size / 2**HALVINGS:
            trial, count = correct(q + length * direction / norm)
            value = objective(name, np.asarray(similarity(trial)[2], dtype=np.float64).reshape(7, q.size),
                              rank=rank)[0]
            if value > w:
                break
            length /= 2  # past the ridge: a shorter step along the same direction
        else:
            break  # N ∇w = 0 or no step length increases w: a local maximum on the self-motion manifold
        q = trial
        w, direction = record(q, count)
        if progress is not None:
            progress(k + 1, w)
    return OptimisationResult(name, np.array(qs), np.array(values), np.array(dilations), np.array(volumes),
                              np.array(errors), np.array(corrections, dtype=np.int64))
