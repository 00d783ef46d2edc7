"""Product tables of the reference interpreter, derived the plain way through an orthonormal frame.

1. In an orthonormal frame the product of two basis blades is a sign times a blade: the sign is the
   parity of the swaps that sort the concatenated vectors, times the squares of the shared vectors.
2. Every blade of the algebra (the outer product of its basis vectors in bit order) is expanded in
   the frame's blades; these columns form the change-of-basis matrix ``B`` (exact rationals), and
   its inverse is taken exactly with sympy.
3. The geometric product of two algebra blades is then ``B⁻¹ (B eᵢ ⋅ B eⱼ)``, computed exactly and
   stored as a dense float64 Cayley tensor ``gp[i, j, k]``. Every other product is a grade selection
   of it: algebra blades are homogeneous, so ``⟨eᵢ eⱼ⟩_g`` is the part of ``gp[i, j]`` on blades of
   grade ``g``.

Nothing here depends on the compiler (``gagen.algebra.blade_rules``): only the algebra description.
Frames must have rational entries (all presets do).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from fractions import Fraction
from functools import cache

import numpy as np
import sympy

from gagen.algebra.signature import Algebra

Sparse = dict[int, Fraction]  # blade bitmask -> exact coefficient


# -- the orthonormal rule ----------------------------------------------------------------------------
def bits(mask: int) -> list[int]:
    """Indices of the vectors in a blade, increasing."""
    return [i for i in range(mask.bit_length()) if mask >> i & 1]


def reorder_sign(a: int, b: int) -> int:
    """(−1)^(swaps needed to sort the vectors of ``a`` followed by those of ``b``)."""
    swaps = sum(1 for i in bits(a) for j in bits(b) if j < i)
    return -1 if swaps % 2 else 1


def ortho_gp(a: int, b: int, squares: tuple[int, ...]) -> tuple[int, int]:
    """Geometric product of two orthonormal blades: (sign, blade), sign 0 if a null vector is shared."""
    sign = reorder_sign(a, b)
    for i in bits(a & b):
        sign *= squares[i]
    return sign, a ^ b


def ortho_op(a: int, b: int) -> tuple[int, int]:
    """Outer product of two orthonormal blades: (sign, blade), sign 0 if they share a vector."""
    return (0 if a & b else reorder_sign(a, b)), a | b


# -- change of basis ------------------------------------------------------------------------------------
def _fraction(x: sympy.Expr) -> Fraction:
    x = sympy.nsimplify(x)
    if not x.is_Rational:
        raise ValueError(f"the interpreter needs rational frame entries, got {x}")
    return Fraction(int(x.p), int(x.q))


def blade_in_frame(algebra: Algebra, mask: int) -> Sparse:
    """The algebra blade ``mask`` (outer product of its basis vectors) expanded in frame blades."""
    result: Sparse = {0: Fraction(1)}
    for i in bits(mask):
        vector = {1 << j: _fraction(c) for j, c in enumerate(algebra.frame[i]) if c != 0}
        product: Sparse = defaultdict(Fraction)
        for a, ca in result.items():
            for b, cb in vector.items():
                sign, c = ortho_op(a, b)
                if sign:
                    product[c] += sign * ca * cb
        result = {k: v for k, v in product.items() if v}
    return result


@dataclass(frozen=True)
class ChangeOfBasis:
    """``to_frame[:, i]`` = frame coefficients of algebra blade ``i``; ``from_frame`` is its inverse."""

    to_frame: tuple[tuple[Fraction, ...], ...]
    from_frame: tuple[tuple[Fraction, ...], ...]


@cache
def change_of_basis(algebra: Algebra) -> ChangeOfBasis:
    if len(algebra.frame_squares) != algebra.dimension:
        raise ValueError("the interpreter needs as many frame vectors as basis vectors")
    n = algebra.size
    columns = [blade_in_frame(algebra, m) for m in range(n)]
    b = [[columns[i].get(a, Fraction(0)) for i in range(n)] for a in range(n)]
    inverse = sympy.Matrix(n, n, lambda r, c: sympy.Rational(b[r][c].numerator, b[r][c].denominator)).inv()
    b_inv = [[_fraction(inverse[r, c]) for c in range(n)] for r in range(n)]
    return ChangeOfBasis(tuple(map(tuple, b)), tuple(map(tuple, b_inv)))


# -- Cayley tensors -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Tables:
    """Dense float64 tables of one algebra, all in its own blade basis (index = bitmask).

    ``gp``, ``op``, ``lc``, ``rc``: ``[i, j, k]`` = coefficient of blade ``k`` in the product of blades
    ``i`` and ``j``. ``grades[k]`` = grade of blade ``k``. ``dual`` and ``undual`` are matrices acting
    on coefficient vectors (``dual @ x``).
    """

    gp: np.ndarray
    op: np.ndarray
    lc: np.ndarray
    rc: np.ndarray
    grades: np.ndarray
    dual: np.ndarray
    undual: np.ndarray


def exact_gp(algebra: Algebra) -> list[list[Sparse]]:
    """Exact geometric product of every pair of algebra blades, in the algebra's basis."""
    basis = change_of_basis(algebra)
    n = algebra.size
    cols = [{a: basis.to_frame[a][i] for a in range(n) if basis.to_frame[a][i]} for i in range(n)]
    back = [{k: basis.from_frame[k][c] for k in range(n) if basis.from_frame[k][c]} for c in range(n)]
    table: list[list[Sparse]] = []
    for i in range(n):
        row = []
        for j in range(n):
            in_frame: Sparse = defaultdict(Fraction)
            for a, ca in cols[i].items():
                for b, cb in cols[j].items():
                    sign, c = ortho_gp(a, b, algebra.frame_squares)
                    if sign:
                        in_frame[c] += sign * ca * cb
            result: Sparse = defaultdict(Fraction)
            for c, v in in_frame.items():
                for k, w in back[c].items():
                    result[k] += w * v
            row.append({k: v for k, v in result.items() if v})
        table.append(row)
    return table


@cache
def tables(algebra: Algebra) -> Tables:
    """All product tables of ``algebra`` (cached)."""
    n = algebra.size
    gp = np.zeros((n, n, n))
    for i, row in enumerate(exact_gp(algebra)):
        for j, entry in enumerate(row):
            for k, v in entry.items():
                gp[i, j, k] = float(v)
    g = np.array([algebra.grade(m) for m in range(n)])
    gi, gj, gk = g[:, None, None], g[None, :, None], g[None, None, :]
    op = np.where(gk == gi + gj, gp, 0.0)
    lc = np.where(gk == gj - gi, gp, 0.0)
    rc = np.where(gk == gi - gj, gp, 0.0)
    dual, undual = _duality(algebra, gp, op)
    for t in (gp, op, lc, rc, g, dual, undual):
        t.flags.writeable = False
    return Tables(gp, op, lc, rc, g, dual, undual)


def _duality(algebra: Algebra, gp: np.ndarray, op: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Matrices of dual and undual (see ``gagen.algebra.protocol``)."""
    n, full = algebra.size, algebra.pseudoscalar
    if not algebra.is_degenerate:
        # right multiplication by I and by I⁻¹ = I / I² (I² is a scalar): (X I)[k] = Σᵢ X[i] gp[i, I, k]
        undual = gp[:, full, :].T.copy()
        return undual / gp[full, full, 0], undual
    # right complement: e_A ∧ dual(e_A) = I, with e_A ∧ e_comp = s I, s = ±1 (metric-free)
    dual, undual = np.zeros((n, n)), np.zeros((n, n))
    for a in range(n):
        comp = full ^ a
        s = op[a, comp, full]
        if s not in (1.0, -1.0):
            raise ValueError("complement sign must be ±1")
        dual[comp, a] = s  # 1/s = s
        undual[a, comp] = s
    return dual, undual
