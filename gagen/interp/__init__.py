"""The reference interpreter: dense numpy multivectors derived through an orthonormal frame.

Independent of the compiler (``gagen.algebra.blade_rules``): it reads only the algebra description
(``gagen.algebra.signature``) and derives its own product tables (see :mod:`gagen.interp.frame`).
It implements the multivector protocol of ``gagen.algebra.protocol``.
"""

from gagen.algebra.signature import Algebra, cga2d, cga3d, from_signature, ga3d, pga3d, preset
from gagen.interp.frame import Tables, tables
from gagen.interp.multivector import MultiVector, conformal_point

__all__ = ["Algebra", "MultiVector", "Tables", "cga2d", "cga3d", "conformal_point", "from_signature",
           "ga3d", "pga3d", "preset", "tables"]
