"""The scalars that multivectors carry, named once for both paths, and what a sparse multivector asks
of the scalar layer under it.

A formula written against the multivector protocol (``gagen.algebra.protocol``) meets the scalars of
two paths: Python floats on the reference interpreter (``gagen.interp``); on the compiler, exact
constants (sympy numbers) and sums of products of a scalar backend's native expressions (``Poly``,
``gagen.symbolic.backend``), which become CasADi SX or sympy expressions. The aliases below name those
roles. ``Scalar`` and ``Native`` are aliases of ``Any``: sympy ships no type information, a native
expression is a CasADi SX or a sympy expression, and a formula is written once for every path.

:class:`ScalarField` is what :class:`gagen.algebra.multivector.SparseMultivector` needs from its scalar
backend; ``gagen.symbolic.backend.ScalarBackend`` implements it, so the algebra stays below the scalar
layer and never imports it.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import Any, Protocol, TypeAlias

import sympy

Exact: TypeAlias = sympy.Expr
"""An exact constant: a sympy number (rationals, sqrt(2), cos(pi/7), …)."""

Native: TypeAlias = Any
"""A scalar backend's own expression: a 1×1 CasADi SX or a sympy expression."""

Scalar: TypeAlias = Any
"""A scalar of either path: a float (the interpreter), or an exact constant, a ``Poly`` or a native
expression (the compiler)."""

Math: TypeAlias = Any
"""A path's namespace of scalar functions (``Multivector.math``): sqrt, sin, …, ``lt``, ``if_else``,
``shared`` on floats (``gagen.interp``) or on a scalar backend's scalars (``gagen.symbolic``)."""

ZERO = sympy.Integer(0)


class ScalarField(Protocol):
    """The scalar arithmetic under a sparse symbolic multivector: exact folding, native expressions,
    and the counts of what the passes removed (``gagen.symbolic.passes``)."""

    name: str
    expand_all: bool  # every product of sums distributed (exact algebra), not materialised
    removed: Counter[str]

    def symbols(self, name: str, labels: Sequence[str]) -> list[Native]:
        """Fresh independent native symbols, one per label."""
        ...

    def lift(self, value: Any) -> Scalar:
        """An exact constant or a symbolic scalar for a number, a native expression or a scalar."""
        ...

    def is_zero(self, value: Scalar) -> bool: ...

    def is_symbol(self, value: Scalar) -> bool:
        """Whether a scalar is one free symbol (an input, not a computed value)."""
        ...

    def graph_cost(self, values: Sequence[Scalar]) -> int:
        """The operations of the graph that computes ``values``."""
        ...

    def add(self, *values: Any) -> Scalar: ...

    def neg(self, a: Any) -> Scalar: ...

    def mul(self, *values: Any) -> Scalar: ...

    def div(self, a: Any, b: Any) -> Scalar: ...

    def call(self, fn: str, *args: Any) -> Scalar:
        """A math function (sqrt, sin, …), exact when every argument is."""
        ...

    @property
    def math(self) -> Math:
        """The ``math``-like namespace over these scalars (the protocol's ``Multivector.math``)."""
        ...
