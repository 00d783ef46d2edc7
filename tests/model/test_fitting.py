"""``gagen.model.fitting.best_fit`` against independent numpy fits, ``through()`` and differences.

The references are plain numpy from the Euclidean points alone: the line and the plane from the SVD of
the centred points, the sphere by ``np.linalg.lstsq`` on Kåsa's rows [2x, 1]·(c, k) = |x|², the circle
by the SVD plane and ``lstsq`` on the centre within it; each reference projects the first
``points_needed`` points onto its fit and spans ``through()`` by them, which is what ``best_fit``
returns. Hypothesis draws clouds near a random primitive of each kind (random pose, size and noise).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from gagen.algebra.multivector import SparseMultivector
from gagen.algebra.signature import cga3d as symbolic_cga3d
from gagen.interp import MultiVector, cga3d
from gagen.model.conformal import point, vector
from gagen.model.fitting import best_fit, check_count, span
from gagen.model.primitives import points_needed, through
from gagen.symbolic.casadi_backend import CasadiBackend

LIKE = MultiVector.zero(cga3d())
FITTED = ("line", "plane", "circle", "sphere")
EXAMPLES = settings(max_examples=25, deadline=None)


def P(x) -> MultiVector:
    return point(vector(LIKE, [float(v) for v in x]))


def _through(kind: str, xs: np.ndarray) -> np.ndarray:
    return through(kind, [P(x) for x in xs]).coeffs


def _fit(kind: str, xs: np.ndarray) -> np.ndarray:
    return best_fit(kind, [P(x) for x in xs]).primitive.coeffs


def _close(ours: np.ndarray, theirs: np.ndarray, rtol: float) -> None:
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=rtol * np.max(np.abs(theirs)))


# -- the numpy references -------------------------------------------------------------------------------
def _reference(kind: str, xs: np.ndarray) -> tuple[np.ndarray, float]:
    """(the first points_needed points projected onto numpy's fit, numpy's conditioning figure)."""
    k = points_needed(kind)
    mean = xs.mean(axis=0)
    y = xs - mean
    _, s, vt = np.linalg.svd(y)
    lam = np.zeros(3)
    lam[:s.size] = s**2 / np.sum(s**2)  # eigenvalues of the unit-trace scatter, descending
    if kind == "line":
        d = vt[0]
        return mean + np.outer(y[:k] @ d, d), (lam[0] - lam[1]) ** 2
    if kind == "plane":
        n = vt[2]
        return xs[:k] - np.outer(y[:k] @ n, n), (lam[1] - lam[2]) ** 2
    if kind == "sphere":
        rows = np.c_[2 * xs, np.ones(len(xs))]
        (c0, c1, c2, kk), *_ = np.linalg.lstsq(rows, np.sum(xs**2, axis=1), rcond=None)
        c = np.array([c0, c1, c2])
        r = np.sqrt(kk + c @ c)
        w = xs[:k] - c
        return c + r * w / np.linalg.norm(w, axis=1)[:, None], 27 * np.prod(lam)
    n, u, v = vt[2], vt[0], vt[1]  # circle: the centre c = x̄ + s u + t v in the plane
    rows = np.c_[2 * xs @ u, 2 * xs @ v, np.ones(len(xs))]
    (s_, t_, kk), *_ = np.linalg.lstsq(rows, np.sum(xs**2, axis=1) - 2 * xs @ mean, rcond=None)
    c = mean + s_ * u + t_ * v
    r = np.sqrt(kk + c @ c)
    z = xs[:k] - np.outer(y[:k] @ n, n)
    return c + r * (z - c) / np.linalg.norm(z - c, axis=1)[:, None], (lam[1] - lam[2]) ** 2


# -- clouds near a primitive ------------------------------------------------------------------------------
def _rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def _on(kind: str, rng: np.random.Generator, n: int) -> np.ndarray:
    """n points on a random primitive of ``kind`` (centre within 1 m, size 0.3-1.5 m)."""
    c, r, rot = rng.uniform(-1, 1, 3), rng.uniform(0.3, 1.5), _rotation(rng)
    if kind == "line":
        local = np.c_[rng.uniform(-r, r, n), np.zeros((n, 2))]
    elif kind == "plane":
        local = np.c_[rng.uniform(-r, r, (n, 2)), np.zeros(n)]
    elif kind == "circle":
        a = rng.uniform(0, 2 * np.pi, n)
        local = r * np.c_[np.cos(a), np.sin(a), np.zeros(n)]
    else:
        d = rng.normal(size=(n, 3))
        local = r * d / np.linalg.norm(d, axis=1)[:, None]
    return c + local @ rot.T


def _spread(kind: str, xs: np.ndarray) -> float:
    """The first points_needed points' size relative to the cloud: length, area or volume (to keep the
    spanning points themselves well-conditioned)."""
    k = points_needed(kind)
    e = xs[1:k] - xs[0]
    scale = np.max(np.linalg.norm(xs - xs.mean(axis=0), axis=1))
    return float(np.sqrt(np.linalg.det(e @ e.T))) / scale ** (k - 1) if k > 1 else 1.0


cloud = st.tuples(st.sampled_from(FITTED), st.integers(0, 2**32 - 1), st.integers(0, 5),
                  st.sampled_from([0.0, 1e-3, 3e-2]))


@EXAMPLES
@given(cloud)
def test_best_fit_equals_the_numpy_fit(case):
    kind, seed, extra, noise = case
    rng = np.random.default_rng(seed)
    xs = _on(kind, rng, points_needed(kind) + 1 + extra)
    xs = xs + noise * rng.normal(size=xs.shape)
    projected, figure = _reference(kind, xs)
    assume(figure > 0.05 and _spread(kind, projected) > 0.05)
    fit = best_fit(kind, [P(x) for x in xs])
    _close(fit.primitive.coeffs, _through(kind, projected), 1e-10)
    # (the closed-form eigenvalues of a near-double pair, which the figure may use, are √ε-sensitive)
    assert fit.conditioning == pytest.approx(figure, abs=1e-7)
    assert fit.fitted


@EXAMPLES
@given(cloud)
def test_points_on_a_primitive_and_exact_counts_give_through(case):
    """On the primitive (any count), or exactly points_needed points: best_fit = through() of the first
    points, orientation and scale included; span() is through() itself for the exact count."""
    kind, seed, extra, _ = case
    rng = np.random.default_rng(seed)
    k = points_needed(kind)
    xs = _on(kind, rng, k + 1 + extra)
    assume(_spread(kind, xs) > 0.05 and _reference(kind, xs)[1] > 0.05)
    _close(_fit(kind, xs), _through(kind, xs[:k]), 1e-12)
    free = rng.uniform(-1, 1, (k, 3))  # any k points in general position
    assume(_spread(kind, free) > 0.05 and (kind == "line" or _reference(kind, free)[1] > 1e-3))
    _close(_fit(kind, free), _through(kind, free), 1e-12)
    spanned = span(kind, [P(x) for x in free])
    assert not spanned.fitted and spanned.conditioning == 1
    np.testing.assert_array_equal(spanned.primitive.coeffs, _through(kind, free))


def test_the_point_is_the_centroid_and_a_pair_is_not_fitted():
    xs = np.random.default_rng(3).uniform(-1, 1, (6, 3))
    np.testing.assert_allclose(_fit("point", xs), P(xs.mean(axis=0)).coeffs, rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match="a point_pair is spanned by exactly 2 points, got 3"):
        best_fit("point_pair", [P(x) for x in xs[:3]])
    with pytest.raises(ValueError, match=r"a sphere is spanned by 4 points .*got 3"):
        span("sphere", [P(x) for x in xs[:3]])
    check_count("circle", 7)  # more is fine


# -- degenerate clouds ------------------------------------------------------------------------------------
def _symbolic(kind: str, n: int) -> tuple[ca.Function, list[int]]:
    """best_fit on CasADi symbols: positions (3n) -> primitive, its AD Jacobian, conditioning, and the
    second derivative along a direction (what J̇ q̇ needs); and the primitive's rows as dense indices."""
    zero = SparseMultivector(symbolic_cga3d(), CasadiBackend(), {})
    x, d = ca.SX.sym("x", 3 * n), ca.SX.sym("d", 3 * n)
    pts = [point(vector(zero, [zero.backend.lift(x[3 * i + k]) for k in range(3)])) for i in range(n)]
    fit = best_fit(kind, pts)
    blades = [fit.primitive.algebra.blade_name(b) for b in fit.primitive.support]
    col = ca.vertcat(*[zero.backend.native(fit.primitive[b]) for b in blades])
    jac = ca.jacobian(col, x)
    function = ca.Function("fit", [x, d], [col, jac, zero.backend.native(zero.backend.lift(fit.conditioning)),
                                           ca.jtimes(ca.mtimes(jac, d), x, d)])
    return function, [LIKE.algebra.blade(b) for b in blades]


CUBE = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]] * 2, dtype=float) * 0.3 + 0.2
DEGENERATE = {  # cloud -> the kinds it is degenerate for
    "coincident": (np.full((6, 3), 0.3), FITTED),
    "collinear": (np.outer(np.arange(6), [0.1, 0.2, 0.3]) + 0.2, ("plane", "circle", "sphere")),
    "coplanar": (np.c_[np.random.default_rng(0).normal(size=(6, 2)), np.zeros(6)], ("sphere",)),
    "isotropic": (CUBE, ("line", "plane", "circle")),
}


@pytest.mark.parametrize("cloud", sorted(DEGENERATE))
def test_degenerate_clouds_give_zero_conditioning_and_finite_values_and_derivatives(cloud):
    xs, kinds = DEGENERATE[cloud]
    for kind in kinds:
        fit = best_fit(kind, [P(x) for x in xs])
        assert abs(fit.conditioning) < 1e-12, (kind, fit.conditioning)
        assert np.all(np.isfinite(fit.primitive.coeffs))
        value, jac, conditioning, second = (np.array(v) for v in _symbolic(kind, len(xs))[0](xs.ravel(), 1.0))
        assert abs(conditioning.item()) < 1e-12, (kind, conditioning)
        assert all(np.all(np.isfinite(v)) for v in (value, jac, second)), kind


# -- the compiler's path ------------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", FITTED)
def test_the_symbolic_fit_equals_the_interpreter_and_its_jacobian_central_differences(kind):
    """Values to 1e-12; the AD Jacobian to central differences of the interpreter (1e-7 relative), at a
    noisy cloud and at points exactly on a regular polygon / a line, where two eigenvalues coincide."""
    rng = np.random.default_rng(11)
    n = points_needed(kind) + 2
    regular = 0.6 * np.c_[np.cos(2 * np.pi * np.arange(n) / n), np.sin(2 * np.pi * np.arange(n) / n),
                          np.zeros(n)] + [0.1, -0.2, 0.5]
    if kind == "line":
        regular = np.outer(np.linspace(-1, 1, n), [0.3, 0.4, 0.5]) + 0.1
    if kind == "sphere":
        regular = _on("sphere", rng, n)
    function, rows = _symbolic(kind, n)
    for xs in (_on(kind, rng, n) + 0.02 * rng.normal(size=(n, 3)), regular):
        value, jac, _, _ = (np.array(v) for v in function(xs.ravel(), 0.0))
        _close(value.ravel(), _fit(kind, xs)[rows], 1e-12)
        h = 1e-6
        columns = []
        for j in range(xs.size):
            step = np.zeros(xs.size)
            step[j] = h
            plus, minus = (_fit(kind, (xs.ravel() + s * step).reshape(n, 3)) for s in (1, -1))
            columns.append((plus - minus) / (2 * h))
        fd = np.array(columns).T
        np.testing.assert_allclose(jac, fd[rows], rtol=0, atol=1e-7 * np.max(np.abs(fd)))
