"""Leader-follower cooperation [COOP Sec. 5, future work]: robots keep a primitive that a measured leader
(a human's hand) helps span.

The primitive X_c(q, q_m) is spanned by the robots' end points (joints q, the decision variables) and
the leader's (joints q_m, measured). Its task error e(q, q_m) = log(V_Sc(q, q_m)~ V_Sd) [COOP Eq. 40-44]
changes at the rate

    ė = J_Be q̇ + J_Be,m q̇_m,

the ``task`` kernel's J_Be and its twin J_Be_m (the system's kernels with measured chains). The
followers hold chosen rows of e at zero while the leader moves:

- ``mode="rate"`` (differential IK, what a velocity-controlled robot runs at each tick):
  q̇ = J_Be⁺ (−K e − J_Be,m q̇_m) on those rows (damped pseudo-inverse), q ← q + Δt q̇ clipped into the
  joint limits. The leader's velocity q̇_m is the causal backward difference of its last two samples
  (zero at the start); ``feedforward=False`` drops the J_Be,m q̇_m term, leaving feedback alone, which
  lags the leader by about ‖J_m q̇_m‖ / K.
- ``mode="ik"``: at each sample the followers solve e(q, q_m,k+1) = 0 on the rows (``ik.solve_ik``:
  Levenberg-Marquardt within the joint limits, to ``tol``) from the rate step's prediction
  q_k + Δt J_Be⁺ (−J_Be,m Δq_m / Δt), so the error is at most ``tol`` at every sample the solve reaches.

Which rows: the leader moves the primitive where it likes, so only rows that a translation of the whole
primitive leaves unchanged can be held for any leader motion: the rotation and dilation rows of e
(e12 e13 e23 e0∞: the similarity group modulo translations), minus the primitive's stabiliser (Table 1).
``SHAPE_ROWS`` lists them: a circle keeps its normal (e13, e23) and radius (e0∞), and its centre follows
the leader; a sphere its radius; a point pair its direction and length.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.control.differential import damped_pseudo_inverse
from gagen.control.ik import solve_ik

Array = NDArray[np.float64]
MeasuredTask = Callable[[Array, Array, Array], tuple[ArrayLike, ArrayLike, ArrayLike]]
"""task(q, q_m, V_Sd) -> (e, J_Be, J_Be_m): the ``task`` kernel of a system with measured chains."""

GENERATOR = ("e12", "e13", "e23", "e0inf", "e1inf", "e2inf", "e3inf")  # the rows of e (SIMILARITY_GENERATOR)
SHAPE_ROWS: dict[str, tuple[str, ...]] = {
    "point": (),                          # a point is all position: nothing survives a translation
    "point_pair": ("e12", "e13", "e0inf"),  # direction and length (turning about its own axis: e23)
    "line": ("e12", "e13"),               # direction
    "circle": ("e13", "e23", "e0inf"),    # normal and radius (turning in its plane: e12)
    "plane": ("e13", "e23"),              # normal
    "sphere": ("e0inf",),                 # radius
}
"""Rows of e that a translation of the primitive leaves unchanged, less its stabiliser [Table 1]."""
MODES = ("ik", "rate")
DEFAULT_GAIN = 20.0  # 1/s: K of the rate mode (a fifth of the sampling rate at 100 Hz)
DEFAULT_TOL = 1e-10


def shape_rows(kind: str) -> NDArray[np.int64]:
    """Indices into e of ``SHAPE_ROWS[kind]`` (a ValueError for an unknown kind or a point)."""
    if kind not in SHAPE_ROWS:
        raise ValueError(f"unknown primitive kind {kind!r}; expected one of {', '.join(SHAPE_ROWS)}")
    if not SHAPE_ROWS[kind]:
        raise ValueError("a point primitive has no rows a moving leader leaves to keep; use a point pair, "
                         "line, circle, plane or sphere")
    return np.array([GENERATOR.index(b) for b in SHAPE_ROWS[kind]], dtype=np.int64)


@dataclass(frozen=True)
class FollowResult:
    """One run over the leader's samples (n + 1 of them, n steps). Per sample: ``t``, ``q`` (robot joints),
    ``q_m`` (the leader's), ``error`` ‖e‖ on the kept rows. Per step: ``speed`` the joint velocities
    Δq/Δt (n, dof), ``iterations`` of the IK solve (0 in rate mode), ``converged`` (rate mode: always),
    ``clipped`` joints held at a limit."""

    mode: str
    feedforward: bool
    dt: float
    rows: tuple[int, ...]
    t: Array
    q: Array
    q_m: Array
    error: Array
    speed: Array
    iterations: NDArray[np.int64]
    converged: NDArray[np.bool_]
    clipped: NDArray[np.int64]
    messages: tuple[str, ...] = ()

    @property
    def moving_error(self) -> float:
        """max ‖e‖ over the samples after the leader first moves (0 if it never does)."""
        moved = np.flatnonzero(np.any(np.abs(self.q_m - self.q_m[0]) > 0, axis=1))
        return float(self.error[moved[0]:].max()) if moved.size else 0.0


def _finite(name: str, values: Sequence[Array], t: float) -> None:
    if not all(np.all(np.isfinite(v)) for v in values):
        raise ValueError(f"the task kernel returned NaN or inf at t = {t:.4f} s ({name}); the spanning "
                         "points may be degenerate")


def follow(task: MeasuredTask, q0: ArrayLike, q_m: ArrayLike, dt: float, V_Sd: ArrayLike,
           rows: ArrayLike, *, mode: str = "ik", feedforward: bool = True, gain: float = DEFAULT_GAIN,
           limits: tuple[ArrayLike, ArrayLike] | None = None, damping: float = 1e-6, tol: float = DEFAULT_TOL,
           max_iterations: int = 50, progress: Callable[[int, float, float], None] | None = None
           ) -> FollowResult:
    """Follow the leader's samples ``q_m`` ((n + 1, m), every ``dt`` s) from the robot joints ``q0``,
    holding ``rows`` of e(q, q_m) = log(V_Sc~ V_Sd) at zero (see the module docstring). ``progress(k, t,
    error)`` is called after each step."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
    if not (math.isfinite(gain) and gain >= 0):
        raise ValueError(f"gain must be a finite number >= 0 (1/s), got {gain!r}")
    leader = np.atleast_2d(np.asarray(q_m, dtype=float))
    q = np.asarray(q0, dtype=float).ravel().copy()
    target = np.asarray(V_Sd, dtype=float).ravel()
    index = np.asarray(rows, dtype=np.int64).ravel()
    if not np.all(np.isfinite(leader)):
        raise ValueError("q_m: the leader's samples must be finite")
    lower, upper = (np.full(q.size, -np.inf), np.full(q.size, np.inf)) if limits is None else \
        (np.broadcast_to(np.asarray(b, dtype=float), q.shape) for b in limits)

    def at(x: Array, xm: Array) -> tuple[Array, Array, Array]:
        e, J, J_m = (np.asarray(v, dtype=float) for v in task(x, xm, target))
        return e.ravel()[index], J.reshape(e.size, -1)[index], J_m.reshape(e.size, -1)[index]

    steps = leader.shape[0] - 1
    qs, errors = [q.copy()], [float(np.linalg.norm(at(q, leader[0])[0]))]
    iterations, converged, clipped, messages = [], [], [], []
    for k in range(steps):
        e, J, J_m = at(q, leader[k])
        _finite("e, J_Be, J_Be_m", [e, J, J_m], k * dt)
        inverse = damped_pseudo_inverse(J, damping)
        if mode == "rate":
            rate = (leader[k] - leader[k - 1]) / dt if k > 0 else np.zeros(leader.shape[1])
            q_dot = inverse @ (-gain * e - (J_m @ rate if feedforward else 0.0))
            q_next = np.clip(q + dt * q_dot, lower, upper)
            iterations.append(0)
            converged.append(True)
        else:
            step = leader[k + 1] - leader[k]
            guess = np.clip(q - inverse @ (J_m @ step) if feedforward else q, lower, upper)

            def reduced(x: Array, _: Array, xm: Array = leader[k + 1]) -> tuple[Array, Array]:
                e_k, J_k, _m = at(x, xm)
                return e_k, J_k

            r = solve_ik(reduced, guess, target, tol=tol, max_iterations=max_iterations,
                         limits=None if limits is None else (lower, upper))
            q_next = r.q
            iterations.append(r.iterations)
            converged.append(r.converged)
            if not r.converged:
                messages.append(f"t = {(k + 1) * dt:.4f} s: {r.message}")
        clipped.append(int(np.count_nonzero((q_next <= lower) | (q_next >= upper))))
        q = q_next
        qs.append(q.copy())
        errors.append(float(np.linalg.norm(at(q, leader[k + 1])[0])))
        if progress is not None:
            progress(k + 1, (k + 1) * dt, errors[-1])
    q_all = np.array(qs)
    return FollowResult(mode=mode, feedforward=feedforward, dt=float(dt), rows=tuple(int(i) for i in index),
                        t=np.arange(steps + 1) * dt, q=q_all, q_m=leader, error=np.array(errors),
                        speed=np.diff(q_all, axis=0) / dt, iterations=np.array(iterations, dtype=np.int64),
                        converged=np.array(converged, dtype=bool), clipped=np.array(clipped, dtype=np.int64),
                        messages=tuple(messages))
