"""sympy as the native scalar type: exact, fully expanded derivations of small pieces.

Every product is distributed (``expand_all``), so polynomial identities cancel exactly (P·P = 0
with symbolic x). Use it for derivations and checks, CasADi SX for robot-scale kernels.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from typing import Any

import sympy
from sympy.core.sorting import default_sort_key

from gagen.symbolic.backend import EXACT_FUNCTIONS, ScalarBackend


class SympyBackend(ScalarBackend):
    name = "sympy"

    expand_all = True

    def symbols(self, name: str, labels: Sequence[str]) -> list[Any]:
        return [sympy.Symbol(f"{name}_{label}", real=True) for label in labels]

    def is_native(self, value: Any) -> bool:
        return isinstance(value, sympy.Expr) and not value.is_number

    def constant(self, value: sympy.Expr) -> Any:
        return value  # sympy keeps constants exact all the way

    def key(self, value: Any) -> Hashable:
        return default_sort_key(value)

    def native_product(self, factors: Sequence[Any]) -> Any:
        return sympy.Mul(*factors)

    def native_sum(self, positive: Sequence[Any], negative: Sequence[Any]) -> Any:
        return sympy.Add(*positive) - sympy.Add(*negative)

    def native_scale(self, value: sympy.Expr, x: Any) -> Any:
        return value * x

    def native_constant_value(self, x: Any) -> float | None:
        return None  # numbers never get here: lift() takes them as exact constants

    def native_call(self, fn: str, *args: Any) -> Any:
        return EXACT_FUNCTIONS[fn](*args)

    def native_divide(self, a: Any, b: Any) -> Any:
        return a / b

    def native_less(self, a: Any, b: Any) -> Any:
        return sympy.Lt(a, b)

    def native_select(self, cond: Any, a: Any, b: Any) -> Any:
        return sympy.Piecewise((a, cond), (b, True))
