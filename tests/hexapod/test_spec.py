"""The hexapod spec (issue 14, item 1): the bundled robot carries the paper's numbers, and every
malformed spec is refused with the file, the field (with its line) and what was expected."""

from __future__ import annotations

import math

import pytest

from gagen.apps.hexapod.spec import load_hexapod
from gagen.build import spec_kind
from gagen.errors import SpecError

from .conftest import SPEC

LEG = "leg:\n  lengths: [0.05, 0.2, 0.2]\n"
NAMES = ("a", "b", "c", "d", "e", "f")


def _legs(names=NAMES, extra: str = "") -> str:
    return "legs:\n" + "".join(f"  - {{name: {n}, xyz: [0.1, 0, 0], rpy: [0, 0, {i}]{extra}}}\n"
                               for i, n in enumerate(names))


def _spec(tmp_path, text: str):
    path = tmp_path / "h.yaml"
    path.write_text(text)
    return path


def _error(tmp_path, text: str) -> SpecError:
    path = _spec(tmp_path, text)
    with pytest.raises(SpecError) as e:
        load_hexapod(path)
    assert e.value.file == str(path)
    return e.value


def test_bundled_hexapod_has_the_papers_leg(hexapod):
    """[HEX 4.1]: l1 = 0.05, l2 = 0.20, l3 = 0.20; hip yaw about z, thigh and knee pitch about y; the
    toe at (l1 + l2 + l3, 0, 0) in the zero pose; six legs 60° apart on a hexagon."""
    assert len(hexapod.legs) == 6 and hexapod.dof == 18
    for i, leg in enumerate(hexapod.legs):
        assert leg.lengths == (0.05, 0.20, 0.20)
        assert leg.axes == ((0, 0, 1), (0, 1, 0), (0, 1, 0))
        assert leg.centres == ((0, 0, 0), (0.05, 0, 0), (0.25, 0, 0)) and leg.toe == (0.45, 0, 0)
        yaw = leg.rpy[2]
        assert math.isclose(yaw, math.radians(30 + 60 * i) if i < 3 else math.radians(30 + 60 * i - 360))
        assert math.isclose(math.hypot(*leg.xyz[:2]), 0.12, rel_tol=1e-11)
    assert spec_kind(SPEC).name == "hexapod"


def test_minimal_spec_and_overrides(tmp_path):
    text = f"app: hexapod\nname: h\n{LEG}" + _legs()
    text = text.replace("{name: f,", "{name: f, lengths: [0.1, 0.3, 0.25],")
    h = load_hexapod(_spec(tmp_path, text))
    assert h.legs[5].lengths == (0.1, 0.3, 0.25) and h.legs[0].lengths == (0.05, 0.2, 0.2)
    assert h.knee == "up" and h.leg("c").rpy == (0, 0, 2)


@pytest.mark.parametrize(("text", "field", "message"), [
    ("app: hexapod\nname: h\n" + LEG + _legs(NAMES[:5]), "legs (line 5)", "got 5 legs; a hexapod has 6"),
    ("app: hexapod\nname: h\nleg:\n  lenghts: [0.05, 0.2, 0.2]\n" + _legs(), "leg.lenghts (line 4)",
     "did you mean 'lengths'?"),
    ("app: hexapod\nname: h\n" + LEG + _legs(("a", "b", "c", "d", "e", "A")), "legs[5].name (line 11)",
     "the name of legs[0] too"),
    ("app: hexapod\nname: 1h\n" + LEG + _legs(), "name (line 2)", "expected"),
    ("app: hexapod\nname: h\n" + LEG + _legs(extra=", axes: [[0, 0, 0], [0, 1, 0], [0, 1, 0]]"),
     "legs[0].axes[0]", "zero vector"),
    ("app: hexapod\nname: h\n" + LEG + _legs(extra=", limits: [[1, -1], [-1, 1], [-1, 1]]"),
     "legs[0].limits[0]", "lower limit must be below the upper"),
    ("app: hexapod\nname: h\nleg:\n  lengths: [0.05, -0.2, 0.2]\n" + _legs(), "leg.lengths (line 4)",
     "three positive lengths"),
    ("app: hexapod\nname: h\n" + _legs(), "legs[0].lengths", "missing"),
    ("app: hexapod\nname: h\n" + LEG + _legs() + "knee: sideways\n", "knee (line 12)", "up, down"),
    ("app: hexapod\nname: h\n" + LEG + _legs() + "neutral: [0, 0, 9]\n", "neutral (line 12)",
     "outside its limits"),
    ("app: hexapod\nname: h\n" + LEG + _legs(extra=", xyz: [.nan, 0, 0]"), "legs[0]", "duplicate key"),
    ("app: hexapod\nname: h\n" + LEG + _legs(extra=", lengths: [.nan, 0.2, 0.2]"), "legs[0].lengths",
     "three positive lengths"),
    ("app: robot\nname: h\n" + LEG + _legs(), "app (line 1)", "app: hexapod"),
])
def test_malformed_spec_names_file_field_and_expectation(tmp_path, text, field, message):
    e = _error(tmp_path, text)
    assert e.field.startswith(field) and message in e.message, (e.field, e.message)


def test_unknown_app_is_refused_before_any_application_reads_it(tmp_path):
    path = _spec(tmp_path, "app: gripper\nname: x\n")
    with pytest.raises(SpecError, match="expected one of cooperative, hexapod, linkage, stereo"):
        spec_kind(path)


def test_a_robot_spec_cannot_claim_another_app(tmp_path):
    from gagen.robots.spec import load_system

    path = _spec(tmp_path, "app: hexapod\nname: t\nprimitive: point\nchains: []\n")
    with pytest.raises(SpecError, match="a robot spec is app: cooperative"):
        load_system(path)


@pytest.mark.parametrize("name", ["front */ #error", "../leg", "import", 'a"b'])
def test_hostile_leg_names_are_refused(tmp_path, name):
    """A leg name names kernels (C symbols, Python attributes): anything but an identifier is refused."""
    text = f"app: hexapod\nname: h\n{LEG}" + _legs(("a", "b", "c", "d", "e", "f")).replace(
        "{name: f,", "{name: " + ('"' + name.replace('"', '\\"') + '"') + ",")
    e = _error(tmp_path, text)
    assert e.field.startswith("legs[5].name"), (e.field, e.message)


@pytest.mark.parametrize("name", ["body", "Body", "BODY"])
def test_a_leg_named_body_is_refused_naming_the_file_and_field(tmp_path, name):
    """A leg ``body`` would name the kernels body_fk_pga, body_fk_cga and body_ik, which are the body's
    (up to case: the C header upper-cases kernel names in its macros)."""
    e = _error(tmp_path, f"app: hexapod\nname: h\n{LEG}" + _legs(("a", "b", name, "d", "e", "f")))
    assert e.field == "legs[2].name (line 8)", e.field
    assert "body_fk_pga" in e.message and "body_ik" in e.message and "expected" in e.message, e.message
    assert "\n" not in str(e)


def test_more_legs_than_the_limit_are_refused_in_one_line(tmp_path, monkeypatch):
    """gagen.limits' hexapod_legs (16): checked before any leg is read; GAGEN_LIMIT_HEXAPOD_LEGS moves it."""
    monkeypatch.delenv("GAGEN_LIMIT_HEXAPOD_LEGS", raising=False)
    many = f"app: hexapod\nname: h\n{LEG}" + _legs(tuple(f"leg{i}" for i in range(17)))
    e = _error(tmp_path, many)
    assert e.field == "legs (line 5)" and "\n" not in str(e)
    assert e.message == ("17 legs in one walker, over the limit of 16 (set GAGEN_LIMIT_HEXAPOD_LEGS to "
                         "raise it)")
    huge = f"app: hexapod\nname: h\n{LEG}legs:\n" + "  - {name: a}\n" * 2_000
    assert _error(tmp_path, huge).message.startswith("2000 legs in one walker, over the limit of 16")
    monkeypatch.setenv("GAGEN_LIMIT_HEXAPOD_LEGS", "20")  # raised: the limit passes, six legs do not
    assert _error(tmp_path, many).message == "got 17 legs; a hexapod has 6"
    monkeypatch.setenv("GAGEN_LIMIT_HEXAPOD_LEGS", "4")
    e = _error(tmp_path, f"app: hexapod\nname: h\n{LEG}" + _legs())
    assert e.message.startswith("6 legs in one walker, over the limit of 4")


@pytest.mark.parametrize("lengths", ["[0.05, 1.0e-300, 1.0e-300]", "[1.0e-7, 0.2, 0.2]", "[0, 0.2, 0.2]"])
def test_links_shorter_than_a_micron_are_refused(tmp_path, lengths):
    """The fuzzer's find: l2 = l3 = 1e-300 made 2 l2 l3 underflow to 0 and the IK divide by it."""
    e = _error(tmp_path, f"app: hexapod\nname: h\nleg:\n  lengths: {lengths}\n" + _legs())
    assert e.field == "leg.lengths (line 4)" and "at least 1e-06" in e.message, (e.field, e.message)
