"""Resource limits (issue 29): a robot too large for the limits of gagen.limits is refused in one line
naming the file, the field and the environment variable that raises the limit, before any costly work;
the override admits it; every real robot (a 60-joint humanoid chain) is inside the defaults."""

from __future__ import annotations

import time

import pytest

from gagen.errors import SpecError
from gagen.limits import LIMITS, check_limit, limit
from gagen.robots.spec import load_system


def _urdf(n: int) -> str:
    """A serial chain of ``n`` revolute joints, link0 … link<n>."""
    links = "".join(f'<link name="link{i}"/>' for i in range(n + 1))
    joints = "".join(f'<joint name="j{i}" type="revolute"><parent link="link{i}"/><child link="link{i + 1}"/>'
                     f'<origin xyz="0 0 0.01" rpy="0 0 0"/><axis xyz="0 0 1"/>'
                     f'<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>' for i in range(n))
    return f'<robot name="snake">{links}{joints}</robot>'


def _spec(tmp_path, n: int) -> object:
    (tmp_path / "snake.urdf").write_text(_urdf(n))
    spec = tmp_path / "snake.yaml"
    spec.write_text(f"name: snake\nprimitive: point\nchains:\n  - name: arm\n    urdf: snake.urdf\n"
                    f"    base_link: link0\n    tip_link: link{n}\n")
    return spec


def _explicit(tmp_path, n: int) -> object:
    joints = "".join(f"      - {{name: j{i}, type: revolute, axis: [0, 0, 1], xyz: [0, 0, 0.01]}}\n"
                     for i in range(n))
    spec = tmp_path / "listed.yaml"
    spec.write_text(f"name: listed\nprimitive: point\nchains:\n  - name: arm\n    joints:\n{joints}")
    return spec


def test_a_thousand_joint_urdf_chain_is_refused_in_one_line_and_quickly(tmp_path):
    spec = _spec(tmp_path, 1000)
    start = time.perf_counter()
    with pytest.raises(SpecError) as e:
        load_system(spec)
    assert time.perf_counter() - start < 10  # it ran past 120 s at 1.1 GB before the limit
    assert e.value.file == str(spec) and e.value.field.startswith("chains[0].tip_link")
    text = str(e.value)
    assert "\n" not in text and "1000 joints in one chain" in text and "GAGEN_LIMIT_JOINTS_PER_CHAIN" in text


def test_a_listed_chain_over_the_limit_is_refused(tmp_path):
    spec = _explicit(tmp_path, limit("joints_per_chain") + 1)
    with pytest.raises(SpecError) as e:
        load_system(spec)
    assert e.value.field.startswith("chains[0].joints") and "over the limit of 100" in e.value.message


def test_the_environment_raises_a_limit(tmp_path, monkeypatch):
    spec = _explicit(tmp_path, 120)
    with pytest.raises(SpecError):
        load_system(spec)
    monkeypatch.setenv("GAGEN_LIMIT_JOINTS_PER_CHAIN", "150")
    system, _ = load_system(spec)
    assert system.dof == 120
    monkeypatch.setenv("GAGEN_LIMIT_JOINTS_PER_CHAIN", "110")
    with pytest.raises(SpecError, match="120 joints in one chain, over the limit of 110"):
        load_system(spec)


def test_a_sixty_joint_humanoid_chain_is_inside_the_defaults(tmp_path):
    system, _ = load_system(_spec(tmp_path, 60))
    assert system.dof == 60


@pytest.mark.parametrize("text", ["0", "-3", "many", "1.5"])
def test_a_bad_override_is_one_line_naming_the_variable(monkeypatch, text):
    monkeypatch.setenv("GAGEN_LIMIT_CHAINS", text)
    with pytest.raises(ValueError) as e:
        limit("chains")
    message = str(e.value)
    assert "\n" not in message and message.startswith("GAGEN_LIMIT_CHAINS=") and "positive" in message


def test_every_limit_is_checked_by_name():
    for name, entry in LIMITS.items():
        assert limit(name) == entry.default
        check_limit(name, entry.default, "f", "x")  # the limit itself is allowed
        with pytest.raises(SpecError, match=entry.variable):
            check_limit(name, entry.default + 1, "f", "x")


def test_the_docs_table_lists_every_limit_with_its_default_and_variable():
    from pathlib import Path

    page = (Path(__file__).resolve().parents[2] / "docs" / "limits.md").read_text()
    rows = {cells[0].strip("` "): (int(cells[1]), cells[3].strip("` "))
            for line in page.splitlines() if line.startswith("| `")
            for cells in [[c.strip() for c in line.strip("|").split("|")]]}
    assert rows == {name: (entry.default, entry.variable) for name, entry in LIMITS.items()}
