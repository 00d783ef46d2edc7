"""Dense numpy multivectors: the reference side of the multivector protocol (``gagen.algebra.protocol``).

A :class:`MultiVector` is an algebra and a float64 array of ``2**n`` coefficients indexed by blade
bitmask. Every product is a contraction with a dense table from :mod:`gagen.interp.frame`; nothing is
sparse, nothing is clever, so that the compiler can be checked against it.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, cast

import numpy as np

from gagen.algebra.signature import Algebra
from gagen.interp.frame import Tables, tables
from gagen.interp.scalar_math import INTERP_MATH

BladeKey = int | str  # a bitmask or a blade name such as "e12", "e0inf", "1"


def _mask(algebra: Algebra, blade: BladeKey) -> int:
    if isinstance(blade, str):
        return algebra.blade(blade)
    mask = int(blade)
    if not 0 <= mask < algebra.size:
        raise KeyError(f"algebra {algebra.name!r} has no blade {blade!r}")
    return mask


def _is_scalar(x: Any) -> bool:
    return isinstance(x, numbers.Real) or (isinstance(x, np.ndarray) and x.ndim == 0)


class MultiVector:
    """A multivector of ``algebra`` with dense float64 coefficients ``coeffs[mask]``."""

    __slots__ = ("algebra", "coeffs")
    __array_ufunc__ = None  # numpy scalars defer to our reflected operators

    def __init__(self, algebra: Algebra, coeffs: Sequence[float] | np.ndarray) -> None:
        values = np.array(coeffs, dtype=np.float64)
        if values.shape != (algebra.size,):
            raise ValueError(f"{algebra.name} needs {algebra.size} coefficients, got shape {values.shape}")
        self.algebra = algebra
        self.coeffs = values

    # -- construction ---------------------------------------------------------------------------------
    @classmethod
    def zero(cls, algebra: Algebra) -> MultiVector:
        return cls(algebra, np.zeros(algebra.size))

    @classmethod
    def from_blades(cls, algebra: Algebra, coefficients: Mapping[BladeKey, Any]) -> MultiVector:
        """``from_blades(cga3d(), {"e0": 1, "e12": 0.5, 16: 2})``; repeated blades add up."""
        values = np.zeros(algebra.size)
        for blade, c in coefficients.items():
            values[_mask(algebra, blade)] += float(c)
        return cls(algebra, values)

    def make(self, coefficients: Mapping[BladeKey, Any]) -> MultiVector:
        return MultiVector.from_blades(self.algebra, coefficients)

    def _like(self, coeffs: np.ndarray) -> MultiVector:
        return MultiVector(self.algebra, coeffs)

    @property
    def _tables(self) -> Tables:
        return tables(self.algebra)

    @property
    def math(self) -> Any:
        """Scalar functions (sqrt, sin, atan2, ..., lt, if_else) for this implementation's floats."""
        return INTERP_MATH

    # -- coefficients ---------------------------------------------------------------------------------
    def __getitem__(self, blade: BladeKey) -> float:
        return float(self.coeffs[_mask(self.algebra, blade)])

    def scalar(self) -> float:
        return float(self.coeffs[0])

    def __repr__(self) -> str:
        body = ""
        for m, c in enumerate(self.coeffs):
            if c != 0:
                term = f"{abs(c):.12g}" + ("" if m == 0 else f" {self.algebra.blade_name(m)}")
                body += (" - " if c < 0 else " + ") + term if body else ("-" if c < 0 else "") + term
        return f"MultiVector({self.algebra.name}: {body or 0})"

    # -- linear structure -----------------------------------------------------------------------------
    def _coerce(self, other: Any) -> MultiVector | None:
        """``other`` as a multivector of this algebra (a scalar lifted), None when it is neither."""
        if isinstance(other, MultiVector):
            if other.algebra != self.algebra:
                raise TypeError(f"cannot mix {self.algebra.name} and {other.algebra.name} multivectors")
            return other
        if _is_scalar(other):
            return MultiVector.from_blades(self.algebra, {0: other})
        return None

    def _require(self, other: Any) -> MultiVector:
        o = self._coerce(other)
        if o is None:
            raise TypeError(f"cannot combine a multivector with {type(other).__name__}")
        return o

    def __add__(self, other: Any) -> MultiVector:
        o = self._coerce(other)
        return NotImplemented if o is None else self._like(self.coeffs + o.coeffs)

    __radd__ = __add__

    def __sub__(self, other: Any) -> MultiVector:
        o = self._coerce(other)
        return NotImplemented if o is None else self._like(self.coeffs - o.coeffs)

    def __rsub__(self, other: Any) -> MultiVector:
        o = self._coerce(other)
        return NotImplemented if o is None else self._like(o.coeffs - self.coeffs)

    def __neg__(self) -> MultiVector:
        return self._like(-self.coeffs)

    def __truediv__(self, scalar: Any) -> MultiVector:
        if not _is_scalar(scalar):
            return NotImplemented
        if scalar == 0:
            raise ZeroDivisionError("multivector divided by zero")
        return self._like(self.coeffs / float(scalar))

    # -- products -------------------------------------------------------------------------------------
    def _product(self, table: np.ndarray, other: Any) -> MultiVector:
        o = self._require(other)
        # result[k] = Σ_ij self[i] other[j] table[i, j, k]
        n = table.shape[0]
        return self._like(o.coeffs @ (self.coeffs @ table.reshape(n, n * n)).reshape(n, n))

    def gp(self, other: Any) -> MultiVector:
        """Geometric product."""
        return self._product(self._tables.gp, other)

    def op(self, other: Any) -> MultiVector:
        """Outer product."""
        return self._product(self._tables.op, other)

    def lc(self, other: Any) -> MultiVector:
        """Left contraction: ⟨⟨A⟩_r ⟨B⟩_s⟩_{s−r}, zero when r > s."""
        return self._product(self._tables.lc, other)

    def rc(self, other: Any) -> MultiVector:
        """Right contraction: ⟨⟨A⟩_r ⟨B⟩_s⟩_{r−s}, zero when s > r."""
        return self._product(self._tables.rc, other)

    def inner(self, other: Any) -> MultiVector:
        """The inner product of gagen = left contraction."""
        return self.lc(other)

    def sp(self, other: Any) -> float:
        """Scalar product ⟨A B⟩₀."""
        return self.gp(other).scalar()

    def commutator(self, other: Any) -> MultiVector:
        """½(AB − BA)."""
        o = self._require(other)
        return (self.gp(o) - o.gp(self)) / 2

    def regressive(self, other: Any) -> MultiVector:
        """Regressive product (meet): undual(dual(A) ∧ dual(B))."""
        return self.dual().op(self._require(other).dual()).undual()

    def __mul__(self, other: Any) -> MultiVector:
        if _is_scalar(other):
            return self._like(self.coeffs * float(other))
        return self.gp(other) if isinstance(other, MultiVector) else NotImplemented

    def __rmul__(self, other: Any) -> MultiVector:
        if _is_scalar(other):
            return self._like(float(other) * self.coeffs)
        return NotImplemented

    def __xor__(self, other: Any) -> MultiVector:
        return self.op(other)

    def __rxor__(self, other: Any) -> MultiVector:
        o = self._coerce(other)
        return NotImplemented if o is None else o.op(self)

    def __or__(self, other: Any) -> MultiVector:
        return self.lc(other)

    def __ror__(self, other: Any) -> MultiVector:
        o = self._coerce(other)
        return NotImplemented if o is None else o.lc(self)

    def __and__(self, other: Any) -> MultiVector:
        return self.regressive(other)

    def __rand__(self, other: Any) -> MultiVector:
        o = self._coerce(other)
        return NotImplemented if o is None else o.regressive(self)

    def __invert__(self) -> MultiVector:
        return self.reverse()

    # -- unary ----------------------------------------------------------------------------------------
    def _grade_sign(self, sign_of_grade: Any) -> MultiVector:
        return self._like(self.coeffs * sign_of_grade(self._tables.grades))

    def reverse(self) -> MultiVector:
        """(−1)^(k(k−1)/2) on grade k."""
        return self._grade_sign(lambda k: (-1.0) ** (k * (k - 1) // 2))

    def involute(self) -> MultiVector:
        """Grade involution: (−1)^k on grade k."""
        return self._grade_sign(lambda k: (-1.0) ** k)

    def conjugate(self) -> MultiVector:
        """Clifford conjugate: reverse of the grade involution."""
        return self.involute().reverse()

    def grade(self, k: int | Iterable[int]) -> MultiVector:
        """Grade projection onto one grade or several."""
        keep = [int(k)] if isinstance(k, numbers.Integral) else list(cast(Iterable[int], k))
        return self._like(np.where(np.isin(self._tables.grades, keep), self.coeffs, 0.0))

    @property
    def grades(self) -> frozenset[int]:
        """Grades with a non-zero coefficient."""
        return frozenset(int(g) for g in self._tables.grades[self.coeffs != 0])

    def dual(self) -> MultiVector:
        """X I⁻¹, or the right complement in degenerate algebras."""
        return self._like(self._tables.dual @ self.coeffs)

    def undual(self) -> MultiVector:
        """Inverse of :meth:`dual`."""
        return self._like(self._tables.undual @ self.coeffs)

    def norm_squared(self) -> float:
        """⟨X X~⟩₀."""
        return self.sp(self.reverse())

    def inverse(self) -> MultiVector:
        """X~ / ⟨X X~⟩₀ (versors and blades)."""
        return self.reverse() / self.norm_squared()

    def normalized(self) -> MultiVector:
        """X / sqrt(|⟨X X~⟩₀|) (versors and blades)."""
        return self / math.sqrt(abs(self.norm_squared()))

    def sandwich(self, x: MultiVector) -> MultiVector:
        """V x V~, restricted to the grades present in x."""
        x = self._require(x)
        return self.gp(x).gp(self.reverse()).grade(x.grades)

    # -- comparison helper (tests) --------------------------------------------------------------------
    def allclose(self, other: Any, rtol: float = 1e-12, atol: float = 0.0) -> bool:
        """Coefficient-wise closeness, tolerance relative to the largest coefficient of either side."""
        o = self._require(other)
        scale = max(float(np.max(np.abs(self.coeffs))), float(np.max(np.abs(o.coeffs))))
        return bool(np.max(np.abs(self.coeffs - o.coeffs)) <= atol + rtol * scale)


def conformal_point(algebra: Algebra, x: Sequence[float]) -> MultiVector:
    """P(x) = e0 + x + ½|x|² e∞ in a conformal algebra (cga3d, cga2d)."""
    labels = algebra.vector_labels
    if labels[0] != "0" or labels[-1] != "inf":
        raise ValueError(f"{algebra.name} is not a conformal algebra with basis e0, ..., einf")
    x = [float(v) for v in x]
    if len(x) != algebra.dimension - 2:
        raise ValueError(f"{algebra.name} points have {algebra.dimension - 2} coordinates, got {len(x)}")
    blades: dict[BladeKey, float] = {"e0": 1.0, "einf": 0.5 * sum(v * v for v in x)}
    blades.update({1 << (i + 1): v for i, v in enumerate(x)})
    return MultiVector.from_blades(algebra, blades)
