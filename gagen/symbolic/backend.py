"""Scalar backends: the arithmetic under sparse symbolic multivectors, with exact constants.

A coefficient is either an **exact constant** (a sympy number: rationals, sqrt(2), cos(pi/7), ...)
or a :class:`Poly`: a sum of terms ``exact coefficient × product of native atoms``, where an atom
is a native expression of the backend (a CasADi ``SX`` node or a sympy expression). Terms with the
same atoms merge exactly, so ``x*y − y*x`` and ``½(x1 − x2) + ½(x1 + x2) − x1`` are exactly zero
and never reach the graph, and a 90° rotation yields exact zeros rather than 1e-17.

A Poly stays unexpanded until it must become one native node ("materialised", once, cached):
when it is multiplied by another sum, passed to a function (sqrt, sin, ...), divided by, or
flattened. Sums that differ only by an exact factor (x − y and y − x, t and −½t) share that node,
so their products merge as exactly as atoms do. Multiplying a Poly by an exact constant keeps it
a Poly when that costs no extra multiplication (the constant is ±1, or the Poly is small), so
chains of exact constants fold.
The sympy backend expands every product instead (``expand_all``): exact polynomial algebra.

When a term is emitted, 0 drops it, ±1 folds into an addition or subtraction and any other value
is rounded once to the nearest double (so ``0.5*x``, never ``x/2``).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections import Counter
from collections.abc import Callable, Sequence
from typing import Any, TypeAlias

import sympy

from gagen.algebra.scalars import ZERO, Exact, Native, Scalar

ONE = sympy.Integer(1)

AtomKey: TypeAlias = Any
"""The identity of a native atom (``ScalarBackend.key``): hashable and orderable within one backend (a
CasADi node's hash, sympy's sort key)."""
Key: TypeAlias = tuple[AtomKey, ...]  # sorted identities of a term's atoms (commutative product)
Normal: TypeAlias = tuple[tuple[Key, Exact], ...]  # a sum up to an exact factor (ScalarBackend._node)


class Poly:
    """Σ coef · Π atoms, with exact coefficients; immutable apart from its materialisation cache.

    Supports Python arithmetic with numbers and other Polys of its backend, so formulas can treat
    scalars of the symbolic path like floats.
    """

    __slots__ = ("_native", "backend", "terms")

    def __init__(self, backend: ScalarBackend, terms: dict[Key, tuple[Exact, tuple[Native, ...]]]) -> None:
        self.backend = backend
        self.terms = terms  # key -> (non-zero exact coefficient, atoms in first-seen order)
        self._native: Native = None

    def __len__(self) -> int:
        return len(self.terms)

    def _operand(self, other: Scalar) -> Scalar:
        if isinstance(other, Poly) or to_exact(other) is not None or self.backend.is_native(other):
            return other
        return None

    def __add__(self, other: Scalar) -> Scalar:
        o = self._operand(other)
        return NotImplemented if o is None else self.backend.add(self, o)

    __radd__ = __add__

    def __sub__(self, other: Scalar) -> Scalar:
        o = self._operand(other)
        return NotImplemented if o is None else self.backend.sub(self, o)

    def __rsub__(self, other: Scalar) -> Scalar:
        o = self._operand(other)
        return NotImplemented if o is None else self.backend.sub(o, self)

    def __mul__(self, other: Scalar) -> Scalar:
        o = self._operand(other)
        return NotImplemented if o is None else self.backend.mul(self, o)

    __rmul__ = __mul__

    def __truediv__(self, other: Scalar) -> Scalar:
        o = self._operand(other)
        return NotImplemented if o is None else self.backend.div(self, o)

    def __rtruediv__(self, other: Scalar) -> Scalar:
        o = self._operand(other)
        return NotImplemented if o is None else self.backend.div(o, self)

    def __neg__(self) -> SymbolicScalar:
        return self.backend.neg(self)

    def __repr__(self) -> str:
        return " + ".join(f"{c}*{'*'.join(map(str, atoms)) or '1'}" for c, atoms in self.terms.values())


SymbolicScalar: TypeAlias = Exact | Poly
"""A scalar of the compiler's path as this layer holds it: an exact constant or a Poly."""


def to_exact(value: Any) -> Exact | None:
    """An exact sympy number for a Python/numpy/sympy number, else None.

    Floats become the exact rational value of the double (no guessing), so no precision is lost.
    """
    if isinstance(value, sympy.Basic):
        if not value.is_number:
            return None
        # a sympy Float (e.g. from 0.5 * Integer(3)) becomes the exact value of its binary digits
        return value.xreplace({f: sympy.Rational(f) for f in value.atoms(sympy.Float)})
    if isinstance(value, bool):
        return sympy.Integer(int(value))
    if isinstance(value, int):
        return sympy.Integer(value)
    if isinstance(value, float) or type(value).__module__ == "numpy":
        f = float(value)
        if not math.isfinite(f):
            raise ValueError(f"non-finite constant {f!r} in a symbolic expression")
        return sympy.Integer(int(f)) if f.is_integer() else sympy.Rational(f)
    return None


class ScalarBackend(ABC):
    """Native arithmetic plus the exact folding shared by every backend."""

    name: str
    expand_all: bool = False  # distribute every product of sums (exact algebra) instead of materialising
    scale_expand_limit: int = 4  # a Poly this small stays a Poly when scaled by any exact constant

    def __init__(self) -> None:
        # a normalised sum -> (f, node, its atoms) with sum = f · node (see _node)
        self._materialised: dict[Normal, tuple[Exact, Native, list[tuple[Native, ...]]]] = {}
        # the key of a node made by _node -> (node, the Poly it computes), for merging by cofactor
        self._node_polys: dict[AtomKey, tuple[Native, Poly]] = {}
        # what the passes of gagen.symbolic.passes removed on this backend (see there)
        self.removed: Counter[str] = Counter()

    # -- to be provided by a backend -------------------------------------------------------------
    @abstractmethod
    def symbols(self, name: str, labels: Sequence[str]) -> list[Native]:
        """Fresh independent native symbols, one per label."""

    @abstractmethod
    def is_native(self, value: object) -> bool:
        """Whether ``value`` is a native scalar expression of this backend."""

    @abstractmethod
    def native_constant_value(self, x: Native) -> float | None:
        """The value of a native expression that is structurally a constant, else None."""

    @abstractmethod
    def constant(self, value: Exact) -> Native:
        """Native constant for an exact value."""

    @abstractmethod
    def key(self, atom: Native) -> AtomKey:
        """Identity of a native atom (orderable), for merging terms with the same atoms."""

    @abstractmethod
    def native_product(self, atoms: Sequence[Native]) -> Native: ...

    @abstractmethod
    def native_sum(self, positive: Sequence[Native], negative: Sequence[Native]) -> Native:
        """Σ positive − Σ negative, at least one of them non-empty."""

    @abstractmethod
    def native_scale(self, value: Exact, x: Native) -> Native:
        """value · x for an exact positive value other than 1."""

    @abstractmethod
    def native_call(self, fn: str, *args: Native) -> Native:
        """A math function (see ``MATH_FUNCTIONS``) of native arguments."""

    @abstractmethod
    def native_divide(self, a: Native, b: Native) -> Native: ...

    @abstractmethod
    def native_less(self, a: Native, b: Native) -> Native:
        """A native boolean expression a < b."""

    @abstractmethod
    def native_select(self, cond: Native, a: Native, b: Native) -> Native:
        """cond ? a : b, without letting a NaN or Inf of the branch not taken leak through."""

    # -- entering the scalar layer ------------------------------------------------------------------
    def lift(self, value: Scalar) -> SymbolicScalar:
        """Exact constant or Poly for a number, a native expression, or a scalar of this layer."""
        if isinstance(value, Poly):
            return value
        exact = to_exact(value)
        if exact is not None:
            return exact
        if self.is_native(value):
            const = self.native_constant_value(value)
            return to_exact(const) if const is not None else self.atom(value)
        raise TypeError(f"{self.name} backend: cannot use {type(value).__name__} as a scalar")

    def atom(self, native: Native) -> Poly:
        """A native expression as a one-term Poly."""
        return Poly(self, {(self.key(native),): (ONE, (native,))})

    @property
    def math(self) -> BackendMath:
        """sqrt, sin, cos, atan2, … ``lt``, ``if_else`` and ``shared`` on this backend's scalars."""
        return BackendMath(self)

    def is_symbol(self, value: SymbolicScalar) -> bool:
        """Whether a scalar is one free symbol of the backend (an input, not a computed value)."""
        return False

    def graph_cost(self, values: Sequence[SymbolicScalar]) -> int:
        """The operations of the graph that computes ``values`` (for choosing between exact forms)."""
        raise NotImplementedError

    @staticmethod
    def is_exact(value: object) -> bool:
        return isinstance(value, sympy.Basic)

    @staticmethod
    def is_zero(value: SymbolicScalar) -> bool:
        return isinstance(value, sympy.Basic) and value == 0

    # -- arithmetic -----------------------------------------------------------------------------------
    def add(self, *values: Scalar) -> SymbolicScalar:
        const = ZERO
        terms: dict[Key, list[Any]] = {}
        for v in values:
            v = self.lift(v)
            if isinstance(v, Poly):
                for k, (c, atoms) in v.terms.items():
                    if k in terms:
                        terms[k][0] += c
                    else:
                        terms[k] = [c, atoms]
            else:
                const += v
        if len(terms) > 1 and self._node_polys:
            self._merge_cofactors(terms)
        return self._poly(terms, const)

    def _merge_cofactors(self, terms: dict[Key, list[Any]]) -> None:
        """Merge terms c₁·f·A + c₂·f·B + … that share a cofactor f, where A, B, … are nodes of sums,
        into f·(c₁A + c₂B + …) when those sums cancel down to at most one term: e.g. x·‖V‖² + x·(1 − ‖V‖²)
        is x. At most one term replaces several, so the sum never costs more."""
        groups: dict[Key, list[tuple[Key, AtomKey]]] = {}
        for k in terms:
            for i, a in enumerate(k):
                if a in self._node_polys and (i == 0 or k[i - 1] != a):
                    groups.setdefault(k[:i] + k[i + 1:], []).append((k, a))
        for cofactor, members in groups.items():
            members = [(k, a) for k, a in members if k in terms and terms[k][0] != 0]
            if len(members) < 2:
                continue
            merged: dict[Key, list[Any]] = {}
            parts = 0
            for k, a in members:
                c = terms[k][0]
                poly = self._node_polys[a][1]
                parts += len(poly)
                for kp, (cp, atoms) in poly.terms.items():
                    if kp in merged:
                        merged[kp][0] += c * cp
                    else:
                        merged[kp] = [c * cp, atoms]
            kept = [(kp, e) for kp, e in merged.items() if e[0] != 0]
            if any(kp for kp, _ in kept) or len(kept) >= parts:
                continue
            k0, a0 = members[0]
            cofactor_atoms = list(terms[k0][1])
            node = self._node_polys[a0][0]
            cofactor_atoms.pop(next(j for j, x in enumerate(cofactor_atoms)
                                    if x is node or self.key(x) == a0))
            for k, _ in members:
                del terms[k]
            self.removed["cancelled terms"] += len(members) + parts - len(kept)
            for kp, (cp, atoms_p) in kept:
                key = tuple(sorted(cofactor + kp))
                if key in terms:
                    terms[key][0] += cp
                else:
                    terms[key] = [cp, tuple(cofactor_atoms) + tuple(atoms_p)]

    def neg(self, a: Scalar) -> SymbolicScalar:
        return self._scale(-ONE, self.lift(a))

    def sub(self, a: Scalar, b: Scalar) -> SymbolicScalar:
        return self.add(a, self.neg(b))

    def mul(self, *values: Scalar) -> SymbolicScalar:
        result: SymbolicScalar = ONE
        for v in values:
            result = self._mul2(result, self.lift(v))
        return result

    def div(self, a: Scalar, b: Scalar) -> SymbolicScalar:
        a, b = self.lift(a), self.lift(b)
        if self.is_exact(b):
            if b == 0:
                raise ZeroDivisionError("division by an exact zero in a symbolic expression")
            return self._scale(1 / b, a)
        if self.is_zero(a):
            return ZERO
        return self.lift(self.native_divide(self.native(a), self.native(b)))

    def call(self, fn: str, *args: Scalar) -> SymbolicScalar:
        """Math function; evaluated exactly when every argument is exact."""
        lifted = [self.lift(a) for a in args]
        if all(self.is_exact(a) for a in lifted):
            self.removed["constant folding"] += 1
            return exact_call(fn, *lifted)
        return self.lift(self.native_call(fn, *(self.native(a) for a in lifted)))

    def less(self, a: Scalar, b: Scalar) -> bool | Native:
        """a < b: a Python bool when both are exact, else a native boolean expression."""
        a, b = self.lift(a), self.lift(b)
        if self.is_exact(a) and self.is_exact(b):
            return bool(a < b)
        return self.native_less(self.native(a), self.native(b))

    def select(self, cond: bool | Native, a: Scalar, b: Scalar) -> SymbolicScalar:
        """cond ? a : b; folded when the condition is known at build time."""
        if isinstance(cond, bool):
            self.removed["constant folding"] += 1
            return self.lift(a if cond else b)
        a, b = self.lift(a), self.lift(b)
        if a is b or (self.is_exact(a) and self.is_exact(b) and a == b):
            return a
        return self.lift(self.native_select(cond, self.native(self.lift(a)), self.native(self.lift(b))))

    def _mul2(self, a: SymbolicScalar, b: SymbolicScalar) -> SymbolicScalar:
        if self.is_exact(a):
            return self._scale(a, b)
        if self.is_exact(b):
            return self._scale(b, a)
        if not self.expand_all:  # a product of sums: each sum becomes one node first
            a, b = self._as_monomial(a), self._as_monomial(b)
        terms: dict[Key, list[Any]] = {}
        for ka, (ca, xa) in a.terms.items():
            for kb, (cb, xb) in b.terms.items():
                k = tuple(sorted(ka + kb))
                if k in terms:
                    terms[k][0] += ca * cb
                else:
                    terms[k] = [ca * cb, xa + xb]
        return self._poly(terms, ZERO)

    def _scale(self, c: Exact, p: SymbolicScalar) -> SymbolicScalar:
        if c == 0:
            self.removed["exact zeros"] += 1
            return ZERO
        if self.is_exact(p):
            self.removed["constant folding"] += 1
            return c * p
        if c == 1:
            return p
        if c != -1 and not self.expand_all and len(p) > self.scale_expand_limit:
            p = self.atom(self.native(p))  # one multiplication instead of one per term
        return Poly(self, {k: (c * cp, atoms) for k, (cp, atoms) in p.terms.items()})

    def _as_monomial(self, p: Poly) -> Poly:
        if len(p) == 1:
            return p
        factor, node = self._node(p)
        return Poly(self, {(self.key(node),): (factor, (node,))})

    def _node(self, p: Poly) -> tuple[Exact, Native]:
        """(c, node) with p = c · node, where every sum that differs from p only by an exact factor
        (½t and −½t of a translator and its reverse, x and −x) shares the node: products of them then
        merge exactly, and each sum is emitted once."""
        signature = sorted((k, c) for k, (c, _) in p.terms.items())
        lead = signature[0][1]
        # divide out the sign, and the magnitude when every coefficient shares it (no rounding then)
        scale = abs(lead) if all(abs(c) == abs(lead) for _, c in signature) else ONE
        scale = -scale if lead.is_extended_negative else scale
        normal = tuple((k, c / scale) for k, c in signature)
        if normal in self._materialised:  # normal = f · node
            self.removed["node sharing"] += 1
            f, node, _ = self._materialised[normal]
            return scale * f, node
        node = p._native if p._native is not None else self._emit(p)
        self._node_polys.setdefault(self.key(node), (node, p))
        # the entry holds the atoms too: keys are node addresses, which must not be reused
        self._materialised[normal] = (1 / scale, node, [atoms for _, atoms in p.terms.values()])
        return ONE, node

    def _poly(self, terms: dict[Key, list[Any]], const: Exact) -> SymbolicScalar:
        if () in terms:  # a Poly's own constant term joins the loose constants
            const = const + terms.pop(())[0]
        kept = {k: (c, atoms) for k, (c, atoms) in terms.items() if c != 0}
        self.removed["cancelled terms"] += len(terms) - len(kept)
        if const != 0:
            kept[()] = (const, ())
        if not kept:
            return ZERO
        if list(kept) == [()]:
            return const
        return Poly(self, kept)

    # -- leaving the scalar layer ---------------------------------------------------------------------
    def native(self, value: SymbolicScalar) -> Native:
        """One native expression for a scalar (materialised once per Poly)."""
        if self.is_exact(value):
            return self.constant(value)
        if value._native is None:
            factor, node = self._node(value)
            scaled = Poly(self, {(self.key(node),): (factor, (node,))})
            value._native = node if factor == 1 else self._emit(scaled)
        return value._native

    def _emit(self, p: Poly) -> Native:
        """Σ ±terms, with terms sharing a coefficient magnitude c ≠ 1 summed first and scaled once."""
        groups: dict[Exact, tuple[list[Native], list[Native]]] = {}
        for coef, atoms in p.terms.values():
            is_negative = bool(coef.is_extended_negative)
            magnitude = -coef if is_negative else coef
            if atoms:
                value = self.native_product(atoms)
            else:  # the constant term
                value, magnitude = self.constant(magnitude), ONE
            groups.setdefault(magnitude, ([], []))[is_negative].append(value)
        positive, negative = groups.pop(ONE, ([], []))
        for magnitude, (pos, neg) in groups.items():
            if pos:
                positive.append(self.native_scale(magnitude, self.native_sum(pos, neg)))
            else:
                negative.append(self.native_scale(magnitude, self.native_sum(neg, [])))
        return self.native_sum(positive, negative)


def exact_call(fn: str, *args: Exact) -> Exact:
    """A math function of exact arguments: exact when the value is rational or a short algebraic
    number (cos(π/4) = √2/2), otherwise the exact value of its nearest double — carrying cos(1/7)
    symbolically through a kinematic chain costs much and gains nothing."""
    value = EXACT_FUNCTIONS[fn](*args)
    if value.is_Rational or (value.is_algebraic and sympy.count_ops(value) <= 8):
        return value
    return to_exact(float(value))


class BackendMath:
    """``math``-like namespace over a backend's scalars (exact when the arguments are).

    Besides the functions of ``MATH_FUNCTIONS`` it has ``lt(a, b)`` and ``if_else(cond, a, b)``,
    with which formulas write guarded, branch-free special cases, and ``shared(a)``.
    """

    def __init__(self, backend: ScalarBackend) -> None:
        self._backend = backend

    def lt(self, a: Scalar, b: Scalar) -> bool | Native:
        return self._backend.less(a, b)

    def if_else(self, cond: bool | Native, a: Scalar, b: Scalar) -> SymbolicScalar:
        return self._backend.select(cond, a, b)

    def shared(self, a: Scalar) -> SymbolicScalar:
        """``a`` as one node, computed once: products with it stay binary instead of expanding it
        into its terms (e.g. cos q = c² − s² of a joint, reused by every frame vector)."""
        value = self._backend.lift(a)
        return value if self._backend.is_exact(value) else self._backend.lift(self._backend.native(value))

    def __getattr__(self, fn: str) -> Callable[..., SymbolicScalar]:
        if fn not in EXACT_FUNCTIONS:
            raise AttributeError(f"no math function {fn!r}; known: {', '.join(MATH_FUNCTIONS)}")
        return lambda *args: self._backend.call(fn, *args)


EXACT_FUNCTIONS = {
    "sqrt": sympy.sqrt, "sin": sympy.sin, "cos": sympy.cos, "tan": sympy.tan, "asin": sympy.asin,
    "acos": sympy.acos, "atan": sympy.atan, "atan2": sympy.atan2, "exp": sympy.exp, "log": sympy.log,
    "sinh": sympy.sinh, "cosh": sympy.cosh, "tanh": sympy.tanh, "asinh": sympy.asinh,
    "acosh": sympy.acosh, "atanh": sympy.atanh, "fabs": sympy.Abs,
}
MATH_FUNCTIONS = tuple(EXACT_FUNCTIONS)
