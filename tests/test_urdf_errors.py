"""Malformed URDF input: each error names the file, the field and what was expected."""

from __future__ import annotations

from pathlib import Path

import pytest

from gagen.errors import SpecError
from gagen.robots.urdf import load_chain

PANDA = Path(__file__).resolve().parent.parent / "robots" / "panda" / "panda.urdf"


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


def test_tip_not_below_base():
    with pytest.raises(SpecError) as e:
        load_chain(PANDA, "panda_link5", "panda_link2")
    assert e.value.field == "tip_link" and "not below" in e.value.message


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
