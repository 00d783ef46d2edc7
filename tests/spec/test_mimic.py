"""URDF ``<mimic>`` joints: a follower turns by multiplier·q_leader + offset and has no entry in q.

The fixture (tests/data/mimic_gripper.urdf) is a 3-joint arm whose joint3 mimics joint2 (−0.5, +0.1)
and a gripper whose finger_joint2 mimics finger_joint1 (+1, +0.003). The chain kernels' FK and 6×n
WORLD Jacobian are compared with Pinocchio (``mimic=True``) and with an independent 4×4-matrix chain
on the expanded angles (its Jacobian by central differences); the other chain Jacobians and the
system Jacobians against central differences of the kernels' own values."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from gagen.algebra.signature import cga3d
from gagen.apps.cooperative.catalogue import build_kernels
from gagen.errors import SpecError
from gagen.interp import MultiVector
from gagen.model import kinematics as K
from gagen.model.kinematics import Joint
from gagen.robots.spec import load_system
from gagen.robots.system import Chain, System
from gagen.robots.urdf import load_chain

URDF = Path(__file__).resolve().parents[1] / "data" / "mimic_gripper.urdf"
# every moving joint of the fixture: (parent-to-joint origin xyz, rpy, axis, kind, value from q)
# with q = (joint1, joint2, finger_joint1), written out independently of the URDF parser
TREE = {
    "link1": ("base", (0.05, -0.02, 0.3), (0, 0, 0.4), (0, 0, 1), "R", lambda q: q[0]),
    "link2": ("link1", (0.1, 0, 0.4), (0.3, -0.2, 0.2), (0, 1, 0), "R", lambda q: q[1]),
    "link3": ("link2", (0.35, 0.03, -0.02), (0, 0.5, 0), (0, 0.6, 0.8), "R", lambda q: -0.5 * q[1] + 0.1),
    "hand": ("link3", (0.2, 0, 0.05), (0, 0, -0.7), None, "F", None),
    "finger1": ("hand", (0.05, 0, 0.06), (0, 0, 0), (0, 1, 0), "P", lambda q: q[2]),
    "finger2": ("hand", (0.05, 0, 0.06), (0, 0, 0), (0, -1, 0), "P", lambda q: q[2] + 0.003),
}
VARIABLES = ("joint1", "joint2", "finger_joint1")
ALG = cga3d()
LIKE = MultiVector.zero(ALG)


def _rotation(axis, angle) -> np.ndarray:
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * skew + (1 - np.cos(angle)) * skew @ skew


def _rpy(rpy) -> np.ndarray:
    return _rotation((0, 0, 1), rpy[2]) @ _rotation((0, 1, 0), rpy[1]) @ _rotation((1, 0, 0), rpy[0])


def _numpy_fk(link: str, q) -> np.ndarray:
    """The 4×4 pose of ``link`` in the base frame: a plain matrix product over the tree above."""
    if link == "base":
        return np.eye(4)
    parent, xyz, rpy, axis, kind, value = TREE[link]
    origin = np.eye(4)
    origin[:3, :3], origin[:3, 3] = _rpy(rpy), xyz
    motion = np.eye(4)
    if kind == "R":
        motion[:3, :3] = _rotation(axis, value(q))
    elif kind == "P":
        motion[:3, 3] = np.asarray(axis, float) * value(q)
    return _numpy_fk(parent, q) @ origin @ motion


def _numpy_world_jacobian(link: str, q, h: float = 1e-6) -> np.ndarray:
    """[v; ω] WORLD columns (Pinocchio's layout) by central differences of the matrix chain:
    ω = vee(Ṙ Rᵀ), v = ṗ − ω × p."""
    pose = _numpy_fk(link, q)
    columns = []
    for i in range(len(q)):
        step = np.zeros(len(q))
        step[i] = h
        d = (_numpy_fk(link, q + step) - _numpy_fk(link, q - step)) / (2 * h)
        w = d[:3, :3] @ pose[:3, :3].T
        omega = np.array([w[2, 1], w[0, 2], w[1, 0]])
        columns.append(np.concatenate([d[:3, 3] - np.cross(omega, pose[:3, 3]), omega]))
    return np.array(columns).T


@cache
def _pinocchio():
    model = pin.buildModelFromUrdf(str(URDF), mimic=True)
    assert model.nq == model.nv == 3  # the two followers add no coordinate
    idx = [model.joints[model.getJointId(name)].idx_q for name in VARIABLES]
    return model, idx


def _pinocchio_pose_and_jacobian(link: str, q) -> tuple[np.ndarray, np.ndarray]:
    model, idx = _pinocchio()
    full = np.zeros(model.nq)
    full[idx] = q
    data = model.createData()
    frame = model.getFrameId(link)
    pin.forwardKinematics(model, data, full)
    pin.updateFramePlacements(model, data)
    jacobian = pin.computeFrameJacobian(model, data, full, frame, pin.ReferenceFrame.WORLD)
    return data.oMf[frame].homogeneous.copy(), jacobian[:, idx]


def _chain(tip: str, name: str, robot: str = "gripper") -> Chain:
    return Chain(name, tuple(load_chain(URDF, "base", tip)), robot)


@cache
def _point_kernels():
    return build_kernels(System("mimic_point", "point", (_chain("finger2", "f2"),)))


@cache
def _pair():
    system = System("mimic_pair", "point_pair", (_chain("finger1", "f1"), _chain("finger2", "f2")))
    return system, build_kernels(system)


def _outputs(kernel, *inputs) -> dict[str, np.ndarray]:
    values = kernel.function(*inputs)
    values = values if isinstance(values, (list, tuple)) else [values]
    return {p.name: np.array(ca.DM(v)).reshape(p.shape, order="F") for p, v in zip(kernel.outputs, values,
                                                                                      strict=True)}


def _multivector(kernel, port: str, values: np.ndarray) -> MultiVector:
    rows = next(p for p in kernel.outputs if p.name == port).rows
    coeffs = np.zeros(ALG.size)
    coeffs[[ALG.blade(b) for b in rows]] = values
    return MultiVector(ALG, coeffs)


def _row(port_rows, name):
    return port_rows.index(name)


def _world(kernel, j_s: np.ndarray) -> np.ndarray:
    """J_S rows [e12, e13, e23, e1∞, e2∞, e3∞] as Pinocchio's [v; ω]."""
    rows = next(p for p in kernel.outputs if p.name == "J_S").rows
    r = {b: j_s[_row(rows, b)] for b in rows}
    return np.array([r["e1inf"], r["e2inf"], r["e3inf"], r["e23"], -r["e13"], r["e12"]])


def _configurations(count: int = 20, seed: int = 5) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-2.5, 2.5, (count, 2)), rng.uniform(0.0, 0.04, count)])


def test_followers_are_no_joint_variables():
    """dof counts the independent joints; q entries are the leaders (finger_joint1 lies outside the
    finger2 chain: its only use there is through the follower)."""
    chain = _chain("finger2", "f2")
    assert sum(j.moves for j in chain.joints) == 4 and chain.dof == 3
    assert chain.joint_keys() == [("gripper", v) for v in VARIABLES]
    assert _chain("link3", "arm").dof == 2
    system, _ = _pair()
    assert system.dof == 3 and system.joint_keys == [("gripper", v) for v in VARIABLES]
    assert system.chain_indices() == [[0, 1, 2], [0, 1, 2]]
    q = [0.3, -0.4, 0.02]
    assert system.joint_values(q)[1] == pytest.approx([0.3, -0.4, 0.5 * 0.4 + 0.1, 0.02 + 0.003], abs=1e-15)
    kernels = _point_kernels()
    assert kernels["f2_fk"].inputs[0].rows == ("gripper/joint1", "gripper/joint2", "gripper/finger_joint1")


@pytest.mark.parametrize("tip", ["finger2", "link3"])
def test_fk_and_world_jacobian_equal_pinocchio_and_a_matrix_chain(tip):
    """P, the rotation and the 6×n WORLD Jacobian of the CasADi chain kernel against Pinocchio's mimic
    model and an independent 4×4 chain, at 20 random configurations, to 1e-10 (the difference
    Jacobian to 1e-8)."""
    if tip == "finger2":
        kernel = _point_kernels()["f2_jacobians"]
    else:
        kernel = build_kernels(System("mimic_arm", "point", (_chain("link3", "arm"),)))["arm_jacobians"]
    used = len(kernel.inputs[0].rows)
    points = kernel.outputs[1].rows
    for q in _configurations():
        q = q[:used]
        qq = np.concatenate([q, np.zeros(3 - used)])
        out = _outputs(kernel, q)
        position = out["P"][[_row(points, b) for b in ("e1", "e2", "e3")], 0]
        pose, jacobian = _pinocchio_pose_and_jacobian(tip, qq)
        reference = _numpy_fk(tip, qq)
        np.testing.assert_allclose(reference, pose, atol=1e-12)  # the two references agree
        np.testing.assert_allclose(position, pose[:3, 3], atol=1e-10)
        world = _world(kernel, out["J_S"])
        np.testing.assert_allclose(world, jacobian[:, :used], atol=1e-10)
        np.testing.assert_allclose(world, _numpy_world_jacobian(tip, qq)[:, :used], atol=1e-8)
        # the interpreter (``--check``'s reference) on the same chain variables
        motor, lines = K.chain_kinematics(LIKE, load_chain(URDF, "base", tip), list(q))
        end = K.end_point(motor)
        np.testing.assert_allclose([end[b] for b in ("e1", "e2", "e3")], pose[:3, 3], atol=1e-10)
        twists = [[c["e1inf"], c["e2inf"], c["e3inf"], c["e23"], -c["e13"], c["e12"]] for c in lines]
        np.testing.assert_allclose(np.array(twists).T, jacobian[:, :used], atol=1e-10)


def test_the_other_chain_jacobians_are_derivatives_with_respect_to_the_variables():
    """J_A = ∂M/∂q, J_P = ∂P/∂q, J_L = ∂L/∂q by central differences of the kernel's own M, P, L;
    J_b = −2 M~ J_A [COOP Eq. 8] in the interpreter."""
    kernel = _point_kernels()["f2_jacobians"]
    h = 1e-6
    for q in _configurations(5, seed=9):
        out = _outputs(kernel, q)
        for value, derivative in (("M", "J_A"), ("P", "J_P"), ("L", "J_L")):
            columns = []
            for i in range(3):
                step = np.zeros(3)
                step[i] = h
                columns.append((_outputs(kernel, q + step)[value] - _outputs(kernel, q - step)[value])[:, 0]
                               / (2 * h))
            np.testing.assert_allclose(out[derivative], np.array(columns).T, atol=1e-8)
        motor = _multivector(kernel, "M", out["M"][:, 0])
        body = [(~motor * _multivector(kernel, "J_A", column) * -2) for column in out["J_A"].T]
        rows = next(p for p in kernel.outputs if p.name == "J_b").rows
        np.testing.assert_allclose(out["J_b"], [[c[b] for c in body] for b in rows], atol=1e-12)


def test_system_jacobians_follow_the_chain_rule():
    """Two chains of one robot (the two fingers) span a point pair: J_c and J_A,Sc against central
    differences of X_c and V_Sc over the 3 shared variables (the fingers are millimetres apart: V_Sc is
    steep there, hence the relative tolerance)."""
    _, kernels = _pair()
    h = 1e-6
    for q in _configurations(4, seed=13):
        for kernel_name, value, derivative in (("primitive", "X_c", "J_c"), ("similarity_jacobians", None,
                                                                              "J_A")):
            kernel = kernels[kernel_name]
            out = _outputs(kernel, q)
            columns = []
            for i in range(3):
                step = np.zeros(3)
                step[i] = h
                if value is None:
                    plus = _outputs(kernels["similarity"], q + step)["V_Sc"]
                    minus = _outputs(kernels["similarity"], q - step)["V_Sc"]
                else:
                    plus, minus = _outputs(kernel, q + step)[value], _outputs(kernel, q - step)[value]
                columns.append((plus - minus)[:, 0] / (2 * h))
            np.testing.assert_allclose(out[derivative], np.array(columns).T, rtol=1e-5, atol=1e-7)


def _variant(tmp_path: Path, old: str, new: str) -> Path:
    text = URDF.read_text()
    assert old in text
    path = tmp_path / "variant.urdf"
    path.write_text(text.replace(old, new))
    return path


def test_chained_mimics_are_resolved_to_the_first_leader(tmp_path):
    """finger_joint2 → finger_joint1 → joint2: q_f2 = 2 (−0.5 q_2 + 0.1) + 0.003 = −q_2 + 0.203."""
    path = _variant(tmp_path, 'type="prismatic">\n    <parent link="hand"/><child link="finger1"/>',
                    'type="prismatic">\n    <parent link="hand"/><child link="finger1"/>\n'
                    '    <mimic joint="joint2" multiplier="-0.5" offset="0.1"/>')
    text = path.read_text().replace('multiplier="1" offset="0.003"', 'multiplier="2" offset="0.003"')
    path.write_text(text)
    follower = load_chain(path, "base", "finger2")[-1]
    assert follower.mimic == ("joint2", -1.0, pytest.approx(0.203, abs=1e-15))
    assert Chain("f2", tuple(load_chain(path, "base", "finger2"))).dof == 2


@pytest.mark.parametrize(("old", "new", "message"), [
    ('<mimic joint="joint2" multiplier', '<mimic joint="jiont2" multiplier', "there is no joint 'jiont2'"),
    ('<mimic joint="joint2" multiplier', '<mimic joint="joint3" multiplier', "loop: joint3 -> joint3"),
    ('<mimic joint="joint2" multiplier', '<mimic joint="hand_joint" multiplier', "'hand_joint' is fixed"),
    ('multiplier="-0.5"', 'multiplier="nan"', "finite multiplier and offset"),
])
def test_bad_mimics_are_spec_errors_naming_file_and_joint(tmp_path, old, new, message):
    path = _variant(tmp_path, old, new)
    with pytest.raises(SpecError) as error:
        load_chain(path, "base", "link3")
    assert str(path) in str(error.value) and "joint joint3: mimic" in str(error.value)
    assert message in str(error.value)


def test_a_spec_over_a_mimic_urdf_loads_with_the_independent_joints(tmp_path):
    spec = tmp_path / "gripper.yaml"
    spec.write_text(f"name: gripper\nprimitive: point_pair\nchains:\n"
                    f"  - {{name: f1, urdf: {URDF}, base_link: base, tip_link: finger1, robot: g}}\n"
                    f"  - {{name: f2, urdf: {URDF}, base_link: base, tip_link: finger2, robot: g}}\n"
                    f"configurations:\n  ready: [0.1, 0.2, 0.01]\n")
    system, configurations = load_system(spec)
    assert system.dof == 3 and configurations["ready"] == [0.1, 0.2, 0.01]


def test_model_refuses_chained_and_fixed_leaders_and_keeps_plain_reprs():
    leader = Joint("a", "revolute")
    follower = Joint("b", "revolute", mimic=("a", 2.0, 0.0))
    assert "mimic" not in repr(leader) and "mimic=('a', 2.0, 0.0)" in repr(follower)
    assert repr(leader) == ("Joint(name='a', kind='revolute', xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0), "
                            "axis=(0.0, 0.0, 1.0))")
    with pytest.raises(ValueError, match="chained mimics"):
        Chain("c", (leader, follower, Joint("c", "revolute", mimic=("b", 1.0, 0.0))))
    with pytest.raises(ValueError, match="mimics the fixed joint"):
        Chain("c", (Joint("f", "fixed"), Joint("g", "revolute", mimic=("f", 1.0, 0.0))))
    with pytest.raises(ValueError, match="cannot mimic"):
        Joint("f", "fixed", mimic=("a", 1.0, 0.0))
    with pytest.raises(ValueError, match="finite"):
        Joint("g", "revolute", mimic=("a", float("inf"), 0.0))


def test_a_fixed_joint_s_mimic_is_ignored(tmp_path):
    """A welded joint that keeps its <mimic> (example-robot-data's talos_reduced.urdf) has no value to
    follow: the chain loads, the joint fixed, as Pinocchio and urdfdom read it."""
    path = tmp_path / "welded.urdf"
    path.write_text('<robot name="r"><link name="a"/><link name="b"/><link name="c"/>'
                    '<joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>'
                    '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
                    '<joint name="j2" type="fixed"><parent link="b"/><child link="c"/>'
                    '<origin xyz="0 0 0.1"/><mimic joint="j1" multiplier="-1"/></joint></robot>')
    joints = load_chain(path, "a", "c")
    assert [(j.name, j.kind, j.mimic) for j in joints] == [("j1", "revolute", None), ("j2", "fixed", None)]


def test_an_explicit_spec_joint_mimics_another(tmp_path):
    """``mimic: {joint, multiplier, offset}`` in a spec's explicit joints, as a URDF's <mimic>: one joint
    variable drives both; the end point equals that of the two-variable chain at (q, 2 q − 0.1)."""
    from gagen.model.kinematics import Joint, chain_kinematics, end_point
    from gagen.robots.spec import load_system

    def spec(mimic: str) -> Path:
        path = tmp_path / "fingers.yaml"
        path.write_text("name: fingers\nprimitive: point\nchains:\n  - name: finger\n    joints:\n"
                        "      - {name: j1, type: revolute, axis: [0, 0, 1], xyz: [0.1, 0, 0]}\n"
                        f"      - {{name: j2, type: revolute, axis: [0, 0, 1], xyz: [0.1, 0, 0]{mimic}}}\n"
                        "      - {name: tip, type: fixed, xyz: [0.05, 0, 0]}\n")
        return path

    system, _ = load_system(spec(", mimic: {joint: j1, multiplier: 2, offset: -0.1}"))
    assert system.dof == 1 and system.joint_keys == [("finger", "j1")]
    joints = system.chains[0].joints
    free = [joints[0], Joint("j2", "revolute", (0.1, 0.0, 0.0)), joints[2]]
    for q in (0.0, 0.4, -1.3):
        mimicked = end_point(chain_kinematics(LIKE, joints, [q])[0])
        reference = end_point(chain_kinematics(LIKE, free, [q, 2 * q - 0.1])[0])
        assert np.allclose(mimicked.coeffs, reference.coeffs, rtol=0, atol=1e-14)
    with pytest.raises(SpecError, match=r"chains\[0\]\.joints\[1\]\.mimic\.multiplier \(line 7\): got .x."):
        load_system(spec(", mimic: {joint: j1, multiplier: x}"))
    with pytest.raises(SpecError, match="a joint cannot mimic itself"):
        load_system(spec(", mimic: {joint: j2}"))
    with pytest.raises(SpecError, match=r"mimic\.joint \(line 7\): got 5; expected the leader"):
        load_system(spec(", mimic: {joint: 5}"))
