"""Algebra descriptions: which basis vectors an algebra has, how they square, how blades are named.

An :class:`Algebra` is pure data, shared by the compiler (``gagen.algebra.blade_rules``) and the
reference interpreter (``gagen.interp``). It holds no product rules: each side derives its own from
this description, so that the two can check each other.

Blades are bitmasks over the basis vectors in the order given (bit ``i`` = basis vector ``i``).
A blade is the *outer* product of its vectors in increasing bit order, so every blade is
homogeneous of grade ``popcount(mask)`` even in a non-orthogonal (null) basis. Coefficient arrays
are indexed by bitmask.

Each basis vector is also given as a combination of an orthonormal frame with squares +1, -1 or 0;
the bilinear form (the metric) follows from that frame, exactly (sympy rationals).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache, cached_property

import sympy

from gagen.algebra.scalars import Exact


@dataclass(frozen=True)
class Algebra:
    """A geometric algebra G(p, q, r) over a chosen basis.

    Attributes:
        name: short identifier, e.g. ``"cga3d"``.
        vector_labels: label of each basis vector in bit order, e.g. ``("0", "1", "2", "3", "inf")``.
        frame_squares: squares (+1, -1, 0) of the orthonormal frame the basis is expressed in.
        frame: ``frame[i][j]`` = coefficient of orthonormal frame vector ``j`` in basis vector ``i``.
    """

    name: str
    vector_labels: tuple[str, ...]
    frame_squares: tuple[int, ...]
    frame: tuple[tuple[Exact, ...], ...]

    def __post_init__(self) -> None:
        n = len(self.vector_labels)
        if len(self.frame) != n or any(len(row) != len(self.frame_squares) for row in self.frame):
            raise ValueError(f"algebra {self.name!r}: frame must be {n} rows of {len(self.frame_squares)}")
        if any(s not in (-1, 0, 1) for s in self.frame_squares):
            raise ValueError(f"algebra {self.name!r}: frame squares must be +1, -1 or 0")
        if sympy.Matrix(self.frame).rank() != n:
            raise ValueError(f"algebra {self.name!r}: basis vectors are not independent")

    def __hash__(self) -> int:  # algebras key every table cache; hashing the sympy frame is slow
        return self._hash

    @cached_property
    def _hash(self) -> int:
        return hash((self.name, self.vector_labels, self.frame_squares, self.frame))

    # -- sizes -------------------------------------------------------------------------------
    @property
    def dimension(self) -> int:
        """Number of basis vectors n."""
        return len(self.vector_labels)

    @property
    def size(self) -> int:
        """Number of blades, 2**n."""
        return 1 << self.dimension

    @property
    def pseudoscalar(self) -> int:
        """Bitmask of the unit pseudoscalar (outer product of all basis vectors)."""
        return self.size - 1

    @property
    def signature(self) -> tuple[int, int, int]:
        """(p, q, r): how many frame vectors square to +1, -1 and 0."""
        s = self.frame_squares
        return (s.count(1), s.count(-1), s.count(0))

    @property
    def is_degenerate(self) -> bool:
        return self.signature[2] > 0

    # -- metric --------------------------------------------------------------------------------
    @cached_property
    def metric(self) -> tuple[tuple[Exact, ...], ...]:
        """Exact bilinear form of the basis vectors: metric[i][j] = e_i . e_j."""
        f = sympy.Matrix(self.frame)
        g = f * sympy.diag(*self.frame_squares) * f.T
        n = self.dimension
        return tuple(tuple(sympy.nsimplify(g[i, j]) for j in range(n)) for i in range(n))

    # -- blades --------------------------------------------------------------------------------
    @staticmethod
    def grade(mask: int) -> int:
        """Grade of a blade (number of basis vectors in it)."""
        return mask.bit_count()

    def blades_of_grade(self, k: int) -> tuple[int, ...]:
        return tuple(m for m in range(self.size) if m.bit_count() == k)

    def blade_name(self, mask: int) -> str:
        """``"1"`` for the scalar, else ``"e"`` + the labels in bit order, e.g. ``"e13"``, ``"e0inf"``."""
        if mask == 0:
            return "1"
        return "e" + "".join(self.vector_labels[i] for i in range(self.dimension) if mask >> i & 1)

    @cached_property
    def blade_index(self) -> dict[str, int]:
        """Blade name -> bitmask."""
        return {self.blade_name(m): m for m in range(self.size)}

    def blade(self, name: str) -> int:
        """Bitmask of a blade given by name (``"e12"``, ``"e0inf"``, ``"1"``)."""
        try:
            return self.blade_index[name]
        except KeyError:
            raise KeyError(f"algebra {self.name!r} has no blade {name!r}") from None

    def __repr__(self) -> str:
        p, q, r = self.signature
        return f"Algebra({self.name!r}, G({p},{q},{r}), basis={self.vector_labels})"


# ---------------------------------------------------------------------------------------------
# Presets
# ---------------------------------------------------------------------------------------------
_HALF = sympy.Rational(1, 2)


def _identity_rows(n: int) -> tuple[tuple[Exact, ...], ...]:
    return tuple(tuple(sympy.Integer(int(i == j)) for j in range(n)) for i in range(n))


def from_signature(p: int, q: int, r: int = 0, name: str | None = None) -> Algebra:
    """Orthonormal G(p, q, r). Null vectors come first and are labelled from 0 (as in PGA),
    then the p positive and the q negative ones, labelled on from 1."""
    if min(p, q, r) < 0 or p + q + r == 0:
        raise ValueError(f"invalid signature G({p},{q},{r})")
    if p + q + r > 9:
        raise ValueError("gagen labels basis vectors with single digits: at most 9 of them")
    squares = (0,) * r + (1,) * p + (-1,) * q
    start = 0 if r else 1
    labels = tuple(str(start + i) for i in range(p + q + r))
    return Algebra(name or f"g{p}{q}{r}", labels, squares, _identity_rows(p + q + r))


@cache
def ga3d() -> Algebra:
    """Euclidean 3D algebra G(3,0): e1, e2, e3."""
    return from_signature(3, 0, 0, name="ga3d")


@cache
def pga3d() -> Algebra:
    """Projective 3D algebra G(3,0,1): e0 (squares to 0), e1, e2, e3."""
    return from_signature(3, 0, 1, name="pga3d")


def _conformal(n_euclid: int, name: str) -> Algebra:
    """Conformal algebra over R^n with the null basis e0 = (e- - e+)/2, einf = e+ + e-.

    Bit order: e0, e1..en, einf, so that e0.einf = -1 and e0^2 = einf^2 = 0.
    Frame: e1..en, e+ (squares +1), e- (squares -1).
    """
    m = n_euclid + 2
    zero, one = sympy.Integer(0), sympy.Integer(1)
    e0 = [zero] * n_euclid + [-_HALF, _HALF]
    einf = [zero] * n_euclid + [one, one]
    euclid = [[one if j == i else zero for j in range(m)] for i in range(n_euclid)]
    frame = (tuple(e0), *(tuple(row) for row in euclid), tuple(einf))
    labels = ("0", *(str(i + 1) for i in range(n_euclid)), "inf")
    return Algebra(name, labels, (1,) * (n_euclid + 1) + (-1,), frame)


@cache
def cga3d() -> Algebra:
    """3D conformal geometric algebra G(4,1) in the null basis e0, e1, e2, e3, einf (gafro's order)."""
    return _conformal(3, "cga3d")


@cache
def cga2d() -> Algebra:
    """2D conformal geometric algebra G(3,1) in the null basis e0, e1, e2, einf."""
    return _conformal(2, "cga2d")


PRESETS = {"cga3d": cga3d, "cga2d": cga2d, "pga3d": pga3d, "ga3d": ga3d}


def preset(name: str) -> Algebra:
    """Algebra by preset name: one of ``cga3d``, ``cga2d``, ``pga3d``, ``ga3d``."""
    try:
        return PRESETS[name]()
    except KeyError:
        raise KeyError(f"unknown algebra preset {name!r}; known: {', '.join(sorted(PRESETS))}") from None
