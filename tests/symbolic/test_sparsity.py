"""Sparsity and op counts: the compiler expands only what can contribute (pinned numbers)."""

from gagen.algebra import SparseMultivector, cga3d
from gagen.model.conformal import MOTOR
from gagen.symbolic import CasadiBackend, SympyBackend
from gagen.symbolic.flatten import flatten

POINT = ("e0", "e1", "e2", "e3", "einf")


def _motors(backend):
    a = cga3d()
    return (SparseMultivector.symbolic(a, backend, "a", MOTOR),
            SparseMultivector.symbolic(a, backend, "b", MOTOR))


def test_motor_product_is_the_dual_quaternion_optimum():
    for backend in (CasadiBackend(), SympyBackend()):
        m, n = _motors(backend)
        product = m * n
        assert product.support == tuple(cga3d().blade(b) for b in MOTOR)
        ops = flatten("mm", [("a", m), ("b", n)], [("m", product)], backend).op_count
        assert (ops.mul, ops.add, ops.neg, ops.div, ops.calls) == (48, 40, 0, 0, {}), backend.name


def test_motor_sandwich_of_a_point_op_count_is_pinned():
    """M P M~ for a general 8-coefficient motor and a general 5-coefficient point."""
    backend = CasadiBackend()
    m, _ = _motors(backend)
    p = SparseMultivector.symbolic(cga3d(), backend, "p", POINT)
    moved = m.sandwich(p)
    assert moved.support == tuple(cga3d().blade(b) for b in POINT)
    ops = flatten("mpm", [("m", m), ("p", p)], [("x", moved)], backend).op_count
    assert (ops.mul, ops.add, ops.neg, ops.div) == (45, 35, 1, 0)  # commutator form (was 76, 59, 0, 0)


def test_products_skip_pairs_that_cannot_contribute():
    """Two translators (1, e1∞, e2∞, e3∞) compose with 7 multiplications: the e∞e∞ pairs are never formed."""
    backend = CasadiBackend()
    a = cga3d()
    blades = ("1", "e1inf", "e2inf", "e3inf")
    t = SparseMultivector.symbolic(a, backend, "t", blades)
    u = SparseMultivector.symbolic(a, backend, "u", blades)
    product = t * u
    assert product.support == tuple(a.blade(b) for b in blades)
    ops = flatten("tt", [("t", t), ("u", u)], [("v", product)], backend).op_count
    assert (ops.mul, ops.add) == (7, 3)
