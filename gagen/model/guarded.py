"""Guarded scalar functions: exact, smooth and NaN-free at their removable singularities.

Each function switches to a Taylor series below a small threshold and evaluates the closed form
at a *safe* argument otherwise (the "double where" pattern), so neither the value nor its
derivative (CasADi AD) meets 0/0 or sqrt(0): the branch not taken never sees the singular point.
The series are truncated where the next term is below 1e-16 relative at the threshold.

A guard that only keeps an argument away from a singular point *adds* a selected constant
(x + [x near 0]·c) instead of selecting between x and a constant: its derivative is then dx with
no select at all, where a selected x makes AD put a select on every derivative path through it
(and the branch it guards is never used where the constant is added).

``m`` is the ``math`` namespace of a multivector (interpreter floats or symbolic scalars).
"""

from __future__ import annotations

from gagen.algebra.scalars import Math, Scalar

SERIES_BELOW = 1e-4  # squared-angle threshold for the series branches
TINY = 1e-300  # replaces an exactly-zero denominator so that nothing becomes Inf or NaN


def _switch(m: Math, s: Scalar, series: Scalar, closed_form: Scalar) -> Scalar:
    return m.if_else(m.lt(s, SERIES_BELOW), series, closed_form)


def _safe(m: Math, s: Scalar) -> Scalar:
    """s where the closed form is used, a harmless s + 1 where the series is."""
    return s + m.if_else(m.lt(s, SERIES_BELOW), 1.0, 0.0)


def cos_half_sqrt(m: Math, s: Scalar) -> Scalar:
    """cos(√s / 2) for s >= 0, smooth at s = 0."""
    series = 1 - s / 8 + s * s / 384 - s * s * s / 46080
    return _switch(m, s, series, m.cos(m.sqrt(_safe(m, s)) / 2))


def sin_half_sqrt_over_sqrt(m: Math, s: Scalar) -> Scalar:
    """sin(√s / 2) / √s for s >= 0, → ½ at s = 0."""
    series = 0.5 - s / 48 + s * s / 3840 - s * s * s / 645120
    safe = _safe(m, s)
    root = m.sqrt(safe)
    return _switch(m, s, series, m.sin(root / 2) / root)


def atan2_sqrt_over_sqrt(m: Math, s: Scalar, w: Scalar) -> Scalar:
    """atan2(√s, w) / √s for s >= 0; for w > 0 it tends to 1/w at s = 0 (the identity rotor)."""
    w_series = w + m.if_else(m.lt(s, SERIES_BELOW), 0.0, 3.0)  # w ≈ ±1 where the series is used
    z2 = s / (w_series * w_series)
    series = (1 - z2 / 3 + z2 * z2 / 5 - z2 * z2 * z2 / 7) / w_series
    safe = _safe(m, s)
    root = m.sqrt(safe)
    return _switch(m, s, series, m.atan2(root, w) / root)


def safe_reciprocal(m: Math, x: Scalar) -> Scalar:
    """1/x, with an exactly-zero (or subnormal) x moved TINY away from 0 so the result stays finite."""
    return 1 / (x + m.if_else(m.lt(m.fabs(x), TINY), m.if_else(m.lt(x, 0), -TINY, TINY), 0.0))
