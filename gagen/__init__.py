"""gagen: a symbolic code-generation compiler for conformal geometric algebra in robotics.

Subpackages: ``algebra`` (algebra descriptions, exact blade rules, sparse symbolic multivectors),
``symbolic`` (exact scalar layer over CasADi SX / sympy, flattening, op counts), ``interp`` (the
independent dense reference interpreter).
"""

__version__ = "0.1.0"
