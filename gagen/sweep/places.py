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


def fitted_rounds(kind: str, points: Array) -> tuple[Array, Array]:
    """Centres (n, 3) and radii (n,) of the best-fit circles or spheres through more points (n, k, 3) than
    the kind needs: ``gagen.model.fitting.best_fit``'s algebraic fit, batched. Centred at the centroid
    (y = x − x̄, C = mean y yᵀ, b = ½ mean y|y|²): a sphere's centre offset solves C c = b; a circle's is
    held in the plane of C's smallest eigenvector n, (P C P + n nᵀ) c = P b with P = I − n nᵀ; and
    r² = mean |y|² − 2 mean(y)·c + |c|² = mean |y|² + |c|². NaN where the system is singular."""
    mean = points.mean(axis=1)
    y = points - mean[:, None, :]
    squared = np.einsum("nki,nki->nk", y, y)
    cov = np.einsum("nki,nkj->nij", y, y) / points.shape[1]
    b = 0.5 * np.einsum("nki,nk->ni", y, squared) / points.shape[1]
    if kind == "circle":
        normal = np.linalg.eigh(cov)[1][:, :, 0]
        plane = np.eye(3) - np.einsum("ni,nj->nij", normal, normal)
        cov = plane @ cov @ plane + np.einsum("ni,nj->nij", normal, normal)
        b = np.einsum("nij,nj->ni", plane, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        singular = np.abs(np.linalg.det(cov)) <= 1e-300
        cov[singular] = np.eye(3)
        offset = np.linalg.solve(cov, b[:, :, None])[:, :, 0]
        offset[singular] = np.nan
    radius = np.sqrt(squared.mean(axis=1) + np.einsum("ni,ni->n", offset, offset))
    return mean + offset, radius


def locate(kind: str, points: Array) -> tuple[Array, Array]:
    """Where the primitive of ``kind`` through ``points`` (n, chains, 3) is, and its size: the centre and
    radius of a circle or sphere (of their best fit through more chains than the kind needs), the midpoint
    and half length of a point pair; else (a point, line or plane: no centre of its own) the end points'
    centroid and NaN."""
    if kind in ("circle", "sphere") and points.shape[1] > (3 if kind == "circle" else 4):
        return fitted_rounds(kind, points)
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
