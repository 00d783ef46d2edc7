"""The compiler's algebra: algebra descriptions, exact blade rules, sparse symbolic multivectors."""

from gagen.algebra.blade_rules import BladeRules, rules_for
from gagen.algebra.multivector import SparseMultivector
from gagen.algebra.protocol import Multivector
from gagen.algebra.signature import Algebra, cga2d, cga3d, from_signature, ga3d, pga3d, preset

__all__ = ["Algebra", "BladeRules", "Multivector", "SparseMultivector", "cga2d", "cga3d",
           "from_signature", "ga3d", "pga3d", "preset", "rules_for"]
