"""Scalar functions of the interpreter's path: Python floats, plus ``lt`` and ``if_else``.

The same names as the symbolic path's ``BackendMath``, so a formula written against the
multivector protocol can call ``X.math.sqrt(...)`` or ``X.math.if_else(...)`` on either path.
"""

from __future__ import annotations

import math

from gagen.algebra.scalars import Scalar


class InterpMath:
    """``math`` for floats, with the extra names formulas use for guarded special cases."""

    sqrt = staticmethod(math.sqrt)
    sin = staticmethod(math.sin)
    cos = staticmethod(math.cos)
    tan = staticmethod(math.tan)
    asin = staticmethod(math.asin)
    acos = staticmethod(math.acos)
    atan = staticmethod(math.atan)
    atan2 = staticmethod(math.atan2)
    exp = staticmethod(math.exp)
    log = staticmethod(math.log)
    sinh = staticmethod(math.sinh)
    cosh = staticmethod(math.cosh)
    tanh = staticmethod(math.tanh)
    asinh = staticmethod(math.asinh)
    acosh = staticmethod(math.acosh)
    atanh = staticmethod(math.atanh)
    fabs = staticmethod(math.fabs)

    @staticmethod
    def lt(a: float, b: float) -> bool:
        return a < b

    @staticmethod
    def if_else(cond: bool, a: Scalar, b: Scalar) -> Scalar:
        return a if cond else b

    @staticmethod
    def shared(a: Scalar) -> Scalar:
        """A value reused in many places: numbers are already shared."""
        return a


INTERP_MATH = InterpMath()
