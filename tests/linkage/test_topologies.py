"""Batches across topologies (issue 32, item 4): one module of several linkages' parametric kernels,
swept in one call on C SIMD (one batched call per topology and Newton iteration) and as one jitted JAX
function. Each group equals ``batch.sweep`` of its topology alone (bitwise), a single mechanism equals
``solver.simulate`` (the four-bar on its own fixed-dimension module), the random four-bars' classes
equal Grashof's closed form, JAX equals C, and putting kernels in one module changes none of them."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import gagen
from gagen.apps.linkage.batch import classify, family, four_bar_points, grashof_class, sweep
from gagen.apps.linkage.bundled import BUNDLED
from gagen.apps.linkage.kernels import initial_labels, initial_points, linkage_kernels
from gagen.apps.linkage.solver import Kernels, kernels, simulate
from gagen.apps.linkage.spec import load_linkage
from gagen.apps.linkage.topologies import (
    Group,
    jax_sweep,
    jax_sweep_function,
    sweep_topologies,
    topology_kernels,
    topology_module,
)

NAMES = ("four_bar", "slider_crank", "jansen")
ANGLES = np.radians(np.arange(0.0, 361.0, 1.0))


@pytest.fixture(scope="module")
def linkages():
    return {name: load_linkage(BUNDLED / f"{name}.yaml") for name in NAMES}


def _random_four_bars(count: int, seed: int) -> tuple[np.ndarray, list[str]]:
    """Four-bars of random lengths away from Grashof's change points, and their Grashof classes."""
    rng = np.random.default_rng(seed)
    points, classes = [], []
    while len(points) < count:
        lengths = rng.uniform(0.5, 3.0, 4)
        ordered = np.sort(lengths)
        x = four_bar_points(*lengths)
        if abs(ordered[0] + ordered[3] - ordered[1] - ordered[2]) > 0.05 and x is not None:
            points.append(x)
            classes.append(grashof_class(*lengths))
    return np.array(points), classes


@pytest.fixture(scope="module")
def batch(linkages):
    """The module of the three topologies (built once), and a batch: 24 random four-bars, the slider-crank
    at its spec, the Jansen leg at its spec and scaled by 1.5 (a different mechanism, same topology)."""
    module = topology_module(list(linkages.values()))
    four_bars, classes = _random_four_bars(24, seed=3)
    jansen = initial_points(linkages["jansen"])
    groups = [Group(linkages["four_bar"], np.vstack([initial_points(linkages["four_bar"]), four_bars])),
              Group(linkages["slider_crank"], initial_points(linkages["slider_crank"])[None]),
              Group(linkages["jansen"], np.array([jansen, 1.5 * jansen]))]
    return SimpleNamespace(module=module, groups=groups, classes=classes,
                           result=sweep_topologies(module, groups, ANGLES))


def test_kernel_names_are_prefixed_by_linkage(linkages):
    names = [k.name for k in topology_kernels([linkages["four_bar"], linkages["slider_crank"]])]
    assert names == [f"{link}_{kernel}" for link in ("four_bar", "slider_crank")
                     for kernel in ("constraints", "positions", "retract", "newton_step")]


def test_renamed_kernels_compute_what_the_originals_do(linkages):
    """On the interpreter: the prefixed newton_step is the family's (same numbers, bitwise)."""
    linkage = linkages["slider_crank"]
    renamed = {k.name: k for k in topology_kernels([linkage])}["slider_crank_newton_step"]
    original = {k.name: k for k in linkage_kernels(linkage, parametric=True)}["newton_step"]
    for args in (original.sample(np.random.default_rng(seed)) for seed in range(3)):
        for a, b in zip(renamed.reference(*args), original.reference(*args), strict=True):
            np.testing.assert_array_equal(a, b)


def test_a_linkage_given_twice_is_refused(linkages):
    with pytest.raises(ValueError, match="four_bar given twice"):
        topology_kernels([linkages["four_bar"], linkages["slider_crank"], linkages["four_bar"]])


@pytest.mark.compiling
def test_each_group_equals_its_topology_swept_alone(batch):
    """Bitwise: the multi-topology call is batch.sweep per group (the same kernel, lanes, freezing)."""
    for group, result in zip(batch.groups, batch.result, strict=True):
        kernel = getattr(batch.module.c, f"{group.linkage.name}_newton_step")
        alone = sweep(SimpleNamespace(newton_step=kernel), group.linkage, group.initial, ANGLES)
        np.testing.assert_array_equal(result.motors, alone.motors)
        np.testing.assert_array_equal(result.residuals, alone.residuals)
        np.testing.assert_array_equal(result.reached, alone.reached)
        np.testing.assert_array_equal(result.iterations, alone.iterations)


@pytest.mark.compiling
def test_four_bar_classes_equal_grashof_and_residuals_converge(batch, linkages):
    four_bars = batch.result[0]
    simulated = classify(linkages["four_bar"], four_bars)[1:]  # (the first: the spec's own four-bar)
    expected = ["rocker" if c in ("double-rocker", "triple-rocker") else c for c in batch.classes]
    assert simulated == expected and len(set(expected)) == 3  # every class sampled
    for result in batch.result[1:]:
        assert (result.reached == len(ANGLES)).all()  # the slider-crank and both Jansen legs turn fully
    assert max(np.nanmax(r.residuals) for r in batch.result) < 1e-12


@pytest.mark.compiling
def test_a_single_mechanism_equals_the_solver(batch, linkages):
    """The spec mechanism of each group against solver.simulate: the four-bar on its committed
    fixed-dimension module (generated/four_bar, no X0 input), the others on their prefixed kernels with
    their spec points bound."""
    c = batch.module.c
    for group, result in zip(batch.groups, batch.result, strict=True):
        linkage, X0 = group.linkage, initial_points(group.linkage)
        if linkage.name == "four_bar":
            k = kernels(linkage, gagen.load("generated/four_bar").c)
        else:
            def bound(kernel, name=linkage.name, X0=X0):
                return lambda R, theta: getattr(c, f"{name}_{kernel}")(R, theta, X0)
            k = Kernels(bound("constraints"), getattr(c, f"{linkage.name}_retract"), bound("positions"),
                        bound("newton_step"))
        path = simulate(k, linkage, ANGLES)
        assert not path.failures and path.halvings.max() == 0
        np.testing.assert_allclose(result.motors[:, 0], path.motors, rtol=0, atol=1e-12)


@pytest.mark.compiling
def test_mixing_topologies_changes_no_kernel(batch, linkages):
    """The four-bar's kernels in the multi-topology module give the single-topology family module's
    numbers, bitwise, on a batch of random inputs."""
    alone = family(linkages["four_bar"])
    rng = np.random.default_rng(5)
    originals = {k.name: k for k in linkage_kernels(linkages["four_bar"], parametric=True)}
    for name, kernel in originals.items():
        samples = [kernel.sample(rng) for _ in range(16)]
        inputs = [np.array([s[i] for s in samples]) for i in range(len(samples[0]))]
        mixed = getattr(batch.module.c, f"four_bar_{name}").batch(*inputs)
        for a, b in zip(mixed, getattr(alone, name).batch(*inputs), strict=True):
            np.testing.assert_array_equal(a, b)


@pytest.mark.compiling
def test_jax_one_call_equals_c(batch):
    """The whole batch as one jitted function: the same reach and convergence as C, motors and
    residuals to 1e-12 (where a mechanism is frozen its motors are a diverged Newton iterate, which
    both keep but need not agree on); the same iterations, but where a residual lands within rounding
    of the tolerance (one more or fewer, rare)."""
    pytest.importorskip("jax")
    run = jax_sweep_function(batch.module, [g.linkage for g in batch.groups])
    for result, jaxed in zip(batch.result, jax_sweep(batch.module, batch.groups, ANGLES, function=run),
                             strict=True):
        np.testing.assert_array_equal(jaxed.reached, result.reached)
        differ = jaxed.iterations != result.iterations
        assert np.abs(jaxed.iterations - result.iterations).max() <= 1 and differ.mean() <= 0.02
        np.testing.assert_array_equal(np.isnan(jaxed.residuals), np.isnan(result.residuals))
        np.testing.assert_allclose(jaxed.residuals, result.residuals, rtol=0, atol=1e-12)
        solved = np.arange(len(ANGLES))[:, None] < result.reached[None, :]
        assert np.abs(jaxed.motors - result.motors)[solved].max() < 1e-12


@pytest.mark.compiling
def test_bad_groups_are_refused_naming_the_group(batch, linkages):
    module, (four_bar, slider_crank, _) = batch.module, batch.groups
    width = len(initial_labels(linkages["slider_crank"]))
    with pytest.raises(ValueError, match=rf"group 1 \(slider_crank\).*expected \(N, {width}\)"):
        sweep_topologies(module, [four_bar, (linkages["slider_crank"], four_bar.initial)], ANGLES)
    with pytest.raises(ValueError, match=r"group 0 \(four_bar\): driver values of shape \(3, 2\), "
                                         r"expected \(steps, 1\)"):
        sweep_topologies(module, [four_bar], np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"361, 362.*as many"):
        sweep_topologies(module, [four_bar, Group(slider_crank.linkage, slider_crank.initial,
                                                  np.zeros(362))], ANGLES)
    six_bar = load_linkage(BUNDLED / "six_bar.yaml")
    with pytest.raises(ValueError, match=r"group 0 \(six_bar\): no kernel six_bar_newton_step.*four_bar"):
        sweep_topologies(module, [(six_bar, initial_points(six_bar)[None])], ANGLES)
