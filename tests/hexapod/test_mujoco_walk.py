"""The hexapod in MuJoCo (gagen.apps.hexapod.mujoco_walk): the MJCF's joints and toes against the
generated FK and an independent matrix chain, the mass model's CoM against MuJoCo's subtree_com, the
support margin against closed forms, and the simulated tripod walk on flat ground and a 10° slope
(drift, yaw, slip and margin within their stated bounds; the report's drift recomputed from MuJoCo's
qpos)."""

from __future__ import annotations

import math

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from gagen.apps.hexapod import gait  # noqa: E402
from gagen.apps.hexapod import mujoco_walk as mw  # noqa: E402
from gagen.apps.hexapod.mass import centre_of_mass, default_mass_model, total_mass  # noqa: E402

from . import matrix_chain  # noqa: E402

SLIP_BOUND = 0.005  # m: a stance toe moves less than this along the ground while in contact


def _random_state(hexapod, rng):
    q = np.concatenate([matrix_chain.random_configurations(leg, rng, 1)[0] for leg in hexapod.legs])
    pose = np.eye(4)
    pose[:3, :3] = matrix_chain.rotation(rng.normal(size=3), np.array([rng.uniform(-math.pi, math.pi)]))[0]
    pose[:3, 3] = rng.uniform(-1, 1, size=3)
    return q, pose


def _place(model, data, hexapod, q, pose):
    data.qpos[:3] = pose[:3, 3]
    data.qpos[3:7] = gait.quaternion(pose[:3, :3])[0]
    data.qpos[mw.joint_qpos(model, hexapod)] = q
    mujoco.mj_forward(model, data)


def test_joints_and_toes_match_the_spec(hexapod, hexapod_module):
    """At random q and body poses: MuJoCo's toe sites against the generated FK (body_fk_pga) carried by
    the pose, and its joint axes and anchors against the 4×4 matrix chain, to 1e-9."""
    model = mw.load_model(hexapod, ground=gait.Ground(math.radians(10)))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    for _ in range(20):
        q, pose = _random_state(hexapod, rng)
        _place(model, data, hexapod, q, pose)
        toes = hexapod_module.c.body_fk_pga(q)[0].reshape(6, 3) @ pose[:3, :3].T + pose[:3, 3]
        sites = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{leg.name}_toe")
                 for leg in hexapod.legs]
        np.testing.assert_allclose(data.site_xpos[sites], toes, rtol=0, atol=1e-9)
        for i, leg in enumerate(hexapod.legs):
            frames, _ = matrix_chain.frames(leg, q[3 * i:3 * i + 3])
            for j, frame in enumerate(frames):
                jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, leg.joint_names[j])
                axis = pose[:3, :3] @ frame[0, :3, :3] @ np.array(leg.axes[j])
                anchor = pose[:3, :3] @ frame[0, :3, 3] + pose[:3, 3]
                np.testing.assert_allclose(data.xaxis[jid], axis, rtol=0, atol=1e-9)
                np.testing.assert_allclose(data.xanchor[jid], anchor, rtol=0, atol=1e-9)


def test_centre_of_mass_matches_mujoco(hexapod):
    """The mass model's CoM and total mass against MuJoCo's subtree_com and subtree mass of the base."""
    mass = default_mass_model(hexapod)
    model = mw.load_model(hexapod, mass)
    data = mujoco.MjData(model)
    base = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "base")
    assert model.body_subtreemass[base] == pytest.approx(total_mass(mass), abs=1e-12)
    rng = np.random.default_rng(4)
    for _ in range(20):
        q, pose = _random_state(hexapod, rng)
        _place(model, data, hexapod, q, pose)
        np.testing.assert_allclose(centre_of_mass(hexapod, mass, pose, q), data.subtree_com[base],
                                   rtol=0, atol=1e-9)


def test_a_stance_without_area_has_no_static_support():
    """Two feet in contact (or three in a line) span no support polygon: the margin is −inf, so the
    walk's minimum margin is negative and ``gagen walk-sim`` fails, rather than a number or a NaN."""
    down = np.array([0.0, 0.0, -9.81])
    com = np.array([0.0, 0.0, 0.3])
    assert mw._margin(np.array([[0.2, 0.1, 0], [-0.2, 0.1, 0]]), com, down) == -math.inf
    assert mw._margin(np.array([[0.2, 0, 0], [0.0, 0, 0], [-0.2, 0, 0]]), com, down) == -math.inf
    square = np.array([[0.2, 0.2, 0], [-0.2, 0.2, 0], [-0.2, -0.2, 0], [0.2, -0.2, 0]])
    assert mw._margin(square, com, down) == pytest.approx(0.2, abs=1e-15)


@pytest.fixture(scope="module", params=[0.0, 10.0], ids=["flat", "slope10"])
def walked(request, hexapod, hexapod_module):
    plan, model, record, report = mw.run(hexapod, hexapod_module, gait.Ground(math.radians(request.param)))
    return plan, model, record, report


def test_walk_stays_within_its_bounds(walked):
    """Drift and yaw below the stated bounds, slip below SLIP_BOUND, the margin positive throughout and
    within 2 cm of the plan's wherever the feet in contact are the plan's stance feet."""
    plan, _, record, report = walked
    assert report.drift_max < mw.DRIFT_BOUND
    assert report.yaw_max < mw.YAW_BOUND
    assert report.slip_max < SLIP_BOUND
    assert report.margin_min > 0.05 and report.ok
    j = np.round(record.t * plan.params.rate).astype(int)
    same = (report.contact == plan.stance[j]).all(axis=1)
    assert same.mean() > 0.8
    assert np.abs(report.margin - report.planned_margin)[same].max() < 0.02
    assert report.cone_max <= mw.FRICTION * (1 + 1e-6) and report.cone_inside > 0.95


def test_report_drift_from_mujoco_qpos(walked, hexapod):
    """The report's position and yaw error recomputed from the recorded qpos (the free joint's position
    and quaternion through mju_quat2Mat) against the plan's own samples at the same times."""
    plan, _, record, report = walked
    j = np.round(record.t * plan.params.rate).astype(int)
    on_sample = np.abs(j / plan.params.rate - record.t) < 1e-12
    assert on_sample.sum() > 300
    for k in np.flatnonzero(on_sample):
        position, quat = record.qpos[k, :3], record.qpos[k, 3:7]
        rotation = np.zeros(9)
        mujoco.mju_quat2Mat(rotation, quat)
        relative = plan.body.rotation[j[k]].T @ rotation.reshape(3, 3)
        assert report.position_error[k] == pytest.approx(
            np.linalg.norm(position - plan.body.position[j[k]]), abs=1e-12)
        assert report.yaw_error[k] == pytest.approx(math.atan2(relative[1, 0], relative[0, 0]), abs=1e-12)


@pytest.mark.compiling
def test_the_balanced_lean_keeps_the_margin_in_mujoco(hexapod, hexapod_module, tmp_path, capsys):
    """A straight walk on a 15° slope rising across the path: leaning by ``balanced_lean`` raises the
    simulated minimum margin by more than 15 mm (plan: 108 → 127 mm), the simulation within 2 mm of the
    plan both ways; ``gagen walk-sim --lean auto`` plans and plays the same walk."""
    from dataclasses import replace

    from gagen.apps.hexapod import gait_statics
    from gagen.cli import main

    ground = gait.Ground(math.radians(15.0), math.radians(90.0))
    params = gait.GaitParameters(straight=0.4, turn=0.0)
    lean = gait_statics.balanced_lean(hexapod_module, hexapod, params, ground)
    margins = []
    for p in (params, replace(params, lean=lean)):
        _, _, _, report = mw.run(hexapod, hexapod_module, ground, p)
        assert abs(report.margin_min - report.planned_margin.min()) < 0.002 and report.ok
        margins.append(report.margin_min)
    assert margins[1] > margins[0] + 0.015
    argv = ["walk-sim", "--module", str(hexapod_module.folder), "--slope", "15", "--uphill", "90", "--lean",
            "auto", "--straight", "0.4", "--turn", "0", "--out", str(tmp_path), "--no-animation"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert f"the body leans {lean:.4f} m uphill" in out
    line = next(x for x in out.splitlines() if "stability margin, min" in x)
    assert abs(float(line.split()[3]) - margins[1] * 1e3) < 0.05  # "stability margin, min  127.5 mm ..."


def test_mjcf_escapes_names(hexapod):
    """A Hexapod built in code (the spec loader takes identifiers only) with names that would break
    the XML: the MJCF stays well-formed and MuJoCo finds every leg's joints and toe under its name."""
    import xml.etree.ElementTree as ET
    from dataclasses import replace

    mujoco = pytest.importorskip("mujoco")
    odd = 'a"b<c>&d\'e'
    robot = replace(hexapod, legs=tuple(replace(leg, name=f"{odd}{i}") for i, leg in enumerate(hexapod.legs)))
    text = mw.mjcf(robot)
    ET.fromstring(text)
    model = mujoco.MjModel.from_xml_string(text)
    for leg in robot.legs:
        assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{leg.name}_toe") >= 0
        for joint in leg.joint_names:
            assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint) >= 0
