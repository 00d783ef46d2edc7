"""Scalar layer of the compiler: exact constants, CasADi SX / sympy backends, flattening, op counts."""

from gagen.symbolic.backend import ScalarBackend, to_exact
from gagen.symbolic.casadi_backend import CasadiBackend
from gagen.symbolic.sympy_backend import SympyBackend

__all__ = ["CasadiBackend", "ScalarBackend", "SympyBackend", "to_exact"]
