"""Cooperative task-space kernels of every bundled system against the interpreter: values, the
similarity property X_c = V_Sc X_u V_Sc~, and every Jacobian against central differences."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from gagen.algebra.signature import cga3d
from gagen.interp import MultiVector
from gagen.kernels import build_system_kernels
from gagen.model.conformal import SIMILARITY, SIMILARITY_GENERATOR
from gagen.model.cooperative import cooperative_primitive, similarity_of, task_error
from gagen.model.primitives import unit_primitive
from gagen.model.similarity import cooperative_similarity
from gagen.model.versors import exp_similarity, log_similarity
from gagen.robots.systems import bundled_systems, ready_configuration

ALG = cga3d()
ZERO = MultiVector.zero(ALG)
SYSTEMS = bundled_systems()


@cache
def _kernels(name):
    return build_system_kernels(SYSTEMS[name])


def _configurations(name, count, seed=0):
    rng = np.random.default_rng(seed)
    q0 = np.array(ready_configuration(SYSTEMS[name]))
    return [q0 + rng.uniform(-0.4, 0.4, q0.size) for _ in range(count)]


def _desired(seed=1):
    rng = np.random.default_rng(seed)
    b = MultiVector.from_blades(ALG, dict(zip(SIMILARITY_GENERATOR, rng.uniform(-0.5, 0.5, 7), strict=True)))
    return exp_similarity(b)


def _interp(name, q, desired):
    """The model on the interpreter (FK once; same formulas as similarity_of and task_error)."""
    system = SYSTEMS[name]
    xc = cooperative_primitive(ZERO, system, list(q))
    v, cond = cooperative_similarity(system.kind, xc)
    return {"X_c": xc, "V_Sc": v, "conditioning": cond, "log_V": log_similarity(v),
            "e": log_similarity(~v * desired)}


def _rows(x: MultiVector, blades):
    return np.array([x[b] for b in blades])


def _outputs(name, q, desired):
    k = _kernels(name)
    values = k.function(q, [desired[b] for b in SIMILARITY])
    return {n: np.asarray(v, dtype=float) for n, v in zip(k.function.name_out(), values, strict=True)}, k


@pytest.mark.parametrize("name", sorted(SYSTEMS))
def test_kernel_values_equal_interpreter_and_v_sc_moves_x_u_onto_x_c(name):
    desired = _desired()
    system = SYSTEMS[name]
    q = _configurations(name, 1)[0]  # the model's own entry points agree with the inlined ones
    v, _ = similarity_of(ZERO, system, list(q))
    np.testing.assert_allclose(v.coeffs, _interp(name, q, desired)["V_Sc"].coeffs, atol=1e-14)
    np.testing.assert_allclose(task_error(ZERO, system, list(q), desired).coeffs,
                               _interp(name, q, desired)["e"].coeffs, atol=1e-14)
    for q in _configurations(name, 20):
        out, k = _outputs(name, q, desired)
        ref = _interp(name, q, desired)
        assert ref["conditioning"] > 1e-6  # configurations near the ready pose are well-conditioned
        for key in ("X_c", "V_Sc", "log_V", "e"):
            np.testing.assert_allclose(out[key].ravel(), _rows(ref[key], k.blades[key]), atol=1e-10)
        assert abs(out["conditioning"].item() - ref["conditioning"]) < 1e-10
        moved = ref["V_Sc"].sandwich(unit_primitive(SYSTEMS[name].kind, ZERO)).coeffs
        xc = ref["X_c"].coeffs
        scale = moved @ xc / (xc @ xc)
        np.testing.assert_allclose(moved, scale * xc, atol=1e-10 * np.max(np.abs(xc)))


def _central_differences(name, q, desired, h=1e-6):
    cols = {key: [] for key in ("X_c", "V_Sc", "log_V", "e")}
    for i in range(q.size):
        step = np.zeros(q.size)
        step[i] = h
        plus, minus = _interp(name, q + step, desired), _interp(name, q - step, desired)
        for key in cols:
            cols[key].append((plus[key].coeffs - minus[key].coeffs) / (2 * h))
    return {key: np.array(c).T for key, c in cols.items()}


def _blade_rows(dense, blades):
    return dense[[ALG.blade(b) for b in blades], :]


@pytest.mark.parametrize("name", sorted(SYSTEMS))
def test_every_jacobian_equals_central_differences(name):
    desired = _desired()
    count = 20 if name == "three_pandas_circle" else 4
    for q in _configurations(name, count, seed=5):
        out, k = _outputs(name, q, desired)
        fd = _central_differences(name, q, desired)
        v = _interp(name, q, desired)["V_Sc"]
        np.testing.assert_allclose(out["J_c"], _blade_rows(fd["X_c"], k.blades["X_c"]), atol=2e-7)
        np.testing.assert_allclose(out["J_A"], _blade_rows(fd["V_Sc"], SIMILARITY), atol=2e-7)
        j_g = np.array([(~v * MultiVector(ALG, col) * -2).coeffs for col in fd["V_Sc"].T]).T
        np.testing.assert_allclose(out["J_G"], _blade_rows(j_g, SIMILARITY_GENERATOR), atol=2e-7)
        np.testing.assert_allclose(out["J_B"], _blade_rows(fd["log_V"], SIMILARITY_GENERATOR), atol=2e-7)
        np.testing.assert_allclose(out["J_Be"], _blade_rows(fd["e"], SIMILARITY_GENERATOR), atol=2e-7)


def test_three_panda_circle_kernel_cost_does_not_regress():
    """The chain rule through the similarity construction (not AD through the kinematics) keeps the
    21-DOF circle's kernels at 29 792 flops + 21 sin/cos together (AD through the kinematics: 113 044)."""
    from gagen.symbolic.flatten import casadi_op_count

    ops = casadi_op_count(_kernels("three_pandas_circle").function)
    assert ops.flops <= 30_000
    assert ops.calls["sin"] == ops.calls["cos"] == 21
