"""The Pinocchio model of a cooperative system: placement and joint order against the generated
kinematics, dynamics against single-robot models and closed forms, and the refusals."""

from pathlib import Path

import numpy as np
import pytest

from gagen.dynamics.rigid_body import GRAVITY, DynamicsError, SystemDynamics

pin = pytest.importorskip("pinocchio")

ROOT = Path(__file__).resolve().parents[2]
ROBOTS = ROOT / "robots"


@pytest.fixture(scope="module")
def pandas() -> SystemDynamics:
    return SystemDynamics(ROBOTS / "three_pandas_circle.yaml")


def test_end_points_match_the_generated_kinematics(pandas):
    """Each arm's flange in the Pinocchio model = the generated chain kernel's end point, at random q:
    base placement, joint order and the URDF's kinematics agree."""
    from gagen.apps.cooperative.bundled import system_module

    module = system_module("three_pandas_circle")
    rng = np.random.default_rng(0)
    for _ in range(5):
        q = rng.uniform(-1.5, 1.5, 21)
        for i in range(3):
            _, point = getattr(module.c, f"arm{i}_fk")(q[7 * i:7 * i + 7])
            assert np.abs(pandas.link_position(q, f"arm{i}", "panda_link8") - point[1:4]).max() <= 1e-13


def test_mass_matrix_is_three_single_panda_blocks(pandas):
    """M is block diagonal, each block the single Panda's M from its URDF (Pinocchio on the file
    alone): the arms do not couple, and the joint order maps as it should."""
    single = pin.buildModelFromUrdf(str(ROBOTS / "panda" / "panda.urdf"))
    data = single.createData()
    rng = np.random.default_rng(1)
    q = rng.uniform(-1.5, 1.5, 21)
    M = pandas.mass_matrix(q)
    assert np.abs(M - M.T).max() == 0.0
    for i in range(3):
        block = pin.crba(single, data, q[7 * i:7 * i + 7])
        block = np.triu(block) + np.triu(block, 1).T
        rows = slice(7 * i, 7 * i + 7)
        assert np.abs(M[rows, rows] - block).max() <= 1e-12
        off = np.delete(M[rows], np.s_[7 * i:7 * i + 7], axis=1)
        assert np.abs(off).max() == 0.0


def test_gravity_does_not_depend_on_the_turned_bases(pandas):
    """The arms stand on the floor turned about z: with equal joint values their gravity torques are
    equal, and at the stretched-up configuration (all links above joint 1) joint 1 carries none."""
    q = np.tile(np.random.default_rng(2).uniform(-1.0, 1.0, 7), 3)
    g = pandas.gravity(q)
    assert np.abs(g[:7] - g[7:14]).max() <= 1e-12 and np.abs(g[:7] - g[14:]).max() <= 1e-12
    assert abs(pandas.gravity(np.zeros(21))[0]) <= 1e-12


def test_potential_energy_is_the_mass_times_the_centre_height(pandas):
    """U = m g z_com, with the moving mass of the URDFs' inertials (three Pandas, 13.786 kg each over
    links 1-7 from the FER inertials.yaml; link0 is welded to the floor and takes no part)."""
    per_arm = 2.7907 + 2.5420 + 2.2513 + 2.2037 + 2.2855 + 1.353 + 0.35973
    assert pandas.total_mass() == pytest.approx(3 * per_arm, rel=1e-12)
    q = np.zeros(21)
    com = pin.centerOfMass(pandas.model, pandas.data, q)
    assert pandas.potential_energy(q) == pytest.approx(pandas.total_mass() * GRAVITY * com[2], rel=1e-12)


def test_forward_dynamics_inverts_the_equation_of_motion(pandas):
    rng = np.random.default_rng(3)
    q, qd, tau = rng.uniform(-1, 1, 21), rng.uniform(-1, 1, 21), rng.uniform(-5, 5, 21)
    qdd = pandas.forward(q, qd, tau)
    assert np.abs(pandas.mass_matrix(q) @ qdd + pandas.bias(q, qd) - tau).max() <= 1e-10


def test_joint_order_is_the_systems(tmp_path):
    """A spec listing the arms in the other order gives the same dynamics, permuted."""
    import yaml

    data = yaml.safe_load((ROBOTS / "two_pandas_point_pair.yaml").read_text())
    data["chains"] = data["chains"][::-1]
    for chain in data["chains"]:
        chain["urdf"] = str(ROBOTS / chain["urdf"])
    spec = tmp_path / "swapped.yaml"
    spec.write_text(yaml.safe_dump(data))
    base, other = SystemDynamics(ROBOTS / "two_pandas_point_pair.yaml"), SystemDynamics(spec)
    q = np.random.default_rng(4).uniform(-1, 1, 14)
    perm = np.r_[7:14, 0:7]  # other's q = base's q with the arms swapped
    assert [c.name for c in other.system.chains] == [c.name for c in base.system.chains][::-1]
    assert np.abs(other.gravity(q[perm]) - base.gravity(q)[perm]).max() <= 1e-12
    M, M_other = base.mass_matrix(q), other.mass_matrix(q[perm])
    assert np.abs(M_other - M[np.ix_(perm, perm)]).max() <= 1e-12


def test_a_urdf_without_inertias_is_refused(tmp_path):
    (tmp_path / "arm").mkdir()
    urdf = (ROBOTS / "iiwa14" / "iiwa14.urdf").read_text()
    link = urdf.index('"iiwa_link_3"')
    start, end = urdf.index("<inertial>", link), urdf.index("</inertial>", link)
    (tmp_path / "arm" / "iiwa14.urdf").write_text(urdf[:start] + urdf[end + len("</inertial>"):])
    spec = (ROBOTS / "two_iiwas_line.yaml").read_text().replace("urdf: iiwa14/", "urdf: arm/")
    (tmp_path / "line.yaml").write_text(spec)
    with pytest.raises(DynamicsError, match=r"iiwa14\.urdf: the links moved by joints .*iiwa_joint_3"):
        SystemDynamics(tmp_path / "line.yaml")


def test_bundled_robots_without_inertias_are_refused_by_name():
    with pytest.raises(DynamicsError, match=r"g1_upper_body\.urdf: the links moved by joints"):
        SystemDynamics(ROBOTS / "two_g1_sphere.yaml")


def test_chains_without_urdf_are_refused(tmp_path):
    spec = tmp_path / "explicit.yaml"
    spec.write_text("name: listed\nprimitive: point\nchains:\n  - name: finger\n    joints:\n"
                    "      - {name: j1, type: revolute, axis: [0, 0, 1], xyz: [0, 0, 0.1], rpy: [0, 0, 0]}\n")
    with pytest.raises(DynamicsError, match=r"explicit\.yaml: chains\[0\]: dynamics need a URDF"):
        SystemDynamics(spec)


def _iiwa_with_continuous_joints(tmp_path, joints=(1, 3, 5, 7)) -> tuple[Path, Path]:
    """A one-arm spec on a copy of the iiwa14 whose joints ``joints`` are continuous (no limits), and
    the copy's URDF."""
    urdf = (ROBOTS / "iiwa14" / "iiwa14.urdf").read_text()
    for k in joints:
        urdf = urdf.replace(f'<joint name="iiwa_joint_{k}" type="revolute">',
                            f'<joint name="iiwa_joint_{k}" type="continuous">')
    path = tmp_path / "iiwa14_continuous.urdf"
    path.write_text(urdf)
    spec = tmp_path / "arm.yaml"
    spec.write_text("name: continuous_arm\nprimitive: point\nchains:\n  - name: arm\n"
                    f"    urdf: {path.name}\n    base_link: iiwa_link_0\n    tip_link: iiwa_link_ee\n"
                    "    base: {xyz: [0.1, -0.2, 0.3], rpy: [0.0, 0.0, 0.5]}\n")
    return spec, path


def test_continuous_joints_agree_with_pinocchio(tmp_path):
    """Continuous joints (Pinocchio's nq = 2: cos, sin) take the system's angle: M, C q̇ + g and g agree
    with Pinocchio on the URDF itself (its configuration built from the angles here), and with the
    same arm whose joints are revolute, to 1e-12; forward dynamics invert the equation of motion."""
    spec, urdf = _iiwa_with_continuous_joints(tmp_path)
    dynamics = SystemDynamics(spec)
    assert dynamics.dof == 7 and dynamics.model.nq == 11 and dynamics.model.nv == 7
    (tmp_path / "revolute").mkdir()
    revolute = SystemDynamics(_iiwa_with_continuous_joints(tmp_path / "revolute", joints=())[0])
    model = pin.buildModelFromUrdf(str(urdf))
    model.gravity = pin.Motion(np.array([0.0, 0.0, -GRAVITY]), np.zeros(3))
    data = model.createData()
    rng = np.random.default_rng(5)
    for _ in range(10):
        q, qd = rng.uniform(-3, 3, 7), rng.uniform(-2, 2, 7)
        config = np.concatenate([[np.cos(a), np.sin(a)] if k % 2 == 0 else [a] for k, a in enumerate(q)])
        M = pin.crba(model, data, config)
        M = np.triu(M) + np.triu(M, 1).T
        bias, gravity = pin.nonLinearEffects(model, data, config, qd), pin.computeGeneralizedGravity(
            model, data, config)
        # the base placement is a turn about the gravity axis: M, C q̇ and g do not depend on it
        assert np.abs(dynamics.mass_matrix(q) - M).max() <= 1e-12
        assert np.abs(dynamics.bias(q, qd) - bias).max() <= 1e-12
        assert np.abs(dynamics.gravity(q) - gravity).max() <= 1e-12
        assert np.abs(dynamics.mass_matrix(q) - revolute.mass_matrix(q)).max() <= 1e-12
        assert np.abs(dynamics.bias(q, qd) - revolute.bias(q, qd)).max() <= 1e-12
        assert np.abs(dynamics.link_position(q, "arm", "iiwa_link_ee")
                      - revolute.link_position(q, "arm", "iiwa_link_ee")).max() <= 1e-12
        tau = rng.uniform(-5, 5, 7)
        assert np.abs(dynamics.mass_matrix(q) @ dynamics.forward(q, qd, tau) + dynamics.bias(q, qd)
                      - tau).max() <= 1e-10
