"""Hexapod leg kinematics held against independent references: the PGA and CGA formulas of
``gagen.apps.hexapod.legs`` agree with each other, with a 4×4 matrix chain (tests/hexapod/matrix_chain.py)
and with Pinocchio on the URDF written from the same spec, at 50 random configurations per leg (1e-12);
J against central differences; the compiled kernels against the interpreter. Also the URDF writer."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gagen.algebra.kinds import kind_blades
from gagen.apps.hexapod.legs import leg_kinematics
from gagen.apps.hexapod.spec import Hexapod, Leg, load_hexapod
from gagen.apps.hexapod.urdf import write_urdf
from gagen.interp import MultiVector, preset
from gagen.model.euclidean import GEOMETRIES

from . import matrix_chain as mc
from .conftest import SPEC

URDF = SPEC.with_suffix(".urdf")
ALGEBRAS = ("pga3d", "cga3d")
CONFIGURATIONS = 50
TOL = 1e-12
HEXAPOD = load_hexapod(SPEC)


def zero(algebra: str) -> MultiVector:
    return MultiVector.zero(preset(algebra))


def interpreted(algebra: str, leg: Leg, q) -> dict:
    return leg_kinematics(GEOMETRIES[algebra], zero(algebra), leg, [float(v) for v in q])


def coefficients(x: MultiVector, kind: str) -> np.ndarray:
    return np.array([x[b] for b in kind_blades(x.algebra, kind)])


@pytest.fixture(scope="module")
def configurations() -> dict[str, np.ndarray]:
    """50 configurations per leg within its limits (fixed seed)."""
    rng = np.random.default_rng(14)
    return {leg.name: mc.random_configurations(leg, rng, CONFIGURATIONS) for leg in HEXAPOD.legs}


@pytest.fixture(scope="module")
def reference(configurations) -> dict[tuple[str, str], list[dict]]:
    """The interpreter's kinematics at those configurations, per (algebra, leg): computed once."""
    return {(a, leg.name): [interpreted(a, leg, q) for q in configurations[leg.name]]
            for a in ALGEBRAS for leg in HEXAPOD.legs}


# -- the URDF --------------------------------------------------------------------------------------------

def test_committed_urdf_is_written_from_the_spec():
    assert URDF.read_text() == write_urdf(load_hexapod(SPEC)), \
        "regenerate gagen/apps/hexapod/robots/hexapod.urdf with write_urdf"


def test_urdf_carries_the_spec_numbers_exactly():
    text = write_urdf(HEXAPOD)
    assert text == write_urdf(load_hexapod(SPEC))  # deterministic
    root = ET.fromstring(text)
    joints = {j.get("name"): j for j in root.iter("joint")}
    links = {link.get("name") for link in root.iter("link")}
    assert links == {"base_link"} | {f"{leg.name}_{p}" for leg in HEXAPOD.legs
                                     for p in ("coxa", "femur", "tibia", "foot")}
    assert len(joints) == 4 * len(HEXAPOD.legs)

    def floats(element, attribute):
        return tuple(float(v) for v in element.get(attribute).split())

    for leg in HEXAPOD.legs:
        l1, l2, l3 = leg.lengths
        chain = [("yaw", "base_link", "coxa", leg.xyz, leg.rpy),
                 ("thigh", "coxa", "femur", (l1, 0, 0), (0, 0, 0)),
                 ("knee", "femur", "tibia", (l2, 0, 0), (0, 0, 0)),
                 ("toe", "tibia", "foot", (l3, 0, 0), (0, 0, 0))]
        for j, (name, parent, child, xyz, rpy) in enumerate(chain):
            joint = joints[f"{leg.name}_{name}"]
            parent = parent if parent == "base_link" else f"{leg.name}_{parent}"
            assert joint.find("parent").get("link") == parent
            assert joint.find("child").get("link") == f"{leg.name}_{child}"
            assert floats(joint.find("origin"), "xyz") == tuple(xyz)  # repr precision: exact doubles
            assert floats(joint.find("origin"), "rpy") == tuple(rpy)
            if name == "toe":
                assert joint.get("type") == "fixed"
                continue
            assert joint.get("type") == "revolute"
            assert floats(joint.find("axis"), "xyz") == leg.axes[j]
            limit = joint.find("limit")
            assert (float(limit.get("lower")), float(limit.get("upper"))) == leg.limits[j]
            assert float(limit.get("effort")) > 0 and float(limit.get("velocity")) > 0
    for link in root.iter("link"):  # loadable by dynamics tools and viewers; the toe frames massless
        foot = link.get("name").endswith("_foot")
        assert (link.find("inertial") is None) if foot else float(link.find("inertial/mass").get("value")) > 0
        assert link.find("visual/geometry") is not None


def test_urdf_inertials_are_the_mass_models_in_pinocchio():
    """Pinocchio's total mass, centre of mass and composite inertia of the URDF at random joint angles
    against the mass model (gagen.apps.hexapod.mass: its own matrix chain; the inertia from its box and
    rod formulas summed here with the parallel-axis theorem)."""
    pin = pytest.importorskip("pinocchio")
    from gagen.apps.hexapod.mass import (
        box_inertia,
        centre_of_mass,
        default_mass_model,
        link_centres,
        rod_inertia,
        total_mass,
    )

    mass = default_mass_model(HEXAPOD)
    # a free-flyer root, so the body is a body of the model (a fixed base's goes to the universe)
    model = pin.buildModelFromXML(write_urdf(HEXAPOD, mass), pin.JointModelFreeFlyer())
    data = model.createData()
    order = [model.joints[model.getJointId(name)].idx_q for name in HEXAPOD.joint_names]
    assert pin.computeTotalMass(model) == pytest.approx(total_mass(mass), abs=1e-14)
    rng = np.random.default_rng(11)
    for _ in range(10):
        q = rng.uniform(-1.0, 1.0, HEXAPOD.dof)
        q_pin = pin.neutral(model)  # the body at the origin
        q_pin[order] = q
        com = pin.centerOfMass(model, data, q_pin)
        np.testing.assert_allclose(com, centre_of_mass(HEXAPOD, mass, np.eye(4), q), rtol=0, atol=1e-15)
        # the whole robot's rotational inertia about its CoM: CRBA's composite inertia of the subtree of
        # the free flyer (the body at the origin: its frame is the world's)
        pin.crba(model, data, q_pin)
        np.testing.assert_allclose(data.Ycrb[1].lever, com, rtol=0, atol=1e-15)
        inertia = data.Ycrb[1].inertia
        expected = np.diag(box_inertia(mass.body_mass, mass.body_size)).astype(float)
        expected -= mass.body_mass * _skew2(np.array(mass.body_centre) - com)
        centres = link_centres(HEXAPOD, q)
        frames = _link_frames(q)
        for leg, (leg_masses, leg_centres) in enumerate(zip(mass.link_masses, centres, strict=True)):
            for j, (m, c) in enumerate(zip(leg_masses, leg_centres, strict=True)):
                rotation = frames[leg][j]
                local = np.diag(rod_inertia(m, HEXAPOD.legs[leg].lengths[j], mass.link_radius))
                expected += rotation @ local @ rotation.T - m * _skew2(c - com)
        np.testing.assert_allclose(inertia, expected, rtol=0, atol=1e-14)


def _skew2(v):
    """[v]×² (so −m [r]×² is a point mass's inertia about the origin)."""
    x, y, z = v
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return k @ k


def _link_frames(q):
    """Each leg's coxa, femur and tibia rotations (body frame): the mount's rpy, then the joint turns."""
    from scipy.spatial.transform import Rotation

    frames = []
    for leg, angles in zip(HEXAPOD.legs, np.reshape(q, (-1, 3)), strict=True):
        rotation = Rotation.from_euler("xyz", leg.rpy).as_matrix()
        links = []
        for axis, angle in zip(leg.axes, angles, strict=True):
            rotation = rotation @ Rotation.from_rotvec(angle * np.asarray(axis, float)).as_matrix()
            links.append(rotation)
        frames.append(links)
    return frames


def test_urdf_escapes_names():
    odd = 'a"b<c>&d\'e'
    legs = tuple(replace(leg, name=f"{odd}{i}") for i, leg in enumerate(HEXAPOD.legs))
    text = write_urdf(Hexapod(odd, legs))
    root = ET.fromstring(text)  # well-formed
    assert root.get("name") == odd
    assert {j.get("name") for j in root.iter("joint")} >= {f"{odd}0_yaw", f"{odd}5_toe"}


# -- formulas against references -------------------------------------------------------------------------

@pytest.fixture(scope="module")
def pinocchio_model():
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromXML(URDF.read_text())
    return pin, model


def pinocchio_kinematics(pin, model, configurations) -> dict[str, tuple[np.ndarray, ...]]:
    """Per leg: Pinocchio's toe positions (n, 3), frame Jacobians J (n, 3, 3) and the knee joint's
    spatial Jacobians S (n, 6, 3), its q order mapped to the spec's by joint names."""
    data = model.createData()
    out: dict[str, tuple[list, list, list]] = {leg.name: ([], [], []) for leg in HEXAPOD.legs}
    for k in range(CONFIGURATIONS):
        q = np.zeros(model.nq)
        for leg in HEXAPOD.legs:
            for name, value in zip(leg.joint_names, configurations[leg.name][k], strict=True):
                q[model.joints[model.getJointId(name)].idx_q] = value
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        pin.computeJointJacobians(model, data, q)
        for leg in HEXAPOD.legs:
            ids = [model.getJointId(name) for name in leg.joint_names]
            columns = [model.joints[i].idx_v for i in ids]
            frame = model.getFrameId(f"{leg.name}_foot")
            p, J, S = out[leg.name]
            p.append(data.oMf[frame].translation.copy())
            J.append(pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)[:3, columns])
            S.append(pin.getJointJacobian(model, data, ids[2], pin.WORLD)[:, columns])
    return {name: tuple(np.array(x) for x in values) for name, values in out.items()}


def test_pga_cga_matrix_chain_and_pinocchio_agree(configurations, reference, pinocchio_model):
    pin, model = pinocchio_model
    expected = pinocchio_kinematics(pin, model, configurations)
    worst = {}
    for leg in HEXAPOD.legs:
        Q = configurations[leg.name]
        candidates = {"matrix chain": (mc.toe(leg, Q), *mc.jacobians(leg, Q))}
        for algebra in ALGEBRAS:
            kins = reference[algebra, leg.name]
            candidates[algebra] = tuple(np.array([np.array(kin[key]).T for kin in kins])
                                        for key in ("p", "J", "S"))
        for source, got in candidates.items():
            for what, g, want in zip("pJS", got, expected[leg.name], strict=True):
                worst[source] = max(worst.get(source, 0.0), np.abs(g - want).max())
                np.testing.assert_allclose(g, want, rtol=0, atol=TOL, err_msg=f"{source} {what} {leg.name}")
        for g_pga, g_cga in zip(candidates["pga3d"], candidates["cga3d"], strict=True):
            np.testing.assert_allclose(g_pga, g_cga, rtol=0, atol=TOL)
    print("largest deviations from Pinocchio:", {k: f"{v:.1e}" for k, v in worst.items()})


def apply_motor(algebra: str, motor: MultiVector, points: np.ndarray) -> np.ndarray:
    geo = GEOMETRIES[algebra]
    return np.array([geo.location(motor.sandwich(geo.point(motor, list(x)))) for x in points])


@settings(max_examples=15, deadline=None, derandomize=True)
@given(leg_index=st.integers(0, 5), fractions=st.tuples(*[st.floats(0, 1)] * 3),
       seed=st.integers(0, 2 ** 32 - 1))
def test_fk_motor_moves_points_like_the_matrix_chain(leg_index, fractions, seed):
    """The toe motor M of both algebras applied to points (M X M~) is the matrix chain's toe transform."""
    leg = HEXAPOD.legs[leg_index]
    q = np.array([[lo + f * (hi - lo) for f, (lo, hi) in zip(fractions, leg.limits, strict=True)]])
    points = np.random.default_rng(seed).normal(scale=0.3, size=(3, 3))
    transform = mc.toe_transform(leg, q)[0]
    want = points @ transform[:3, :3].T + transform[:3, 3]
    for algebra in ALGEBRAS:
        motor = interpreted(algebra, leg, q[0])["motor"]
        moved = apply_motor(algebra, motor, points)
        np.testing.assert_allclose(moved, want, rtol=0, atol=TOL, err_msg=algebra)


STEP = 1e-6


def central_differences(p_of_q, q: np.ndarray) -> np.ndarray:
    """(3, 3): column j = (p(q + h e_j) − p(q − h e_j)) / 2h."""
    columns = []
    for j in range(3):
        e = np.zeros(3)
        e[j] = STEP
        columns.append((np.asarray(p_of_q(q + e)) - np.asarray(p_of_q(q - e))) / (2 * STEP))
    return np.stack(columns, axis=1)


def test_jacobian_against_central_differences(configurations, reference):
    for leg in HEXAPOD.legs:
        for k in range(2):  # the compiled test below covers all 50
            q = configurations[leg.name][k]
            for algebra in ALGEBRAS:
                fd = central_differences(lambda x, a=algebra, g=leg: interpreted(a, g, x)["p"], q)
                J = np.array(reference[algebra, leg.name][k]["J"]).T
                np.testing.assert_allclose(J, fd, rtol=0, atol=1e-8, err_msg=f"{algebra} {leg.name}")


# -- compiled kernels against the interpreter ----------------------------------------------------------

@pytest.mark.compiling
def test_compiled_leg_kernels_match_the_interpreter(hexapod_module, configurations, reference):
    for leg in HEXAPOD.legs:
        Q = configurations[leg.name]
        for algebra, suffix in zip(ALGEBRAS, ("pga", "cga"), strict=True):
            kernel = getattr(hexapod_module.c, f"{leg.name}_fk_{suffix}")
            M, toe, p, J, S = kernel.batch(Q)
            for k, kin in enumerate(reference[algebra, leg.name]):
                np.testing.assert_allclose(M[k], coefficients(kin["motor"], "motor"), rtol=0, atol=TOL)
                np.testing.assert_allclose(toe[k], coefficients(kin["toe"], "point"), rtol=0, atol=TOL)
                np.testing.assert_allclose(p[k], kin["p"], rtol=0, atol=TOL)
                np.testing.assert_allclose(J[k], np.array(kin["J"]).T, rtol=0, atol=TOL)
                np.testing.assert_allclose(S[k], np.array(kin["S"]).T, rtol=0, atol=TOL)
            for k, q in enumerate(Q):  # J against central differences of the compiled p
                fd = central_differences(lambda x, f=kernel: f(x)[2], q)
                np.testing.assert_allclose(J[k], fd, rtol=0, atol=1e-8, err_msg=f"{suffix} {leg.name}")


@pytest.mark.compiling
def test_compiled_body_fk_matches_the_interpreter(hexapod_module, configurations, reference):
    Q = np.concatenate([configurations[leg.name] for leg in HEXAPOD.legs], axis=1)  # (50, 18)
    for algebra, suffix in zip(ALGEBRAS, ("pga", "cga"), strict=True):
        p, J = getattr(hexapod_module.c, f"body_fk_{suffix}").batch(Q)
        assert p.shape == (CONFIGURATIONS, 18) and J.shape == (CONFIGURATIONS, 18, 18)
        for k in range(CONFIGURATIONS):
            for i, leg in enumerate(HEXAPOD.legs):
                kin = reference[algebra, leg.name][k]
                block = slice(3 * i, 3 * i + 3)
                np.testing.assert_allclose(p[k, block], kin["p"], rtol=0, atol=TOL)
                np.testing.assert_allclose(J[k, block, block], np.array(kin["J"]).T, rtol=0, atol=TOL)
                off = J[k, block].copy()
                off[:, block] = 0.0
                assert not off.any(), f"{suffix}: leg {leg.name}'s rows reach into other legs' joints"
