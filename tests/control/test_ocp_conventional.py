"""The OCP benchmark's conventional baseline (benchmarks/conventional.py) against gagen's ``task`` kernel.

The baseline computes e = log(V_Sc~ V_Sd) without geometric algebra: adam-robotics' FK of the URDFs,
the primitive's similarity from 3-vector algebra (circumcircle, circumsphere, closest points, plane
intersection), a quaternion log. Both sides are independent: the target is the primitive at a second
random configuration, built by the baseline's own FK on one side and by gagen's ``similarity`` kernel
on the other, so any difference in FK, base placement, shared joints, point order, orientation, rotor
sign, dilation sign or row order shows as a difference in e. Every reaching scenario's system is checked.
"""

from __future__ import annotations

import sys
from functools import cache
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from gagen.apps.cooperative import scenarios
from gagen.control.ocp import target_from

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks import conventional  # noqa: E402  (needs adam-robotics[casadi], in the test extra)

SCENARIOS = list(scenarios.SCENARIOS)


@cache
def setup(system: str):
    module = scenarios.module(system)
    kind = module.manifest["primitive"]
    joints = next(k for k in module.manifest["kernels"] if k["name"] == "task")["inputs"][0]["rows"]
    return module, kind, conventional.points_function(system, joints), conventional.task(system, kind, joints)


def configurations(system: str, count: int, seed: int) -> np.ndarray:
    """Random configurations around ``ready``, within the URDF joint limits."""
    lower, upper = scenarios.joint_limits(system)
    q0 = scenarios.ready(system)
    rng = np.random.default_rng(seed)
    return np.clip(q0 + 0.5 * rng.standard_normal((count, q0.size)), lower, upper)


@pytest.mark.parametrize("name", SCENARIOS)
def test_error_equals_gagen_at_random_configurations(name):
    system = scenarios.SCENARIOS[name].system
    module, kind, points, task = setup(system)
    worst, largest = 0.0, 0.0
    for q, q_d in zip(configurations(system, 20, 1), configurations(system, 20, 2), strict=True):
        V_Sd = np.array(module.c.similarity(q_d)[0]).ravel()
        e_gagen = np.array(module.c.task(q, V_Sd)[0]).ravel()
        e_conv = np.array(task(q, conventional.target_at(points, kind, q_d))).ravel()
        worst = max(worst, float(np.abs(e_conv - e_gagen).max()))
        largest = max(largest, float(np.abs(e_gagen).max()))
    assert largest > 0.2  # the errors compared are far from zero: signs and rows matter
    assert worst < 1e-12


@pytest.mark.parametrize("name", SCENARIOS)
def test_error_jacobian_equals_gagen(name):
    """J_Be = ∂e/∂q, the part of e the NLP differentiates: CasADi's AD of the baseline vs the kernel's."""
    system = scenarios.SCENARIOS[name].system
    module, kind, points, task = setup(system)
    q_sym, p_sym = ca.SX.sym("q", task.size1_in(0)), ca.SX.sym("p", task.size1_in(1))
    jacobian = ca.Function("J", [q_sym, p_sym], [ca.jacobian(task(q_sym, p_sym), q_sym)])
    for q, q_d in zip(configurations(system, 3, 3), configurations(system, 3, 4), strict=True):
        V_Sd = np.array(module.c.similarity(q_d)[0]).ravel()
        J_gagen = np.array(module.c.task(q, V_Sd)[1])
        J_conv = np.array(jacobian(q, conventional.target_at(points, kind, q_d)))
        assert np.abs(J_conv - J_gagen).max() < 1e-11 * max(1.0, np.abs(J_gagen).max())


@pytest.mark.parametrize("name", SCENARIOS)
def test_benchmark_target_is_gagens_target(name):
    """The scenario's target moved by 3-vector algebra (``moved``) is its V_Sd (``target_from``)."""
    s = scenarios.SCENARIOS[name]
    module, kind, points, task = setup(s.system)
    q0 = scenarios.ready(s.system)
    V_Sd = target_from(np.array(module.c.similarity(q0)[0]), s.translation, s.rotation, s.dilation, kind=kind)
    target = conventional.moved(kind, [np.array(p).ravel() for p in points(q0)], s.translation, s.rotation,
                                s.dilation)
    for q in [q0, *configurations(s.system, 3, 5)]:
        e_gagen = np.array(module.c.task(q, V_Sd)[0]).ravel()
        assert np.abs(np.array(task(q, target)).ravel() - e_gagen).max() < 1e-12
