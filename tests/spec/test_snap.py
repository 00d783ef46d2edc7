"""The spec's ``snap`` switch: snapping rpy angles to exact multiples of π/4 (the default) or keeping the
numbers as written, strictly validated, and covered by the build key (the loaded system's repr)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gagen.apps.cooperative.module import cooperative_source
from gagen.errors import SpecError
from gagen.robots.spec import load_system

ROBOTS = Path(__file__).resolve().parents[2] / "robots"


def _spec(tmp_path: Path, snap: str | None) -> Path:
    path = tmp_path / f"spec_{snap}.yaml"
    path.write_text("name: rounded\nprimitive: point\n" + (f"snap: {snap}\n" if snap is not None else "")
                    + "chains:\n  - name: arm\n"
                    f"    urdf: {ROBOTS / 'panda' / 'panda.urdf'}\n"
                    "    base_link: panda_link0\n    tip_link: panda_link8\n"
                    "    base: {xyz: [0, 0, 0], rpy: [0, 0, 1.57079632679]}\n"
                    "    tool: {xyz: [0, 0, 0.1]}\n")
    return path


def test_snap_false_keeps_every_joint_as_written_and_changes_the_build_key(tmp_path):
    default, on, off = (load_system(_spec(tmp_path, s))[0] for s in (None, "true", "false"))
    assert repr(default) == repr(on) and "snap" not in repr(default)  # the bundled modules' keys stay
    joints = [j for chain in off.chains for j in chain.joints]
    assert all(not j.snap for j in joints) and repr(off).count("snap=False") == len(joints)
    assert joints[0].name == "arm_base" and joints[-1].name == "arm_tool"
    assert joints[0].rpy == (0.0, 0.0, 1.57079632679)
    keys = {cooperative_source(_spec(tmp_path, s)).key for s in (None, "true", "false")}
    assert len(keys) == 2


@pytest.mark.parametrize("value", ['"no"', "0", "1", "[false]", "null"])
def test_snap_takes_a_bool_only(tmp_path, value):
    with pytest.raises(SpecError) as e:
        load_system(_spec(tmp_path, value))
    assert e.value.field.startswith("snap") and "expected true" in e.value.message


def test_a_misspelt_snap_is_suggested(tmp_path):
    path = _spec(tmp_path, None)
    path.write_text(path.read_text().replace("primitive: point\n", "primitive: point\nsnpa: false\n"))
    with pytest.raises(SpecError) as e:
        load_system(path)
    assert "snap" in e.value.message
