"""Malformed robot specs: each raises a SpecError naming the file, the field (with its line) and
what was expected; a valid spec loads into the system it describes."""

from __future__ import annotations

from pathlib import Path

import pytest

from gagen.errors import SpecError
from gagen.robots.spec import load_system

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
PANDA_URDF = ROBOTS / "panda" / "panda.urdf"

CHAIN = """  - name: arm{i}
    urdf: {urdf}
    base_link: panda_link0
    tip_link: {tip}
"""


def _write(tmp_path, text: str) -> Path:
    path = tmp_path / "spec.yaml"
    path.write_text(text)
    return path


def _spec(primitive="point_pair", chains=2, tip="panda_link8", extra=""):
    body = "".join(CHAIN.format(i=i, urdf=PANDA_URDF, tip=tip) for i in range(chains))
    return f"name: test\nprimitive: {primitive}\nchains:\n{body}{extra}"


def _error(tmp_path, text: str) -> SpecError:
    path = _write(tmp_path, text)
    with pytest.raises(SpecError) as e:
        load_system(path)
    assert e.value.file == str(path)
    return e.value


def test_valid_spec_loads(tmp_path):
    system, configs = load_system(_write(tmp_path, _spec(extra="configurations:\n  zero: [" +
                                                          ", ".join(["0"] * 14) + "]\n")))
    assert system.kind == "point_pair" and system.dof == 14 and configs["zero"] == [0.0] * 14


def test_missing_file(tmp_path):
    with pytest.raises(SpecError) as e:
        load_system(tmp_path / "absent.yaml")
    assert e.value.field == "spec" and "not found" in e.value.message


def test_bad_yaml_names_the_position(tmp_path):
    e = _error(tmp_path, "name: x\nprimitive: [circle\nchains: []\n")
    assert e.field == "spec" and "not valid YAML at line" in e.message


def test_unknown_link(tmp_path):
    e = _error(tmp_path, _spec(tip="panda_hand"))
    assert e.field == "chains[0].tip_link (line 7)" and "'panda_hand'" in e.message


def test_circle_given_two_chains(tmp_path):
    e = _error(tmp_path, _spec(primitive="circle", chains=2))
    assert e.field == "chains (line 3)" and "spanned by 3 chains" in e.message and "got 2" in e.message


def test_unknown_primitive(tmp_path):
    e = _error(tmp_path, _spec(primitive="torus"))
    assert e.field == "primitive (line 2)" and "circle" in e.message


def test_joint_without_axis(tmp_path):
    text = ("name: t\nprimitive: point\nchains:\n  - name: finger\n    joints:\n"
            "      - {name: j1, type: revolute, xyz: [0, 0, 0.1]}\n")
    e = _error(tmp_path, text)
    assert e.field == "chains[0].joints[0].axis" and "needs its axis" in e.message


def test_unknown_joint_type(tmp_path):
    text = ("name: t\nprimitive: point\nchains:\n  - name: finger\n    joints:\n"
            "      - {name: j1, type: spherical, axis: [0, 0, 1]}\n")
    e = _error(tmp_path, text)
    assert e.field == "chains[0].joints[0].type (line 6)" and "revolute" in e.message


def test_bad_vector(tmp_path):
    text = ("name: t\nprimitive: point\nchains:\n  - name: finger\n    joints:\n"
            "      - {name: j1, type: revolute, axis: [0, 1]}\n")
    e = _error(tmp_path, text)
    assert e.field == "chains[0].joints[0].axis (line 6)" and "three finite numbers" in e.message


def test_configuration_of_wrong_length(tmp_path):
    e = _error(tmp_path, _spec(extra="configurations:\n  ready: [0, 0]\n"))
    assert e.field.startswith("configurations.ready") and "14 numbers" in e.message


def test_missing_urdf_file(tmp_path):
    e = _error(tmp_path, _spec().replace(str(PANDA_URDF), "nowhere.urdf", 1))
    assert e.field == "chains[0].urdf (line 5)" and "file not found" in e.message


@pytest.mark.parametrize("name", sorted(p.stem for p in ROBOTS.glob("*.yaml")))
def test_every_bundled_spec_loads_with_a_ready_configuration(name):
    system, configs = load_system(ROBOTS / f"{name}.yaml")
    assert system.name == name and len(configs["ready"]) == system.dof


def _robot_chain(i, robot, base="", tip="panda_link8"):
    return (f"  - name: arm{i}\n    robot: {robot}\n    urdf: {PANDA_URDF}\n    base_link: panda_link0\n"
            f"    tip_link: {tip}\n" + (f"    base: {base}\n" if base else ""))


def test_chains_of_one_robot_share_same_named_joints(tmp_path):
    """Two chains of one Panda, to link8 and link6: joints 1-6 appear once in q (7 DOF, not 13)."""
    text = ("name: t\nprimitive: point_pair\nchains:\n" + _robot_chain(0, "p") +
            _robot_chain(1, "p", tip="panda_link6"))
    system, _ = load_system(_write(tmp_path, text))
    assert system.dof == 7
    assert system.chain_indices() == [list(range(7)), list(range(6))]


def test_chains_of_one_robot_with_different_bases(tmp_path):
    text = ("name: t\nprimitive: point_pair\nchains:\n" + _robot_chain(0, "p", "{xyz: [0, 0, 0]}") +
            _robot_chain(1, "p", "{xyz: [1, 0, 0]}"))
    e = _error(tmp_path, text)
    assert e.field.startswith("chains[1].base") and "share one base placement" in e.message


def test_duplicate_chain_names(tmp_path):
    chain = CHAIN.format(i=0, urdf=PANDA_URDF, tip="panda_link8")
    text = "name: t\nprimitive: point_pair\nchains:\n" + chain * 2
    e = _error(tmp_path, text)
    assert e.field.startswith("chains[1].name") and "twice" in e.message


@pytest.mark.parametrize(("text", "line", "column"), [("name: x\x00y\nprimitive: point\n", 1, 8),
                                                       ("name: x\nprimitive: po\x07int\n", 2, 14)])
def test_a_control_character_is_one_line_with_its_position(tmp_path, text, line, column):
    """PyYAML's message for a NUL or another control byte is two lines without a line number (issue 29)."""
    e = _error(tmp_path, text)
    assert "\n" not in str(e) and e.field == "spec", str(e)
    assert f"at line {line}, column {column}" in e.message and "control character" in e.message, e.message
