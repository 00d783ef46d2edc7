"""The compiler's optimisation passes, in one place, each reporting what it removed.

gagen does not run passes over a finished graph: each acts while the graph is built, where it has
the most information, and counts what it removes on the scalar backend (``ScalarBackend.removed``);
CSE runs last, per kernel, over all its outputs together. In the order a formula meets them:

- ``sparsity pruning`` (``gagen.algebra.multivector``): a product expands only the blade pairs whose
  product can be non-zero (the rules' tables); each pair skipped is one count;
- ``exact zeros`` and ``constant folding`` (``gagen.symbolic.backend``): constants stay exact sympy
  numbers, so ×0 drops a term and functions, products and selects of constants are evaluated at
  build time (a 90° URDF rotation gives exact 0 and ±1); ``snapping`` of URDF constants to exact
  values happens before, in ``gagen.model.kinematics.exact_angle``;
- ``cancelled terms``: terms of a sum whose exact coefficients cancel (x·y − y·x) never reach the
  graph;
- ``node sharing``: sums that differ only by an exact factor (½t and −½t) become one node;
- ``common subexpressions``: ``casadi.cse`` over all of a kernel's outputs; its count is the
  operations it removed (op count of the graph before minus after).

``report(backend, before, after)`` gives the counts of one kernel, as the manifest lists them.
"""

from __future__ import annotations

from collections.abc import Mapping

from gagen.symbolic.backend import ScalarBackend
from gagen.symbolic.flatten import OpCount

PASSES = ("sparsity pruning", "exact zeros", "constant folding", "cancelled terms", "node sharing",
          "common subexpressions")


def report(backend: ScalarBackend | None, before: OpCount, after: OpCount,
           extra: Mapping[str, int] | None = None) -> dict[str, int]:
    """What each pass removed while one kernel was built (in PASSES order)."""
    counts = dict(backend.removed) if backend is not None else {}
    for name, count in (extra or {}).items():
        counts[name] = counts.get(name, 0) + count
    operations = before.flops + sum(before.calls.values())
    remaining = after.flops + sum(after.calls.values())
    counts["common subexpressions"] = max(0, operations - remaining)
    return {name: int(counts.get(name, 0)) for name in PASSES}
