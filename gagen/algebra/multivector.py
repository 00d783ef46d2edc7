"""Sparse symbolic multivectors: the compiler's side of the multivector protocol.

A :class:`SparseMultivector` stores only the blades that may be non-zero, each with a coefficient
that is an exact constant or a ``Poly`` over native atoms of its scalar backend (a
:class:`~gagen.algebra.scalars.ScalarField`: ``gagen.symbolic``'s CasADi SX or sympy backend). A
bilinear product visits only pairs of stored blades whose product table entry is non-empty and sums
the terms of each output blade in the scalar layer, so exact constants fold and identical monomials
merge. Blades whose coefficient ends up exactly zero are dropped: the support of every result is what
the sparsity analysis proves may be non-zero.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from typing import TypeAlias

import sympy

from gagen.algebra.blade_rules import BladeRules, Entries, rules_for
from gagen.algebra.protocol import BladeKey
from gagen.algebra.scalars import ZERO, Math, Scalar, ScalarField
from gagen.algebra.signature import Algebra

Operand: TypeAlias = "SparseMultivector | Scalar"  # the other side of a product or a sum


class SparseMultivector:
    """Multivector with a proven-sparse support over a scalar backend."""

    __slots__ = ("algebra", "backend", "coeffs")
    __array_priority__ = 1000  # keep numpy scalars from broadcasting over us

    def __init__(self, algebra: Algebra, backend: ScalarField, coeffs: Mapping[int, Scalar]) -> None:
        self.algebra = algebra
        self.backend = backend
        lifted = {b: backend.lift(c) for b, c in coeffs.items()}
        self.coeffs: dict[int, Scalar] = {
            b: lifted[b] for b in sorted(lifted) if not backend.is_zero(lifted[b])
        }

    # -- construction --------------------------------------------------------------------------------
    @classmethod
    def symbolic(cls, algebra: Algebra, backend: ScalarField, name: str,
                 blades: Iterable[BladeKey] | None = None) -> SparseMultivector:
        """A multivector whose coefficients on ``blades`` (default: all) are fresh symbols."""
        masks = [_mask(algebra, b) for b in (range(algebra.size) if blades is None else blades)]
        masks = sorted(set(masks))
        labels = [algebra.blade_name(m).replace("e", "", 1) if m else "s" for m in masks]
        return cls(algebra, backend, dict(zip(masks, backend.symbols(name, labels), strict=True)))

    def make(self, coefficients: Mapping[BladeKey, Scalar]) -> SparseMultivector:
        return SparseMultivector(self.algebra, self.backend,
                                 {_mask(self.algebra, b): c for b, c in coefficients.items()})

    def _like(self, coeffs: Mapping[int, Scalar]) -> SparseMultivector:
        return SparseMultivector(self.algebra, self.backend, coeffs)

    @property
    def math(self) -> Math:
        """sqrt, sin, cos, atan2, ... on scalars of this multivector's backend."""
        return self.backend.math

    # -- coefficients --------------------------------------------------------------------------------
    @property
    def support(self) -> tuple[int, ...]:
        """Blades that may be non-zero, in bitmask order."""
        return tuple(self.coeffs)

    def __getitem__(self, blade: BladeKey) -> Scalar:
        return self.coeffs.get(_mask(self.algebra, blade), ZERO)

    def scalar(self) -> Scalar:
        return self.coeffs.get(0, ZERO)

    def __repr__(self) -> str:
        if not self.coeffs:
            return "0"
        return " + ".join(f"({c})*{self.algebra.blade_name(b)}" for b, c in self.coeffs.items())

    # -- linear structure --------------------------------------------------------------------------
    def _coerce(self, other: Operand) -> SparseMultivector:
        if isinstance(other, SparseMultivector):
            if other.algebra != self.algebra or other.backend is not self.backend:
                raise TypeError("multivectors of different algebras or backends do not mix")
            return other
        return self._like({0: self.backend.lift(other)})

    def __add__(self, other: Operand) -> SparseMultivector:
        other = self._coerce(other)
        blades = sorted(set(self.coeffs) | set(other.coeffs))
        return self._like({b: self.backend.add(self[b], other[b]) for b in blades})

    __radd__ = __add__

    def __sub__(self, other: Operand) -> SparseMultivector:
        return self + (-self._coerce(other))

    def __rsub__(self, other: Operand) -> SparseMultivector:
        return self._coerce(other) - self

    def __neg__(self) -> SparseMultivector:
        return self._like({b: self.backend.neg(c) for b, c in self.coeffs.items()})

    def scale(self, s: Scalar) -> SparseMultivector:
        """Multiply every coefficient by a scalar."""
        return self._like({b: self.backend.mul(s, c) for b, c in self.coeffs.items()})

    def __truediv__(self, s: Scalar) -> SparseMultivector:
        return self._like({b: self.backend.div(c, s) for b, c in self.coeffs.items()})

    # -- bilinear products ---------------------------------------------------------------------------
    @property
    def _rules(self) -> BladeRules:
        return rules_for(self.algebra)

    def _bilinear(self, other: Operand, kind: str,
                  keep: Callable[[int], bool] | None = None) -> SparseMultivector:
        other = self._coerce(other)
        rule = self._rules.table(kind)
        mul = self.backend.mul
        acc: dict[int, list[Scalar]] = {}
        for a, ca in self.coeffs.items():
            for b, cb in other.coeffs.items():
                entries = rule(a, b)
                if not entries:
                    self.backend.removed["sparsity pruning"] += 1  # a blade pair that cannot contribute
                    continue
                product = mul(ca, cb)
                for blade, c in entries:
                    if keep is None or keep(blade):
                        acc.setdefault(blade, []).append(mul(c, product))
        return self._like({b: self.backend.add(*terms) for b, terms in sorted(acc.items())})

    def gp(self, other: Operand) -> SparseMultivector:
        return self._bilinear(other, "gp")

    def op(self, other: Operand) -> SparseMultivector:
        return self._bilinear(other, "op")

    def lc(self, other: Operand) -> SparseMultivector:
        return self._bilinear(other, "lc")

    def rc(self, other: Operand) -> SparseMultivector:
        return self._bilinear(other, "rc")

    inner = lc

    def sp(self, other: Operand) -> Scalar:
        return self._bilinear(other, "sp").scalar()

    def commutator(self, other: Operand) -> SparseMultivector:
        return self._bilinear(other, "commutator")

    def regressive(self, other: Operand) -> SparseMultivector:
        return self.dual().op(self._coerce(other).dual()).undual()

    def __mul__(self, other: Operand) -> SparseMultivector:
        if isinstance(other, SparseMultivector):
            return self.gp(other)
        return self.scale(other)

    def __rmul__(self, other: Operand) -> SparseMultivector:
        return self.scale(other)

    __xor__ = op
    __or__ = lc
    __and__ = regressive

    # -- unary ----------------------------------------------------------------------------------------
    def _signed(self, sign: Callable[[int], int]) -> SparseMultivector:
        return self._like({b: (c if sign(b) > 0 else self.backend.neg(c)) for b, c in self.coeffs.items()})

    def _linear_map(self, blade_map: Callable[[int], Entries]) -> SparseMultivector:
        acc: dict[int, list[Scalar]] = {}
        for a, ca in self.coeffs.items():
            for blade, c in blade_map(a):
                acc.setdefault(blade, []).append(self.backend.mul(c, ca))
        return self._like({b: self.backend.add(*terms) for b, terms in sorted(acc.items())})

    def reverse(self) -> SparseMultivector:
        return self._signed(BladeRules.reverse_sign)

    __invert__ = reverse

    def involute(self) -> SparseMultivector:
        return self._signed(BladeRules.involute_sign)

    def conjugate(self) -> SparseMultivector:
        return self._signed(lambda b: BladeRules.reverse_sign(b) * BladeRules.involute_sign(b))

    def grade(self, k: int | Iterable[int]) -> SparseMultivector:
        grades = {k} if isinstance(k, int) else set(k)
        return self._like({b: c for b, c in self.coeffs.items() if b.bit_count() in grades})

    @property
    def grades(self) -> frozenset[int]:
        """Grades present in the support."""
        return frozenset(b.bit_count() for b in self.coeffs)

    def dual(self) -> SparseMultivector:
        return self._linear_map(self._rules.dual)

    def undual(self) -> SparseMultivector:
        return self._linear_map(self._rules.undual)

    # -- versors and blades ---------------------------------------------------------------------------
    def norm_squared(self) -> Scalar:
        return self.sp(self.reverse())

    def inverse(self) -> SparseMultivector:
        inverse: SparseMultivector = self.reverse() / self.norm_squared()
        return inverse

    def normalized(self) -> SparseMultivector:
        n2 = self.norm_squared()
        return self.scale(self.backend.div(1, self.backend.call("sqrt", self.backend.call("fabs", n2))))

    def sandwich(self, x: Operand) -> SparseMultivector:
        """⟨V X Ṽ⟩ on the grades of X, in one of two exact forms of the same polynomial:

        - ``(V X) Ṽ``, the two products one after the other;
        - ``X (V Ṽ) + 2 (½(V X − X V)) Ṽ`` (V X Ṽ − X V Ṽ = (V X − X V) Ṽ): the commutator's
          coefficients are short sums shared by every output, and for a unit versor the ``X ⟨V Ṽ⟩₀``
          part cancels exactly against a correction ``X (1 − ‖V‖²)`` (``gagen.symbolic.backend``),
          leaving kingdon's ``X + 2 (½[V, X]) Ṽ``.

        The second form is weighed (the operations of each graph, ``graph_cost``) only when every
        coefficient of V and X is a free symbol (a kernel's input multivectors): over computed versors
        (the kinematic chains) the two products stay, as their derivatives are cheaper there."""
        x_ = self._coerce(x)
        grades = x_.grades

        def keep(b: int) -> bool:
            return b.bit_count() in grades

        backend = self.backend
        rev = self.reverse()

        def two_products() -> SparseMultivector:
            return self.gp(x_)._bilinear(rev, "gp", keep=keep)

        given = [*self.coeffs.values(), *x_.coeffs.values()]
        if backend.expand_all or not all(backend.is_symbol(c) for c in given):
            return two_products()

        def commutator() -> SparseMultivector:
            half = (self.gp(x_) - x_.gp(self)).scale(sympy.Rational(1, 2))
            return x_._bilinear(self.gp(rev), "gp", keep=keep) + half._bilinear(rev, "gp", keep=keep).scale(2)

        removed = backend.removed.copy()
        best: tuple[int, SparseMultivector, Counter[str]] | None = None
        for form in (two_products, commutator):
            backend.removed = removed.copy()
            result = form()
            cost = backend.graph_cost([*given, *result.coeffs.values()])
            if best is None or cost < best[0]:
                best = (cost, result, backend.removed)
        assert best is not None
        backend.removed = best[2]
        return best[1]


def _mask(algebra: Algebra, blade: BladeKey) -> int:
    if isinstance(blade, str):
        return algebra.blade(blade)
    if not 0 <= blade < algebra.size:
        raise KeyError(f"algebra {algebra.name!r} has no blade with bitmask {blade}")
    return int(blade)
