"""Names that reach generated code and file names (issue 12, deliverable 1): system and chain names are
identifiers, joint names, robot labels and configuration names are labels; anything else is a SpecError
naming the file, the field with its line and the rule. Each payload below was accepted before."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from gagen.apps.cooperative.catalogue import build_kernels
from gagen.errors import SpecError
from gagen.model.kinematics import Joint
from gagen.names import (
    CHAIN_KERNEL_SUFFIXES,
    SYSTEM_KERNELS,
    chain_kernel_names,
    identifier_problem,
    label_problem,
    suggest_identifier,
)
from gagen.robots.spec import load_system
from gagen.robots.system import Chain, System

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
PANDA_URDF = ROBOTS / "panda" / "panda.urdf"


def _spec(tmp_path, name="t", chains=("arm0",), robot=None, urdf=PANDA_URDF, config="") -> Path:
    """A spec of Panda chains; names are written as JSON strings (valid YAML double-quoted scalars)."""
    kind = {1: "point", 2: "point_pair", 3: "circle"}[len(chains)]
    text = f"name: {json.dumps(name)}\nprimitive: {kind}\nchains:\n"
    for chain in chains:
        text += (f"  - name: {json.dumps(chain)}\n    urdf: {urdf}\n    base_link: panda_link0\n"
                 f"    tip_link: panda_link8\n")
        if robot is not None:
            text += f"    robot: {json.dumps(robot)}\n"
    path = tmp_path / "spec.yaml"
    path.write_text(text + config)
    return path


def _error(path: Path) -> SpecError:
    with pytest.raises(SpecError) as e:
        load_system(path)
    assert e.value.file == str(path)
    return e.value


# -- the rules ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["arm0", "arm_0", "g1a_left_hand", "A", "x9_y8", "match", "type", "a" * 64])
def test_valid_identifiers(name):
    assert identifier_problem(name) is None


@pytest.mark.parametrize(("name", "problem"), [
    ("arm-0", "not an identifier"), ("_arm", "not an identifier"), ("arm_", "not an identifier"),
    ("arm__0", "not an identifier"), ("0arm", "not an identifier"), ("", "not an identifier"),
    ("../escape", "not an identifier"), ("/tmp/x", "not an identifier"), ('a"""b', "not an identifier"),
    ("arm\u00e9", "not an identifier"), ("for", "a C, C++ or Python keyword"),
    ("None", "a C, C++ or Python keyword"), ("class", "a C, C++ or Python keyword"),
    ("volatile", "a C, C++ or Python keyword"), ("static_assert", "a C, C++ or Python keyword"),
    ("a" * 65, "65 characters; at most 64"),
])
def test_invalid_identifiers(name, problem):
    assert identifier_problem(name) == problem


def test_identifiers_are_exactly_the_names_the_kernel_namer_keeps():
    """gagen.symbolic.flatten.identifier maps runs of other characters to one '_' and strips the ends:
    a valid identifier is its own image, so '<chain>_fk' is the kernel name verbatim."""
    from gagen.symbolic.flatten import identifier
    for name in ["arm0", "arm_0", "g1a_left_hand", "x9_y8"]:
        assert identifier(name) == name and identifier_problem(name) is None
    for name in ["arm-0", "arm__0", "_arm", "arm_"]:
        assert identifier(name) != name and identifier_problem(name) is not None


def test_suggestions_are_valid_identifiers():
    for name in ["arm-0", "../escape", "0arm", "for", "  ", 'a"""b', "x" * 200]:
        assert identifier_problem(suggest_identifier(name)) is None
    assert suggest_identifier("arm-0") == "arm_0"


def test_every_joint_name_of_the_bundled_urdfs_is_a_label():
    names = set()
    for urdf in ROBOTS.glob("*/*.urdf"):
        names |= set(re.findall(r'<joint name="([^"]*)"', urdf.read_text()))
    assert len(names) > 50 and {"0", "15", "panda_joint1", "iiwa_joint_ee"} <= names
    assert [n for n in sorted(names) if label_problem(n)] == []


@pytest.mark.parametrize("label", ["j*/", "a/b", "a b", "a\nb", 'a"', "a'", "", "-a", ".", "\u00e9",
                                   "x" * 65])
def test_invalid_labels(label):
    assert label_problem(label) is not None


def test_kernel_names_are_the_ones_build_kernels_makes():
    """names.py predicts the kernel names without importing the kernel builder: check it."""
    system = System("s", "point", (Chain("f", (Joint("j1", "revolute", (0, 0, 0.1)),)),))
    assert set(build_kernels(system)) == {*chain_kernel_names("f"), *SYSTEM_KERNELS}
    assert chain_kernel_names("f") == tuple(f"f_{s}" for s in CHAIN_KERNEL_SUFFIXES)


# -- the findings of issue 12, through load_system ---------------------------------------------------------

def test_chain_name_with_a_c_payload(tmp_path):
    """Built and ran the injected C at library load before."""
    payload = "arm0*/ __attribute__((constructor)) static void x(void) { system(\"id\"); } /*"
    e = _error(_spec(tmp_path, chains=(payload,)))
    assert e.field == "chains[0].name (line 4)" and "not an identifier" in e.message
    assert "a letter, then letters, digits and single underscores" in e.message


@pytest.mark.parametrize("name", ['x"""\nimport os; os.system("id")\n"""', "../escape", "/tmp/absolute",
                                  "a.b", "x y", "class", "int"])
def test_system_names_that_became_code_or_paths(tmp_path, name):
    """'\"\"\"' injected Python into __init__.py, '../escape' wrote escape.c outside -o, an absolute name
    overwrote a file; keywords cannot name a package or a C symbol prefix."""
    e = _error(_spec(tmp_path, name=name))
    assert e.field == "name (line 1)" and "the system's name names files, C symbols" in e.message


def test_arm_dash_0_is_refused_with_a_suggestion(tmp_path):
    """'arm-0' and 'arm_0' both became the kernels arm_0_* before: 3 kernels were silently lost."""
    e = _error(_spec(tmp_path, chains=("arm-0", "arm_0")))
    assert e.field == "chains[0].name (line 4)" and "e.g. 'arm_0'" in e.message


def test_chain_names_differing_only_by_case(tmp_path):
    """The header's size macros upper-case kernel names: ARM0_FK_M_SIZE would be defined twice."""
    e = _error(_spec(tmp_path, chains=("arm0", "ARM0")))
    assert e.field == "chains[1].name (line 8)"
    assert "'ARM0_fk', which collides with kernel 'arm0_fk' of chains[0] ('arm0')" in e.message


def test_chain_named_like_a_system_kernel(tmp_path):
    """A chain 'similarity' makes a kernel 'similarity_jacobians': the system kernel's twin."""
    e = _error(_spec(tmp_path, chains=("similarity",)))
    assert e.field == "chains[0].name (line 4)"
    assert ("chain 'similarity' names the kernel 'similarity_jacobians', which collides with the system "
            "kernel 'similarity_jacobians'") in e.message


def test_urdf_joint_name_with_a_preprocessor_payload(tmp_path):
    """'*/ #error x /*' reached the C preprocessor through the header's row-label comment before."""
    urdf = tmp_path / "panda.urdf"
    urdf.write_text(PANDA_URDF.read_text().replace('name="panda_joint3"', 'name="j3*/ #error x /*"'))
    e = _error(_spec(tmp_path, urdf=urdf))
    assert e.field == "chains[0].urdf (line 5)"
    assert f"{urdf}: joint 'j3*/ #error x /*': line" in e.message and "row label" in e.message


@pytest.mark.parametrize("robot", ["a/b", "r*/", "r\n#define x", "x" * 65])
def test_robot_labels(tmp_path, robot):
    e = _error(_spec(tmp_path, robot=robot))
    assert e.field == "chains[0].robot (line 8)" and "a robot label becomes a row label" in e.message


def test_configuration_names(tmp_path):
    e = _error(_spec(tmp_path, config='configurations:\n  "a */ b": [0, 0, 0, 0, 0, 0, 0]\n'))
    assert e.field == "configurations.a */ b (line 9)" and "a configuration name" in e.message


def test_explicit_joint_names(tmp_path):
    path = tmp_path / "spec.yaml"
    path.write_text('name: t\nprimitive: point\nchains:\n  - name: f\n    joints:\n'
                    '      - {name: "j */", type: revolute, axis: [0, 0, 1]}\n')
    e = _error(path)
    assert e.field == "chains[0].joints[0].name (line 6)" and "row label" in e.message
