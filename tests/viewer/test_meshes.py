"""The viewer draws the robots' URDF visuals: boxes, cylinders, spheres and meshes (an ASCII STL found by a
relative path and by ``package://``), each at its link's pose along the chain; a missing mesh is a warning
and a stick, never a crash; a URDF without visuals stays sticks. In a real browser (headless Chromium),
the mesh render differs from the stick render where the robot is, and shows the URDF's material colour."""

import os
import textwrap

import numpy as np
import pytest

from gagen.robots.spec import load_system
from gagen.viewer.browser import find_chromium
from gagen.viewer.geometry import system_pose
from gagen.viewer.visuals import chain_joint_values, load_visuals, resolve_mesh_path

BLUE = (0.1, 0.3, 0.9)  # link1's material: a colour no stick has


def _box_stl(sx: float, sy: float, sz: float) -> str:
    """An ASCII STL of a box sx × sy × sz standing on z = 0, centred on the z axis."""
    x, y = sx / 2, sy / 2
    v = np.array([[-x, -y, 0], [x, -y, 0], [x, y, 0], [-x, y, 0],
                  [-x, -y, sz], [x, -y, sz], [x, y, sz], [-x, y, sz]])
    faces = [(0, 2, 1), (0, 3, 2), (4, 5, 6), (4, 6, 7), (0, 1, 5), (0, 5, 4),
             (1, 2, 6), (1, 6, 5), (2, 3, 7), (2, 7, 6), (3, 0, 4), (3, 4, 7)]
    lines = ["solid box"]
    for f in faces:
        a, b, c = v[list(f)]
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n)
        lines += [f"  facet normal {n[0]:g} {n[1]:g} {n[2]:g}", "    outer loop",
                  *(f"      vertex {p[0]:g} {p[1]:g} {p[2]:g}" for p in (a, b, c)),
                  "    endloop", "  endfacet"]
    return "\n".join([*lines, "endsolid box", ""])


def _urdf(visuals: bool, mesh: str = "../meshes/link.stl") -> str:
    def visual(xml: str) -> str:
        return xml if visuals else ""

    return textwrap.dedent(f"""\
        <?xml version="1.0"?>
        <robot name="testbot">
          <material name="blue"><color rgba="{BLUE[0]} {BLUE[1]} {BLUE[2]} 1"/></material>
          <link name="base_link">{visual('''
            <visual><origin xyz="0 0 0.05"/><geometry><box size="0.25 0.25 0.1"/></geometry></visual>''')}
          </link>
          <link name="link1">{visual('''
            <visual><origin xyz="0 0 0.15"/><geometry><cylinder radius="0.05" length="0.3"/></geometry>
              <material name="blue"/></visual>''')}
          </link>
          <link name="link2">{visual(f'''
            <visual><geometry><mesh filename="{mesh}"/></geometry></visual>''')}
          </link>
          <link name="link3">{visual('''
            <visual><geometry><sphere radius="0.06"/></geometry></visual>
            <visual><origin xyz="0 0 0.02"/>
              <geometry><mesh filename="package://testbot/meshes/link.stl" scale="0.5 0.5 0.5"/></geometry>
            </visual>''')}
          </link>
          <link name="hand">{visual('''
            <visual><origin xyz="0 0 0.03"/><geometry><box size="0.04 0.16 0.06"/></geometry></visual>''')}
          </link>
          <joint name="j1" type="revolute"><parent link="base_link"/><child link="link1"/>
            <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
            <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
          <joint name="j2" type="revolute"><parent link="link1"/><child link="link2"/>
            <origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>
            <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
          <joint name="j3" type="revolute"><parent link="link2"/><child link="link3"/>
            <origin xyz="0 0 0.3" rpy="0 0 0.3"/><axis xyz="0 1 0"/>
            <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
          <joint name="hand_joint" type="fixed"><parent link="link3"/><child link="hand"/>
            <origin xyz="0 0 0.08"/></joint>
        </robot>
        """)


SPEC = """\
name: testbots
primitive: point_pair
chains:
  - name: left
    urdf: testbot/urdf/testbot.urdf
    base_link: base_link
    tip_link: link3
    base: {xyz: [0, -0.35, 0], rpy: [0, 0, 0.5]}
    tool: {xyz: [0, 0, 0.1]}
  - name: right
    urdf: testbot/urdf/testbot.urdf
    base_link: base_link
    tip_link: link3
    base: {xyz: [0, 0.35, 0], rpy: [0, 0, -0.5]}
    tool: {xyz: [0, 0, 0.1]}
configurations:
  ready: [0.4, 0.5, 0.7, -0.4, 0.6, 0.5]
goals:
  apart: {point_pair: {first: [0.3, -0.5, 0.5], second: [0.3, 0.5, 0.5]}}
"""


def write_robot(folder, *, visuals=True, mesh="../meshes/link.stl", stl=True):
    """The test robot's spec (two arms of the URDF above), its URDF and mesh under ``folder``."""
    (folder / "testbot" / "urdf").mkdir(parents=True)
    (folder / "testbot" / "meshes").mkdir()
    (folder / "testbot" / "urdf" / "testbot.urdf").write_text(_urdf(visuals, mesh))
    if stl:
        (folder / "testbot" / "meshes" / "link.stl").write_text(_box_stl(0.08, 0.08, 0.3))
    spec = folder / "testbots.yaml"
    spec.write_text(SPEC)
    return spec


def test_visuals_are_read_and_placed_at_their_links(tmp_path):
    spec = write_robot(tmp_path)
    system, named = load_system(spec)
    warnings = []
    visuals = load_visuals(spec, system, warn=warnings.append)
    assert warnings == []
    left = visuals[0]
    assert left is not None and visuals[1] is not None
    assert list(left.links) == ["base_link", "link1", "link2", "link3", "hand"]  # the hand hangs rigidly
    assert [v.kind for v in left.links["link3"]] == ["sphere", "mesh"]
    assert left.links["link1"][0].colour == tuple(round(255 * c) for c in BLUE)
    mesh = left.links["link2"][0]
    assert mesh.faces.shape == (12, 3)
    np.testing.assert_allclose(np.ptp(mesh.vertices, axis=0), [0.08, 0.08, 0.3])
    np.testing.assert_allclose(np.ptp(left.links["link3"][1].vertices, axis=0), [0.04, 0.04, 0.15])  # scaled
    assert left.missing == frozenset()
    # each link where the chain's FK puts its joint frames: link3 at the end frame less the tool offset
    q = np.array(named["ready"])
    values = chain_joint_values(system, q)
    for c, pose in enumerate(system_pose(system, q)):
        frames = visuals[c].link_frames(values[c])
        end = pose.frames[-1]
        np.testing.assert_allclose(frames["link3"][:3, :3], end[:3, :3], atol=1e-12)
        np.testing.assert_allclose(frames["link3"][:3, 3], end[:3, 3] - end[:3, :3] @ [0, 0, 0.1], atol=1e-12)
        np.testing.assert_allclose(frames["base_link"][:3, 3], pose.origins[0], atol=1e-12)  # base placement
        link3 = frames["link3"]
        np.testing.assert_allclose(frames["hand"][:3, 3], link3[:3, 3] + link3[:3, 2] * 0.08, atol=1e-12)
    # every joint's stick belongs to a link drawn from its visuals: the base, j1..j3, the tool
    assert left.sticks == ("base_link", "link1", "link2", "link3", "link3")


def test_package_and_relative_mesh_paths(tmp_path, monkeypatch):
    write_robot(tmp_path)
    urdf = tmp_path / "testbot" / "urdf" / "testbot.urdf"
    stl = (tmp_path / "testbot" / "meshes" / "link.stl").resolve()
    assert resolve_mesh_path("../meshes/link.stl", urdf) == stl
    assert resolve_mesh_path("package://testbot/meshes/link.stl", urdf) == stl
    assert resolve_mesh_path(f"file://{stl}", urdf) == stl
    assert resolve_mesh_path("package://otherbot/meshes/link.stl", urdf) is None
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path))  # a package found beside, through the path
    (tmp_path / "otherbot").symlink_to(tmp_path / "testbot")
    assert resolve_mesh_path("package://otherbot/meshes/link.stl", urdf) is not None


def test_a_collada_mesh_keeps_its_own_colour(tmp_path):
    """A DAE (as most robot descriptions ship) read by trimesh; without a URDF material, the file's colour."""
    pytest.importorskip("collada")  # trimesh's DAE reader
    import trimesh

    spec = write_robot(tmp_path, mesh="package://testbot/meshes/link.dae")
    box = trimesh.creation.box((0.1, 0.1, 0.3))
    box.visual.face_colors = [200, 40, 30, 255]
    box.export(str(tmp_path / "testbot" / "meshes" / "link.dae"))
    warnings = []
    visuals = load_visuals(spec, load_system(spec)[0], warn=warnings.append)
    assert warnings == []
    (mesh,) = visuals[0].links["link2"]
    assert mesh.kind == "mesh" and mesh.colour == (200, 40, 30)
    np.testing.assert_allclose(np.ptp(mesh.vertices, axis=0), [0.1, 0.1, 0.3], rtol=1e-6)


def test_a_missing_mesh_is_a_warning_and_a_stick(tmp_path):
    (tmp_path / "first").mkdir()
    spec = write_robot(tmp_path / "first", mesh="../meshes/gone.stl")
    system, _ = load_system(spec)
    warnings = []
    visuals = load_visuals(spec, system, warn=warnings.append)
    assert len(warnings) == 2 and all("gone.stl" in w and "stick" in w and "\n" not in w for w in warnings)
    assert visuals[0].missing == {"link2"}
    assert not visuals[0].covered("link2") and visuals[0].covered("link3")
    # and without the STL at all: link3's sphere is still drawn, with the stick
    other = tmp_path / "bare"
    other.mkdir()
    spec = write_robot(other, stl=False)
    warnings.clear()
    visuals = load_visuals(spec, *load_system(spec)[:1], warn=warnings.append)
    assert visuals[0].missing == {"link2", "link3"} and len(warnings) == 4
    assert [v.kind for v in visuals[0].links["link3"]] == ["sphere"]


def test_a_urdf_without_visuals_and_bundled_systems_are_sticks(tmp_path):
    spec = write_robot(tmp_path, visuals=False)
    system, _ = load_system(spec)
    warnings = []
    assert load_visuals(spec, system, warn=warnings.append) == [None, None]
    assert warnings == []
    from gagen.registry import resolve_spec

    panda = resolve_spec("two_pandas_point_pair", "cooperative", "system")
    assert load_visuals(panda, load_system(panda)[0], warn=warnings.append) == [None, None]


def test_the_scene_draws_visuals_instead_of_sticks(tmp_path):
    pytest.importorskip("viser")
    from gagen.viewer.scene import Scene

    spec = write_robot(tmp_path, mesh="../meshes/gone.stl")
    system, named = load_system(spec)
    visuals = load_visuals(spec, system, warn=lambda _: None)
    q = np.array(named["ready"])
    with Scene(system, q, port=0, visuals=visuals) as scene:
        assert [(c, link) for c, link, _ in scene._bodies] == \
            [(c, link) for c in (0, 1) for link in ("base_link", "link1", "link3", "hand")]  # link2: no mesh
        # sticks only for link2, whose mesh is missing (joint index 2: j2's stick)
        assert sorted({i for _, i, _ in scene._links}) == [2]
        q2 = q + 0.3
        scene.update(q2)
        values = chain_joint_values(system, q2)
        for c, link, handle in scene._bodies:
            pose = visuals[c].link_frames(values[c])[link]
            np.testing.assert_allclose(handle.position, pose[:3, 3], atol=1e-6)
        # the camera frames the visuals: the base boxes' corners are among its points
        assert np.min(scene.points()[:, 2]) == pytest.approx(0.0, abs=1e-9)
    with Scene(system, q, port=0) as sticks:
        assert sticks._bodies == [] and len({i for _, i, _ in sticks._links}) >= 3
    with pytest.raises(ValueError, match="one entry"):
        Scene(system, q, port=0, visuals=visuals[:1])


def test_no_meshes_flag():
    import argparse

    from gagen.viewer.command import add_arguments

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert parser.parse_args(["x", "--no-meshes"]).no_meshes is True
    assert parser.parse_args(["x"]).no_meshes is False


def _example_robot_data():
    """The robots folder of example-robot-data where it is installed (Pinocchio's wheels bring it)."""
    import sys
    from pathlib import Path

    for entry in sys.path:
        folder = Path(entry) / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if folder.is_dir():
            return folder
    pytest.skip("example-robot-data is not installed (it comes with the dynamics extra's Pinocchio)")


@pytest.mark.slow  # reads 9 Collada meshes: 2 s
def test_a_real_robot_description_with_package_meshes(tmp_path):
    """example-robot-data's Panda: its links' Collada meshes named by package://example-robot-data/…,
    every link on the chain and the hand fixed on the flange drawn from them, where the FK puts them."""
    robots = _example_robot_data()
    spec = tmp_path / "panda.yaml"
    spec.write_text(textwrap.dedent(f"""\
        name: erd_panda
        primitive: point
        chains:
          - name: arm
            urdf: {robots / "panda_description" / "urdf" / "panda.urdf"}
            base_link: panda_link0
            tip_link: panda_link8
            base: {{xyz: [0.2, 0, 0]}}
        configurations:
          ready: [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]
        """))
    system, named = load_system(spec)
    warnings = []
    (arm,) = load_visuals(spec, system, warn=warnings.append)
    assert warnings == []
    assert list(arm.links) == [f"panda_link{i}" for i in range(8)] + ["panda_hand"]
    assert all(v.kind == "mesh" and len(v.faces) > 100 for vs in arm.links.values() for v in vs)
    assert arm.missing == frozenset()
    q = np.array(named["ready"])
    (pose,) = system_pose(system, q)
    hand = arm.link_frames(chain_joint_values(system, q)[0])["panda_hand"]
    np.testing.assert_allclose(hand[:3, 3], pose.end_point, atol=1e-12)  # the hand sits on link8's origin


# -- in a real browser ---------------------------------------------------------------------------------
WIDTH, HEIGHT = 640, 480


def _browser():
    pytest.importorskip("viser")
    if find_chromium() is None:
        if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
            pytest.fail("no Chromium on PATH: CI must run the browser tests")
        pytest.skip("no Chromium on PATH: apt-get install chromium, or set GAGEN_CHROMIUM")


def _blue(image):
    r, g, b, a = (image[..., k].astype(int) for k in range(4))
    return (a > 128) & (b - r > 60) & (b - g > 30)


def _joint_orange(image):
    r, g, b, a = (image[..., k].astype(int) for k in range(4))
    return (a > 128) & (r > 140) & (r - b > 90) & (g > 50) & (r - g > 40)


@pytest.mark.slow  # two browser starts and software rendering: 10-40 s
def test_the_mesh_render_differs_from_the_stick_render(tmp_path):
    _browser()
    from gagen.viewer.browser import render
    from gagen.viewer.scene import Scene

    spec = write_robot(tmp_path)
    system, named = load_system(spec)
    q = np.array(named["ready"])
    visuals = load_visuals(spec, system)
    with Scene(system, q, port=0, visuals=visuals, frames="none") as scene:
        scene.show_primitive(False)
        camera = scene.default_camera(WIDTH / HEIGHT)
        robot = camera.project(scene.points(), WIDTH, HEIGHT)
        meshes = render(scene, width=WIDTH, height=HEIGHT, camera=camera, timeout=90)
    with Scene(system, q, port=0, frames="none") as scene:
        scene.show_primitive(False)
        sticks = render(scene, width=WIDTH, height=HEIGHT, camera=camera, timeout=90)
    # the region of the robots: the bounding box of every drawn point and visual corner, projected
    (u0, v0), (u1, v1) = np.floor(np.nanmin(robot, axis=0)), np.ceil(np.nanmax(robot, axis=0))
    u0, v0, u1, v1 = (int(np.clip(x, 0, m))
                      for x, m in ((u0, WIDTH), (v0, HEIGHT), (u1, WIDTH), (v1, HEIGHT)))
    region = (slice(v0, v1), slice(u0, u1))
    difference = np.abs(meshes[region].astype(int) - sticks[region].astype(int)).max(axis=2) > 40
    changed = float(difference.mean())
    print(f"pixels changed in the robots' region ({u1 - u0}x{v1 - v0}): {changed:.1%}; blue pixels: "
          f"meshes {int(_blue(meshes).sum())}, sticks {int(_blue(sticks).sum())}; orange joints: meshes "
          f"{int(_joint_orange(meshes).sum())}, sticks {int(_joint_orange(sticks).sum())}")
    assert changed > 0.10, f"only {changed:.1%} of the robots' region differs between meshes and sticks"
    assert int(_blue(meshes).sum()) > 300 and int(_blue(sticks).sum()) == 0  # link1's blue cylinder
    assert int(_joint_orange(sticks).sum()) > 50 and int(_joint_orange(meshes).sum()) == 0


@pytest.mark.slow  # a browser start
def test_a_urdf_without_visuals_renders_sticks(tmp_path):
    _browser()
    import cv2

    from gagen.viewer.command import main

    spec = write_robot(tmp_path, visuals=False)
    path = tmp_path / "sticks.png"
    assert main([str(spec), "--png", str(path), "--size", f"{WIDTH}x{HEIGHT}", "--no-primitive",
                 "--goal", "apart"]) == 0
    image = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)
    rgba = np.dstack([image, np.full(image.shape[:2], 255, np.uint8)])
    assert int(_joint_orange(rgba).sum()) > 50  # the joints' balls: a stick figure
    r, g, b = (image[..., k].astype(int) for k in range(3))
    cyan = (b > 140) & (g > 110) & (r < 80)  # the goal's segment (GOAL_COLOUR), drawn with --goal
    assert int(cyan.sum()) > 40, f"{int(cyan.sum())} pixels of the goal's colour"
