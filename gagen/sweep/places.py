"""Batched geometry of the sweeps' rows: where the primitive that n sets of end points span is (its centre
and size), and the volume of the unit ball that turns a product of singular values into an ellipsoid's
volume. Degenerate rows (collinear or coplanar points) give inf/NaN instead of raising: a random sweep
meets them, and the plots leave non-finite rows out."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def circumcircles(a: Array, b: Array, c: Array) -> tuple[Array, Array]:
    """Centres (n, 3) and radii (n,) of the circles through the rows of a, b, c (NaN when collinear)."""
    u, v = b - a, c - a
    n = np.cross(u, v)
    nn = np.einsum("ij,ij->i", n, n)
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = (np.einsum("ij,ij->i", u, u)[:, None] * np.cross(v, n)
                  + np.einsum("ij,ij->i", v, v)[:, None] * np.cross(n, u)) / (2.0 * nn[:, None])
    return a + offset, np.linalg.norm(offset, axis=1)


def circumspheres(a: Array, b: Array, c: Array, d: Array) -> tuple[Array, Array]:
    """Centres (n, 3) and radii (n,) of the spheres through the rows of a, b, c, d (inf/NaN when
    coplanar): the closed form of 2 (p_i − a)·x = |p_i − a|², by Cramer's rule with cross products."""
    u, v, w = b - a, c - a, d - a
    volume = np.einsum("ij,ij->i", u, np.cross(v, w))
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = (np.einsum("ij,ij->i", u, u)[:, None] * np.cross(v, w)
                  + np.einsum("ij,ij->i", v, v)[:, None] * np.cross(w, u)
                  + np.einsum("ij,ij->i", w, w)[:, None] * np.cross(u, v)) / (2.0 * volume[:, None])
    return a + offset, np.linalg.norm(offset, axis=1)


def locate(kind: str, points: Array) -> tuple[Array, Array]:
    """Where the primitive of ``kind`` through ``points`` (n, chains, 3) is, and its size: the centre and
    radius of a circle or sphere, the midpoint and half length of a point pair; else (a point, line or
    plane: no centre of its own) the end points' centroid and NaN."""
    if kind == "circle":
        return circumcircles(*points.transpose(1, 0, 2))
    if kind == "sphere":
        return circumspheres(*points.transpose(1, 0, 2))
    centroid = points.mean(axis=1)
    if kind == "point_pair":
        return centroid, np.linalg.norm(points[:, 1] - points[:, 0], axis=1) / 2.0
    return centroid, np.full(len(points), np.nan)


def unit_ball_volume(rank: int) -> float:
    """V_r = π^(r/2) / Γ(r/2 + 1): the volume of the unit ball in r dimensions (π³/6 for r = 6)."""
    volume: float = math.pi ** (rank / 2) / math.gamma(rank / 2 + 1)  # (float ** float is Any to typeshed)
    return volume
