"""Row orders of the chain kernels' outputs, and converters to the layouts other libraries use.

A chain kernel's spatial Jacobian ``J_S`` (6 × n, ``<chain>_fk_jacobian`` and ``<chain>_jacobians``)
has one column per joint: the joint's line L'_j in the system's base frame, as a motor generator on
the rows ``SPATIAL_JACOBIAN_ROWS`` = (e12, e13, e23, e1∞, e2∞, e3∞). For a joint turning about the
unit axis ω through the point p (or sliding along ω), the rows hold (ω_z, −ω_y, ω_x, v_x, v_y, v_z)
with v = p × ω (v = ω for a prismatic joint): the twist of the base frame's origin. Pinocchio's
``computeFrameJacobian(..., ReferenceFrame.WORLD)`` holds the same twist as [v; ω];
``to_pinocchio_world`` reorders one into the other (and ``from_pinocchio_world`` back).

The motor M (8 rows ``MOTOR``) of ``<chain>_fk`` maps to a 4 × 4 homogeneous transform (Pinocchio's
``oMf[frame].homogeneous``) by ``motor_to_homogeneous``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.model.conformal import MOTOR, MOTOR_GENERATOR

__all__ = ["MOTOR_ROWS", "SPATIAL_JACOBIAN_ROWS", "from_pinocchio_world", "motor_to_homogeneous",
           "to_pinocchio_world"]

SPATIAL_JACOBIAN_ROWS = MOTOR_GENERATOR
MOTOR_ROWS = MOTOR

# [v; ω] = signs * J_S[order]: v = (e1∞, e2∞, e3∞), ω = (e23, −e13, e12)
_ORDER = np.array([SPATIAL_JACOBIAN_ROWS.index(b) for b in ("e1inf", "e2inf", "e3inf", "e23", "e13", "e12")])
_SIGNS = np.array([1.0, 1.0, 1.0, 1.0, -1.0, 1.0])
_INVERSE = np.argsort(_ORDER)


def _rows(array: ArrayLike, axis: int) -> NDArray[np.float64]:
    values = np.asarray(array, dtype=float)
    if values.ndim == 0 or values.shape[axis] != 6:
        raise ValueError(f"expected 6 rows on axis {axis} (a twist or a 6 × n Jacobian), got shape "
                         f"{values.shape}")
    return values


def to_pinocchio_world(J_S: ArrayLike, axis: int = -2) -> NDArray[np.float64]:
    """Pinocchio's WORLD Jacobian [v; ω] from gagen's J_S (rows e12, e13, e23, e1∞, e2∞, e3∞).

    ``axis`` is the row axis: −2 for a (6, n) Jacobian or an (m, 6, n) batch (the default), −1 for
    a twist (6,) or an (m, 6) batch of twists, 0 for a column-layout batch (6, n, m)."""
    values = _rows(J_S, axis)
    moved = np.moveaxis(values, axis, 0)
    return np.moveaxis(moved[_ORDER] * _SIGNS.reshape((6,) + (1,) * (moved.ndim - 1)), 0, axis)


def from_pinocchio_world(J: ArrayLike, axis: int = -2) -> NDArray[np.float64]:
    """gagen's J_S row order from Pinocchio's [v; ω] (the inverse of ``to_pinocchio_world``)."""
    values = _rows(J, axis)
    moved = np.moveaxis(values, axis, 0)
    signed = moved * _SIGNS.reshape((6,) + (1,) * (moved.ndim - 1))
    return np.moveaxis(signed[_INVERSE], 0, axis)


def motor_to_homogeneous(M: ArrayLike) -> NDArray[np.float64]:
    """The 4 × 4 transform [R t; 0 1] of a motor given by its 8 coefficients on ``MOTOR_ROWS``
    (1, e12, e13, e23, e1∞, e2∞, e3∞, e123∞), e.g. the ``M`` output of ``<chain>_fk``; also for
    an (m, 8) batch, giving (m, 4, 4). x ↦ M x M~ is x ↦ R x + t."""
    m = np.asarray(M, dtype=float)
    if m.shape[-1] != 8:
        raise ValueError(f"expected 8 motor coefficients on the last axis, got shape {m.shape}")
    s, b12, b13, b23, t1, t2, t3, p = np.moveaxis(m, -1, 0)
    # rotor R = s + b12 e12 + b13 e13 + b23 e23 is the quaternion (w, x, y, z) = (s, −b23, b13, −b12)
    w, x, y, z = s, -b23, b13, -b12
    out = np.zeros((*m.shape[:-1], 4, 4))
    out[..., 0, 0] = w * w + x * x - y * y - z * z
    out[..., 0, 1] = 2 * (x * y - w * z)
    out[..., 0, 2] = 2 * (x * z + w * y)
    out[..., 1, 0] = 2 * (x * y + w * z)
    out[..., 1, 1] = w * w - x * x + y * y - z * z
    out[..., 1, 2] = 2 * (y * z - w * x)
    out[..., 2, 0] = 2 * (x * z - w * y)
    out[..., 2, 1] = 2 * (y * z + w * x)
    out[..., 2, 2] = w * w - x * x - y * y + z * z
    # M = T R with T = 1 − ½ t e∞ and e∞ commuting with R, so M's e∞ part is −½ (t R) e∞: with
    # c = (e1∞, e2∞, e3∞), p = e123∞ and R~ = s − I β (β the rotor's axis vector), t = (t R) R~ gives
    # t = −2 (s c + c × β + p β)
    c = np.stack([t1, t2, t3], axis=-1)
    beta = np.stack([b23, -b13, b12], axis=-1)
    out[..., :3, 3] = -2 * (s[..., None] * c + np.cross(c, beta) + p[..., None] * beta)
    out[..., 3, 3] = 1.0
    return out
