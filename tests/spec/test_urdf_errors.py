"""Malformed URDF input: each error names the file, the field and what was expected."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import deadline

from gagen.errors import SpecError
from gagen.robots.urdf import load_chain

PANDA = Path(__file__).resolve().parents[2] / "robots" / "panda" / "panda.urdf"


def test_missing_file(tmp_path):
    missing = tmp_path / "nope.urdf"
    with pytest.raises(SpecError) as e:
        load_chain(missing, "a", "b")
    assert e.value.file == str(missing) and e.value.field == "urdf" and "not found" in e.value.message


def test_unreadable_xml(tmp_path):
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot")
    with pytest.raises(SpecError) as e:
        load_chain(bad, "a", "a")
    assert e.value.field == "urdf" and "not a readable URDF" in e.value.message


@pytest.mark.parametrize("field", ["base_link", "tip_link"])
def test_unknown_link_lists_the_known_ones(field):
    links = {"base_link": "panda_link0", "tip_link": "panda_link8"}
    links[field] = "panda_hand"
    with pytest.raises(SpecError) as e:
        load_chain(PANDA, links["base_link"], links["tip_link"])
    assert e.value.field == field and "'panda_hand'" in e.value.message and "panda_link3" in e.value.message


def test_a_chain_up_the_tree_is_the_inverse_of_the_chain_down():
    """From any link to any link: panda_link5 -> panda_link2 walks joints 5, 4, 3 against their direction,
    and its motor is the reverse of link2 -> link5's at the same joint values."""
    from gagen.algebra.signature import cga3d
    from gagen.interp import MultiVector
    from gagen.model import kinematics as K

    down = load_chain(PANDA, "panda_link2", "panda_link5")
    up = load_chain(PANDA, "panda_link5", "panda_link2")
    assert K.chain_variables(up) == ["panda_joint5", "panda_joint4", "panda_joint3"]
    assert [j.name for j in up if not j.moves] == [f"panda_joint{k}_inverse" for k in (5, 4, 3)]
    like = MultiVector.zero(cga3d())
    q = [0.3, -1.1, 0.7]
    forward, _ = K.chain_kinematics(like, down, q)
    backward, _ = K.chain_kinematics(like, up, q[::-1])
    product = forward * backward
    assert abs(product["1"]) == pytest.approx(1.0, abs=1e-14)
    assert max(abs(product[b]) for b in ("e12", "e13", "e23", "e1inf", "e2inf", "e3inf")) <= 1e-14


def test_links_of_two_trees_are_not_connected(tmp_path):
    path = tmp_path / "two.urdf"
    path.write_text('<robot name="r"><link name="a"/><link name="b"/><link name="c"/><link name="d"/>'
                    '<joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>'
                    '</joint><joint name="j2" type="revolute"><parent link="c"/><child link="d"/>'
                    '<axis xyz="0 0 1"/></joint></robot>')
    with pytest.raises(SpecError) as e:
        load_chain(path, "b", "d")
    assert e.value.field == "tip_link" and "not connected" in e.value.message


def test_zero_axis(tmp_path):
    urdf = tmp_path / "zero_axis.urdf"
    urdf.write_text(PANDA.read_text().replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>', 1))
    with pytest.raises(SpecError) as e:
        load_chain(urdf, "panda_link0", "panda_link8")
    assert e.value.field == "joint panda_joint1: axis"


def test_chain_of_the_bundled_panda():
    joints = load_chain(PANDA, "panda_link0", "panda_link8")
    assert [j.name for j in joints] == [f"panda_joint{i}" for i in range(1, 9)]
    assert [j.kind for j in joints] == ["revolute"] * 7 + ["fixed"]


# -- strict URDFs: structure, numbers, names, unsupported joint types and formats --------------------

LIMIT = '<limit lower="-1" upper="1" effort="1" velocity="1"/>'


def _urdf(tmp_path, joints, links=("a", "b", "c"), name="robot.urdf", head="", root='name="r"',
          elements="") -> Path:
    """A URDF with the given links and joints (name, type, parent, child, extra XML), the root's
    attributes and extra elements."""
    body = "".join(f'  <link name="{link}"/>\n' for link in links)
    for joint, kind, parent, child, extra in joints:
        body += (f'  <joint name="{joint}" type="{kind}">\n    <parent link="{parent}"/>\n'
                 f'    <child link="{child}"/>\n{extra}  </joint>\n')
    path = tmp_path / name
    path.write_text(f'{head}<robot {root}>\n{body}{elements}</robot>\n')
    return path


def _moving(origin='<origin xyz="0 0 0.1" rpy="0 0 0"/>', axis='<axis xyz="0 0 1"/>'):
    return f"    {origin}\n    {axis}\n    {LIMIT}\n"




def _refused(path, base="a", tip="c") -> SpecError:
    with deadline(5), pytest.raises(SpecError) as e:
        load_chain(path, base, tip)
    assert e.value.file == str(path)
    return e.value


def test_kinematic_loop_is_refused_not_walked_forever(tmp_path):
    """b is c's parent and c is b's: the old walk from c went round the loop forever."""
    path = _urdf(tmp_path, [("j1", "revolute", "b", "c", _moving()), ("j2", "revolute", "c", "b", _moving())])
    e = _refused(path)
    assert e.field == "joint j1" and "kinematic loop (j1 -> j2 -> j1)" in e.message and "line 5" in e.message


def test_link_with_two_parents(tmp_path):
    """b is the child of j1 and of j3: the old loader kept the last silently."""
    path = _urdf(tmp_path, [("j1", "revolute", "a", "b", _moving()), ("j2", "revolute", "a", "c", _moving()),
                            ("j3", "revolute", "c", "b", _moving())])
    e = _refused(path, tip="b")
    assert e.field == "joint j3" and "link 'b' already has the parent joint 'j1' (line 5)" in e.message


def test_duplicate_joint_names(tmp_path):
    path = _urdf(tmp_path, [("j1", "revolute", "a", "b", _moving()), ("j1", "revolute", "b", "c", _moving())])
    e = _refused(path)
    assert e.field == "joint j1" and "defined twice (lines 5 and 12)" in e.message


@pytest.mark.parametrize(("part", "element"), [
    ("origin", '<origin xyz="nan 0 0" rpy="0 0 0"/>'),
    ("origin", '<origin xyz="0 inf 0" rpy="0 0 0"/>'),
    ("origin", '<origin xyz="0 0 2e6" rpy="0 0 0"/>'),
    ("origin", '<origin xyz="0 0 0" rpy="0 nan 0"/>'),
    ("origin", '<origin xyz="0 0 0" rpy="0 0 1e300"/>'),
    ("origin", '<origin xyz="0 0" rpy="0 0 0"/>'),
    ("axis", '<axis xyz="0 1"/>'),
    ("axis", '<axis xyz="0 0 1 0"/>'),
    ("axis", '<axis xyz="0 0 -inf"/>'),
    ("axis", '<axis xyz="0 0 x"/>'),
])
def test_non_finite_huge_or_malformed_numbers(tmp_path, part, element):
    """The old loader took NaN, inf and 1e300 (yourdfpy turns inf into a NaN matrix) and 2- or 4-element
    axes into the model, or failed on them with a bare exception."""
    moving = _moving(origin=element) if part == "origin" else _moving(axis=element)
    path = _urdf(tmp_path, [("j1", "revolute", "a", "b", moving), ("j2", "revolute", "b", "c", _moving())])
    e = _refused(path)
    line = 8 if part == "origin" else 9  # the line of the <origin> or <axis> element
    assert e.field == f"joint j1: {part}" and f"line {line}:" in e.message
    assert "three finite numbers" in e.message


@pytest.mark.parametrize("kind", ["floating", "planar"])
def test_floating_and_planar_joints(tmp_path, kind):
    path = _urdf(tmp_path, [("j1", kind, "a", "b", ""), ("j2", "revolute", "b", "c", _moving())])
    e = _refused(path)
    assert e.field == "joint j1" and "floating/planar joints are not supported" in e.message


@pytest.mark.parametrize("name", ['j*/ #error x /*', "j 1", "j/1", "j\u00e9", "x" * 65])
def test_joint_name_outside_the_label_set(tmp_path, name):
    """A joint name reaches the generated code's row labels: the old loader took '*/ #error x /*'."""
    escaped = name.replace("&", "&amp;")
    path = _urdf(tmp_path, [(escaped, "revolute", "a", "b", _moving()),
                            ("j2", "revolute", "b", "c", _moving())])
    e = _refused(path)
    assert e.field == f"joint {name!r}" and "row label" in e.message


XACRO_NS = 'xmlns:xacro="http://www.ros.org/wiki/xacro"'


@pytest.mark.parametrize(("name", "element", "text"), [
    ("arm.urdf.xacro", '<xacro:property name="l" value="0.1"/>', "xacro arm.urdf.xacro > arm.urdf"),
    ("arm.urdf", '<xacro:include filename="hand.xacro"/>', "xacro arm.urdf > arm_expanded.urdf"),
    ("arm.urdf", '<link name="d"><xacro:insert_block name="geometry"/></link>', "xacro arm.urdf > "),
])
def test_xacro_files_are_refused_with_the_command_to_expand_them(tmp_path, name, element, text):
    """A real xacro element (anywhere in the tree) is refused with the command that expands it."""
    path = _urdf(tmp_path, [("j1", "revolute", "a", "b", _moving()), ("j2", "revolute", "b", "c", _moving())],
                 name=name, root=f'name="r" {XACRO_NS}', elements=element)
    e = _refused(path)
    assert e.field == "urdf" and "expand it first" in e.message and text in e.message


def test_xacro_substitution_left_in_a_number_is_refused_with_the_hint(tmp_path):
    path = _urdf(tmp_path, [("j1", "revolute", "a", "b", _moving(origin='<origin xyz="0 0 ${l}"/>')),
                            ("j2", "revolute", "b", "c", _moving())], root=f'name="r" {XACRO_NS}')
    e = _refused(path)
    assert e.field == "urdf" and "expand it first" in e.message and "${l}" in e.message


@pytest.mark.parametrize("head", ["", '<?xml version="1.0"?>\n<!-- <xacro:include filename="x"/> -->\n'])
def test_expanded_xacro_output_is_a_urdf(tmp_path, head):
    """xacro leaves its namespace declaration (and comments) in its output, which is a plain URDF: it
    loads (38 of example-robot-data's 69 URDFs carry the declaration; the old check refused them)."""
    path = _urdf(tmp_path, [("j1", "revolute", "a", "b", _moving()), ("j2", "revolute", "b", "c", _moving())],
                 root=f'name="r" {XACRO_NS}', head=head)
    joints = load_chain(path, "a", "c")
    assert [j.name for j in joints] == ["j1", "j2"]


def test_entity_declarations_are_refused(tmp_path):
    head = '<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;">]>\n'
    path = _urdf(tmp_path, [("j1", "revolute", "a", "b", _moving()), ("j2", "revolute", "b", "c", _moving())],
                 head=head)
    e = _refused(path)
    assert e.field == "urdf" and "<!ENTITY" in e.message


def test_non_utf8_file(tmp_path):
    path = _urdf(tmp_path, [("j1", "revolute", "a", "b", _moving()), ("j2", "revolute", "b", "c", _moving())])
    path.write_bytes(path.read_bytes().replace(b'name="r"', b'name="\xe9"'))
    e = _refused(path)
    assert e.field == "urdf" and "malformed XML at line 1" in e.message


def test_a_valid_small_urdf_loads(tmp_path):
    """The strict checks accept what they should: the chain a -> c with its numbers."""
    path = _urdf(tmp_path, [("j1", "revolute", "a", "b", _moving()),
                            ("j2", "prismatic", "b", "c", _moving('<origin xyz="1 2 3" rpy="0 0 0"/>',
                                                                  '<axis xyz="0 2 0"/>'))])
    joints = load_chain(path, "a", "c")
    assert [(j.name, j.kind, j.xyz, j.axis) for j in joints] == [
        ("j1", "revolute", (0.0, 0.0, 0.1), (0.0, 0.0, 1.0)),
        ("j2", "prismatic", (1.0, 2.0, 3.0), (0.0, 1.0, 0.0))]
