"""Hold a formula's flattened kernel against the reference interpreter.

A :class:`Formula` is a plain function over the multivector protocol plus the blades of each input.
``flatten_formula`` runs it on symbolic sparse multivectors and flattens the result;
``interpret`` runs the same function on the interpreter's dense multivectors; ``relative_error``
compares the two on given inputs. Used by the tests, ``gagen demo`` and, later, ``gagen build --check``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gagen.algebra.multivector import SparseMultivector
from gagen.algebra.protocol import BladeKey
from gagen.algebra.signature import Algebra
from gagen.interp import MultiVector
from gagen.symbolic.backend import ScalarBackend
from gagen.symbolic.casadi_backend import CasadiBackend
from gagen.symbolic.flatten import FlatKernel, flatten


@dataclass(frozen=True)
class Formula:
    """A function of multivectors (and of scalar vectors, such as joint angles), with the blades
    each multivector input may have, or the length of each scalar-vector input."""

    name: str
    algebra: Algebra
    inputs: tuple[tuple[str, tuple[BladeKey, ...] | int], ...]
    fn: Callable[..., Any]
    pass_zero: bool = False  # call fn(zero, *inputs), zero being a 0 multivector of the path's kind

    def masks(self, blades: Sequence[BladeKey]) -> list[int]:
        return [self.algebra.blade(b) if isinstance(b, str) else b for b in blades]


def _outputs(result: Any) -> list[Any]:
    """A formula returns one value or a tuple of values (multivectors or scalars)."""
    return list(result) if isinstance(result, tuple) else [result]


def flatten_formula(formula: Formula, backend: ScalarBackend | None = None) -> FlatKernel:
    """Run the formula on symbolic inputs and flatten its result(s): ports ``out0``, ``out1``, ..."""
    backend = backend or CasadiBackend()
    args = [[backend.lift(x) for x in backend.symbols(name, [str(i) for i in range(spec)])]
            if isinstance(spec, int) else SparseMultivector.symbolic(formula.algebra, backend, name, spec)
            for name, spec in formula.inputs]
    if formula.pass_zero:
        args = [SparseMultivector(formula.algebra, backend, {}), *args]
    results = _outputs(formula.fn(*args))
    args = args[1:] if formula.pass_zero else args
    return flatten(formula.name, [(n, a) for (n, _), a in zip(formula.inputs, args, strict=True)],
                   [(f"out{i}", r) for i, r in enumerate(results)], backend)


def interpret(formula: Formula, arrays: Sequence[np.ndarray]) -> list[np.ndarray]:
    """The formula on the interpreter: dense coefficients per output (length 1 for a scalar)."""
    args: list[Any] = []
    for (_, spec), values in zip(formula.inputs, arrays, strict=True):
        if isinstance(spec, int):
            args.append([float(v) for v in values])
            continue
        args.append(MultiVector.from_blades(formula.algebra, dict(zip(formula.masks(spec), values,
                                                                      strict=True))))
    if formula.pass_zero:
        args = [MultiVector.zero(formula.algebra), *args]
    return [np.asarray(r.coeffs, dtype=float) if isinstance(r, MultiVector) else np.array([float(r)])
            for r in _outputs(formula.fn(*args))]


def dense_outputs(kernel: FlatKernel, algebra: Algebra, values: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Scatter a kernel's outputs (ordered by port labels) into dense arrays (length 1 for scalars)."""
    dense_all = []
    for port, vals in zip(kernel.outputs, values, strict=True):
        if port.rows == ("0",):
            dense_all.append(np.asarray(vals, dtype=float).reshape(1))
            continue
        dense = np.zeros(algebra.size)
        for label, v in zip(port.rows, vals, strict=True):
            dense[algebra.blade(label)] = v
        dense_all.append(dense)
    return dense_all


def relative_error(kernel: FlatKernel, formula: Formula, arrays: Sequence[np.ndarray]) -> float:
    """max over outputs of |kernel − interpreter| / max(1, max |interpreter|) on one set of inputs."""
    ours = dense_outputs(kernel, formula.algebra, kernel(*arrays))
    refs = interpret(formula, arrays)
    return max(float(np.max(np.abs(o - r)) / max(1.0, float(np.max(np.abs(r)))))
               for o, r in zip(ours, refs, strict=True))
