"""Versors of the similarity group and their exp/log charts [COOP Appendix A].

Convention of [COOP]: ``exp(B) = e^{−B/2}``; B is the twist-like generator, a bivector on
e12, e13, e23 (rotation: angle θ about unit n is θ(n3 e12 − n2 e13 + n1 e23)), e0∞ (dilation:
λ = −ln d scales about the origin by d, gafro's convention) and e1∞, e2∞, e3∞ (translation by t
is t ∧ e∞). Motors and similarity versors use the *decoupled* product charts of Eq. 72-77:
exp(B) = T(t) R(b) [D(λ)], log returns the world-frame translation and the rotation generator.

Every exp/log is exact and smooth at the identity (guarded series, see ``guarded``), valid for
rotation angles |θ| < π, and finite at θ = π.
"""

from __future__ import annotations

from typing import Any, NamedTuple

from gagen.algebra.protocol import Multivector
from gagen.algebra.scalars import Scalar
from gagen.model.conformal import (
    DILATION,
    EUCLID,
    MOTOR,
    ROTATION,
    TRANSLATION,
    e0,
    einf,
    location,
    normalized_point,
    part,
    vector,
)
from gagen.model.guarded import (
    atan2_sqrt_over_sqrt,
    cos_half_sqrt,
    safe_reciprocal,
    sin_half_sqrt_over_sqrt,
)

ROTOR = ("1", *ROTATION)
DILATOR = ("1", *DILATION)


# -- rotors -------------------------------------------------------------------------------------------
def exp_rotor(b: Multivector) -> Multivector:
    """R = cos(‖B‖/2) − sin(‖B‖/2) B/‖B‖ for the rotation part of B [Eq. 62]."""
    m = b.math
    br = part(b, ROTATION)
    s = br.sp(~br)  # = b12² + b13² + b23² = θ²
    rotor: Multivector = cos_half_sqrt(m, s) - br * sin_half_sqrt_over_sqrt(m, s)  # Scalar (Any) − … is Any
    return rotor


def log_rotor(r: Multivector) -> Multivector:
    """Rotation generator of a rotor (any positive scale): −2 atan2(|⟨R⟩₂|, ⟨R⟩₀) ⟨R⟩₂/|⟨R⟩₂| [Eq. 63]."""
    br = part(r, ROTATION)
    s = br.sp(~br)
    generator: Multivector = br * (-2 * atan2_sqrt_over_sqrt(r.math, s, r.scalar()))
    return generator


def rotor(axis: Multivector, angle: Scalar) -> Multivector:
    """Rotor turning by ``angle`` about the unit Euclidean vector ``axis`` (right-handed)."""
    n1, n2, n3 = (axis[k] for k in EUCLID)
    return exp_rotor(axis.make({"e12": angle * n3, "e13": -angle * n2, "e23": angle * n1}))


# -- translators --------------------------------------------------------------------------------------
def exp_translator(b: Multivector) -> Multivector:
    """T = 1 − ½ B_T [Eq. 64]."""
    return 1 - part(b, TRANSLATION) * 0.5


def log_translator(t: Multivector) -> Multivector:
    """B_T = −2 ⟨T⟩₂ / ⟨T⟩₀ [Eq. 65] (the scalar part divides out any scale)."""
    generator: Multivector = part(t, TRANSLATION) * (-2 / t.scalar())
    return generator


def translator(t: Multivector) -> Multivector:
    """Translator by the Euclidean vector t: exp(t ∧ e∞) [Eq. 66]."""
    return exp_translator(t ^ einf(t))


# -- dilators -----------------------------------------------------------------------------------------
def exp_dilator(b: Multivector) -> Multivector:
    """D = cosh(λ/2) − sinh(λ/2) e0∞ for λ the e0∞ coefficient of B [Eq. 67]; scales by e^{−λ}."""
    m = b.math
    half = b["e0inf"] * 0.5
    return b.make({"1": m.cosh(half), "e0inf": -m.sinh(half)})


def log_dilator(d: Multivector) -> Multivector:
    """λ e0∞ with λ = 2 atanh(−⟨D⟩_{e0∞} / ⟨D⟩₀) [Eq. 68], any positive scale of D."""
    return d.make({"e0inf": 2 * d.math.atanh(-d["e0inf"] / d.scalar())})


def dilator(like: Multivector, d: Scalar) -> Multivector:
    """Dilator scaling about the origin by d > 0."""
    return exp_dilator(like.make({"e0inf": -like.math.log(d)}))


# -- motors and similarity versors --------------------------------------------------------------------
def exp_motor(b: Multivector) -> Multivector:
    """M = exp(B_T) exp(B_R) [Eq. 72]."""
    return exp_translator(b) * exp_rotor(b)


def log_motor(motor: Multivector) -> Multivector:
    """log M = log T + log R with R the Euclidean part of M and T = M R⁻¹ [Eq. 73]."""
    r = part(motor, ROTOR)
    t = part(motor * ~r, ("1", *TRANSLATION))  # = T ⟨R R~⟩₀; log_translator divides the scale out
    return log_translator(t) + log_rotor(r)


def exp_similarity(b: Multivector) -> Multivector:
    """V = exp(B_T) exp(B_R) exp(B_D) [Eq. 76]."""
    return exp_translator(b) * exp_rotor(b) * exp_dilator(b)


class SimilarityFactors(NamedTuple):
    translator: Any
    rotor: Any
    dilator: Any


def decompose_similarity(v: Multivector) -> SimilarityFactors:
    """V = T R D for a unit similarity versor.

    T from the image of the origin (V e0 V~ ∝ P(t): R and D keep the origin), then R D = T~ V,
    whose {1, e12, e13, e23} part is cosh(λ/2) R; D = R~ (R D).
    """
    t = translator(location(v.sandwich(e0(v))))
    rd = ~t * v
    a = part(rd, ROTOR)
    r = a / a.math.sqrt(a.norm_squared())
    d = part(~r * rd, DILATOR)
    return SimilarityFactors(t, r, d)


def log_similarity(v: Multivector) -> Multivector:
    """log V = log V_T + log V_R + log V_D [Eq. 77]."""
    t, r, d = decompose_similarity(v)
    return log_translator(t) + log_rotor(r) + log_dilator(d)


# -- versors between two objects ----------------------------------------------------------------------
class Versor(NamedTuple):
    """A versor and how well-conditioned its construction was (0 = degenerate; see each function)."""

    versor: Any
    conditioning: Scalar


def half_turn_perpendicular(v: Multivector) -> Multivector:
    """A rotor turning by π about a unit axis perpendicular to the Euclidean vector v
    (v × e1, or v × e2 when v is close to e1); it maps v to −v."""
    m = v.math
    v1, v2, v3 = (v[k] for k in EUCLID)
    use_e1 = m.lt(m.fabs(v1) * m.fabs(v1), 0.81 * v.sp(v))
    h1, h2 = m.if_else(use_e1, 1.0, 0.0), m.if_else(use_e1, 0.0, 1.0)
    u1, u2, u3 = -v3 * h2, v3 * h1, v1 * h2 - v2 * h1
    inv = safe_reciprocal(m, m.sqrt(u1 * u1 + u2 * u2 + u3 * u3))
    return v.make({"e12": -u3 * inv, "e13": u2 * inv, "e23": -u1 * inv})


def _select(cond: Any, x: Multivector, y: Multivector, blades: tuple[str, ...]) -> Any:
    m = x.math
    return x.make({k: m.if_else(cond, x[k], y[k]) for k in blades})


ANTIPARALLEL = 1e-16  # |a + b|² (or K0) below this: a guarded half turn; both forms err by ~1e-8 there


def rotor_between(a: Multivector, b: Multivector) -> Versor:
    """Rotor turning unit vector a onto unit vector b: (1 + b a)/‖1 + b a‖ [COOP Eq. 26].

    Evaluated as (a + b) a / |a + b|, which equals it for unit vectors and loses only eps/|a + b|
    near antiparallel vectors (the problem's own conditioning), where 1 + a·b would lose
    eps/|a + b|². Conditioning |a + b|²/4 = (1 + a·b)/2: 1 for a = b, 0 for antiparallel vectors,
    where the rotor is a half turn about an axis perpendicular to a (guarded, never NaN).
    """
    m = a.math
    s = a + b
    n2 = s.sp(s)
    antiparallel = m.lt(n2, ANTIPARALLEL)
    generic = (s * a) * (1 / m.sqrt(n2 + m.if_else(antiparallel, 1.0, 0.0)))
    return Versor(_select(antiparallel, half_turn_perpendicular(a), generic, ROTOR), n2 * 0.25)


def _flat_axis(x: Multivector, sigma: int) -> Multivector:
    """Direction of a line P∧P∧e∞ (σ = 1: its e0∧d∧e∞ part), or normal of a plane (σ = −1: the
    Euclidean part of X*)."""
    if sigma < 0:
        return part(x.dual(), EUCLID)
    return vector(x, [x[f"e0{k}inf"] for k in "123"])


def versor_between(x1: Multivector, x2: Multivector, sigma: int) -> Versor:
    """Motor taking the flat x1 onto the flat x2 of the same kind and orientation [COOP Eq. 21].

    Each is scaled so that X² = σ (σ = +1 for lines P∧P∧e∞, −1 for planes P∧P∧P∧e∞);
    K = 2 + σ(X2X1 + X1X2) = K0 + K4 with K4 null, and V = (1 + σX2X1)(1 − K4/(2K0))/√K0.
    With S = X1 + X2 these are K = σS² and 1 + σX2X1 = σSX1, which avoid the cancellation in
    1 + σX2X1 itself. Near opposite orientations Eq. 21 stays ill-conditioned all the same: the screw
    axis of two nearly antiparallel skew flats runs ~1/√K0 away, so the motor grows like that and
    loses ~eps/K0 (e.g. 5e-10 at 0.6° from opposite; the conditioning K0/4 reports it).
    Conditioning K0/4: 1 for x1 = x2, 0 for x2 = −x1, where x1 is first given a half turn about a
    perpendicular axis through its point nearest the origin (guarded).
    """
    m = x1.math
    n1 = x1 * safe_reciprocal(m, m.sqrt(m.fabs(x1.sp(x1))))
    n2 = x2 * safe_reciprocal(m, m.sqrt(m.fabs(x2.sp(x2))))

    def eq21(a: Any) -> tuple[Any, Any]:
        s = a + n2
        k = s * s * sigma
        k0 = k.scalar()
        inv_k0 = safe_reciprocal(m, k0)
        v = s * a * sigma * (1 - k.grade(4) * (0.5 * inv_k0)) * m.sqrt(m.fabs(inv_k0))
        return part(v, MOTOR), k0

    direct, k0 = eq21(n1)
    foot = location(normalized_point(project_point_of_origin(n1)))
    flip = translator(foot) * half_turn_perpendicular(_flat_axis(n1, sigma)) * translator(-foot)
    flipped, _ = eq21(flip.sandwich(n1))
    opposite = m.lt(k0, ANTIPARALLEL)
    return Versor(_select(opposite, part(flipped * flip, MOTOR), direct, MOTOR), k0 * 0.25)


def project_point_of_origin(x: Multivector) -> Multivector:
    """(e0·X) X⁻¹: the origin projected onto a flat (a scaled point)."""
    projected: Multivector = (e0(x) | x) * ~x * safe_reciprocal(x.math, x.norm_squared())
    return projected


# -- the similarity group's own exponential (one-parameter subgroups) --------------------------------
# exp_similarity above is the decoupled chart T(t) R(b) D(λ) of Eq. 76, whose exp(sB) is not a
# one-parameter subgroup when B both turns (or dilates) and translates. Interpolation [COOP Fig. 4]
# needs the group's exponential e^{−B/2}: with A = [Θ]× + σ I (Θ = θn the rotation vector of B_R,
# σ = −λ the log-scale rate) and v the translation part, points follow x' = A x + v, whose time-1
# flow is x ↦ e^A x + W v with W = Σ A^k/(k+1)! = ∫₀¹ e^{sA} ds. So e^{−B/2} = T(W v) R(Θ) D(λ), and
# W v = a0 v + c1 Θ×v + c2 Θ×(Θ×v), from w = (e^z − 1)/z, z = σ + iθ (W's eigenvalue on the plane
# ⟂ n; a0 = (e^σ − 1)/σ along n): Im w = c1 θ, Re w = a0 − c2 θ².

LIE_SERIES_BELOW = 0.25  # |z|² below this: c1, c2 from their power series (16 terms, < 1e-17 there)
_LIE_TERMS = 16


def _sinhc(m: Any, x: Scalar) -> Scalar:
    """sinh(x)/x, → 1 at x = 0 (guarded like ``guarded``)."""
    s = x * x
    series = 1 + s / 6 + s * s / 120 + s * s * s / 5040
    safe = x + m.if_else(m.lt(s, 1e-4), 1.0, 0.0)
    return m.if_else(m.lt(s, 1e-4), series, m.sinh(safe) / safe)


def similarity_flow_coefficients(m: Any, sigma: Scalar, s: Scalar) -> tuple[Scalar, Scalar, Scalar]:
    """(a0, c1, c2) of W = a0 + c1 [Θ]× + c2 [Θ]×² for log-scale rate σ and θ² = s (see above).

    Closed forms away from z = 0 (no division by θ or σ alone: sin θ/θ, (1 − cos θ)/θ² and
    (e^σ − 1)/σ are guarded), the series Σ z^k/(k+1)! split into real recurrences below
    ``LIE_SERIES_BELOW``: z^k = p_k + iθ q_k, (σ^k − p_k)/θ² = r_k, so c1 = Σ q_k/(k+1)!,
    c2 = Σ r_k/(k+1)!. Both branches are exact to ~1e-15 relative and smooth (AD-safe).
    """
    half = sin_half_sqrt_over_sqrt(m, s)  # sin(θ/2)/θ
    f1 = 2 * half * cos_half_sqrt(m, s)  # sin θ/θ
    f2 = 2 * half * half  # (1 − cos θ)/θ²
    e = m.exp(sigma)
    a0 = m.exp(sigma * 0.5) * _sinhc(m, sigma * 0.5)  # (e^σ − 1)/σ
    zz = sigma * sigma + s
    near = m.lt(zz, LIE_SERIES_BELOW)
    safe = zz + m.if_else(near, 1.0, 0.0)
    # e^σ cos θ − 1 = (e^σ − 1) − e^σ (1 − cos θ), without the cancellation of the first form
    c1_closed = (sigma * e * f1 - (sigma * a0 - e * s * f2)) / safe
    c2_closed = (sigma * e * f2 + a0 - e * f1) / safe
    p, q, r = 1.0, 0.0, 0.0  # z^0 (Scalar: floats, or symbolic after the first step)
    c1_series: Scalar = 0.0
    c2_series: Scalar = 0.0
    factorial = 1
    for k in range(_LIE_TERMS):
        factorial *= k + 1
        c1_series = c1_series + q * (1.0 / factorial)
        c2_series = c2_series + r * (1.0 / factorial)
        p, q, r = sigma * p - s * q, p + sigma * q, sigma * r + q
    return a0, m.if_else(near, c1_series, c1_closed), m.if_else(near, c2_series, c2_closed)


def _rotation_vector(b: Multivector) -> Multivector:
    """Θ = θ n of a rotation generator θ(n3 e12 − n2 e13 + n1 e23), as a Euclidean vector."""
    return vector(b, [b["e23"], -b["e13"], b["e12"]])


def _cross(a: Multivector, b: Multivector) -> Multivector:
    """a × b of Euclidean vectors."""
    a1, a2, a3 = (a[k] for k in EUCLID)
    b1, b2, b3 = (b[k] for k in EUCLID)
    return vector(a, [a2 * b3 - a3 * b2, a3 * b1 - a1 * b3, a1 * b2 - a2 * b1])


def _with_translation(b: Multivector, t: Multivector) -> Multivector:
    """B with its translation part replaced by t ∧ e∞."""
    return part(b, (*ROTATION, *DILATION)) + (t ^ einf(t))


def exp_similarity_lie(b: Multivector) -> Multivector:
    """The group exponential e^{−B/2} of a similarity generator B (rotation, dilation, translation):
    exp_similarity_lie(sB) is a one-parameter subgroup, unlike the decoupled ``exp_similarity``
    (they agree when B has no translation, or only a translation). Unit versor; valid for all B,
    and log_similarity_lie inverts it for rotation angles θ < π."""
    m = b.math
    theta = _rotation_vector(b)
    v = vector(b, [b[f"{k}inf"] for k in EUCLID])
    a0, c1, c2 = similarity_flow_coefficients(m, -b["e0inf"], theta.sp(theta))
    tv = _cross(theta, v)
    return exp_similarity(_with_translation(b, v * a0 + tv * c1 + _cross(theta, tv) * c2))


def log_similarity_lie(v: Multivector) -> Multivector:
    """The generator B with e^{−B/2} = ±V for a unit similarity versor V, rotation angle θ ∈ [0, π]
    (V and −V are the same similarity; the sign with the shorter turn is taken): the decoupled
    log, then the translation part W⁻¹u, W⁻¹ = 1/a0 − (c1/|w|²)[Θ]× + (c1² − wr c2)/(a0 |w|²)[Θ]×²
    with wr = a0 − c2 θ², |w|² = wr² + c1² θ² (> 0 for θ < 2π)."""
    m = v.math
    t, r, d = decompose_similarity(v)
    r = r * m.if_else(m.lt(r.scalar(), 0), -1.0, 1.0)
    b = log_translator(t) + log_rotor(r) + log_dilator(d)
    theta = _rotation_vector(b)
    u = vector(b, [b[f"{k}inf"] for k in EUCLID])
    s = theta.sp(theta)
    a0, c1, c2 = similarity_flow_coefficients(m, -b["e0inf"], s)
    wr = a0 - c2 * s
    w2 = wr * wr + c1 * c1 * s
    tu = _cross(theta, u)
    inverse = u * (1 / a0) + tu * (-c1 / w2) + _cross(theta, tu) * ((c1 * c1 - wr * c2) / (a0 * w2))
    return _with_translation(b, inverse)
