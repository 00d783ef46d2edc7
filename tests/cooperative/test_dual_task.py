"""The cooperative dual task space [COOP Section 2.5, Eq. 10-11] against dqrobotics, the paper's formulas
and finite differences.

dqrobotics (DQ_CooperativeDualTaskSpace) defines x_r = x_2* x_1 and x_a = x_2 (x_r)^½ with the same
decoupled log as gagen's motor chart, so poses compare exactly, sign included: each dqrobotics arm's
base is built from the spec's xyz/rpy with the same half-angle rotors, which gives every end pose the
same lift as gagen's motor (checked below). Its relative_pose_jacobian is ∂vec8(x_r)/∂q. Its
absolute_pose_jacobian is not ∂vec8(x_a)/∂q in general: it differentiates the square root of the
relative rotation as ½ ṙ r* r^½, exact only when the relative angular velocity is along the relative
rotation's axis (e.g. where the relative rotation is the identity); elsewhere it misses its own
absolute_pose's differences by up to ~0.6. So J_Aa is held against Richardson differences of
dqrobotics' absolute_pose everywhere, and against its absolute_pose_jacobian where that is exact.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from dqrobotics import DQ, E_, conj, i_, j_, k_, vec4, vec8
from dqrobotics.robot_modeling import DQ_CooperativeDualTaskSpace, DQ_SerialManipulatorMDH
from hypothesis import given
from hypothesis import strategies as st

from gagen.algebra.signature import cga3d
from gagen.apps.cooperative.bundled import bundled_specs, bundled_systems
from gagen.apps.cooperative.catalogue import kernel_functions
from gagen.apps.cooperative.dual_task import (
    absolute_motor,
    dual_task,
    dual_task_kernel_functions,
    half_motor,
    relative_motor,
)
from gagen.errors import SpecError
from gagen.interp import MultiVector
from gagen.model import kinematics as K
from gagen.model.conformal import MOTOR, MOTOR_GENERATOR
from gagen.model.versors import ROTOR, rotor, translator
from gagen.names import DUAL_TASK_KERNELS
from gagen.robots.spec import load_system

ZERO = MultiVector.zero(cga3d())
TWO_CHAINS = ("two_pandas_point_pair", "two_iiwas_line", "g1_arms_line")
PANDA = "two_pandas_point_pair"
SEEDED = 20  # configurations per comparison with dqrobotics

# vec8 = [p0, p1, p2, p3, d0, d1, d2, d3] of x = p + ε d ↦ the motor [1, e12, e13, e23, e1∞, e2∞, e3∞,
# e123∞]: the quaternion units i, j, k are the rotors' −e23, e13, −e12 (so that i j = k), and the dual
# part ½ t p is the translation part −½ t e∞ R read through e123 (I₃ Q(d) = d0 e123 + d1 e1 + …)
_MOTOR_FROM_VEC8 = ((0, 1), (3, -1), (2, 1), (1, -1), (5, -1), (6, -1), (7, -1), (4, -1))
DQ_TO_MOTOR = np.zeros((8, 8))
for _row, (_column, _sign) in enumerate(_MOTOR_FROM_VEC8):
    DQ_TO_MOTOR[_row, _column] = _sign


def motor_from_dq(x: DQ | np.ndarray) -> np.ndarray:
    """The CGA motor coefficients (MOTOR order) of a dual quaternion, or of the rows ∂vec8/∂q of a
    dqrobotics Jacobian (the map is linear)."""
    return DQ_TO_MOTOR @ (vec8(x) if isinstance(x, DQ) else np.asarray(x))


def coefficients(x: MultiVector, blades: tuple[str, ...] = MOTOR) -> np.ndarray:
    return np.array([x[b] for b in blades])


def columns(xs: list[MultiVector], blades: tuple[str, ...]) -> np.ndarray:
    return np.array([coefficients(x, blades) for x in xs]).T


def motor_of(array: np.ndarray) -> MultiVector:
    return MultiVector.from_blades(cga3d(), dict(zip(MOTOR, array, strict=True)))


# -- the dual quaternion ↔ motor map ----------------------------------------------------------------------

def _unit_dq(angle: float, axis: np.ndarray, t: np.ndarray) -> DQ:
    n = axis / np.linalg.norm(axis)
    r = math.cos(angle / 2) + math.sin(angle / 2) * (n[0] * i_ + n[1] * j_ + n[2] * k_)
    return (1 + 0.5 * E_ * (t[0] * i_ + t[1] * j_ + t[2] * k_)) * r


def _gagen_motor(angle: float, axis: np.ndarray, t: np.ndarray) -> MultiVector:
    n = axis / np.linalg.norm(axis)
    e = ZERO.make({"e1": n[0], "e2": n[1], "e3": n[2]})
    return translator(ZERO.make({"e1": t[0], "e2": t[1], "e3": t[2]})) * rotor(e, angle)


poses = st.tuples(st.floats(-3.1, 3.1), st.lists(st.floats(-1, 1), min_size=3, max_size=3)
                  .filter(lambda v: np.linalg.norm(v) > 0.1).map(np.array),
                  st.lists(st.floats(-2, 2), min_size=3, max_size=3).map(np.array))


@given(poses, poses)
def test_the_map_takes_dual_quaternions_to_motors_as_a_homomorphism(a, b):
    """Rotation by θ about n and translation by t give the same rigid motion on both sides, and the map
    keeps products and conjugation (x* ↦ M~)."""
    xa, xb = _unit_dq(*a), _unit_dq(*b)
    ma, mb = _gagen_motor(*a), _gagen_motor(*b)
    assert np.allclose(motor_from_dq(xa), coefficients(ma), atol=1e-13)
    assert np.allclose(motor_from_dq(xa * xb), coefficients(ma * mb), atol=1e-13)
    assert np.allclose(motor_from_dq(conj(xa) * xb), coefficients(~ma * mb), atol=1e-13)


def test_the_map_moves_points_alike():
    """A point moved by the DQ (the translation of x T(p) = T(t + R p) R) lands where the motor's
    sandwich puts it."""
    x = _unit_dq(1.1, np.array([0.2, -0.5, 0.7]), np.array([0.3, -0.1, 0.4]))
    p = np.array([0.5, 0.25, -1.0])
    moved = vec4((x * (1 + 0.5 * E_ * (p[0] * i_ + p[1] * j_ + p[2] * k_))).translation())[1:]
    m = motor_of(motor_from_dq(x))
    image = m.sandwich(ZERO.make({"e0": 1, "e1": p[0], "e2": p[1], "e3": p[2], "einf": 0.5 * p @ p}))
    assert np.allclose(coefficients(image, ("e1", "e2", "e3")), moved, atol=1e-14)


# -- the same two-Panda system in dqrobotics ---------------------------------------------------------------

# Franka's modified DH (Craig) parameters; the URDF's panda_link8 (the flange) is 0.107 m further along z
PANDA_MDH = np.array([[0.0] * 7,
                      [0.333, 0, 0.316, 0, 0.384, 0, 0],
                      [0, 0, 0, 0.0825, -0.0825, 0, 0.088],
                      [0, -math.pi / 2, math.pi / 2, math.pi / 2, -math.pi / 2, math.pi / 2, math.pi / 2],
                      [0.0] * 7])
FLANGE = 0.107


def _base(joint: K.Joint) -> DQ:
    """The spec's base placement T(xyz) Rz(yaw) Ry(pitch) Rx(roll) with half-angle rotors as gagen
    builds it (yaw 2π is the rotor −1: the lift matters to x_a)."""
    roll, pitch, yaw = joint.rpy

    def turn(unit: DQ, angle: float) -> DQ:
        return math.cos(angle / 2) + math.sin(angle / 2) * unit

    x, y, z = joint.xyz
    return (1 + 0.5 * E_ * (x * i_ + y * j_ + z * k_)) * turn(k_, yaw) * turn(j_, pitch) * turn(i_, roll)


class _TwoPandas:
    """dqrobotics' model of two_pandas_point_pair (the arms are kept alive beside the cooperative object,
    which does not own them)."""

    def __init__(self) -> None:
        self.system = bundled_systems()[PANDA]
        self.arms = []
        for chain in self.system.chains:
            assert chain.joints[0].kind == "fixed" and len(chain.joints) == 9  # base, 7 joints, flange
            arm = DQ_SerialManipulatorMDH(PANDA_MDH)
            arm.set_reference_frame(_base(chain.joints[0]))
            arm.set_effector(1 + 0.5 * E_ * FLANGE * k_)
            self.arms.append(arm)
        self.cdts = DQ_CooperativeDualTaskSpace(self.arms[0], self.arms[1])

    def configurations(self, seed: int = 0, count: int = SEEDED) -> list[np.ndarray]:
        return list(np.random.default_rng(seed).uniform(-2.5, 2.5, (count, self.system.dof)))


@pytest.fixture(scope="module")
def pandas() -> _TwoPandas:
    return _TwoPandas()


def _richardson(f, q: np.ndarray, h: float = 5e-4) -> np.ndarray:
    """∂f/∂q by the fourth-order central difference: truncation ~h⁴ (1e-11 where M_r's rotation nears
    the chart's singular angle 2π and x_a turns fast, e.g. the 8th configuration of seed 5; 8e-11 there
    at h = 1e-3), rounding ~eps/h (~1e-12)."""
    found = []
    for e in np.eye(len(q)):
        found.append((8 * (f(q + h * e) - f(q - h * e)) - (f(q + 2 * h * e) - f(q - 2 * h * e))) / (12 * h))
    return np.array(found).T


def _geometric(m: np.ndarray, derivative: np.ndarray) -> np.ndarray:
    """−2 M~ ∂M/∂q on the MOTOR_GENERATOR rows, from a motor and its analytic Jacobian (arrays)."""
    inverse = ~motor_of(m)
    return np.array([coefficients(inverse * motor_of(c) * -2, MOTOR_GENERATOR) for c in derivative.T]).T


def test_the_mdh_panda_is_the_urdf_chain_with_the_same_lift(pandas):
    """Each arm's end pose in dqrobotics (MDH + flange + spec base) is gagen's FK motor, sign included."""
    worst = 0.0
    for q in pandas.configurations(seed=1):
        for arm, chain, qc in zip(pandas.arms, pandas.system.chains, pandas.system.split(list(q)),
                                  strict=True):
            motor = K.forward_kinematics(ZERO, chain.joints, qc)
            worst = max(worst, np.abs(coefficients(motor) - motor_from_dq(arm.fkm(np.array(qc)))).max())
    assert worst < 1e-12


def test_poses_and_relative_jacobian_match_dqrobotics(pandas):
    """M_r, M_a and ∂M_r/∂q against relative_pose, absolute_pose and relative_pose_jacobian, and the
    geometric J_r against −2 M_r~ ∂M_r/∂q from dqrobotics' Jacobian, at 20 seeded configurations."""
    worst = dict.fromkeys(("M_r", "M_a", "J_Ar", "J_r"), 0.0)
    for q in pandas.configurations():
        v = dual_task(ZERO, pandas.system, list(q))
        xr, xa = motor_from_dq(pandas.cdts.relative_pose(q)), motor_from_dq(pandas.cdts.absolute_pose(q))
        jr = motor_from_dq(pandas.cdts.relative_pose_jacobian(q))
        found = {"M_r": (coefficients(v["M_r"]), xr), "M_a": (coefficients(v["M_a"]), xa),
                 "J_Ar": (columns(v["J_Ar"], MOTOR), jr),
                 "J_r": (columns(v["J_r"], MOTOR_GENERATOR), _geometric(xr, jr))}
        for name, (ours, theirs) in found.items():
            worst[name] = max(worst[name], np.abs(ours - theirs).max())
    assert max(worst.values()) < 1e-10, worst


def test_absolute_jacobian_matches_differences_of_dqrobotics_absolute_pose(pandas):
    """∂M_a/∂q and J_a against fourth-order differences of dqrobotics' absolute_pose (its own
    absolute_pose_jacobian is an approximation here, see the module docstring)."""
    worst = {"J_Aa": 0.0, "J_a": 0.0}
    for q in pandas.configurations(seed=2):
        v = dual_task(ZERO, pandas.system, list(q), ("M_a", "J_a", "J_Aa"))
        ja = motor_from_dq(_richardson(lambda x: vec8(pandas.cdts.absolute_pose(x)), q))
        worst["J_Aa"] = max(worst["J_Aa"], np.abs(columns(v["J_Aa"], MOTOR) - ja).max())
        worst["J_a"] = max(worst["J_a"], np.abs(columns(v["J_a"], MOTOR_GENERATOR)
                                                - _geometric(coefficients(v["M_a"]), ja)).max())
    assert max(worst.values()) < 1e-10, worst


def _aligned(q: np.ndarray, turn: float) -> np.ndarray:
    """Arm 2 at arm 1's joint angles with joint 1 turned by ``turn``: the arms face each other (bases at
    yaw 2π and π), so both flanges have one orientation; turn = +π gives them the same lift (relative
    rotor +1), turn = −π opposite lifts (relative rotor −1, the chart's singularity)."""
    aligned = np.concatenate([q[:7], q[:7]])
    aligned[7] += turn
    return aligned


def test_absolute_jacobian_matches_dqrobotics_where_its_formula_is_exact(pandas):
    """With the relative rotation the identity, dqrobotics' absolute_pose_jacobian is exact: ∂M_a/∂q
    equals it."""
    worst = 0.0
    for q in pandas.configurations(seed=3):
        q = _aligned(q, math.pi)
        v = dual_task(ZERO, pandas.system, list(q), ("M_r", "J_Aa"))
        assert abs(v["M_r"]["1"] - 1) < 1e-14
        worst = max(worst, np.abs(columns(v["J_Aa"], MOTOR)
                                  - motor_from_dq(pandas.cdts.absolute_pose_jacobian(q))).max())
    assert worst < 1e-10


def test_the_relative_rotor_minus_one_stays_finite(pandas):
    """At the chart's singularity (M_r's rotor −1) every output is finite; (1 + ⟨M_r⟩₀)/2 reports it."""
    q = _aligned(pandas.configurations(seed=4, count=1)[0], -math.pi)
    v = dual_task(ZERO, pandas.system, list(q))
    assert abs(v["M_r"]["1"] + 1) < 1e-14
    assert all(np.all(np.isfinite(coefficients(v[n]))) for n in ("M_r", "M_a"))
    assert all(np.all(np.isfinite(columns(v[n], MOTOR))) for n in ("J_r", "J_a", "J_Ar", "J_Aa"))


# -- the paper's formulas and differences, every two-chain system ------------------------------------------

def _q(name: str, seed: int) -> list[float]:
    return list(np.random.default_rng(seed).uniform(-1.5, 1.5, bundled_systems()[name].dof))


@pytest.mark.parametrize("name", TWO_CHAINS)
def test_motors_are_the_papers_formulas(name):
    """M_r = M_2~ M_1 [Eq. 10] and M_a = M_2 exp(½ log M_r) [Eq. 11] through the motor exp/log charts;
    the half motor's rotor squares to M_r's."""
    system = bundled_systems()[name]
    for seed in range(3):
        q = _q(name, seed)
        m1, m2 = (K.forward_kinematics(ZERO, c.joints, qc) for c, qc in zip(system.chains, system.split(q),
                                                                            strict=True))
        v = dual_task(ZERO, system, q, ("M_r", "M_a"))
        assert np.allclose(coefficients(v["M_r"]), coefficients(~m2 * m1), atol=1e-14)
        assert np.allclose(coefficients(v["M_r"]), coefficients(relative_motor(m1, m2)), atol=0)
        assert np.allclose(coefficients(v["M_a"]), coefficients(absolute_motor(m1, m2)), atol=1e-13)
        half = half_motor(v["M_r"])
        assert np.allclose(coefficients(half.half_rotor * half.half_rotor, ROTOR),
                           coefficients(v["M_r"], ROTOR), atol=1e-14)


def _central(f, q: list[float], h: float = 1e-6) -> np.ndarray:
    found = []
    for k in range(len(q)):
        up, down = list(q), list(q)
        up[k] += h
        down[k] -= h
        found.append((f(up) - f(down)) / (2 * h))
    return np.array(found).T


@pytest.mark.parametrize("name", TWO_CHAINS)
def test_jacobians_against_differences(name):
    """J_Ar, J_Aa against central differences of M_r, M_a and J_r, J_a = −2 M~ ∂M/∂q, every joint
    (g1_arms_line: the waist joints move both hands)."""
    system = bundled_systems()[name]
    q = _q(name, 7)
    v = dual_task(ZERO, system, q)
    both = _central(lambda x: np.concatenate(
        [coefficients(m) for m in dual_task(ZERO, system, x, ("M_r", "M_a")).values()]), q)
    for fd, (motor, analytic, geometric) in zip((both[:8], both[8:]), (("M_r", "J_Ar", "J_r"),
                                                                       ("M_a", "J_Aa", "J_a")), strict=True):
        assert np.abs(columns(v[analytic], MOTOR) - fd).max() < 1e-8
        assert np.abs(columns(v[geometric], MOTOR_GENERATOR) - _geometric(coefficients(v[motor]), fd)).max() \
            < 1e-8


def test_shared_waist_joints_leave_the_relative_motor_alone():
    """The G1's waist carries both hands alike, so M_r = M_2~ M_1 does not depend on it: its columns
    of J_r vanish, while J_a has them."""
    system = bundled_systems()["g1_arms_line"]
    shared = [j for j, key in enumerate(system.joint_keys)
              if all(key in c.joint_keys() for c in system.chains)]
    assert len(shared) == 3
    v = dual_task(ZERO, system, _q("g1_arms_line", 3), ("J_r", "J_a"))
    jr, ja = columns(v["J_r"], MOTOR_GENERATOR), columns(v["J_a"], MOTOR_GENERATOR)
    assert np.abs(jr[:, shared]).max() < 1e-15
    assert np.linalg.norm(ja[:, shared], axis=0).min() > 0.1


def test_a_chain_named_like_a_dual_task_kernel_is_refused(tmp_path):
    """A chain 'dual_task' of a two-chain system would make the kernel 'dual_task_jacobians' twice; with
    three chains there is no dual task space and the name is free."""
    urdf = bundled_specs()[PANDA].parent / "panda/panda.urdf"

    def spec(chains: tuple[str, ...]) -> Path:
        text = f"name: t\nprimitive: {'point_pair' if len(chains) == 2 else 'circle'}\nchains:\n"
        for chain in chains:
            text += (f"  - name: {chain}\n    urdf: {urdf}\n    base_link: panda_link0\n"
                     f"    tip_link: panda_link8\n")
        path = tmp_path / "spec.yaml"
        path.write_text(text)
        return path

    with pytest.raises(SpecError) as e:
        load_system(spec(("arm0", "dual_task")))
    assert e.value.field.startswith("chains[1].name")
    assert "collides with the system kernel 'dual_task_jacobians'" in e.value.message
    load_system(spec(("arm0", "dual_task", "arm2")))


def test_the_catalogue_has_the_dual_task_kernels_for_two_chains_only():
    """... under the names gagen.names predicts (the spec checks chain names against them)."""
    for name, system in bundled_systems().items():
        found = {"dual_task", "dual_task_jacobians"} & set(kernel_functions(system))
        assert found == (set(DUAL_TASK_KERNELS) if len(system.chains) == 2 else set()), name
    assert dual_task_kernel_functions(bundled_systems()["three_pandas_circle"]) == {}
    with pytest.raises(ValueError, match="two chains"):
        dual_task(ZERO, bundled_systems()["three_pandas_circle"], [0.0] * 21)


# -- the generated kernels -----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def built():
    """The two Pandas' module, built on first use into the gagen cache (shared with the other tests)."""
    from gagen.apps.cooperative.bundled import system_module

    return system_module(PANDA)


@pytest.mark.compiling
def test_generated_kernels_match_dqrobotics(pandas, built):
    """dual_task and dual_task_jacobians of the built module (C single, C batched, CasADi) against
    dqrobotics at 20 seeded configurations: poses, ∂M_r/∂q, and ∂M_a/∂q against differences."""
    qs = pandas.configurations(seed=5)
    worst = 0.0
    batched = built.c.dual_task_jacobians.batch(np.array(qs))
    for k, q in enumerate(qs):
        theirs = {"M_r": motor_from_dq(pandas.cdts.relative_pose(q)),
                  "M_a": motor_from_dq(pandas.cdts.absolute_pose(q)),
                  "J_Ar": motor_from_dq(pandas.cdts.relative_pose_jacobian(q)),
                  "J_Aa": motor_from_dq(_richardson(lambda x: vec8(pandas.cdts.absolute_pose(x)), q))}
        theirs["J_r"] = _geometric(theirs["M_r"], theirs["J_Ar"])
        theirs["J_a"] = _geometric(theirs["M_a"], theirs["J_Aa"])
        for kernel, names in (("dual_task", ("M_r", "M_a", "J_r", "J_a")),
                              ("dual_task_jacobians", ("M_r", "M_a", "J_Ar", "J_Aa"))):
            c_out = getattr(built.c, kernel)(q)
            ca_out = getattr(built.casadi, kernel)(q)
            for i, name in enumerate(names):
                expected = np.reshape(theirs[name], np.shape(c_out[i]))
                worst = max(worst, np.abs(c_out[i] - expected).max(),
                            np.abs(np.reshape(np.asarray(ca_out[i]), expected.shape) - expected).max())
                if kernel == "dual_task_jacobians":
                    worst = max(worst, np.abs(np.reshape(batched[i][k], expected.shape) - expected).max())
    assert worst < 1e-10


@pytest.mark.compiling
def test_generated_kernels_pass_the_check(built):
    """``gagen build --check`` on the dual task kernels: values against the interpreter, every Jacobian
    against differences."""
    from gagen import check

    system = bundled_systems()[PANDA]
    functions = {k: f for k, f in kernel_functions(system).items() if k.startswith("dual_task")}
    found = check.check_kernels(_Only(built, set(functions)), functions, count=3)
    assert {d.kernel for d in found} == set(functions)
    assert not check.failures(found), check.format_report(found)


@pytest.mark.compiling
@pytest.mark.parametrize("name", ["two_iiwas_line", "g1_arms_line"])
def test_the_other_systems_kernels_pass_the_check(tmp_path, name):
    """The dual task kernels alone (``compile_kernels``), checked like ``gagen build --check`` does."""
    from gagen import check
    from gagen.build import compile_kernels
    from gagen.runtime import load

    functions = dual_task_kernel_functions(bundled_systems()[name])
    compile_kernels(list(functions.values()), name=name, folder=tmp_path / name)
    found = check.check_kernels(load(tmp_path / name), functions, count=3)
    assert {d.kernel for d in found} == set(functions)
    assert not check.failures(found), check.format_report(found)


class _Only:
    """A module seen through some of its kernels."""

    def __init__(self, module, names: set[str]) -> None:
        self.c, self.casadi = module.c, module.casadi
        kernels = [k for k in module.manifest["kernels"] if k["name"] in names]
        self.manifest = {**module.manifest, "kernels": kernels}
