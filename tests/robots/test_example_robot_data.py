"""Real robots as users have them, from ``example-robot-data`` (the PyPI wheel that ships the URDFs
Pinocchio's examples use): expanded xacro output carrying ``xmlns:xacro``, ``1.57079632679`` for π/2,
continuous joints, floating-base robots with a chain from a chosen link. Each chain is built from a
one-chain spec written into tmp_path (``snap: false``), its ``<chain>_fk_jacobian`` kernel traced from
the cooperative catalogue and evaluated in CasADi (nothing compiled), and held to Pinocchio on the same
file: end point, rotation and spatial Jacobian ≤ 1e-12 at random configurations of the whole robot.

The comparison is ``benchmarks/example_robot_data.py``'s, which tries every URDF of the package (the
table in docs/robots.md)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pinocchio", reason="the comparison needs Pinocchio: pip install 'gagen[dynamics]'")

_SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "example_robot_data.py"
_spec = importlib.util.spec_from_file_location("example_robot_data_survey", _SCRIPT)
assert _spec is not None and _spec.loader is not None
erd = sys.modules.setdefault(_spec.name, importlib.util.module_from_spec(_spec))
_spec.loader.exec_module(erd)  # registered first: its dataclasses look their module up

if not erd.urdf_files():
    pytest.skip("example-robot-data is not installed (pip install 'gagen[test]' or example-robot-data); "
                "its URDFs are the real robots these tests build", allow_module_level=True)

# name: (URDF file, base link, tip link, free-flyer root in Pinocchio's model, continuous joints)
ROBOTS = {
    "ur10": ("ur10_robot.urdf", "base_link", "ee_link", False, 0),
    "ur5": ("ur5_robot.urdf", "base_link", "tool0", False, 0),
    "kinova_jaco": ("kinova.urdf", "base", "j2s6s200_end_effector", False, 3),
    "panda": ("panda.urdf", "panda_link0", "panda_hand_tcp", False, 0),
    "xarm7": ("xarm7.urdf", "link_base", "link_eef", False, 0),
    # floating-base robots: the chain starts at a link chosen in the tree (the torso, the trunk), the
    # Pinocchio model has a free-flyer root at a random placement and every other joint random
    "talos_left_arm": ("talos_reduced.urdf", "torso_2_link", "gripper_left_fingertip_1_link", True, 0),
    "solo12_front_left_leg": ("solo12.urdf", "base_link", "FL_FOOT", True, 0),
    # from any link to any link: up the left arm and down the right one (hand to hand, through the torso)
    "talos_hand_to_hand": ("talos_reduced.urdf", "arm_left_7_link", "arm_right_7_link", True, 0),
}


def _urdf(name: str) -> Path:
    path = erd.find_urdf(ROBOTS[name][0])
    assert path is not None, f"example-robot-data ships no {ROBOTS[name][0]}"
    return path


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_chain_builds_and_agrees_with_pinocchio(tmp_path, name):
    _, base, tip, floating, continuous = ROBOTS[name]
    outcome = erd.check(_urdf(name), base, tip, snap=False, samples=10, floating=floating, folder=tmp_path)
    assert outcome.built, outcome.reason
    assert (tmp_path / "chain.yaml").is_file()  # built from a spec, as a user's
    assert outcome.continuous == continuous and outcome.dof >= 3
    assert outcome.fk <= 1e-12 and outcome.jacobian <= 1e-12, (outcome.fk, outcome.jacobian)


def test_expanded_xacro_output_is_among_them():
    """The UR and Kinova files are xacro output: they keep the xmlns:xacro declaration (the old check
    refused them as xacro sources) and write π/2 as 1.57079632679."""
    for name in ("ur10", "kinova_jaco"):
        text = _urdf(name).read_text()
        assert "xmlns:xacro" in text and "<xacro:" not in text
    assert "1.57079632679" in _urdf("ur10").read_text()


def test_snapping_is_what_separates_them_from_pinocchio(tmp_path):
    """With the default snapping the UR10's 1.57079632679 becomes an exact π/2: the chain is then off
    the file's numbers by ≈ 1e-11, which is what ``snap: false`` removes."""
    snapped = erd.check(_urdf("ur10"), "base_link", "ee_link", snap=True, samples=10, folder=tmp_path)
    assert snapped.built and 1e-12 < max(snapped.fk, snapped.jacobian) < 1e-9


def test_continuous_joints_in_the_dynamics(tmp_path):
    """The Jaco's continuous joints (Pinocchio's cos/sin pairs) in the system's dynamics: M, C q̇ + g
    and g as Pinocchio's on the file itself."""
    import pinocchio as pin

    from gagen.dynamics.rigid_body import GRAVITY, SystemDynamics

    _, base, tip, _, _ = ROBOTS["kinova_jaco"]
    spec = tmp_path / "jaco.yaml"
    spec.write_text(f"name: jaco\nprimitive: point\nchains:\n  - name: arm\n"
                    f"    urdf: {_urdf('kinova_jaco')}\n    base_link: {base}\n    tip_link: {tip}\n")
    dynamics = SystemDynamics(spec)
    model = pin.buildModelFromUrdf(str(_urdf("kinova_jaco")))
    model.gravity = pin.Motion(np.array([0.0, 0.0, -GRAVITY]), np.zeros(3))
    assert model.nq == dynamics.dof + 3 and model.nv == dynamics.dof  # three continuous joints
    data = model.createData()
    rng = np.random.default_rng(3)
    for _ in range(5):
        config = erd.random_configuration(pin, model, rng)
        q = np.array([erd._angle(model, config, j) for j in range(1, model.njoints)])
        qd = rng.uniform(-1, 1, model.nv)
        M = pin.crba(model, data, config)
        M = np.triu(M) + np.triu(M, 1).T
        assert np.abs(dynamics.mass_matrix(q) - M).max() <= 1e-12
        assert np.abs(dynamics.bias(q, qd) - pin.nonLinearEffects(model, data, config, qd)).max() <= 1e-12
        assert np.abs(dynamics.gravity(q) - pin.computeGeneralizedGravity(model, data, config)).max() <= 1e-12
