"""The goal (target primitive) the viewer draws: a spec goal's ``move`` of the ready primitive lands where
the controllers' ``target_from`` puts it, a goal stated outright is that primitive, and the scene draws it
apart from the current primitive (``gagen view --goal NAME``)."""

import numpy as np
import pytest

from gagen.viewer.geometry import goal_shape, moved, shape

NEED = {"point": 1, "point_pair": 2, "line": 2, "circle": 3, "plane": 3, "sphere": 4}


@pytest.mark.parametrize("kind", list(NEED))
def test_a_move_is_the_controllers_target(kind):
    """X_d through the moved points is ∝ X_d = V_Sd X_u V_Sd~ of ``target_from`` (6 kinds: ≤ 2e-15)."""
    from gagen.algebra.signature import cga3d
    from gagen.control.ocp import multivector, target_from
    from gagen.interp import MultiVector
    from gagen.model.conformal import SIMILARITY, point, vector
    from gagen.model.primitives import through, unit_primitive
    from gagen.model.similarity import cooperative_similarity

    like = MultiVector.from_blades(cga3d(), {})

    def primitive(points):
        return through(kind, [point(vector(like, [float(c) for c in p])) for p in points])

    points = np.random.default_rng(3).uniform(-1, 1, (NEED[kind], 3))
    v0 = cooperative_similarity(kind, primitive(points)).versor
    t, turn, k = [0.1, -0.2, 0.3], ([1.0, 0.5, 0.2], 0.4), 1.3
    vd = multivector(SIMILARITY, target_from([v0[b] for b in SIMILARITY], t, turn, k, kind=kind))
    expected = vd.sandwich(unit_primitive(kind, vd)).coeffs
    got = primitive(moved(shape(kind, points), t, turn, k).points).coeffs
    expected, got = expected / np.linalg.norm(expected), got / np.linalg.norm(got)
    assert min(np.linalg.norm(expected - got), np.linalg.norm(expected + got)) < 1e-13


def test_goals_stated_outright():
    c = goal_shape("circle", {"centre": [0.6, 0, 0.5], "radius": 0.25, "normal": [0, 0, 2]})
    np.testing.assert_allclose(c.centre, [0.6, 0, 0.5], atol=1e-15)
    assert c.radius == pytest.approx(0.25) and abs(c.normal @ [0, 0, 1]) == pytest.approx(1.0)
    s = goal_shape("sphere", {"centre": [0, 1, 0], "radius": 0.3})
    np.testing.assert_allclose(s.centre, [0, 1, 0], atol=1e-15)
    assert s.radius == pytest.approx(0.3)
    line = goal_shape("line", {"point": [0, 0, 1], "direction": [0, 3, 0]})
    np.testing.assert_allclose(line.direction, [0, 1, 0])
    plane = goal_shape("plane", {"point": [0, 0, 1], "normal": [0, 0, 1]})
    assert abs(plane.normal @ [0, 0, 1]) == pytest.approx(1.0) and not plane.degenerate
    np.testing.assert_allclose(goal_shape("point", {"position": [1, 2, 3]}).centre, [1, 2, 3])
    pair = goal_shape("point_pair", {"first": [0, 0, 0], "second": [0, 0, 2]})
    assert pair.radius == pytest.approx(1.0)


def test_the_view_commands_goal_and_the_scene_draw_it():
    pytest.importorskip("viser")
    from gagen.registry import resolve_spec
    from gagen.robots.spec import load_system
    from gagen.viewer.command import goal_shape as spec_goal
    from gagen.viewer.geometry import system_pose
    from gagen.viewer.scene import Scene

    path = resolve_spec("three_pandas_circle", "cooperative", "system")
    system, named = load_system(path)
    ready = shape("circle", np.array([p.end_point for p in system_pose(system, np.array(named["ready"]))]))
    goal = spec_goal("circle", path, system, named)  # move: up 0.1, turned 0.2 about x, dilated 1.3
    assert goal.radius == pytest.approx(1.3 * ready.radius)
    np.testing.assert_allclose(goal.centre, ready.centre + np.array([0, 0, 0.1]), atol=1e-12)
    assert np.degrees(np.arccos(abs(goal.normal @ ready.normal))) == pytest.approx(np.degrees(0.2), abs=1e-9)
    with pytest.raises(ValueError, match="names circle; got 'nope'"):
        spec_goal("nope", path, system, named)
    with Scene(system, named["ready"], port=0, goal=goal) as scene:
        assert {h.name for h in scene._goal} == {"/goal/lines"}
        scene.show_primitive(False)
        assert scene._goal[0].visible  # the goal stays when the current primitive is hidden
        scene.show_goal(None)
        assert scene._goal == [] and scene.goal is None
