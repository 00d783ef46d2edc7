"""The best-fit primitive through n points [COOP Section 5, future work: more chains than needed].

``best_fit(kind, points)`` fits a primitive of ``kind`` to n >= ``points_needed(kind)`` conformal
points, written once against the multivector protocol (arithmetic, sqrt, cos, atan2 and guarded
selects only), so the interpreter evaluates it and the compiler flattens and differentiates it:

- point: the centroid x̄.
- line (n >= 2): through x̄ along the eigenvector of the largest eigenvalue of the scatter C.
- plane (n >= 3): through x̄, normal along the eigenvector of the smallest eigenvalue of C.
- sphere (n >= 4): Kåsa's algebraic fit, min Σ (|x_i|² − 2c·x_i − k)² over (c, k), which is the
  conformal least squares min Σ (P_i·S)² over dual spheres S with S·e∞ = −1 (P·S = −½(|x|² −
  2c·x − k)); r² = k + |c|².
- circle (n >= 3): the plane fit, then the same algebraic fit with the centre held in that plane
  (min Σ (|x_i|² − 2c·x_i − k)² subject to n·c = n·x̄).
- point pair: only n = 2 (there is no canonical pair through more points).

Centred at x̄ (y_i = x_i − x̄, C = mean y yᵀ) the algebraic fits decouple: k' = mean |y|² and
C c' = ½ mean y|y|² (within the plane for circles), solved by the adjugate. The eigenvalues of the
symmetric 3×3 are the trigonometric closed form, evaluated so that the eigenvalue used stays smooth
where the *other* two coincide (points on a regular polygon, exactly collinear points).

The result is the OPNS blade ``through(kind, …)`` of the first ``points_needed(kind)`` points
projected onto the fitted primitive: with exactly that many points, or points exactly on a
primitive, it equals ``through()`` of the first points (orientation and scale included, up to
rounding), and otherwise it is oriented like them.

Conditioning (dimensionless, in [0, 1]; from the scatter normalised to unit trace, Ĉ = C / tr C,
eigenvalues λ̂1 >= λ̂2 >= λ̂3): point 1; line (λ̂1 − λ̂2)²; plane and circle (λ̂2 − λ̂3)²; sphere
27 det Ĉ. It is zero (to rounding) for coincident points, for an isotropic cloud, and where the fitted
direction is undefined (collinear points for a plane or circle, coplanar points for a sphere); every
value stays finite there. The figure is accurate to ~1e-8 (where it uses a near-double pair of the
closed-form eigenvalues, which carry √ε of rounding); the fit itself to rounding.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

from gagen.algebra.protocol import Multivector
from gagen.algebra.scalars import Math, Scalar
from gagen.model.conformal import EUCLID, location, point, vector
from gagen.model.primitives import points_needed, through

Vec = list[Scalar]
Mat = list[list[Scalar]]

# floors added (as selected constants) to quantities that vanish only for degenerate point sets:
# they keep every value and derivative finite there and never touch a meaningful input
TRACE_FLOOR = 1e-100  # tr C in m²: all points coincident
COINCIDENT = 1e-28  # tr C / |x̄|² below which the points count as coincident (conditioning 0)
SPREAD_FLOOR = 1e-40  # |Ĉ − I/3|²: an isotropic cloud (all eigenvalues equal)
SINE_FLOOR = 1e-60  # 1 − r²: the eigenvalue used is one of two equal ones (its direction is undefined)
DET_FLOOR = 1e-60  # det of the fit's normal equations: coplanar (sphere) or collinear (circle) points
SERIES_BELOW = 1e-3  # 1 − r below which cos(acos(r)/3) is its Taylor series
# cos(acos(1 − s)/3) = Σ c_k s^k; the next term is below 1e-19 at s = SERIES_BELOW
_SERIES = (1.0, -1 / 9, -4 / 243, -28 / 6561, -80 / 59049, -2288 / 4782969)


class Fit(NamedTuple):
    """A primitive spanned by points, how well-conditioned it is, and whether it was fitted (more
    points than the kind needs) or is ``through()`` of exactly the needed points (conditioning 1)."""

    primitive: Any
    conditioning: Scalar
    fitted: bool
    spanning: tuple[Any, ...] = ()  # a fit's: the positions (x, y, z) of the points through() spans it by


def check_count(kind: str, count: int) -> None:
    """A ValueError unless ``count`` points can span (or be fitted by) a primitive of ``kind``."""
    need = points_needed(kind)
    if kind == "point_pair" and count != need:
        raise ValueError(f"a point_pair is spanned by exactly 2 points, got {count} (no best fit of a "
                         f"pair through more points)")
    if count < need:
        raise ValueError(f"a {kind} is spanned by {need} points (or fitted to more), got {count}")


def span(kind: str, points: Sequence[Multivector]) -> Fit:
    """The primitive of ``kind`` spanned by ``points``: ``through()`` for exactly the points the kind
    needs (conditioning 1, ``fitted`` False), the best fit for more."""
    check_count(kind, len(points))
    if len(points) == points_needed(kind):
        return Fit(through(kind, points), 1, False)
    return best_fit(kind, points)


def best_fit(kind: str, points: Sequence[Multivector]) -> Fit:
    """The best-fit primitive of ``kind`` through ``points`` (see the module docstring)."""
    check_count(kind, len(points))
    like = points[0]
    m = like.math
    xs = [_xyz(location(p)) for p in points]
    n = len(xs)
    mean = [sum((x[k] for x in xs), start=0) / n for k in range(3)]
    ys = [_sub(x, mean) for x in xs]
    if kind == "point":
        return Fit(through("point", [point(vector(like, mean))]), 1, True)
    if kind == "point_pair":
        return Fit(through(kind, points), 1, True)  # (check_count allowed exactly two)
    cov = [[sum((y[i] * y[j] for y in ys), start=0) / n for j in range(3)] for i in range(3)]
    trace = cov[0][0] + cov[1][1] + cov[2][2]  # = mean |y|²
    # coincident to rounding (a relative spread below 1e-14): the figure would be the noise's, and the
    # floor keeps Ĉ's derivative (~ 1/|y|) bounded
    floor = COINCIDENT * _dot(mean, mean) + TRACE_FLOOR
    coincident = m.lt(trace, floor)
    scale = 1 / (trace + m.if_else(coincident, floor, 0.0))
    unit_cov = [[m.shared(c * scale) for c in row] for row in cov]
    need = points_needed(kind)
    if kind == "sphere":
        rhs = [sum((y[k] * _dot(y, y) for y in ys), start=0) * (0.5 / n) * scale for k in range(3)]
        det = _det(unit_cov)
        offset = _solve(m, unit_cov, rhs, det)
        projected = _onto_round(m, mean, ys[:need], offset, trace)
        conditioning = 27 * det
    else:
        largest, smallest, spread = _eigenvalues(m, unit_cov)
        simple = largest if kind == "line" else smallest
        axis = _unit(m, _eigenvector(m, unit_cov, simple))
        # (λ1 − λ2)² (line), (λ2 − λ3)² (plane, circle): from the eigenvalue that is accurate where they meet
        other = smallest if kind == "line" else largest
        conditioning = m.if_else(m.lt(spread, SPREAD_FLOOR), 0.0, _squared_gap_of_others(unit_cov, other))
        if kind == "line":  # x̄ + d (d·y_i)
            projected = [_add(mean, _scale(axis, _dot(axis, y))) for y in ys[:need]]
        elif kind == "plane":  # x̄ + y_i − n (n·y_i)
            projected = [_add(mean, _sub(y, _scale(axis, _dot(axis, y)))) for y in ys[:need]]
        else:  # circle: the centre offset c' in the plane, from (P Ĉ P + n nᵀ) c' = P b̂
            plane = [[(1.0 if i == j else 0.0) - axis[i] * axis[j] for j in range(3)] for i in range(3)]
            rhs = [sum((y[k] * _dot(y, y) for y in ys), start=0) * (0.5 / n) * scale for k in range(3)]
            system = _mul(_mul(plane, unit_cov), plane)
            system = [[system[i][j] + axis[i] * axis[j] for j in range(3)] for i in range(3)]
            offset = _solve(m, system, _apply(plane, rhs), _det(system))
            in_plane = [_sub(y, _scale(axis, _dot(axis, y))) for y in ys[:need]]
            projected = _onto_round(m, mean, in_plane, offset, trace)
    return Fit(through(kind, [point(vector(like, x)) for x in projected]),
               m.if_else(coincident, 0.0, conditioning), True, tuple(projected))


# -- the fits' pieces ---------------------------------------------------------------------------------
def _onto_round(m: Math, mean: Vec, ys: Sequence[Vec], offset: Vec, trace: Scalar) -> list[Vec]:
    """Points x̄ + y projected radially onto the round of centre x̄ + c', r² = mean|y|² + |c'|²."""
    radius = m.sqrt(_floored(m, trace + _dot(offset, offset), TRACE_FLOOR))
    centre = _add(mean, offset)
    return [_add(centre, _scale(_unit(m, _sub(y, offset)), radius)) for y in ys]


def _eigenvalues(m: Math, a: Mat) -> tuple[Scalar, Scalar, Scalar]:
    """(largest, smallest, spread) of a symmetric 3×3, by the trigonometric closed form
    λ = q + 2p cos((acos r + 2πk)/3); spread = |A − qI|², zero when all three are equal.

    The largest is q + 2p t(r) and the smallest q − 2p t(−r) with t(r) = cos(acos(r)/3), which is
    analytic at r = 1 (the two others equal: there its series) and singular only at r = −1, where the
    eigenvalue itself is one of two equal ones."""
    q = (a[0][0] + a[1][1] + a[2][2]) / 3
    d = [[a[i][j] - (q if i == j else 0.0) for j in range(3)] for i in range(3)]
    spread = d[0][0] * d[0][0] + d[1][1] * d[1][1] + d[2][2] * d[2][2] + 2 * (
        a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2])
    p = m.sqrt(_floored(m, spread, SPREAD_FLOOR) / 6)
    r = _det(d) / (2 * p * p * p)
    r = m.if_else(m.lt(1.0, r), 1.0, m.if_else(m.lt(r, -1.0), -1.0, r))  # rounding can leave [−1, 1]
    largest = q + 2 * p * _cos_third_acos(m, r)
    smallest = q - 2 * p * _cos_third_acos(m, -r)
    return largest, smallest, spread


def _squared_gap_of_others(a: Mat, value: Scalar) -> Scalar:
    """(λ_a − λ_b)² of the two eigenvalues other than ``value``, from their sum tr − λ and product
    M₂ − λ (tr − λ) (M₂: the sum of the principal 2×2 minors): zero to rounding where they are equal,
    which the trigonometric values, √-sensitive there, are not."""
    total = a[0][0] + a[1][1] + a[2][2] - value
    minors = (a[0][0] * a[1][1] - a[0][1] * a[0][1] + a[0][0] * a[2][2] - a[0][2] * a[0][2]
              + a[1][1] * a[2][2] - a[1][2] * a[1][2])
    return total * total - 4 * (minors - value * total)


def _cos_third_acos(m: Math, r: Scalar) -> Scalar:
    """cos(acos(r)/3) for r in [−1, 1]: its Taylor series in s = 1 − r below SERIES_BELOW, the closed
    form cos(atan2(√(1 − r²), r)/3) at a safe argument otherwise (its derivative is finite, large
    near r = −1, where the function is not smooth)."""
    s = 1 - r
    series = _SERIES[-1]
    for c in reversed(_SERIES[:-1]):
        series = series * s + c
    near = m.lt(s, SERIES_BELOW)
    safe = r - m.if_else(near, 0.5, 0.0)  # the closed form's branch is never evaluated near r = 1
    sine2 = (1 - safe) * (1 + safe)
    closed = m.cos(m.atan2(m.sqrt(_floored(m, sine2, SINE_FLOOR)), safe) / 3)
    return m.if_else(near, series, closed)


def _eigenvector(m: Math, a: Mat, value: Scalar) -> Vec:
    """An eigenvector of the symmetric a for a simple eigenvalue: the longest cross product of two
    rows of a − λI (not normalised)."""
    rows = [[a[i][j] - (value if i == j else 0.0) for j in range(3)] for i in range(3)]
    best = _cross(rows[0], rows[1])
    best_norm = _dot(best, best)
    for candidate in (_cross(rows[0], rows[2]), _cross(rows[1], rows[2])):
        norm = _dot(candidate, candidate)
        longer = m.lt(best_norm, norm)
        best = [m.if_else(longer, c, b) for c, b in zip(candidate, best, strict=True)]
        best_norm = m.if_else(longer, norm, best_norm)
    return best


def _solve(m: Math, a: Mat, b: Vec, det: Scalar) -> Vec:
    """a⁻¹ b by the adjugate (a symmetric), with det a kept away from zero (degenerate points)."""
    adj = [[a[(j + 1) % 3][(i + 1) % 3] * a[(j + 2) % 3][(i + 2) % 3]
            - a[(j + 1) % 3][(i + 2) % 3] * a[(j + 2) % 3][(i + 1) % 3] for j in range(3)] for i in range(3)]
    inverse_det = 1 / (det + m.if_else(m.lt(m.fabs(det), DET_FLOOR), DET_FLOOR, 0.0))
    return [_dot(row, b) * inverse_det for row in adj]


def _floored(m: Math, x: Scalar, floor: Scalar) -> Scalar:
    """x >= 0, moved up by ``floor`` where it is below it (a selected constant: its derivative is dx)."""
    return x + m.if_else(m.lt(x, floor), floor, 0.0)


def _unit(m: Math, v: Vec) -> Vec:
    norm2 = _dot(v, v)
    inverse = 1 / m.sqrt(norm2 + m.if_else(m.lt(norm2, DET_FLOOR), DET_FLOOR, 0.0))
    return _scale(v, inverse)


# -- 3-vectors and 3×3 matrices as lists of scalars ---------------------------------------------------
def _xyz(v: Multivector) -> Vec:
    return [v[b] for b in EUCLID]


def _add(a: Vec, b: Vec) -> Vec:
    return [x + y for x, y in zip(a, b, strict=True)]


def _sub(a: Vec, b: Vec) -> Vec:
    return [x - y for x, y in zip(a, b, strict=True)]


def _scale(a: Vec, s: Scalar) -> Vec:
    return [x * s for x in a]


def _dot(a: Vec, b: Vec) -> Scalar:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Vec, b: Vec) -> Vec:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _det(a: Mat) -> Scalar:
    return _dot(a[0], _cross(a[1], a[2]))


def _mul(a: Mat, b: Mat) -> Mat:
    return [[a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j] for j in range(3)] for i in range(3)]


def _apply(a: Mat, v: Vec) -> Vec:
    return [_dot(row, v) for row in a]
