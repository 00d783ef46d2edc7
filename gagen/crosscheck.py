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
    """A function of multivectors, with the blades each input may have."""

    name: str
    algebra: Algebra
    inputs: tuple[tuple[str, tuple[BladeKey, ...]], ...]
    fn: Callable[..., Any]

    def masks(self, blades: Sequence[BladeKey]) -> list[int]:
        return [self.algebra.blade(b) if isinstance(b, str) else b for b in blades]


def flatten_formula(formula: Formula, backend: ScalarBackend | None = None) -> FlatKernel:
    """Run the formula on symbolic inputs and flatten its result (one output port, ``out``)."""
    backend = backend or CasadiBackend()
    args = [SparseMultivector.symbolic(formula.algebra, backend, name, blades)
            for name, blades in formula.inputs]
    result = formula.fn(*args)
    return flatten(formula.name, [(n, a) for (n, _), a in zip(formula.inputs, args, strict=True)],
                   [("out", result)], backend)


def interpret(formula: Formula, arrays: Sequence[np.ndarray]) -> np.ndarray:
    """The formula on the interpreter: dense coefficients (or a length-1 array for a scalar)."""
    args = []
    for (_, blades), values in zip(formula.inputs, arrays, strict=True):
        args.append(MultiVector.from_blades(formula.algebra, dict(zip(formula.masks(blades), values,
                                                                      strict=True))))
    result = formula.fn(*args)
    if isinstance(result, MultiVector):
        return np.asarray(result.coeffs, dtype=float)
    return np.array([float(result)])


def dense_output(kernel: FlatKernel, algebra: Algebra, values: np.ndarray) -> np.ndarray:
    """Scatter a kernel's multivector output (ordered by its port labels) into a dense array."""
    port = kernel.outputs[0]
    if port.labels == ("0",):
        return np.asarray(values, dtype=float).reshape(1)
    dense = np.zeros(algebra.size)
    for label, v in zip(port.labels, values, strict=True):
        dense[algebra.blade(label)] = v
    return dense


def relative_error(kernel: FlatKernel, formula: Formula, arrays: Sequence[np.ndarray]) -> float:
    """max |kernel − interpreter| / max(1, max |interpreter|) on one set of inputs."""
    (out,) = kernel(*arrays)
    ours = dense_output(kernel, formula.algebra, out)
    ref = interpret(formula, arrays)
    return float(np.max(np.abs(ours - ref)) / max(1.0, float(np.max(np.abs(ref)))))
