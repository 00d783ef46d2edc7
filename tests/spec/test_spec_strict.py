"""Strict specs (issue 12, deliverable 3): unknown and duplicate keys, the per-chain tool offset,
non-finite or huge numbers, bounded YAML (alias bombs, recursive anchors, deep nesting), non-UTF-8
files. Each case names the file, the field with its line and what was expected; each was accepted
silently (or raised something other than a SpecError, or hung) before."""

from __future__ import annotations

import itertools
import math
import time
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import deadline

from gagen.algebra.signature import cga3d
from gagen.errors import SpecError
from gagen.interp import MultiVector
from gagen.model.conformal import EUCLID, location, vector
from gagen.model.kinematics import end_point, forward_kinematics
from gagen.robots.spec import load_system

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
PANDA_URDF = ROBOTS / "panda" / "panda.urdf"
ARM = f"  - name: arm0\n    urdf: {PANDA_URDF}\n    base_link: panda_link0\n    tip_link: panda_link8\n"
FINGER = "  - name: f\n    joints:\n      - {name: j1, type: revolute, axis: [0, 0, 1]}\n"


def _write(tmp_path, text: str | bytes) -> Path:
    path = tmp_path / "spec.yaml"
    path.write_bytes(text.encode() if isinstance(text, str) else text)
    return path


def _error(tmp_path, text: str | bytes) -> SpecError:
    path = _write(tmp_path, text)
    with pytest.raises(SpecError) as e:
        load_system(path)
    assert e.value.file == str(path)
    return e.value


def _point(chain: str = ARM, extra: str = "") -> str:
    return f"name: t\nprimitive: point\nchains:\n{chain}{extra}"


# -- unknown keys, with the nearest valid one --------------------------------------------------------------

@pytest.mark.parametrize(("text", "field", "message"), [
    (_point(ARM + "    bse: {xyz: [1, 0, 0]}\n"), "chains[0].bse (line 8)",
     "unknown key 'bse'; did you mean 'base'?"),
    (_point(extra="units: mm\n"), "units (line 8)",
     "unknown key 'units'; expected one of app, name, primitive, chains, configurations"),
    (_point(extra="configuration:\n  ready: [0, 0, 0, 0, 0, 0, 0]\n"), "configuration (line 8)",
     "unknown key 'configuration'; did you mean 'configurations'?"),
    (_point(ARM + "    base: {xyz: [1, 0, 0], rpyy: [0, 0, 1]}\n"), "chains[0].base.rpyy (line 8)",
     "unknown key 'rpyy'; did you mean 'rpy'?"),
    (_point(ARM + "    tool: {xzy: [0, 0, 0.1]}\n"), "chains[0].tool.xzy (line 8)",
     "unknown key 'xzy'; did you mean 'xyz'?"),
    (_point("  - name: f\n    joints:\n      - {name: j1, type: revolute, axes: [0, 0, 1]}\n"),
     "chains[0].joints[0].axes (line 6)", "unknown key 'axes'; did you mean 'axis'?"),
    (_point(ARM + "    joints: []\n"), "chains[0].joints (line 8)",
     "either urdf (with base_link, tip_link) or joints"),
    (_point(FINGER + "    tip_link: x\n"), "chains[0].tip_link (line 7)", "only used with urdf"),
])
def test_unknown_and_misplaced_keys(tmp_path, text, field, message):
    e = _error(tmp_path, text)
    assert e.field == field and message in e.message


# -- duplicate keys -----------------------------------------------------------------------------------------

def test_duplicate_top_level_key(tmp_path):
    e = _error(tmp_path, _point(extra="name: u\n"))
    assert e.field == "name (line 8)" and "duplicate key 'name' (first at line 1)" in e.message


def test_duplicate_key_in_a_chain(tmp_path):
    e = _error(tmp_path, _point(ARM + "    tip_link: panda_link7\n"))
    assert e.field == "chains[0].tip_link (line 8)"
    assert "duplicate key 'tip_link' (first at line 7)" in e.message


def test_anchors_and_merge_keys_still_work(tmp_path):
    """Aliases are allowed (bounded): a shared placement written once, and a merge key."""
    text = ("name: t\nprimitive: point_pair\nchains:\n"
            f"  - &arm\n    name: arm0\n    urdf: {PANDA_URDF}\n    base_link: panda_link0\n"
            "    tip_link: panda_link8\n    base: &b {xyz: [1, 0, 0]}\n"
            "  - <<: *arm\n    name: arm1\n    base: *b\n")
    system, _ = load_system(_write(tmp_path, text))
    assert [c.name for c in system.chains] == ["arm0", "arm1"] and system.dof == 14
    bases = [c.joints[0] for c in system.chains]  # the same placement, named after each chain
    assert [(b.name, b.xyz) for b in bases] == [("arm0_base", (1.0, 0, 0)), ("arm1_base", (1.0, 0, 0))]


# -- the tool offset ----------------------------------------------------------------------------------------

def test_tool_offset_moves_the_end_point(tmp_path):
    """tool: {xyz, rpy} was ignored before. Now the end point is the tip frame's origin plus R_tip·xyz and
    the end frame is R_tip·R(rpy), checked against Pinocchio's panda_link8 placement."""
    xyz, rpy = np.array([0.01, -0.02, 0.1034]), (0.1, -0.2, 0.3)
    text = _point(ARM + f"    tool: {{xyz: {xyz.tolist()}, rpy: {list(rpy)}}}\n")
    system, _ = load_system(_write(tmp_path, text))
    joints = system.chains[0].joints
    assert joints[-1].name == "arm0_tool" and joints[-1].kind == "fixed" and system.dof == 7
    model = pin.buildModelFromUrdf(str(PANDA_URDF))
    data = model.createData()
    frame = model.getFrameId("panda_link8")
    zero = MultiVector.zero(cga3d())
    tool_rotation = pin.rpy.rpyToMatrix(*rpy)
    for q in np.random.default_rng(3).uniform(-2, 2, (5, 7)):
        pin.framesForwardKinematics(model, data, q)
        tip = data.oMf[frame]
        motor = forward_kinematics(zero, joints, list(q))
        np.testing.assert_allclose([location(end_point(motor))[k] for k in EUCLID],
                                   tip.translation + tip.rotation @ xyz, atol=1e-12)
        for i in range(3):  # the end frame: images of the basis vectors
            image = motor.sandwich(vector(zero, np.eye(3)[i]))
            np.testing.assert_allclose([image[k] for k in EUCLID], (tip.rotation @ tool_rotation)[:, i],
                                       atol=1e-12)


# -- numbers ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("chain", "field"), [
    (ARM + "    base: {xyz: [.nan, 0, 0]}\n", "chains[0].base.xyz (line 8)"),
    (ARM + "    base: {xyz: [0, 0, 2.0e6]}\n", "chains[0].base.xyz (line 8)"),
    (ARM + "    base: {rpy: [0, -.inf, 0]}\n", "chains[0].base.rpy (line 8)"),
    (ARM + "    base: {rpy: [0, 0, 1.0e4]}\n", "chains[0].base.rpy (line 8)"),
    (ARM + f"    base: {{xyz: [{10 ** 400}, 0, 0]}}\n", "chains[0].base.xyz (line 8)"),
    (ARM + "    tool: {xyz: [0, .inf, 0]}\n", "chains[0].tool.xyz (line 8)"),
    ("  - name: f\n    joints:\n      - {name: j1, type: revolute, axis: [0, 0, 1, 0]}\n",
     "chains[0].joints[0].axis (line 6)"),
    ("  - name: f\n    joints:\n      - {name: j1, type: revolute, axis: [0, .nan, 1]}\n",
     "chains[0].joints[0].axis (line 6)"),
    ("  - name: f\n    joints:\n      - {name: j1, type: revolute, axis: [0, 0, 1], xyz: [1.0e7, 0, 0]}\n",
     "chains[0].joints[0].xyz (line 6)"),
])
def test_non_finite_and_huge_numbers(tmp_path, chain, field):
    e = _error(tmp_path, _point(chain))
    assert e.field == field and "expected a list of three finite numbers within" in e.message


def test_tiny_axis(tmp_path):
    chain = "  - name: f\n    joints:\n      - {name: j1, type: revolute, axis: [0, 0, 1.0e-300]}\n"
    e = _error(tmp_path, _point(chain))
    assert e.field == "chains[0].joints[0].axis (line 6)" and "zero vector" in e.message


@pytest.mark.parametrize(("value", "shown"), [(".nan", "nan"), ("-.inf", "-inf"), (str(10 ** 400), "1000000"),
                                              ("'1'", "'1'")])
def test_non_finite_configuration(tmp_path, value, shown):
    e = _error(tmp_path, _point(extra=f"configurations:\n  ready: [0, 0, {value}, 0, 0, 0, 0]\n"))
    assert e.field == "configurations.ready[2] (line 9)"
    assert f"got {shown}" in e.message and "for joint arm0/panda_joint3" in e.message


@pytest.mark.parametrize("value", ["[0, 0, 0, 0, 0, 0, 0]", "ready", "''"])
def test_configurations_must_be_a_mapping(tmp_path, value):
    e = _error(tmp_path, _point(extra=f"configurations: {value}\n"))
    assert e.field == "configurations (line 8)" and "expected a mapping of names to lists of 7" in e.message


def test_duplicate_explicit_joint_names(tmp_path):
    e = _error(tmp_path, _point(FINGER + "      - {name: j1, type: prismatic, axis: [1, 0, 0]}\n"))
    assert e.field == "chains[0].joints[1].name (line 7)" and "the name of joints[0] too" in e.message


# -- bounded YAML, encodings --------------------------------------------------------------------------------



def _laughs() -> str:
    """The YAML billion laughs: 9 levels of 9 aliases, 9^9 strings."""
    keys = "abcdefghi"
    lines = ["a: &a [lol,lol,lol,lol,lol,lol,lol,lol,lol]"]
    lines += [f"{k}: &{k} [{','.join([f'*{p}'] * 9)}]" for p, k in itertools.pairwise(keys)]
    return "\n".join(lines) + "\n"


@pytest.mark.realtime
def test_billion_laughs_is_refused_at_once(tmp_path):
    """9^9 strings from a few hundred bytes: the old line-number walk took minutes."""
    text = _laughs()
    assert len(text) < 330
    start = time.perf_counter()
    with deadline(5):  # the old loader ran for minutes: fail, do not hang
        e = _error(tmp_path, text)
    assert time.perf_counter() - start < 0.5
    assert e.field == "spec" and "expands (through its aliases) to more than 100000 nodes" in e.message


def test_recursive_anchor(tmp_path):
    e = _error(tmp_path, _point(extra="configurations: &c {ready: *c}\n"))
    assert e.field == "spec" and "line 8: a recursive anchor" in e.message


def test_deep_nesting(tmp_path):
    e = _error(tmp_path, "x: " + "[" * 5000 + "]" * 5000 + "\n")
    assert e.field == "spec" and "nested too deeply" in e.message


@pytest.mark.parametrize(("text", "message"), [
    (b"name: t\xe9\nprimitive: point\n", "not UTF-8 text: byte 0xe9 at offset 7"),
    (b"name: t\nprimitive: point\nwhen: 2001-02-30\n", "not valid YAML: ValueError: day is out of range"),
    (b"name: !!python/object:os.system x\n", "not valid YAML at line 1"),
])
def test_unreadable_text(tmp_path, text, message):
    e = _error(tmp_path, text)
    assert e.field == "spec" and message in e.message


def test_every_number_bound_leaves_the_bundled_specs_alone():
    """Every bundled spec loads; its numbers are far inside the bounds."""
    for spec in ROBOTS.glob("*.yaml"):
        system, _ = load_system(spec)
        values = [v for c in system.chains for j in c.joints for v in (*j.xyz, *j.rpy, *j.axis)]
        assert all(math.isfinite(v) and abs(v) < 10 for v in values), spec
