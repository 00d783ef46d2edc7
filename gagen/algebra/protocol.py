"""The multivector API that every formula in ``gagen.model`` is written against.

Two classes implement it: ``gagen.interp.MultiVector`` (dense numpy, the reference interpreter)
and ``gagen.algebra.SparseMultivector`` (sparse, symbolic, the compiler). A formula written once
against this protocol runs on numbers through the first and flattens to CasADi SX through the
second; the tests hold the two against each other.

Conventions (both implementations):

* ``a * b`` geometric product (or scaling when one side is a scalar), ``a ^ b`` outer product,
  ``a | b`` the inner product, which in gagen is the **left contraction** ``a ⌋ b`` (it equals the
  Hestenes inner product whenever grade(a) <= grade(b), which covers every use in the papers,
  and unlike it does not vanish for scalars), ``a & b`` regressive product (meet),
  ``~a`` reverse.
* ``dual(X) = X I⁻¹`` and ``undual(X) = X I`` in non-degenerate algebras, with
  ``I = e_1 ∧ … ∧ e_n`` the outer product of the basis vectors in bit order (for CGA
  ``I = e0∧e1∧e2∧e3∧e∞``, ``I² = −1``). In degenerate algebras (PGA), where ``I`` has no inverse,
  ``dual`` is the metric-free right complement: ``e_A ∧ dual(e_A) = I``; ``undual`` inverts it.
* ``regressive(A, B) = undual(dual(A) ∧ dual(B))`` [COOP Eq. 5].
* ``commutator(A, B) = ½(AB − BA)``.
* ``inverse()`` and ``normalized()`` are for versors and blades, where ``X X~`` is a scalar:
  ``X⁻¹ = X~ / ⟨X X~⟩₀``, ``X̄ = X / sqrt(|⟨X X~⟩₀|)``.
* ``sandwich(X) = V X V~`` for a versor ``V``; it keeps only the grades present in ``X`` (a versor
  preserves grade, so the others are zero up to rounding).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Protocol, Self, runtime_checkable

from gagen.algebra.scalars import Math, Scalar
from gagen.algebra.signature import Algebra

BladeKey = int | str  # a bitmask or a blade name such as "e12", "e0inf", "1"


@runtime_checkable
class Multivector(Protocol):
    algebra: Algebra

    @property
    def math(self) -> Math:
        """Namespace of scalar functions (sqrt, sin, cos, tan, asin, acos, atan, atan2, exp, log,
        sinh, cosh, tanh, asinh, acosh, atanh, fabs) for this implementation's scalars, plus
        ``lt(a, b)`` (a < b) and ``if_else(cond, a, b)`` for guarded, branch-free special cases, and
        ``shared(a)``: the same value, computed once where it is reused (identity on numbers)."""

    # -- construction of constants of the same kind (same backend) ------------------------------
    def make(self, coefficients: Mapping[BladeKey, Scalar]) -> Self:
        """A multivector of the same kind with the given coefficients (others zero)."""

    # -- coefficients ------------------------------------------------------------------------------
    def __getitem__(self, blade: BladeKey) -> Scalar:
        """Coefficient of one blade (zero if absent)."""

    @property
    def grades(self) -> frozenset[int]:
        """Grades present: non-zero coefficients (interpreter) or the proven support (compiler)."""

    def scalar(self) -> Scalar:
        """The grade-0 coefficient ⟨X⟩₀ as a scalar."""

    # -- linear structure ---------------------------------------------------------------------------
    def __add__(self, other: Self | Scalar) -> Self: ...
    def __radd__(self, other: Scalar) -> Self: ...
    def __sub__(self, other: Self | Scalar) -> Self: ...
    def __rsub__(self, other: Scalar) -> Self: ...
    def __neg__(self) -> Self: ...
    def __truediv__(self, scalar: Scalar) -> Self: ...

    # -- products ---------------------------------------------------------------------------------
    def __mul__(self, other: Self | Scalar) -> Self: ...
    def __rmul__(self, other: Scalar) -> Self: ...
    def __xor__(self, other: Self) -> Self: ...
    def __or__(self, other: Self) -> Self: ...
    def __and__(self, other: Self) -> Self: ...
    def __invert__(self) -> Self: ...

    def gp(self, other: Self) -> Self:
        """Geometric product."""

    def op(self, other: Self) -> Self:
        """Outer product."""

    def lc(self, other: Self) -> Self:
        """Left contraction: ⟨⟨A⟩_r ⟨B⟩_s⟩_{s−r}, zero when r > s."""

    def rc(self, other: Self) -> Self:
        """Right contraction: ⟨⟨A⟩_r ⟨B⟩_s⟩_{r−s}, zero when s > r."""

    def inner(self, other: Self) -> Self:
        """The inner product of gagen = left contraction."""

    def sp(self, other: Self) -> Scalar:
        """Scalar product ⟨A B⟩₀, as a scalar."""

    def commutator(self, other: Self) -> Self:
        """½(AB − BA)."""

    def regressive(self, other: Self) -> Self:
        """Regressive product (meet): undual(dual(A) ∧ dual(B))."""

    # -- unary -------------------------------------------------------------------------------------
    def reverse(self) -> Self: ...
    def involute(self) -> Self:
        """Grade involution: (−1)^k on grade k."""

    def conjugate(self) -> Self:
        """Clifford conjugate: reverse of the grade involution."""

    def grade(self, k: int | Iterable[int]) -> Self:
        """Grade projection onto one grade or several."""

    def dual(self) -> Self: ...
    def undual(self) -> Self: ...
    def norm_squared(self) -> Scalar:
        """⟨X X~⟩₀ as a scalar."""

    def inverse(self) -> Self:
        """X~ / ⟨X X~⟩₀ (versors and blades)."""

    def normalized(self) -> Self:
        """X / sqrt(|⟨X X~⟩₀|) (versors and blades)."""

    def sandwich(self, x: Self) -> Self:
        """V x V~ for a versor V, restricted to the grades of x."""
