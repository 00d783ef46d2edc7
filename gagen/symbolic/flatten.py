"""Flattening: symbolic multivectors and scalars -> one flat scalar graph with an op count.

``flatten`` takes named inputs (multivectors whose coefficients are fresh symbols, or lists of
symbols) and named outputs (multivectors or scalars), and returns a :class:`FlatKernel`: a callable
on numpy arrays plus its :class:`OpCount`. For CasADi the graph is a ``casadi.Function`` after
``casadi.cse`` on all outputs together; for sympy it is ``sympy.cse`` + ``lambdify``.
Each port records its layout (blade order for multivectors), so callers know what each entry means.
"""

from __future__ import annotations

import itertools
import re
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeAlias

import casadi as ca
import numpy as np
import sympy

from gagen.algebra.multivector import SparseMultivector
from gagen.algebra.scalars import Scalar
from gagen.symbolic.backend import ScalarBackend, SymbolicScalar


@dataclass(frozen=True)
class OpCount:
    """Scalar operations of a flat kernel."""

    mul: int = 0
    add: int = 0  # additions and subtractions
    neg: int = 0
    div: int = 0
    calls: dict[str, int] = field(default_factory=dict)  # math function calls by name

    @property
    def flops(self) -> int:
        """mul + add + neg + div (function calls counted apart)."""
        return self.mul + self.add + self.neg + self.div

    def __str__(self) -> str:
        calls = "".join(f" {n}={k}" for n, k in sorted(self.calls.items()))
        return f"mul={self.mul} add={self.add} neg={self.neg} div={self.div}{calls} (flops={self.flops})"


@dataclass(frozen=True)
class Port:
    """A named input or output of a kernel: one label per row (a blade name for multivectors, a joint,
    an index) and a column count. The one port of gagen: flat kernels, the backends' kernels
    (``gagen.codegen.ir``) and the loaded C kernels (from a manifest's entries) all use it."""

    name: str
    rows: tuple[str, ...]
    cols: int = 1

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.rows), self.cols

    @property
    def size(self) -> int:
        return len(self.rows) * self.cols

    @property
    def array_shape(self) -> tuple[int, ...]:
        """The shape of its array in a call from Python: ``(rows,)`` for a vector, ``(rows, cols)``."""
        return (len(self.rows),) if self.cols == 1 else self.shape


@dataclass
class FlatKernel:
    """A flattened computation: call it with one numpy array per input port."""

    name: str
    inputs: tuple[Port, ...]
    outputs: tuple[Port, ...]
    op_count: OpCount
    evaluate: Callable[..., list[np.ndarray]]
    function: ca.Function | None = None  # the CasADi Function, for the casadi backend

    def __call__(self, *args: Any) -> list[np.ndarray]:
        if len(args) != len(self.inputs):
            raise TypeError(f"kernel {self.name} takes {len(self.inputs)} inputs, got {len(args)}")
        arrays = [np.asarray(a, dtype=float).reshape(p.size) for a, p in zip(args, self.inputs, strict=True)]
        return self.evaluate(*arrays)


Value: TypeAlias = SparseMultivector | Sequence[Scalar] | Scalar  # a port's value: a multivector or scalars


def _port(name: str, value: Value, backend: ScalarBackend,
          is_input: bool) -> tuple[Port, list[SymbolicScalar]]:
    """Layout and scalar entries of a port (exact constants kept as-is for outputs)."""
    if isinstance(value, SparseMultivector):
        labels = tuple(value.algebra.blade_name(b) for b in value.support)
        entries = list(value.coeffs.values())
    elif isinstance(value, (list, tuple)):
        labels = tuple(str(i) for i in range(len(value)))
        entries = [backend.lift(v) for v in value]
    else:
        labels, entries = ("0",), [backend.lift(value)]
    if is_input and any(backend.is_exact(e) for e in entries):
        raise ValueError(f"input {name!r} has constant entries; inputs must be fresh symbols")
    return Port(name, labels), entries


def flatten(name: str, inputs: Sequence[tuple[str, Value]], outputs: Sequence[tuple[str, Value]],
            backend: ScalarBackend) -> FlatKernel:
    """Flatten named outputs as functions of named inputs on the given backend."""
    in_ports, in_entries = zip(*(_port(n, v, backend, True) for n, v in inputs), strict=True)
    out_ports, out_entries = zip(*(_port(n, v, backend, False) for n, v in outputs), strict=True)
    if backend.name == "casadi":
        return _flatten_casadi(name, in_ports, in_entries, out_ports, out_entries, backend)
    return _flatten_sympy(name, in_ports, in_entries, out_ports, out_entries, backend)


def identifier(name: str) -> str:
    """A C/CasADi identifier for a human-readable name: 'v v^-1' -> 'v_v_1'."""
    ident = re.sub(r"[^0-9A-Za-z]+", "_", name).strip("_") or "f"
    return ident if ident[0].isalpha() else "f_" + ident


# -- CasADi ------------------------------------------------------------------------------------------
# the name of each CasADi operation code ("ADD", "SIN", …), for every reader of a flat graph (the op
# counts here, the backends' printers)
OPCODES: dict[int, str] = {getattr(ca, a): a[3:] for a in dir(ca) if a.startswith("OP_")}
_OP_NAMES = {code: name.lower() for code, name in OPCODES.items()}
_IGNORED = {"const", "input", "output", "parameter", "assign"}
_KIND = {"mul": "mul", "sq": "mul", "add": "add", "sub": "add", "twice": "add", "neg": "neg",
         "div": "div", "inv": "div"}


def casadi_op_count(f: ca.Function) -> OpCount:
    """Count the scalar instructions of an SX Function."""
    kinds: Counter[str] = Counter()
    calls: Counter[str] = Counter()
    for k in range(f.n_instructions()):
        op = _OP_NAMES.get(f.instruction_id(k), "unknown")
        if op in _IGNORED:
            continue
        if op in _KIND:
            kinds[_KIND[op]] += 1
        else:
            calls[op] += 1
    return OpCount(kinds["mul"], kinds["add"], kinds["neg"], kinds["div"], dict(sorted(calls.items())))


def _flatten_casadi(name: str, in_ports: Sequence[Port], in_entries: Sequence[list[SymbolicScalar]],
                    out_ports: Sequence[Port], out_entries: Sequence[list[SymbolicScalar]],
                    backend: ScalarBackend) -> FlatKernel:
    sym_in = [ca.vertcat(*(backend.native(x) for x in e)) for e in in_entries]
    flat = [backend.native(e) for es in out_entries for e in es]
    joined = ca.cse(ca.vertcat(*flat)) if flat else ca.SX(0, 1)
    sizes = np.cumsum([0] + [p.size for p in out_ports])
    sym_out = [joined[int(a):int(b)] for a, b in itertools.pairwise(sizes)]
    f = ca.Function(identifier(name), sym_in, sym_out, [identifier(p.name) for p in in_ports],
                    [identifier(p.name) for p in out_ports])

    def evaluate(*arrays: np.ndarray) -> list[np.ndarray]:
        res = f.call(list(arrays))
        return [np.asarray(r, dtype=float).reshape(-1) for r in res]

    return FlatKernel(name, tuple(in_ports), tuple(out_ports), casadi_op_count(f), evaluate, f)


# -- sympy -------------------------------------------------------------------------------------------
def sympy_op_count(exprs: Sequence[sympy.Expr]) -> OpCount:
    """Count the operations of sympy expressions after common-subexpression elimination."""
    replacements, reduced = sympy.cse(list(exprs))
    kinds: Counter[str] = Counter()
    calls: Counter[str] = Counter()

    def visit(e: sympy.Expr) -> None:
        if e.is_Atom:
            return
        if e.is_Add:
            # a − b is Add(a, −b): count the subtraction, not a negation
            kinds["add"] += len(e.args) - 1
            negative = [a.could_extract_minus_sign() for a in e.args]
            kinds["neg"] += all(negative)
            for a, neg in zip(e.args, negative, strict=True):
                visit(-a if neg else a)
            return
        if e.is_Mul:
            coeff, rest = e.as_coeff_Mul()
            factors = sympy.Mul.make_args(rest)
            kinds["mul"] += len(factors) - 1 + (coeff not in (1, -1))
            kinds["neg"] += coeff == -1
        elif e.is_Pow:
            _base, exp = e.args
            if exp == -1:
                kinds["div"] += 1
            elif exp == sympy.Rational(1, 2):
                calls["sqrt"] += 1
            elif exp.is_Integer and exp > 0:
                kinds["mul"] += int(exp) - 1
            else:
                calls["pow"] += 1
        else:
            calls[type(e).__name__.lower()] += 1
        for a in e.args:
            visit(a)

    for _, e in replacements:
        visit(e)
    for e in reduced:
        visit(e)
    return OpCount(kinds["mul"], kinds["add"], kinds["neg"], kinds["div"], dict(sorted(calls.items())))


def _flatten_sympy(name: str, in_ports: Sequence[Port], in_entries: Sequence[list[SymbolicScalar]],
                   out_ports: Sequence[Port], out_entries: Sequence[list[SymbolicScalar]],
                   backend: ScalarBackend) -> FlatKernel:
    symbols = [backend.native(s) for es in in_entries for s in es]
    exprs = [sympy.sympify(backend.native(e)) for es in out_entries for e in es]
    fn = sympy.lambdify(symbols, exprs, modules="numpy", cse=True)
    sizes = np.cumsum([0] + [p.size for p in out_ports])

    def evaluate(*arrays: np.ndarray) -> list[np.ndarray]:
        values = np.array(fn(*np.concatenate(arrays)), dtype=float).reshape(-1)
        return [values[int(a):int(b)] for a, b in itertools.pairwise(sizes)]

    return FlatKernel(name, tuple(in_ports), tuple(out_ports), sympy_op_count(exprs), evaluate)
