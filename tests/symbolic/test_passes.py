"""The optimisation passes report what they removed (``gagen.symbolic.passes``), on kernels whose
removable parts are known by hand."""

from __future__ import annotations

import numpy as np

import gagen
from gagen.kinds import algebra, vector
from gagen.symbolic.passes import PASSES


def _passes(fn, **declaration):
    return gagen.kernel(fn, **declaration).trace()


def test_cancelled_terms_never_reach_the_graph():
    # a b − b a of two vectors is a bivector; its grade-0 part cancels exactly (and a·b − b·a = 0)
    def commutes(a: vector, b: vector):
        return {"s": (a * b - b * a).scalar() + a.sp(b) - b.sp(a)}

    kernel = _passes(commutes, algebra="ga3d")
    assert kernel.passes["cancelled terms"] >= 6
    assert kernel.op_count.flops == 0  # the output is an exact 0


def test_sparsity_pruning_counts_the_blade_pairs_skipped():
    # e1-vector times e23-bivector in ga3d: 3 × 3 pairs; all contribute in the geometric product,
    # but the outer product of a vector with a vector skips the 3 parallel pairs
    def wedge(a: vector, b: vector):
        return {"B": a ^ b}

    kernel = _passes(wedge, algebra="ga3d")
    assert kernel.passes["sparsity pruning"] == 3
    assert kernel.op_count.mul == 6 and kernel.op_count.add == 3


def test_constant_folding_and_exact_zeros():
    # a quarter turn about z as exact constants: the rotated e1 is exactly e2, no operation left
    def turn(x: vector, ga: algebra):
        r = ga.make({"1": ga.math.sqrt(0.5), "e12": -ga.math.sqrt(0.5)})
        return {"y": r.sandwich(x)}

    kernel = _passes(turn, algebra="ga3d")
    assert kernel.passes["constant folding"] > 0
    x = np.array([1.0, 2.0, 3.0])
    y = kernel.function(x)
    np.testing.assert_allclose(np.ravel(y), [-2.0, 1.0, 3.0], rtol=0, atol=1e-15)


def test_cse_reports_the_operations_it_removed():
    # a·b is one node (node sharing), but sin of it is called twice: CSE keeps one call
    def repeated(a: vector, b: vector, ga: algebra):
        m = ga.math
        return {"u": m.sin(a.sp(b)) * 2.0, "v": m.sin(a.sp(b)) * 3.0}

    kernel = _passes(repeated, algebra="ga3d")
    assert kernel.passes["node sharing"] == 1
    assert kernel.passes["common subexpressions"] == 1
    assert kernel.op_count.calls == {"sin": 1} and kernel.op_count.flops == 3 + 2 + 2
    assert list(kernel.passes) == list(PASSES)
