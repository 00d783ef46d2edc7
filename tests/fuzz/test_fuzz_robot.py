"""The fuzz tier for robot specs and their URDFs (issue 29): mutations of every bundled spec and URDF
(YAML fields replaced by hostile values and names, keys deleted or renamed, bytes flipped, NULs, lines
doubled; URDF joint types, parents, numbers and names replaced), and specs drawn from the schema
(explicit joints of random types, axes, offsets, mimics and names). Each case: a one-line SpecError
naming the spec or a URDF and a field, or a system whose forward kinematics (the interpreter, at zero
and a random configuration) is finite at every chain's end point."""

from __future__ import annotations

import math
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from gagen.algebra.signature import cga3d
from gagen.interp import MultiVector
from gagen.model.kinematics import end_point, forward_kinematics
from gagen.robots.spec import load_system

from .harness import HOSTILE_NAMES, all_finite, byte_mutation, examples, run_case, yaml_mutation

APP = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "cooperative" / "robots"
SPECS = sorted(APP.glob("*.yaml"))
XML_NUMBERS = ["nan", "inf", "-inf", "1e9", "1e400", "x", "", "0 0", "1 2 3 4", "1e-320 0 0", "0x10 0 0"]
JOINT_TYPES = ["floating", "planar", "fixed", "prismatic", "continuous", "revolute", "weird", ""]
ZERO = MultiVector.zero(cga3d())


def _evaluate(spec: Path):
    """Load the spec, then each chain's end point at zero and at a random configuration (the
    interpreter's forward kinematics)."""
    system, configurations = load_system(spec)
    rng = np.random.default_rng(0)
    points = []
    for chain in system.chains:
        for q in (np.zeros(chain.dof), rng.uniform(-math.pi, math.pi, chain.dof)):
            motor = forward_kinematics(ZERO, chain.joints, list(q))
            points.append([end_point(motor)[b] for b in ("e1", "e2", "e3")])
    return system, configurations, points


def _check(result) -> None:
    system, configurations, points = result
    assert system.dof > 0
    values = [v for chain in system.chains for j in chain.joints for v in (*j.xyz, *j.rpy, *j.axis)]
    values += [v for q in configurations.values() for v in q]
    assert all_finite(values), "a non-finite joint constant or configuration"
    assert all_finite(points), f"a non-finite end point: {points}"


def _urdf_mutation(draw, text: str) -> tuple[str, str | bytes]:
    kind = draw(st.sampled_from(["type", "parent", "redirect", "number", "name", "duplicate", "bytes"]))
    joints = list(re.finditer(r'<joint name="([^"]*)" type="([^"]*)"', text))
    joint = draw(st.sampled_from(joints))
    if kind == "type":
        new = draw(st.sampled_from(JOINT_TYPES))
        return f"{kind} {joint[1]}={new}", text[:joint.start(2)] + new + text[joint.end(2):]
    parents = list(re.finditer(r'<parent link="([^"]*)"\s*/>', text))
    if kind == "parent":
        p = draw(st.sampled_from(parents))
        return kind, text[:p.start()] + text[p.end():]
    if kind == "redirect":  # a joint's parent becomes another link: loops and links with two parents
        p = draw(st.sampled_from(parents))
        links = re.findall(r'<link name="([^"]*)"', text)
        return kind, text[:p.start(1)] + draw(st.sampled_from(links)) + text[p.end(1):]
    if kind == "number":
        numbers = list(re.finditer(r'(xyz|rpy|lower|upper)="([^"]*)"', text))
        n = draw(st.sampled_from(numbers))
        return f"{kind} {n[1]}", text[:n.start(2)] + draw(st.sampled_from(XML_NUMBERS)) + text[n.end(2):]
    if kind == "name":
        new = draw(st.sampled_from(HOSTILE_NAMES))
        new = new.replace("&", "&amp;").replace("<", "&lt;").replace('"', "&quot;")
        return f"{kind} {joint[1]}", text[:joint.start(1)] + new + text[joint.end(1):]
    if kind == "duplicate":
        end = text.index("</joint>", joint.start()) + len("</joint>")
        return f"{kind} {joint[1]}", text[:end] + text[joint.start():end] + text[end:]
    return draw(byte_mutation(text))


@examples(fast=60, full=300)
@given(st.data())
def test_mutated_bundled_specs_and_urdfs(data):
    spec_source = data.draw(st.sampled_from(SPECS), label="spec")
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder) / "robots"
        shutil.copytree(APP, root, ignore=shutil.ignore_patterns("*.stl", "*.dae", "*.obj", "*.STL"))
        spec = root / spec_source.name
        text = spec.read_text()
        urdfs = sorted({(spec.parent / u).resolve() for u in re.findall(r"urdf: (\S+)", text)})
        if urdfs and data.draw(st.booleans(), label="mutate the URDF"):
            target = data.draw(st.sampled_from(urdfs), label="urdf")
            what, mutated = _urdf_mutation(data.draw, target.read_text())
        else:
            target = spec
            what, mutated = data.draw(st.one_of(yaml_mutation(text), byte_mutation(text)), label="mutation")
        if isinstance(mutated, bytes):
            target.write_bytes(mutated)
        else:
            target.write_text(mutated, encoding="utf-8")
        run_case("robot spec + URDF", (spec, *urdfs), lambda: _evaluate(spec), _check,
                 what=f"{spec_source.name} {target.name}: {what}")


NUMBER = st.one_of(st.floats(-2, 2),
                   st.sampled_from([0.0, 1e-320, 1e308, float("nan"), float("inf"), 1e6, 2e6]))


@st.composite
def _joint(draw, i: int):
    joint: dict = {"name": draw(st.one_of(st.just(f"j{i}"), st.sampled_from(HOSTILE_NAMES)))}
    joint["type"] = draw(st.sampled_from(JOINT_TYPES))
    for key in ("axis", "xyz", "rpy"):
        if draw(st.booleans()):
            joint[key] = draw(st.lists(NUMBER, min_size=2, max_size=4))
    if i and draw(st.floats(0, 1)) < 0.15:
        joint["mimic"] = {"joint": draw(st.sampled_from([f"j{i - 1}", "j0", "nobody"])),
                          "multiplier": draw(NUMBER), "offset": draw(NUMBER)}
    return joint


def _invalid(chains: list[list[dict]], name: str) -> bool:
    """Certainly refused: a non-finite or huge number anywhere, or a system name no identifier."""
    def bad(v) -> bool:
        return isinstance(v, float) and (not math.isfinite(v) or abs(v) > 1e6)
    joints = [j for listed in chains for j in listed]
    numbers = [v for j in joints for key in ("axis", "xyz", "rpy") for v in j.get(key, [])]
    numbers += [j["mimic"][k] for j in joints if "mimic" in j for k in ("multiplier", "offset")]
    return any(bad(v) for v in numbers) or not re.fullmatch(r"[A-Za-z][A-Za-z0-9]*(_[A-Za-z0-9]+)*", name)


@examples(fast=60, full=300)
@given(st.data())
def test_specs_drawn_from_the_schema(data):
    import yaml

    kind, count = data.draw(st.sampled_from([("point", 1), ("point_pair", 2), ("line", 2), ("circle", 3)]))
    name = data.draw(st.one_of(st.just("drawn"), st.sampled_from(HOSTILE_NAMES)), label="name")
    chains = [[data.draw(_joint(i)) for i in range(data.draw(st.integers(0, 6)))] for _ in range(count)]
    document = {"name": name, "primitive": kind,
                "chains": [{"name": f"arm{k}", "joints": joints} for k, joints in enumerate(chains)]}
    with tempfile.TemporaryDirectory() as folder:
        spec = Path(folder) / "drawn.yaml"
        spec.write_text(yaml.safe_dump(document, allow_unicode=True))
        run_case("robot spec + URDF", (spec,), lambda: _evaluate(spec), _check,
                 must_refuse=_invalid(chains, name), what=f"drawn {document}"[:400])
