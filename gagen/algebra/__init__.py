"""The compiler's algebra: algebra descriptions, exact blade rules, sparse symbolic multivectors, and
the names of the scalars they carry (``scalars``: what a sparse multivector asks of the scalar layer
above it, ``gagen.symbolic``).

Names load lazily, so that the reference interpreter, which needs only ``signature`` (and the names
of ``scalars``), never imports the compiler's rules.
"""

from importlib import import_module
from typing import Any

_EXPORTS = {
    "Algebra": "signature", "cga2d": "signature", "cga3d": "signature", "from_signature": "signature",
    "ga3d": "signature", "pga3d": "signature", "preset": "signature",
    "BladeRules": "blade_rules", "rules_for": "blade_rules",
    "SparseMultivector": "multivector", "Multivector": "protocol",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'gagen.algebra' has no attribute {name!r}")
    return getattr(import_module(f"gagen.algebra.{_EXPORTS[name]}"), name)
