"""``resolve_package_uri``: a URDF's mesh filenames (``package://``, ``file://``, relative) to files."""

from __future__ import annotations

import re
from importlib import metadata
from pathlib import Path

import pytest

from gagen.robots.urdf import resolve_package_uri


@pytest.fixture
def tree(tmp_path: Path) -> Path:
    """share/my_robot/{urdf/robot.urdf, meshes/base.stl} and share/other/meshes/arm.stl."""
    for name in ("my_robot/urdf/robot.urdf", "my_robot/meshes/base.stl", "other/meshes/arm.stl"):
        path = tmp_path / "share" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("x")
    return tmp_path / "share" / "my_robot" / "urdf" / "robot.urdf"


def test_package_uris_beside_the_urdf(tree):
    meshes = tree.parents[1]
    assert resolve_package_uri("package://my_robot/meshes/base.stl", tree) == meshes / "meshes" / "base.stl"
    assert resolve_package_uri("package:///my_robot/meshes/base.stl", tree) == meshes / "meshes" / "base.stl"
    # a sibling package in the same share folder
    arm = tree.parents[2] / "other" / "meshes" / "arm.stl"
    assert resolve_package_uri("package://other/meshes/arm.stl", tree) == arm
    assert resolve_package_uri("../meshes/base.stl", tree) is None  # '..' is not followed
    assert resolve_package_uri("package://my_robot/../other/meshes/arm.stl", tree) is None
    assert resolve_package_uri("package://my_robot/meshes/missing.stl", tree) is None
    assert resolve_package_uri("package://nowhere/meshes/base.stl", tree) is None


def test_ros_package_path_and_file_uris(tmp_path, tree, monkeypatch):
    elsewhere = tmp_path / "elsewhere" / "robot.urdf"
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tree.parents[2]))
    found = resolve_package_uri("package://my_robot/meshes/base.stl", elsewhere)
    assert found == tree.parents[1] / "meshes" / "base.stl"
    monkeypatch.delenv("ROS_PACKAGE_PATH")
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tree.parents[3]))
    assert resolve_package_uri("package://my_robot/meshes/base.stl", elsewhere) == found
    assert resolve_package_uri(f"file://{found}", elsewhere) == found
    assert resolve_package_uri("base.stl", found) == found  # relative to the URDF's folder
    assert resolve_package_uri("http://example.com/base.stl", tree) is None


def test_every_mesh_of_the_ur10_and_the_talos_resolves():
    """example-robot-data's files write package://example-robot-data/robots/… (and package:///…)."""
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed")
    files = {Path(str(dist.locate_file(f))).name: Path(str(dist.locate_file(f)))
             for f in dist.files or () if str(f).endswith(".urdf")}
    for name in ("ur10_robot.urdf", "talos_reduced.urdf"):
        uris = re.findall(r'filename="(package://[^"]+)"', files[name].read_text())
        assert uris and all(resolve_package_uri(u, files[name]) is not None for u in uris), name
