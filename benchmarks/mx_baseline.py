"""Baseline for the OCP benchmark: gagen's GA formulas evaluated directly on CasADi MX, unflattened.

:class:`MXMultiVector` is the reference interpreter (``gagen.interp.multivector``) with its float64
coefficient arrays replaced, wherever a value depends on a symbol, by a CasADi MX column (32 x 1,
structurally sparse). Every product is the interpreter's dense-table contraction, written as MX
matrix products with the same tables as sparse DM constants:

    result = reshape(a^T T2, n, n) b,    T2 = table.reshape(n, n * n)

and the unary operations are the interpreter's sign vectors and dual matrices. Multivectors whose
coefficients are all constants (fixed joint transforms, basis vectors) stay numpy arrays and are
combined exactly as the interpreter does, so a constant factor of a product is folded into one DM
matrix (``M^T b``) instead of becoming MX nodes. Nothing is expanded: the result is an MX graph of
matrix products, one per GA operation, which is the "unflattened" form the generated, flattened
kernels are compared against.

Scalars drawn from a symbolic multivector (``X[blade]``, ``X.sp(Y)``, the ``math`` functions) are
:class:`Scalar` wrappers around 1 x 1 MX expressions: the model multiplies them by exact sympy
constants (joint axes), which CasADi cannot convert, so the wrapper turns those into floats.

    python benchmarks/mx_baseline.py     # checks task_mx against the generated CasADi task
"""

from __future__ import annotations

import math
import numbers
import sys
from collections.abc import Iterable, Mapping, Sequence
from functools import cache
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gagen.algebra.signature import Algebra, cga3d  # noqa: E402
from gagen.interp.frame import tables  # noqa: E402
from gagen.interp.multivector import _mask  # noqa: E402
from gagen.interp.scalar_math import INTERP_MATH  # noqa: E402
from gagen.model.conformal import SIMILARITY  # noqa: E402
from gagen.robots.system import System, task_error  # noqa: E402

BladeKey = int | str


# -- scalars ----------------------------------------------------------------------------------------
def _raw(x: Any) -> Any:
    """An MX for a symbolic scalar, a float for a constant (numbers, numpy and sympy numbers)."""
    if isinstance(x, Scalar):
        return x.mx
    if isinstance(x, (ca.MX, ca.SX, ca.DM)):
        return x
    return float(x)


def _wrap(x: Any) -> Any:
    return Scalar(x) if isinstance(x, ca.MX) else x


class Scalar:
    """A 1 x 1 MX expression that accepts sympy numbers as operands (converted to floats)."""

    __slots__ = ("mx",)
    __array_ufunc__ = None

    def __init__(self, mx: ca.MX) -> None:
        self.mx = mx

    def __add__(self, o: Any) -> Any:
        return _scalar_op(self, o, lambda a, b: a + b)

    def __radd__(self, o: Any) -> Any:
        return _scalar_op(o, self, lambda a, b: a + b)

    def __sub__(self, o: Any) -> Any:
        return _scalar_op(self, o, lambda a, b: a - b)

    def __rsub__(self, o: Any) -> Any:
        return _scalar_op(o, self, lambda a, b: a - b)

    def __mul__(self, o: Any) -> Any:
        if isinstance(o, MXMultiVector):
            return NotImplemented
        return _scalar_op(self, o, lambda a, b: a * b)

    def __rmul__(self, o: Any) -> Any:
        return _scalar_op(o, self, lambda a, b: a * b)

    def __truediv__(self, o: Any) -> Any:
        return _scalar_op(self, o, lambda a, b: a / b)

    def __rtruediv__(self, o: Any) -> Any:
        return _scalar_op(o, self, lambda a, b: a / b)

    def __pow__(self, o: Any) -> Any:
        return _scalar_op(self, o, lambda a, b: a ** b)

    def __neg__(self) -> Scalar:
        return Scalar(-self.mx)

    def __pos__(self) -> Scalar:
        return self

    def __abs__(self) -> Scalar:
        return Scalar(ca.fabs(self.mx))

    def __repr__(self) -> str:
        return f"Scalar({self.mx})"


def _scalar_op(a: Any, b: Any, f: Any) -> Any:
    if isinstance(a, MXMultiVector) or isinstance(b, MXMultiVector):
        return NotImplemented
    return _wrap(f(_raw(a), _raw(b)))


def _is_symbolic(*xs: Any) -> bool:
    return any(isinstance(x, (Scalar, ca.MX)) for x in xs)


def _unary(name: str) -> Any:
    f, g = getattr(ca, name), getattr(INTERP_MATH, name)

    def apply(x: Any) -> Any:
        return Scalar(f(_raw(x))) if _is_symbolic(x) else g(float(x))

    apply.__name__ = name
    return staticmethod(apply)


class MXMath:
    """``math`` for MX scalars: CasADi's functions on symbols, Python's on constants."""

    sqrt, sin, cos, tan = _unary("sqrt"), _unary("sin"), _unary("cos"), _unary("tan")
    asin, acos, atan = _unary("asin"), _unary("acos"), _unary("atan")
    exp, log = _unary("exp"), _unary("log")
    sinh, cosh, tanh = _unary("sinh"), _unary("cosh"), _unary("tanh")
    asinh, acosh, atanh = _unary("asinh"), _unary("acosh"), _unary("atanh")
    fabs = _unary("fabs")

    @staticmethod
    def atan2(y: Any, x: Any) -> Any:
        return Scalar(ca.atan2(_raw(y), _raw(x))) if _is_symbolic(y, x) else math.atan2(float(y), float(x))

    @staticmethod
    def lt(a: Any, b: Any) -> Any:
        return Scalar(_raw(a) < _raw(b)) if _is_symbolic(a, b) else float(a) < float(b)

    @staticmethod
    def if_else(cond: Any, a: Any, b: Any) -> Any:
        if not _is_symbolic(cond):
            return a if cond else b
        return Scalar(ca.if_else(_raw(cond), ca.MX(_raw(a)), ca.MX(_raw(b))))

    @staticmethod
    def shared(a: Any) -> Any:
        return a  # an MX node is already shared wherever it is reused


MX_MATH = MXMath()


# -- tables as DM -----------------------------------------------------------------------------------
def _sparse_dm(a: np.ndarray) -> ca.DM:
    return ca.sparsify(ca.DM(np.asarray(a, dtype=np.float64)))


@cache
def _flat_table(algebra: Algebra, name: str) -> ca.DM:
    """T2 = table.reshape(n, n * n) as a sparse DM (row i, column j * n + k)."""
    t = getattr(tables(algebra), name)
    n = t.shape[0]
    return _sparse_dm(t.reshape(n, n * n))


@cache
def _matrix(algebra: Algebra, name: str) -> ca.DM:
    return _sparse_dm(getattr(tables(algebra), name))


@cache
def _signs(algebra: Algebra, kind: str) -> np.ndarray:
    k = tables(algebra).grades
    return (-1.0) ** (k * (k - 1) // 2) if kind == "reverse" else (-1.0) ** k


def _is_number(x: Any) -> bool:
    return isinstance(x, numbers.Real) or (isinstance(x, np.ndarray) and x.ndim == 0)


# -- multivectors -----------------------------------------------------------------------------------
class MXMultiVector:
    """A multivector whose coefficients are a numpy array (constant) or an MX column (symbolic)."""

    __slots__ = ("algebra", "coeffs")
    __array_ufunc__ = None

    def __init__(self, algebra: Algebra, coeffs: Any) -> None:
        self.algebra = algebra
        if isinstance(coeffs, ca.MX):
            if coeffs.shape != (algebra.size, 1):
                raise ValueError(f"{algebra.name} needs a {algebra.size} x 1 MX, got {coeffs.shape}")
            self.coeffs = coeffs
        else:
            values = np.array(coeffs, dtype=np.float64)
            if values.shape != (algebra.size,):
                raise ValueError(f"{algebra.name} needs {algebra.size} coefficients, got {values.shape}")
            self.coeffs = values

    @property
    def symbolic(self) -> bool:
        return isinstance(self.coeffs, ca.MX)

    # -- construction ---------------------------------------------------------------------------------
    @classmethod
    def zero(cls, algebra: Algebra) -> MXMultiVector:
        return cls(algebra, np.zeros(algebra.size))

    @classmethod
    def from_coefficients(cls, algebra: Algebra, values: Any) -> MXMultiVector:
        """From an MX column (symbolic) in bitmask order."""
        return cls(algebra, values)

    def make(self, coefficients: Mapping[BladeKey, Any]) -> MXMultiVector:
        n = self.algebra.size
        constant = np.zeros(n)
        symbolic: dict[int, Any] = {}
        for blade, c in coefficients.items():
            m = _mask(self.algebra, blade)
            if _is_symbolic(c):
                symbolic[m] = symbolic[m] + _raw(c) if m in symbolic else _raw(c)
            else:
                constant[m] += float(c)
        if not symbolic:
            return MXMultiVector(self.algebra, constant)
        entries = [symbolic[m] + constant[m] if m in symbolic and constant[m] != 0
                   else symbolic[m] if m in symbolic
                   else ca.MX(constant[m]) if constant[m] != 0 else ca.MX(1, 1) for m in range(n)]
        return MXMultiVector(self.algebra, ca.vertcat(*entries))

    def _like(self, coeffs: Any) -> MXMultiVector:
        return MXMultiVector(self.algebra, coeffs)

    @property
    def math(self) -> Any:
        return MX_MATH

    # -- coefficients ---------------------------------------------------------------------------------
    def __getitem__(self, blade: BladeKey) -> Any:
        m = _mask(self.algebra, blade)
        if not self.symbolic:
            return float(self.coeffs[m])
        if not self.coeffs.sparsity().has_nz(m, 0):
            return 0.0
        return Scalar(self.coeffs[m])

    def scalar(self) -> Any:
        return self[0]

    def __repr__(self) -> str:
        return f"MXMultiVector({self.algebra.name}: {self.coeffs})"

    # -- linear structure -----------------------------------------------------------------------------
    def _coerce(self, other: Any) -> Any:
        if isinstance(other, MXMultiVector):
            if other.algebra != self.algebra:
                raise TypeError(f"cannot mix {self.algebra.name} and {other.algebra.name} multivectors")
            return other
        if _is_number(other) or _is_symbolic(other):
            return self.make({0: other})
        return NotImplemented

    def _require(self, other: Any) -> MXMultiVector:
        o = self._coerce(other)
        if o is NotImplemented:
            raise TypeError(f"cannot combine a multivector with {type(other).__name__}")
        return o

    @staticmethod
    def _column(c: Any) -> Any:
        return c if isinstance(c, ca.MX) else _sparse_dm(c)

    def _linear(self, o: MXMultiVector, sign: float) -> MXMultiVector:
        if not self.symbolic and not o.symbolic:
            return self._like(self.coeffs + sign * o.coeffs)
        a, b = self._column(self.coeffs), self._column(o.coeffs)
        return self._like(ca.MX(a + b if sign > 0 else a - b))

    def __add__(self, other: Any) -> MXMultiVector:
        o = self._coerce(other)
        return NotImplemented if o is NotImplemented else self._linear(o, 1.0)

    __radd__ = __add__

    def __sub__(self, other: Any) -> MXMultiVector:
        o = self._coerce(other)
        return NotImplemented if o is NotImplemented else self._linear(o, -1.0)

    def __rsub__(self, other: Any) -> MXMultiVector:
        o = self._coerce(other)
        return NotImplemented if o is NotImplemented else o._linear(self, -1.0)

    def __neg__(self) -> MXMultiVector:
        return self._like(-self.coeffs)

    def _scaled(self, s: Any) -> MXMultiVector:
        if not _is_symbolic(s):
            return self._like(self.coeffs * float(s))
        return self._like(self._column(self.coeffs) * _raw(s))

    def __truediv__(self, scalar: Any) -> MXMultiVector:
        if _is_symbolic(scalar):
            return self._like(self._column(self.coeffs) / _raw(scalar))
        if not _is_number(scalar):
            return NotImplemented
        if scalar == 0:
            raise ZeroDivisionError("multivector divided by zero")
        return self._like(self.coeffs / float(scalar))

    # -- products -------------------------------------------------------------------------------------
    def _product(self, name: str, other: Any) -> MXMultiVector:
        o = self._require(other)
        n = self.algebra.size
        table = getattr(tables(self.algebra), name)
        if not self.symbolic and not o.symbolic:  # the interpreter, verbatim
            return self._like(o.coeffs @ (self.coeffs @ table.reshape(n, n * n)).reshape(n, n))
        if not self.symbolic:  # result = M^T b, M[j, k] = Σ_i a_i T[i, j, k]: one constant matrix
            m = (self.coeffs @ table.reshape(n, n * n)).reshape(n, n)
            return self._like(ca.mtimes(_sparse_dm(m.T), o.coeffs))
        if not o.symbolic:  # result = N^T a, N[i, k] = Σ_j b_j T[i, j, k]
            m = np.einsum("j,ijk->ik", o.coeffs, table)
            return self._like(ca.mtimes(_sparse_dm(m.T), self.coeffs))
        # result[k] = Σ_ij a_i b_j T[i, j, k]: (a^T T2) reshaped column-major is M^T
        t2 = _flat_table(self.algebra, name)
        return self._like(ca.mtimes(ca.reshape(ca.mtimes(self.coeffs.T, t2), n, n), o.coeffs))

    def gp(self, other: Any) -> MXMultiVector:
        return self._product("gp", other)

    def op(self, other: Any) -> MXMultiVector:
        return self._product("op", other)

    def lc(self, other: Any) -> MXMultiVector:
        return self._product("lc", other)

    def rc(self, other: Any) -> MXMultiVector:
        return self._product("rc", other)

    def inner(self, other: Any) -> MXMultiVector:
        return self.lc(other)

    def sp(self, other: Any) -> Any:
        """⟨A B⟩₀, as the interpreter computes it: the geometric product's scalar coefficient."""
        return self.gp(other).scalar()

    def commutator(self, other: Any) -> MXMultiVector:
        o = self._require(other)
        return (self.gp(o) - o.gp(self)) / 2

    def regressive(self, other: Any) -> MXMultiVector:
        return self.dual().op(self._require(other).dual()).undual()

    def __mul__(self, other: Any) -> MXMultiVector:
        if _is_number(other) or _is_symbolic(other):
            return self._scaled(other)
        return self.gp(other) if isinstance(other, MXMultiVector) else NotImplemented

    def __rmul__(self, other: Any) -> MXMultiVector:
        if _is_number(other) or _is_symbolic(other):
            return self._scaled(other)
        return NotImplemented

    def __xor__(self, other: Any) -> MXMultiVector:
        return self.op(other)

    def __rxor__(self, other: Any) -> MXMultiVector:
        o = self._coerce(other)
        return NotImplemented if o is NotImplemented else o.op(self)

    def __or__(self, other: Any) -> MXMultiVector:
        return self.lc(other)

    def __ror__(self, other: Any) -> MXMultiVector:
        o = self._coerce(other)
        return NotImplemented if o is NotImplemented else o.lc(self)

    def __and__(self, other: Any) -> MXMultiVector:
        return self.regressive(other)

    def __rand__(self, other: Any) -> MXMultiVector:
        o = self._coerce(other)
        return NotImplemented if o is NotImplemented else o.regressive(self)

    def __invert__(self) -> MXMultiVector:
        return self.reverse()

    # -- unary ----------------------------------------------------------------------------------------
    def _signed(self, signs: np.ndarray) -> MXMultiVector:
        if not self.symbolic:
            return self._like(self.coeffs * signs)
        return self._like(self.coeffs * ca.DM(signs))  # keeps the structural zeros

    def reverse(self) -> MXMultiVector:
        return self._signed(_signs(self.algebra, "reverse"))

    def involute(self) -> MXMultiVector:
        return self._signed(_signs(self.algebra, "involute"))

    def conjugate(self) -> MXMultiVector:
        return self.involute().reverse()

    def grade(self, k: int | Iterable[int]) -> MXMultiVector:
        keep = [k] if isinstance(k, numbers.Integral) else list(k)
        mask = np.isin(tables(self.algebra).grades, keep)
        if not self.symbolic:
            return self._like(np.where(mask, self.coeffs, 0.0))
        return self._like(self.coeffs * _sparse_dm(mask.astype(np.float64)))  # drops the other rows

    @property
    def grades(self) -> frozenset[int]:
        """Grades with a non-zero coefficient: numerically (constants) or structurally (MX)."""
        g = tables(self.algebra).grades
        if not self.symbolic:
            return frozenset(int(x) for x in g[self.coeffs != 0])
        return frozenset(int(g[r]) for r in self.coeffs.sparsity().row())

    def dual(self) -> MXMultiVector:
        if not self.symbolic:
            return self._like(tables(self.algebra).dual @ self.coeffs)
        return self._like(ca.mtimes(_matrix(self.algebra, "dual"), self.coeffs))

    def undual(self) -> MXMultiVector:
        if not self.symbolic:
            return self._like(tables(self.algebra).undual @ self.coeffs)
        return self._like(ca.mtimes(_matrix(self.algebra, "undual"), self.coeffs))

    def norm_squared(self) -> Any:
        return self.sp(self.reverse())

    def inverse(self) -> MXMultiVector:
        return self.reverse() / self.norm_squared()

    def normalized(self) -> MXMultiVector:
        m = self.math
        return self / m.sqrt(m.fabs(self.norm_squared()))

    def sandwich(self, x: Any) -> MXMultiVector:
        x = self._require(x)
        return self.gp(x).gp(self.reverse()).grade(x.grades)

    def column(self, blades: Sequence[BladeKey]) -> ca.MX:
        """The coefficients on ``blades`` as an MX column."""
        return ca.vertcat(*[ca.MX(_raw(self[b])) for b in blades])


# -- the task function ------------------------------------------------------------------------------
def task_mx(system: System, name: str = "task_mx") -> ca.Function:
    """e(q, V_Sd) = log(V_Sc(q)~ V_Sd) on MX, unflattened: outputs e on SIMILARITY_GENERATOR order
    as the generated ``task`` (its first output)."""
    from gagen.model.conformal import SIMILARITY_GENERATOR

    algebra = cga3d()
    zero = MXMultiVector.zero(algebra)
    q = ca.MX.sym("q", system.dof)
    v = ca.MX.sym("V_Sd", len(SIMILARITY))
    desired = zero.make({b: Scalar(v[i]) for i, b in enumerate(SIMILARITY)})
    e = task_error(zero, system, [Scalar(q[i]) for i in range(system.dof)], desired)
    return ca.Function(name, [q, v], [e.column(SIMILARITY_GENERATOR)], ["q", "V_Sd"], ["e"])


def main() -> int:
    import time

    from gagen.apps.cooperative import scenarios
    from gagen.apps.cooperative.bundled import bundled_systems, ready_configuration

    name = "three_pandas_circle"
    system = bundled_systems()[name]
    started = time.perf_counter()
    f = task_mx(system)
    print(f"task_mx built in {time.perf_counter() - started:.2f} s: {f.n_instructions()} MX instructions")
    module = scenarios.module(name)
    generated = module.casadi.task
    print(f"generated task: {generated.n_instructions()} SX instructions, outputs {generated.name_out()}")
    rng = np.random.default_rng(0)
    q0 = np.array(ready_configuration(system), dtype=float)
    v_sd = np.array(module.c.similarity(q0 + 0.1)[0], dtype=float)
    worst = 0.0
    for _ in range(5):
        q = q0 + 0.2 * rng.standard_normal(q0.size)
        a = np.array(f(q, v_sd)).ravel()
        b = np.array(generated(q, v_sd)[0]).ravel()
        worst = max(worst, float(np.max(np.abs(a - b))))
        print(f"  |e| = {np.linalg.norm(b):.3e}, max |e_mx - e_generated| = {np.max(np.abs(a - b)):.2e}")
    print(f"max difference {worst:.2e}: {'match' if worst <= 1e-10 else 'MISMATCH'}")
    return 0 if worst <= 1e-10 else 1


if __name__ == "__main__":
    sys.exit(main())
