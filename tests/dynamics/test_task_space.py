"""Task-space dynamics [COOP Eq. 33-38] against independent computations: Pinocchio's kinetic and
potential energy, finite differences of the generated J_G, and Pinocchio's forward dynamics.

The fast tests use random matrices (closed forms of the linear algebra); the others the committed
three_iiwas_circle module (its C compiles on first use: ``compiling``) and Pinocchio."""

from functools import cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gagen.dynamics.task_space import task_space

ROOT = Path(__file__).resolve().parents[2]
SPEC = ROOT / "robots" / "three_iiwas_circle.yaml"
Q0 = np.array([0.0, -0.7854, 0.0, 1.3962, 0.0, 0.6109, 0.0] * 3)
CIRCLE_RANK = 6


def _spd(rng: np.random.Generator, n: int) -> np.ndarray:
    a = rng.normal(size=(n, n))
    return a @ a.T + n * np.eye(n)


@given(st.integers(0, 10_000), st.integers(1, 7))
def test_inverse_is_exact_on_the_range(seed, rank):
    """With J of rank r (7 rows), M_Sc A M_Sc = M_Sc and A M_Sc A = A (A = J M⁻¹ Jᵀ): the
    pseudo-inverse on the range; J̄ = M⁻¹ Jᵀ M_Sc is a generalised inverse: J J̄ J = J."""
    rng = np.random.default_rng(seed)
    m = 12
    J = rng.normal(size=(7, rank)) @ rng.normal(size=(rank, m))
    M = _spd(rng, m)
    space = task_space(J, np.zeros(7), M, np.zeros(m), np.zeros(m), rank)
    A = J @ np.linalg.solve(M, J.T)
    L = space.inertia
    scale = np.abs(A).max()
    assert space.rank == rank
    assert np.abs(L @ A @ L - L).max() <= 1e-8 * np.abs(L).max()
    assert np.abs(A @ L @ A - A).max() <= 1e-9 * scale
    assert np.abs(J @ space.consistent_inverse @ J - J).max() <= 1e-9 * np.abs(J).max()


@given(st.integers(0, 10_000))
def test_nullspace_torques_do_not_accelerate_the_task(seed):
    """J M⁻¹ Nᵀ τ = 0 for any τ (dynamic consistency), on a rank-deficient J."""
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(7, 6)) @ rng.normal(size=(6, 15))
    M = _spd(rng, 15)
    space = task_space(J, np.zeros(7), M, np.zeros(15), np.zeros(15), 6)
    tau = rng.normal(size=15)
    assert np.abs(J @ np.linalg.solve(M, space.nullspace_torque(J, tau))).max() <= 1e-10 * np.abs(tau).max()


def test_bad_rank_and_damping_are_refused():
    J = np.ones((7, 3))
    with pytest.raises(ValueError, match="rank must be between 1 and 7"):
        task_space(J, np.zeros(7), np.eye(3), np.zeros(3), np.zeros(3), 0)
    with pytest.raises(ValueError, match="damping must be >= 0"):
        task_space(J, np.zeros(7), np.eye(3), np.zeros(3), np.zeros(3), 1, damping=-1.0)


# -- on the three iiwas (Pinocchio + the generated kernels) ------------------------------------------
@cache
def _system():
    from gagen.apps.cooperative.bundled import system_module
    from gagen.dynamics.rigid_body import SystemDynamics

    return system_module("three_iiwas_circle"), SystemDynamics(SPEC)


def _state(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return Q0 + rng.uniform(-0.4, 0.4, Q0.size), rng.uniform(-1.0, 1.0, Q0.size)


def _space(q, qd):
    module, dynamics = _system()
    _, _, J = module.c.similarity(q)
    _, jdot_qdot = module.c.similarity_rate(q, qd)
    space = task_space(J, jdot_qdot, dynamics.mass_matrix(q), dynamics.bias(q, qd), dynamics.gravity(q),
                       CIRCLE_RANK)
    return J, jdot_qdot, space



@pytest.mark.compiling
@pytest.mark.parametrize("seed", range(5))
def test_kinetic_energy_in_task_space(seed):
    """½ q̇ᵀ M q̇ (Pinocchio's own kinetic energy) = ½ V_Sᵀ M_Sc V_S for q̇ = J̄ V_S, the inertia-weighted
    inverse of J_G; for the Moore-Penrose q̇ = J_G⁺ V_S and any other q̇ with the same twist it is larger
    (M_Sc is the least kinetic energy per twist)."""
    _, dynamics = _system()
    q, _ = _state(seed)
    J, _, space = _space(q, np.zeros(q.size))
    twist = J @ np.random.default_rng(100 + seed).normal(size=q.size)  # a twist the system can make
    qd = space.consistent_inverse @ twist
    assert np.abs(J @ qd - twist).max() <= 1e-10 * np.abs(twist).max()
    task_energy = 0.5 * twist @ space.inertia @ twist
    assert dynamics.kinetic_energy(q, qd) == pytest.approx(task_energy, rel=1e-10)
    for other in (np.linalg.pinv(J) @ twist, qd + (np.eye(q.size) - np.linalg.pinv(J) @ J) @ np.ones(q.size)):
        assert np.abs(J @ other - twist).max() <= 1e-9 * np.abs(twist).max()
        assert dynamics.kinetic_energy(q, other) > task_energy


@pytest.mark.compiling
@pytest.mark.parametrize("seed", range(3))
def test_gravity_is_the_potential_gradient_mapped_to_the_task(seed):
    """g_Sc = J̄ᵀ ∇U with ∇U by central differences of Pinocchio's potential energy (not its RNEA)."""
    _, dynamics = _system()
    q, _ = _state(seed)
    _, _, space = _space(q, np.zeros(q.size))
    h = 1e-6
    energy = dynamics.potential_energy
    gradient = np.array([(energy(q + h * e) - energy(q - h * e)) / (2 * h) for e in np.eye(q.size)])
    expected = space.consistent_inverse.T @ gradient
    assert np.abs(space.gravity - expected).max() <= 1e-6 * np.abs(expected).max()


@pytest.mark.compiling
@pytest.mark.parametrize("seed", range(5))
def test_jdot_qdot_is_the_derivative_of_jg_along_qdot(seed):
    """The generated J̇_G q̇ against Richardson central differences of the generated J_G along q̇, and
    V_S against J_G q̇."""
    module, _ = _system()
    q, qd = _state(seed)
    twist, jdot_qdot = module.c.similarity_rate(q, qd)
    _, _, J = module.c.similarity(q)
    assert np.abs(twist - J @ qd).max() <= 1e-13 * np.abs(J).max()

    def along(h: float) -> np.ndarray:
        return (module.c.similarity(q + h * qd)[2] - module.c.similarity(q - h * qd)[2]) @ qd / (2 * h)

    h = 1e-4
    estimate = (4 * along(h / 2) - along(h)) / 3
    assert np.abs(jdot_qdot - estimate).max() <= 1e-8 * np.abs(jdot_qdot).max()


@pytest.mark.compiling
@pytest.mark.parametrize("seed", range(3))
def test_task_space_dynamics_close_the_loop_in_pinocchio(seed):
    """For τ = J_Gᵀ (M_Sc a + C_Sc + g_Sc), Pinocchio's ABA gives a q̈ whose twist rate, measured by
    differences of the generated J_G along the motion (d/dt J_G(q(t)) q̇(t)), is a projected on the
    twists the circle can make: the task-space quantities (Eq. 36-38) and J̇_G q̇ hold together."""
    module, dynamics = _system()
    q, qd = _state(seed)
    J, _, space = _space(q, qd)
    a = np.random.default_rng(200 + seed).normal(size=7)
    tau = J.T @ (space.inertia @ a + space.coriolis + space.gravity)
    qdd = dynamics.forward(q, qd, tau)

    def twist_at(h: float) -> np.ndarray:
        return module.c.similarity(q + h * qd + 0.5 * h * h * qdd)[2] @ (qd + h * qdd)

    h = 1e-5
    rate = (twist_at(h) - twist_at(-h)) / (2 * h)
    A = J @ np.linalg.solve(dynamics.mass_matrix(q), J.T)
    projected = A @ space.inertia @ a  # a on the range of A (the reachable twist rates)
    assert np.abs(rate - projected).max() <= 1e-6 * np.abs(projected).max()


@pytest.mark.compiling
def test_error_rate_is_minus_the_twist_at_the_target():
    """The convention of Eq. 49 in gagen: at B_S,e = 0 the task kernel's J_Be equals −J_G, so
    Ḃ_S,e = −V_S (the paper's −½ is gafro's scaling)."""
    module, _ = _system()
    q, _ = _state(7)
    target, _, J = module.c.similarity(q)
    error, J_Be = module.c.task(q, target)
    assert np.abs(error).max() <= 1e-14
    assert np.abs(J_Be + J).max() <= 1e-12 * np.abs(J).max()
