"""The native (C++) similarity impedance step (issue 30): the same torques as the Python
``ImpedanceController`` (numpy, LAPACK and Pinocchio's own gravity: an independent computation of the
law) at random states on three systems of 21, 7 and 14 joints, every gain branch, a moved target, the
closed loop and threads; and its refusals of bad inputs before the C++ runs."""

from __future__ import annotations

import copy
import threading
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("pinocchio")

from gagen.control.impedance import Gains, simulate

pytestmark = pytest.mark.compiling  # the C++ source compiles on first use (minutes), then is cached

TUNED = Gains(stiffness=(25.0,) * 7, damping=(10.0,) * 7)
RELATIVE = 1e-10


def _pair(system: str, gains: Gains = TUNED):
    """The Python controller of ``system``, its native twin and q0."""
    from gagen.apps.cooperative.impedance_demo import controller
    from gagen.control.impedance_native import NativeImpedance

    control, q0 = controller(system, gains)
    return control, NativeImpedance(control), q0


@pytest.fixture(scope="module")
def circle():
    return _pair("three_iiwas_circle")


def _states(q0, count: int, seed: int):
    rng = np.random.default_rng(seed)
    return [(q0 + rng.uniform(-0.3, 0.3, q0.size), rng.uniform(-1.0, 1.0, q0.size)) for _ in range(count)]


def _assert_same(expected, actual):
    scale = np.abs(expected).max()
    assert np.abs(actual - expected).max() <= RELATIVE * scale, (
        f"relative difference {np.abs(actual - expected).max() / scale:.2e}")


@pytest.mark.parametrize("system", ["three_iiwas_circle", "panda_point",
                                    pytest.param("two_iiwas_line", marks=pytest.mark.slow)])
def test_the_native_torque_is_the_python_controllers(system, circle):
    """21 (circle, rank 6), 7 (one Panda on a point, rank 3) and 14 joints (a line, rank 4): τ, B_S,e and
    V_S at 25 random states around q0 with random velocities."""
    control, native, q0 = circle if system == "three_iiwas_circle" else _pair(system)
    for q, qd in _states(q0, 25, seed=1):
        step = control(q, qd)
        _assert_same(step.tau, native.torque(q, qd))
        both = native(q, qd)
        _assert_same(step.tau, both.tau)
        np.testing.assert_allclose(both.error, step.error, rtol=0, atol=1e-14)
        np.testing.assert_allclose(both.twist, step.twist, rtol=0, atol=1e-14)


BRANCHES = {"paper": Gains(),
            "eq52-alone": Gains(posture_stiffness=0.0, posture_damping=0.0, gravity_nullspace=False),
            "posture-without-gravity": Gains(posture_stiffness=3.0, posture_damping=0.5,
                                             gravity_nullspace=False)}


@pytest.mark.parametrize("gains", list(BRANCHES.values()), ids=list(BRANCHES))
def test_every_gain_branch_is_the_python_controllers(gains):
    control, native, q0 = _pair("three_iiwas_circle", gains)
    for q, qd in _states(q0, 20, seed=2):
        _assert_same(control(q, qd).tau, native.torque(q, qd))


def test_a_moved_target_is_used_at_the_next_step(circle):
    control, native, q0 = circle
    control = copy.copy(control)  # (the fixture's stays as it is)
    target = np.array(control.c.similarity(q0 + 0.05)[0])
    control.target = target
    native = type(native)(control)
    native.target = np.array(circle[0].target)  # back to the old one...
    q, qd = _states(q0, 1, seed=3)[0]
    _assert_same(circle[0](q, qd).tau, native.torque(q, qd))
    native.target = target  # ...and to the new one
    _assert_same(control(q, qd).tau, native.torque(q, qd))


def test_the_closed_loop_is_the_python_controllers(circle):
    """``simulate`` runs the native step as it runs the controller: 50 ms at 1 kHz from the same start."""
    control, native, q0 = circle
    start = _states(q0, 1, seed=4)[0][0]
    python, ours = (simulate(c, start, duration=0.05, dt=1e-3) for c in (control, native))
    np.testing.assert_allclose(ours.q, python.q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(ours.error_norm, python.error_norm, rtol=1e-9, atol=1e-14)


def test_threads_each_get_their_own_workspace(circle):
    control, native, q0 = circle
    states = _states(q0, 40, seed=5)
    expected = [control(q, qd).tau for q, qd in states]
    results: dict[int, list[np.ndarray]] = {}

    def work(k: int) -> None:
        results[k] = [native.torque(q, qd) for q, qd in states for _ in range(3)][::3]

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k in range(4):
        for want, got in zip(expected, results[k], strict=True):
            _assert_same(want, got)


def test_inputs_of_the_wrong_shape_or_not_finite_are_refused_naming_them(circle):
    _, native, q0 = circle
    qd = np.zeros_like(q0)
    with pytest.raises(ValueError, match=r"^q: expected shape \(21,\) .* got \(20,\)$"):
        native.torque(q0[:20], qd)
    with pytest.raises(ValueError, match=r"^qd: expected shape \(21,\) .* got \(21, 1\)$"):
        native.torque(q0, qd[:, None])
    with pytest.raises(ValueError, match=r"^q: expected finite values$"):
        native.torque(np.where(np.arange(21) == 4, np.nan, q0), qd)
    with pytest.raises(ValueError, match=r"^qd: expected finite values$"):
        native.torque(q0, np.where(np.arange(21) == 20, np.inf, qd))
    with pytest.raises(ValueError, match=r"^target \(V_Sd\): expected 12 values, got 10$"):
        native.target = np.zeros(10)
    with pytest.raises(ValueError, match=r"^target \(V_Sd\): expected finite values$"):
        native.target = np.full(12, np.nan)
    _assert_same(circle[0](q0, qd).tau, native.torque(list(q0), list(qd)))  # still serving, lists too


def test_kernels_of_another_system_or_without_c_are_refused(circle):
    from gagen.control.impedance_native import NativeImpedance

    control, _, _ = circle
    other, _, _ = _pair("panda_point")
    mixed = copy.copy(control)
    mixed.c = other.c
    with pytest.raises(ValueError, match=r"^similarity: the kernel takes \[\(7, 1\)\] .* of 21 joints"):
        NativeImpedance(mixed)
    mixed.c = SimpleNamespace(similarity=control.c.similarity, task=lambda q, v: None,
                              similarity_rate=control.c.similarity_rate)
    with pytest.raises(ValueError, match=r"^task: the native impedance step needs the compiled kernels"):
        NativeImpedance(mixed)
    mixed = copy.copy(control)
    mixed.q_rest = np.zeros(20)
    with pytest.raises(ValueError, match=r"^q_rest: expected 21 values, got 20$"):
        NativeImpedance(mixed)

