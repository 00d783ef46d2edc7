"""CasADi SX as the native scalar type: the backend for robot-scale expansion and differentiation."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import reduce

import casadi as ca

from gagen.algebra.scalars import Exact, Native
from gagen.symbolic.backend import AtomKey, ScalarBackend, SymbolicScalar

_CALLS: dict[str, Callable[..., Native]] = {
    "sqrt": ca.sqrt, "sin": ca.sin, "cos": ca.cos, "tan": ca.tan, "asin": ca.asin, "acos": ca.acos,
    "atan": ca.atan, "atan2": ca.atan2, "exp": ca.exp, "log": ca.log, "sinh": ca.sinh,
    "cosh": ca.cosh, "tanh": ca.tanh, "asinh": ca.asinh, "acosh": ca.acosh, "atanh": ca.atanh,
    "fabs": ca.fabs,
}


class CasadiBackend(ScalarBackend):
    name = "casadi"

    def symbols(self, name: str, labels: Sequence[str]) -> list[Native]:
        return [ca.SX.sym(f"{name}_{label}") for label in labels]

    def is_native(self, value: object) -> bool:
        return isinstance(value, ca.SX) and value.shape == (1, 1)

    def constant(self, value: Exact) -> Native:
        return ca.SX(float(value))

    def key(self, value: Native) -> AtomKey:
        return value.element_hash()

    def is_symbol(self, value: SymbolicScalar) -> bool:
        if self.is_exact(value) or len(value.terms) != 1:
            return False
        ((c, atoms),) = value.terms.values()
        return c == 1 and len(atoms) == 1 and atoms[0].is_symbolic()

    def graph_cost(self, values: Sequence[SymbolicScalar]) -> int:
        """The operations (after CSE) of the graph that computes ``values``: what they would cost a
        kernel that computes them from its inputs."""
        from gagen.symbolic.flatten import casadi_op_count

        natives = [self.native(v) for v in values]
        if not natives:
            return 0
        f = ca.Function("cost", [], [ca.cse(ca.vertcat(*natives))], {"allow_free": True})
        return casadi_op_count(f).flops

    def native_product(self, factors: Sequence[Native]) -> Native:
        return reduce(lambda a, b: a * b, factors)

    def native_sum(self, positive: Sequence[Native], negative: Sequence[Native]) -> Native:
        if positive:
            return reduce(lambda a, b: a - b, negative, reduce(lambda a, b: a + b, positive))
        return -reduce(lambda a, b: a + b, negative)

    def native_scale(self, value: Exact, x: Native) -> Native:
        return float(value) * x

    def native_constant_value(self, x: Native) -> float | None:
        return float(x) if x.is_constant() else None

    def native_call(self, fn: str, *args: Native) -> Native:
        return _CALLS[fn](*args)

    def native_divide(self, a: Native, b: Native) -> Native:
        return a / b

    def native_less(self, a: Native, b: Native) -> Native:
        return a < b

    def native_select(self, cond: Native, a: Native, b: Native) -> Native:
        # if_else_zero(c, x) is "c ? x : 0" in generated code, so a NaN in the other branch stays out
        return ca.if_else(cond, a, b)
