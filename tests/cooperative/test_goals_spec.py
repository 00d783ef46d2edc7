"""A spec's ``goals:`` section (``gagen.robots.goals``): parsed strictly, turned into V_Sd by
``gagen.control.goals.desired`` exactly as the goal constructors and ``target_from`` do, and reached by
``gagen reach`` on a user's spec written here, by its goal or one given on the command line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gagen.apps.cooperative.scenario_table import SCENARIOS, scenarios_of
from gagen.control import goals as goal_constructors
from gagen.control.goals import desired
from gagen.control.ocp import target_from
from gagen.errors import SpecError
from gagen.registry import bundled_specs
from gagen.robots.goals import load_goals
from gagen.robots.spec import load_system

PANDA = bundled_specs("cooperative")["panda_point"].parent / "panda" / "panda.urdf"
CIRCLE = bundled_specs("cooperative")["three_pandas_circle"]


def _user_spec(folder: Path, goals: str, primitive: str = "point") -> Path:
    spec = folder / "my_panda.yaml"
    spec.write_text(f"""name: my_panda
primitive: {primitive}
chains:
  - name: arm0
    urdf: {PANDA}
    base_link: panda_link0
    tip_link: panda_link8
configurations:
  ready: [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]
{goals}""")
    return spec


def test_the_bundled_scenarios_are_the_bundled_specs_goals():
    assert set(SCENARIOS) == {"line", "circle", "torso_circle", "collaboration_circle", "plane",
                              "hand_sphere", "humanoids_sphere"}
    circle = SCENARIOS["circle"]
    assert (circle.system, circle.translation, circle.rotation, circle.dilation) == \
        ("three_pandas_circle", (0.0, 0.0, 0.1), ((1.0, 0.0, 0.0), 0.2), 1.3)
    assert scenarios_of("three_pandas_circle") == [circle] == scenarios_of("circle")
    assert scenarios_of(str(CIRCLE), "circle")[0].goal == circle.goal
    with pytest.raises(ValueError, match=r"--goal 'square': .*three_pandas_circle.yaml states circle"):
        scenarios_of("three_pandas_circle", "square")


def test_a_primitive_goal_and_a_move_give_the_constructors_v_sd(tmp_path):
    spec = _user_spec(tmp_path, """goals:
  above: {point: {position: [0.4, 0.1, 0.5]}}
  up:
    title: ten centimetres up
    move: {translation: [0, 0, 0.1], rotation: {axis: [0, 0, 2], angle: 0.3}}
""")
    found = load_goals(spec)
    assert list(found) == ["above", "up"] and found["up"].title == "ten centimetres up"
    np.testing.assert_array_equal(desired(found["above"], np.zeros(12), "point"),
                                  goal_constructors.point([0.4, 0.1, 0.5]))
    V_Sc0 = goal_constructors.circle([0.5, 0.0, 0.4], 0.2, [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(desired(found["up"], V_Sc0, "circle"),
                                  target_from(V_Sc0, (0, 0, 0.1), ((0, 0, 2), 0.3), 1.0, kind="circle"))
    load_system(spec)  # the system loader takes the section too
    with pytest.raises(ValueError, match="goal 'above' is a point; the system spans a circle"):
        desired(found["above"], V_Sc0, "circle")


@pytest.mark.parametrize(("goals", "field", "message"), [
    ("goals: [1, 2]", "goals", "expected a mapping of goal names to goals"),
    ("goals:\n  g: {pointt: {position: [0, 0, 1]}}", "goals.g.pointt", "did you mean 'point'?"),
    ("goals:\n  g: {circle: {centre: [0, 0, 1], radius: 0.1, normal: [0, 0, 1]}}", "goals.g.circle",
     "the system spans a point"),
    ("goals:\n  g: {point: {position: [0, 0, .nan]}}", "goals.g.point.position", "three finite numbers"),
    ("goals:\n  g: {move: {dilation: -1}}", "goals.g.move.dilation", "finite number > 0"),
    ("goals:\n  g: {move: {rotation: {axis: [0, 0, 0], angle: 1}}}", "goals.g.move.rotation.axis", "zero"),
    ("goals:\n  g: {move: {}, point: {position: [0, 0, 1]}}", "goals.g", "exactly one of move"),
    ("goals:\n  'a b': {move: {}}", "goals.a b", "a goal name"),
])
def test_a_malformed_goal_names_the_file_and_the_field(tmp_path, goals, field, message):
    spec = _user_spec(tmp_path, goals + "\n")
    with pytest.raises(SpecError) as raised:
        load_system(spec)
    assert raised.value.file == str(spec) and raised.value.field.startswith(field), raised.value
    assert message in raised.value.message


@pytest.mark.compiling
def test_reach_takes_a_user_spec_with_its_goal_or_one_given_here(tmp_path, capsys):
    from gagen.cli import main
    from gagen.modules import bundled_module
    from gagen.robots.points import end_points

    target = np.array([0.35, 0.15, 0.55])
    spec = _user_spec(tmp_path, f"goals:\n  over_there: {{point: {{position: {target.tolist()}}}}}\n")
    out = tmp_path / "plots"
    assert main(["reach", str(spec), "--N", "20", "--solver", "ilqr", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "over_there" in printed and "reached" in printed
    assert sorted(p.name for p in out.iterdir()) == ["over_there_command.png", "over_there_trajectory.png"]
    # the same goal given on the command line, as a move of the ready point: the end point lands there
    module = bundled_module(spec)
    ready = np.array(load_system(spec)[1]["ready"])
    start = end_points(module, ready)[0]
    assert main(["reach", str(spec), "--N", "20", "--solver", "ilqr", "--out", str(out),
                 "--translation", ",".join(map(str, target - start))]) == 0
    assert "command_line" in capsys.readouterr().out
    from gagen.apps.cooperative import scenarios

    result = scenarios.run(scenarios_of(str(spec))[0], N=20, solver="ilqr")
    np.testing.assert_allclose(end_points(module, result.result.q[-1])[0], target, atol=1e-8)


@pytest.mark.compiling
def test_teleop_takes_a_user_spec(tmp_path, capsys):
    """``gagen teleop SPEC --trace``: a single Panda's end point driven 2 cm along x over 0.2 s (a point has
    only translations); the report is written and the point moved as commanded."""
    from gagen.apps.cooperative.teleop import bundled_kernels, read_trace, run_trace
    from gagen.cli import main

    spec = _user_spec(tmp_path, "")
    trace = tmp_path / "slide.csv"
    trace.write_text("t,tx,ty,tz,rx,ry,rz\n0.0,0.1,0,0,0,0,0\n0.2,0,0,0,0,0,0\n")
    out = tmp_path / "teleop"
    assert main(["teleop", str(spec), "--trace", str(trace), "--out", str(out)]) == 0
    assert "my_panda" in capsys.readouterr().out and (out / "teleop.txt").is_file()
    result = run_trace(bundled_kernels(str(spec)), read_trace(trace))
    assert result.converged.all()
    np.testing.assert_allclose(result.centre[-1] - result.centre[0], [0.02, 0.0, 0.0], atol=1e-9)
