"""An independent reference for the hexapod tests: a leg's kinematics as a chain of 4×4 homogeneous
matrices in numpy, batched over configurations (no geometric algebra, no gagen code but the spec).

Body ← hip: T(xyz) Rz(yaw) Ry(pitch) Rx(roll) (URDF rpy); then per joint Rot(axis_j, q_j) followed by
the translation to the next joint along x of the hip frame: (l1, 0, 0), (l2, 0, 0), (l3, 0, 0) to the toe.
"""

from __future__ import annotations

import numpy as np

from gagen.apps.hexapod.spec import Leg


def rotation(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: the rotations by ``angle`` (n,) about the unit ``axis`` (3,), shape (n, 3, 3)."""
    u = np.asarray(axis, dtype=float)
    u = u / np.linalg.norm(u)
    k = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * k + (1 - c) * (k @ k)


def homogeneous(r: np.ndarray | None = None, t=(0.0, 0.0, 0.0), n: int = 1) -> np.ndarray:
    out = np.tile(np.eye(4), (n, 1, 1))
    if r is not None:
        out[:, :3, :3] = r
    out[:, :3, 3] = t
    return out


def rpy_matrix(rpy) -> np.ndarray:
    roll, pitch, yaw = (np.array([a], dtype=float) for a in rpy)
    return (rotation([0, 0, 1], yaw) @ rotation([0, 1, 0], pitch) @ rotation([1, 0, 0], roll))[0]


def mount_matrix(leg: Leg) -> np.ndarray:
    return homogeneous(rpy_matrix(leg.rpy), leg.xyz)[0]


def frames(leg: Leg, q: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """The three joint frames before each joint turns (n, 4, 4) and the toe frame, in the body frame,
    for configurations q of shape (n, 3)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = len(q)
    current = np.tile(mount_matrix(leg), (n, 1, 1))
    joints = []
    for j, step in enumerate(leg.lengths):
        joints.append(current)
        turn = homogeneous(rotation(leg.axes[j], q[:, j]), n=n)
        current = current @ turn @ homogeneous(t=(step, 0, 0), n=n)
    return joints, current


def toe_transform(leg: Leg, q: np.ndarray) -> np.ndarray:
    return frames(leg, q)[1]


def toe(leg: Leg, q: np.ndarray) -> np.ndarray:
    """Toe positions (n, 3) in the body frame."""
    return toe_transform(leg, q)[:, :3, 3]


def jacobians(leg: Leg, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """J (n, 3, 3): columns w_j × (p − c_j); S (n, 6, 3): columns (c_j × w_j, w_j), the world-frame twist
    of joint j with w_j its axis in the body frame and c_j its origin."""
    joints, tip = frames(leg, q)
    p = tip[:, :3, 3]
    J, S = [], []
    for j, frame in enumerate(joints):
        w = frame[:, :3, :3] @ np.asarray(leg.axes[j], dtype=float)
        c = frame[:, :3, 3]
        J.append(np.cross(w, p - c))
        S.append(np.concatenate([np.cross(c, w), w], axis=1))
    return np.stack(J, axis=2), np.stack(S, axis=2)


def to_hip(leg: Leg, points: np.ndarray) -> np.ndarray:
    """Body-frame points (n, 3) in the leg's hip frame."""
    m = mount_matrix(leg)
    return (np.atleast_2d(points) - m[:3, 3]) @ m[:3, :3]


def from_hip(leg: Leg, points: np.ndarray) -> np.ndarray:
    m = mount_matrix(leg)
    return np.atleast_2d(points) @ m[:3, :3].T + m[:3, 3]


def random_configurations(leg: Leg, rng: np.random.Generator, n: int) -> np.ndarray:
    lo, hi = np.array(leg.limits).T
    return rng.uniform(lo, hi, size=(n, 3))
