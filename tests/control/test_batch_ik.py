"""Batched cooperative IK (``gagen.control.batch_ik``) on the CPU with the C column batch: targets spanned
by random in-limit configurations of the three Pandas are reached, checked by another kernel (the
similarity V_Sc(q*) against the target) and the joint box; setting solved targets aside changes nothing
but the work; a NaN target fails alone. The same code runs on the GPU with the CUDA kernels
(benchmarks/cuda_gpu.py)."""

from __future__ import annotations

import numpy as np
import pytest

from gagen.apps.cooperative.bundled import system_module
from gagen.check import joint_limits
from gagen.control.batch_ik import solve_batch
from gagen.registry import bundled_specs
from gagen.robots.spec import load_system

TOL = 1e-9


@pytest.fixture(scope="module")
def pandas():
    module = system_module("three_pandas_circle")
    system, _ = load_system(bundled_specs()["three_pandas_circle"])
    lower, upper, _ = joint_limits(system)

    def task(q, V):
        return module.c.task.batch_columns(np.ascontiguousarray(q), np.ascontiguousarray(V))

    return module, task, lower, upper


def _targets(module, lower, upper, count, seed):
    q = np.random.default_rng(seed).uniform(lower, upper, (count, lower.size)).T
    return np.ascontiguousarray(module.c.similarity.batch_columns(np.ascontiguousarray(q))[0])


def test_reaches_spanned_targets_inside_the_box(pandas):
    module, task, lower, upper = pandas
    targets = _targets(module, lower, upper, 40, 0)
    seeds = np.random.default_rng(1).uniform(lower, upper, (16, lower.size)).T
    result = solve_batch(task, targets, seeds, lower, upper, iterations=40, tol=TOL)
    assert result.success_rate >= 0.975, result.best_error
    S = seeds.shape[1]
    for t in np.flatnonzero(result.success):
        q = result.q[:, t * S + result.best[t]]
        assert np.all(q >= lower) and np.all(q <= upper)
        reached = np.asarray(module.c.similarity(q)[0])
        # ‖e‖ = ‖log(V_Sc~ V_Sd)‖ ≤ 1e-9 puts the similarity itself within a few 1e-9 of the target
        assert np.abs(reached - targets[:, t]).max() <= 20 * TOL * max(1.0, np.abs(targets[:, t]).max())


def test_setting_solved_targets_aside_keeps_the_answers(pandas):
    module, task, lower, upper = pandas
    targets = _targets(module, lower, upper, 12, 2)
    seeds = np.random.default_rng(3).uniform(lower, upper, (8, lower.size)).T
    every = solve_batch(task, targets, seeds, lower, upper, iterations=30, tol=TOL, compact_every=0)
    compacted = solve_batch(task, targets, seeds, lower, upper, iterations=30, tol=TOL, compact_every=5)
    assert np.array_equal(every.success, compacted.success)
    # a target solved by the fifth iteration keeps the iterate it had then: the same in both runs
    # up to the iterations the full run went on with; an unsolved one ran every iteration in both
    unsolved = ~every.success
    S = seeds.shape[1]
    for t in np.flatnonzero(unsolved):
        columns = slice(t * S, (t + 1) * S)
        assert np.array_equal(every.q[:, columns], compacted.q[:, columns])


def test_a_nan_target_fails_alone(pandas):
    module, task, lower, upper = pandas
    targets = _targets(module, lower, upper, 4, 4)
    targets[:, 1] = np.nan
    seeds = np.random.default_rng(5).uniform(lower, upper, (16, lower.size)).T
    result = solve_batch(task, targets, seeds, lower, upper, iterations=40, tol=TOL)
    assert not result.success[1] and result.success[[0, 2, 3]].all()
    assert np.isfinite(result.q).all()


def test_what_the_solve_cannot_take_is_one_line(pandas):
    module, task, lower, upper = pandas
    targets = _targets(module, lower, upper, 2, 6)
    seeds = np.random.default_rng(7).uniform(lower, upper, (2, lower.size)).T
    cases = [((targets[:11], seeds, lower, upper), "shape \\(12, T\\)"),
             ((targets, seeds[:, :0], lower, upper), "seeds"),
             ((targets, np.where(seeds > 0, np.inf, seeds), lower, upper), "finite joint columns"),
             ((targets, seeds, lower[:5], upper), "joint bounds"),
             ((targets, seeds, upper, lower), "lower <= upper"),
             ((targets, seeds, np.full_like(lower, np.nan), upper), "joint bounds")]
    for args, message in cases:
        with pytest.raises(ValueError, match=message) as raised:
            solve_batch(task, *args)
        assert "\n" not in str(raised.value)
    with pytest.raises(ValueError, match="iterations"):
        solve_batch(task, targets, seeds, lower, upper, iterations=0)
