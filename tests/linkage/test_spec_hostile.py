"""A linkage spec's hostile values (issue 29): names YAML reads as numbers or booleans, fields of the
wrong type, and specs over the resource limits are refused by a one-line SpecError naming the file,
the field and what was expected, never a raw TypeError."""

from __future__ import annotations

from pathlib import Path

import pytest

from gagen.apps.linkage.spec import load_linkage
from gagen.errors import SpecError
from gagen.limits import limit

FOUR_BAR = (Path(__file__).resolve().parents[2] / "gagen" / "apps" / "linkage" / "robots"
            / "four_bar.yaml").read_text()


def _refusal(tmp_path: Path, text: str) -> SpecError:
    path = tmp_path / "m.yaml"
    path.write_text(text)
    with pytest.raises(SpecError) as e:
        load_linkage(path)
    assert e.value.file == str(path)
    assert "\n" not in str(e.value), str(e.value)
    return e.value


@pytest.mark.parametrize(("old", "new", "field", "message"), [
    # body names: YAML reads 1, on and 1.5 unquoted as a number, a boolean and a number
    ("  crank: {A", "  1: {A", "bodies.1", "got the number 1"),
    ("  crank: {A", "  on: {A", "bodies.on (line", "got the boolean True"),
    ("  crank: {A", "  1.5: {A", "bodies.1.5", "got the number 1.5"),
    ("  crank: {A", "  null: {A", "bodies.null (line", "got null"),
    # point names of a body and of the ground
    ("crank: {A: [0, 0], B: [1, 0]}", "crank: {A: [0, 0], 1: [1, 0]}", "bodies.crank.1", "got the number 1"),
    ("ground: {A: [0, 0], D: [4, 0]}", "ground: {A: [0, 0], yes: [4, 0]}", "ground.yes (line",
     "got the boolean"),
    # the containers themselves
    ("bodies:\n  crank: {A: [0, 0], B: [1, 0]}\n  coupler: {B: [1, 0], C: [4.0, 3.0], P: [2.0, 3.0]}\n"
     "  rocker: {C: [4.0, 3.0], D: [4, 0]}\n", "bodies: 5\n", "bodies", "expected a mapping"),
    ("bodies:\n  crank: {A: [0, 0], B: [1, 0]}\n  coupler: {B: [1, 0], C: [4.0, 3.0], P: [2.0, 3.0]}\n"
     "  rocker: {C: [4.0, 3.0], D: [4, 0]}\n", "bodies: [crank, coupler]\n", "bodies", "expected a mapping"),
    ("driver: {body: crank, pivot: ground.A}", "driver: {body: 1, pivot: ground.A}", "driver.body",
     "the crank or slider body"),
])
def test_names_and_containers_of_the_wrong_type_are_named(tmp_path, old, new, field, message):
    assert old in FOUR_BAR, old
    e = _refusal(tmp_path, FOUR_BAR.replace(old, new, 1))
    assert e.field.startswith(field) and message in e.message, (e.field, e.message)


def test_a_numeric_name_is_told_what_a_name_is(tmp_path):
    e = _refusal(tmp_path, FOUR_BAR.replace("  crank: {A", "  1: {A", 1))
    assert "YAML reads" in e.message and "a letter" in e.message and "n_1" in e.message, e.message


def test_a_boolean_name_is_told_to_quote_it(tmp_path):
    e = _refusal(tmp_path, FOUR_BAR.replace("  crank: {A", "  on: {A", 1))
    assert "quote it" in e.message, e.message


@pytest.mark.parametrize(("old", "new", "field"), [
    ("  crank: {A", '  "a\\nb": {A', "bodies.'a\\nb'"),  # found by the fuzz tier: a two-line message
    ("crank: {A: [0, 0], B", 'crank: {A: [0, 0], "\\0": [1, 0]}\n  x: {B', "bodies.crank.'\\x00'"),
    ("name: four_bar", 'name: four_bar\n"x\\ny": 1', "'x\\ny'"),
    ("driver: {body: crank,", 'driver: {"a\\tb": 1, body: crank,', "driver.'a\\tb'"),
])
def test_a_key_with_a_newline_or_nul_is_named_on_one_line(tmp_path, old, new, field):
    assert old in FOUR_BAR, old
    e = _refusal(tmp_path, FOUR_BAR.replace(old, new, 1))
    assert e.field.startswith(field), (e.field, e.message)


def _chain(n: int) -> str:
    """A spec of ``n`` bodies in one chain off the ground, and n joints (its mobility is n, so it is
    refused anyway; the limit must refuse it first, before any per-body work)."""
    bodies = "".join(f"  b{i}: {{P: [{i}, 0], Q: [{i + 1}, 0]}}\n" for i in range(n))
    joints = "  - {revolute: [b0.P, ground.A]}\n" + "".join(
        f"  - {{revolute: [b{i - 1}.Q, b{i}.P]}}\n" for i in range(1, n))
    return (f"app: linkage\nname: chain\nground: {{A: [0, 0]}}\nbodies:\n{bodies}joints:\n{joints}"
            f"driver: {{body: b0, pivot: ground.A}}\n")


def test_too_many_bodies_are_refused_in_one_line(tmp_path):
    e = _refusal(tmp_path, _chain(limit("linkage_bodies") + 1))
    assert e.field.startswith("bodies") and "over the limit of 100" in e.message
    assert "GAGEN_LIMIT_LINKAGE_BODIES" in e.message


def test_too_many_joints_are_refused_in_one_line(tmp_path):
    text = FOUR_BAR.replace("joints:\n", "joints:\n" + "  - {revolute: [crank.A, ground.A]}\n" * 200, 1)
    e = _refusal(tmp_path, text)
    assert e.field.startswith("joints") and "over the limit of 200" in e.message
    assert "GAGEN_LIMIT_LINKAGE_JOINTS" in e.message


def test_the_environment_raises_the_linkage_limits(tmp_path, monkeypatch):
    """Over the default limits, but under the raised ones: the spec reaches the next check (its
    mobility), which is what refuses it."""
    monkeypatch.setenv("GAGEN_LIMIT_LINKAGE_BODIES", "1000")
    monkeypatch.setenv("GAGEN_LIMIT_LINKAGE_JOINTS", "1000")
    e = _refusal(tmp_path, _chain(150))
    assert "over the limit" not in e.message and "under-constrained" in e.message, e.message
