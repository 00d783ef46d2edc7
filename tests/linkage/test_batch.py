"""Many four-bars in one batched call (issue 15, item 5): the parametric kernels take each mechanism's
initial points, ``sweep`` follows all cranks at once, and the class found by simulation (does the crank
turn fully; does the rocker) equals Grashof's prediction for every sampled four-bar."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from gagen.apps.linkage.batch import classify, family, four_bar_points, grashof_class, sweep
from gagen.apps.linkage.kernels import initial_labels, initial_points, linkage_kernels
from gagen.apps.linkage.spec import load_linkage

FOUR_BAR = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "linkage" / "robots" / "four_bar.yaml"


def test_four_bar_points_close_the_loop_and_follow_the_spec_layout():
    linkage = load_linkage(FOUR_BAR)
    x = four_bar_points(4.0, 1.0, np.hypot(3, 3), 3.0)
    labels = initial_labels(linkage)
    assert len(x) == len(labels) == len(initial_points(linkage))
    point = {label[:-2]: x[i:i + 2] for i, label in enumerate(labels) if label.endswith("_x")}
    np.testing.assert_allclose(point["crank_B"], point["coupler_B"], atol=0)
    np.testing.assert_allclose(point["coupler_C"], point["rocker_C"], atol=0)
    assert np.linalg.norm(point["crank_B"]) == pytest.approx(1.0, abs=1e-15)
    assert np.linalg.norm(point["coupler_C"] - point["coupler_B"]) == pytest.approx(np.hypot(3, 3), abs=1e-14)
    assert np.linalg.norm(point["rocker_D"] - point["rocker_C"]) == pytest.approx(3.0, abs=1e-14)


@pytest.mark.parametrize(("lengths", "expected"), [
    ((4, 1, 4.243, 3), "crank-rocker"), ((1, 3, 3.5, 3), "double-crank"), ((3, 3.5, 1, 3), "double-rocker"),
    ((3, 2.5, 2, 3.9), "triple-rocker")])
def test_grashof_classes(lengths, expected):
    assert grashof_class(*lengths) == expected


def test_parametric_kernels_equal_the_fixed_ones_at_the_spec_points():
    """The family's constraints at the spec's own initial points are the four-bar's (interpreter)."""
    linkage = load_linkage(FOUR_BAR)
    fixed = {k.name: k for k in linkage_kernels(linkage)}["constraints"]
    family_kernel = {k.name: k for k in linkage_kernels(linkage, parametric=True)}["constraints"]
    rng = np.random.default_rng(2)
    R, theta = np.tile([1.0, 0, 0, 0], 2) + rng.normal(0, 0.05, 8), np.array([0.7])
    for a, b in zip(fixed.reference(R, theta), family_kernel.reference(R, theta, initial_points(linkage)),
                    strict=True):
        np.testing.assert_allclose(a, b, atol=1e-15)


@pytest.mark.compiling
def test_batched_sweep_classifies_four_bars_like_grashof():
    linkage = load_linkage(FOUR_BAR)
    rng = np.random.default_rng(0)
    points, predicted = [], []
    while len(points) < 120:
        lengths = rng.uniform(0.5, 3.0, 4)
        ordered = np.sort(lengths)
        if abs(ordered[0] + ordered[3] - ordered[1] - ordered[2]) < 0.05:  # change points: both classes
            continue
        x = four_bar_points(*lengths)
        if x is not None:
            points.append(x)
            predicted.append(grashof_class(*lengths))
    result = sweep(family(linkage), linkage, np.array(points), np.radians(np.arange(0.0, 361.0)))
    simulated = classify(linkage, result)
    expected = ["rocker" if p in ("double-rocker", "triple-rocker") else p for p in predicted]
    assert simulated == expected
    assert set(Counter(expected)) == {"rocker", "crank-rocker", "double-crank"}  # every class is sampled
    reached = ~np.isnan(result.residuals)
    assert np.nanmax(result.residuals) < 1e-12 and reached.any()
    # a mechanism that cannot turn further stays at its last solved configuration (finite, not the
    # diverged Newton iterate of the angle it failed at)
    frozen = [k for k in range(len(points)) if 0 < result.reached[k] < len(result.angles)]
    assert frozen
    for k in frozen:
        last = result.motors[result.reached[k] - 1, k]
        assert np.isfinite(last).all()
        np.testing.assert_array_equal(result.motors[result.reached[k]:, k], np.broadcast_to(
            last, result.motors[result.reached[k]:, k].shape))
