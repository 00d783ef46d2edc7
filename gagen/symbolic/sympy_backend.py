"""sympy as the native scalar type: exact, fully expanded derivations of small pieces.

Every product is distributed (``expand_all``), so polynomial identities cancel exactly (P·P = 0
with symbolic x). Use it for derivations and checks, CasADi SX for robot-scale kernels.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy
from sympy.core.sorting import default_sort_key

from gagen.algebra.scalars import Exact, Native
from gagen.symbolic.backend import EXACT_FUNCTIONS, AtomKey, ScalarBackend


class SympyBackend(ScalarBackend):
    name = "sympy"

    expand_all = True

    def symbols(self, name: str, labels: Sequence[str]) -> list[Native]:
        return [sympy.Symbol(f"{name}_{label}", real=True) for label in labels]

    def is_native(self, value: object) -> bool:
        return isinstance(value, sympy.Expr) and not value.is_number

    def constant(self, value: Exact) -> Native:
        return value  # sympy keeps constants exact all the way

    def key(self, value: Native) -> AtomKey:
        return default_sort_key(value)

    def native_product(self, factors: Sequence[Native]) -> Native:
        return sympy.Mul(*factors)

    def native_sum(self, positive: Sequence[Native], negative: Sequence[Native]) -> Native:
        return sympy.Add(*positive) - sympy.Add(*negative)

    def native_scale(self, value: Exact, x: Native) -> Native:
        return value * x

    def native_constant_value(self, x: Native) -> float | None:
        return None  # numbers never get here: lift() takes them as exact constants

    def native_call(self, fn: str, *args: Native) -> Native:
        return EXACT_FUNCTIONS[fn](*args)

    def native_divide(self, a: Native, b: Native) -> Native:
        return a / b

    def native_less(self, a: Native, b: Native) -> Native:
        return sympy.Lt(a, b)

    def native_select(self, cond: Native, a: Native, b: Native) -> Native:
        return sympy.Piecewise((a, cond), (b, True))
