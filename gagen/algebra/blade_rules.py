"""The compiler's blade rules: products of basis blades as exact sparse sums, for any bilinear form.

Blades are outer products of basis vectors (bitmasks, see ``signature``). The geometric product
is derived directly in the algebra's own basis from the bilinear form by Chevalley's recursion

    a e_B = a ⌋ e_B + a ∧ e_B,       e_{a ∧ R} = a e_R − a ⌋ e_R,

so a non-diagonal metric (the null basis e0, e∞ of CGA) or a degenerate one (PGA) needs no change
of basis; entries are exact sympy numbers. Every other bilinear product is a grade selection of the
geometric one, and every unary operation (reverse, involutions, duals) is a signed blade map.
Tables are memoised per algebra; ``rules_for(algebra)`` returns the shared instance.

Entries are tuples of ``(blade, coefficient)`` with non-zero exact coefficients, sorted by blade.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache

import sympy

from gagen.algebra.scalars import Exact
from gagen.algebra.signature import Algebra

Entries = tuple[tuple[int, Exact], ...]

_ZERO = sympy.Integer(0)
_ONE = sympy.Integer(1)


def _bits(mask: int) -> list[int]:
    return [i for i in range(mask.bit_length()) if mask >> i & 1]


def _freeze(acc: dict[int, Exact]) -> Entries:
    return tuple((b, c) for b, c in sorted(acc.items()) if c != 0)


class BladeRules:
    """Exact product tables of one algebra, derived lazily and memoised."""

    def __init__(self, algebra: Algebra) -> None:
        self.algebra = algebra
        self._g = algebra.metric
        self._gp: dict[tuple[int, int], Entries] = {}
        self._tables: dict[str, dict[tuple[int, int], Entries]] = {}

    # -- vector rules ------------------------------------------------------------------------------
    def _vector_outer(self, i: int, blade: int) -> tuple[int, Exact] | None:
        """e_i ∧ e_blade as (blade, ±1), or None if e_i is already in it."""
        if blade >> i & 1:
            return None
        lower = (blade & ((1 << i) - 1)).bit_count()  # swaps to move e_i into place
        return blade | 1 << i, (_ONE if lower % 2 == 0 else -_ONE)

    def _vector_contract(self, i: int, blade: int) -> dict[int, Exact]:
        """e_i ⌋ e_blade = Σ_k (−1)^k (e_i · b_k) e_{blade without b_k}."""
        out: dict[int, Exact] = {}
        for k, j in enumerate(_bits(blade)):
            g = self._g[i][j]
            if g != 0:
                out[blade & ~(1 << j)] = out.get(blade & ~(1 << j), _ZERO) + (g if k % 2 == 0 else -g)
        return out

    def _vector_times(self, i: int, x: dict[int, Exact]) -> dict[int, Exact]:
        """e_i X for a multivector X given as {blade: coefficient}."""
        out: dict[int, Exact] = {}
        for blade, c in x.items():
            wedge = self._vector_outer(i, blade)
            if wedge is not None:
                out[wedge[0]] = out.get(wedge[0], _ZERO) + wedge[1] * c
            for b, v in self._vector_contract(i, blade).items():
                out[b] = out.get(b, _ZERO) + v * c
        return out

    # -- geometric product of blades ---------------------------------------------------------------
    def gp(self, a: int, b: int) -> Entries:
        """e_a e_b as exact sparse sum."""
        key = (a, b)
        if key not in self._gp:
            self._gp[key] = _freeze(self._gp_dict(a, b))
        return self._gp[key]

    def _gp_dict(self, a: int, b: int) -> dict[int, Exact]:
        if a == 0:
            return {b: _ONE}
        low = (a & -a).bit_length() - 1
        rest = a & ~(1 << low)
        # e_a = e_low ∧ e_rest = e_low e_rest − e_low ⌋ e_rest
        out = self._vector_times(low, dict(self.gp(rest, b)))
        for r, c in self._vector_contract(low, rest).items():
            for blade, v in self.gp(r, b):
                out[blade] = out.get(blade, _ZERO) - c * v
        return out

    # -- grade-selected bilinear products ------------------------------------------------------------
    def _graded(self, a: int, b: int, grade: int | None) -> Entries:
        if grade is None or grade < 0:
            return ()
        return tuple((blade, c) for blade, c in self.gp(a, b) if blade.bit_count() == grade)

    def op(self, a: int, b: int) -> Entries:
        """Outer product: metric-free, a reordering sign on disjoint blades."""
        if a & b:
            return ()
        swaps = sum((a >> i & 1) * (b & ((1 << i) - 1)).bit_count() for i in range(a.bit_length()))
        return ((a | b, _ONE if swaps % 2 == 0 else -_ONE),)

    def lc(self, a: int, b: int) -> Entries:
        return self._graded(a, b, b.bit_count() - a.bit_count())

    def rc(self, a: int, b: int) -> Entries:
        return self._graded(a, b, a.bit_count() - b.bit_count())

    def sp(self, a: int, b: int) -> Entries:
        return self._graded(a, b, 0)

    def commutator(self, a: int, b: int) -> Entries:
        acc: dict[int, Exact] = {}
        half = sympy.Rational(1, 2)
        for blade, c in self.gp(a, b):
            acc[blade] = acc.get(blade, _ZERO) + half * c
        for blade, c in self.gp(b, a):
            acc[blade] = acc.get(blade, _ZERO) - half * c
        return _freeze(acc)

    def table(self, kind: str) -> Callable[[int, int], Entries]:
        """Memoised blade-pair rule of a bilinear product: gp, op, lc, rc, sp, commutator."""
        rule = {"gp": self.gp, "op": self.op, "lc": self.lc, "rc": self.rc, "sp": self.sp,
                "commutator": self.commutator}[kind]
        memo = self._tables.setdefault(kind, {})

        def lookup(a: int, b: int) -> Entries:
            key = (a, b)
            if key not in memo:
                memo[key] = rule(a, b)
            return memo[key]

        return lookup

    # -- unary blade maps --------------------------------------------------------------------------
    @staticmethod
    def reverse_sign(blade: int) -> int:
        k = blade.bit_count()
        return -1 if (k * (k - 1) // 2) % 2 else 1

    @staticmethod
    def involute_sign(blade: int) -> int:
        return -1 if blade.bit_count() % 2 else 1

    @cache  # noqa: B019 - one instance per algebra, kept for the process lifetime
    def pseudoscalar_inverse(self) -> Entries:
        """I⁻¹ = I~ / (I I~); only for non-degenerate algebras."""
        i = self.algebra.pseudoscalar
        norm = dict(self.gp(i, i)).get(0, _ZERO) * self.reverse_sign(i)
        if norm == 0 or len(self.gp(i, i)) != 1:
            raise ValueError(f"algebra {self.algebra.name!r} is degenerate: its pseudoscalar has no inverse")
        return ((i, sympy.Integer(self.reverse_sign(i)) / norm),)

    def _complement(self, blade: int) -> tuple[int, Exact]:
        """Right complement: e_A ∧ c(e_A) = I."""
        comp = self.algebra.pseudoscalar & ~blade
        ((_, sign),) = self.op(blade, comp)
        return comp, sign

    def dual(self, blade: int) -> Entries:
        """X* = X I⁻¹, or the right complement in degenerate algebras."""
        if self.algebra.is_degenerate:
            return (self._complement(blade),)
        ((i, c),) = self.pseudoscalar_inverse()
        return tuple((b, v * c) for b, v in self.gp(blade, i))

    def undual(self, blade: int) -> Entries:
        """Inverse of ``dual``: X I, or the inverse right complement."""
        if self.algebra.is_degenerate:
            source = self.algebra.pseudoscalar & ~blade
            _, sign = self._complement(source)
            return ((source, 1 / sign),)
        return self.gp(blade, self.algebra.pseudoscalar)


@cache
def rules_for(algebra: Algebra) -> BladeRules:
    """The shared, memoised rules of an algebra."""
    return BladeRules(algebra)
