"""``gagen build --check``: relative tolerances, step-adapted differences, samples within the joint
limits and at every named configuration, failures named by kernel, output, path and sample."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from conftest import bundled_module, tiered

import gagen.check as check
from gagen.apps.cooperative.catalogue import kernel_functions
from gagen.apps.cooperative.check import check_module
from gagen.model.kinematics import Joint
from gagen.robots.spec import load_system
from gagen.robots.system import Chain, System

ROOT = Path(__file__).resolve().parents[2]
# a LEAP hand configuration drawn uniformly within the URDF limits (seed 1): its sphere is small and
# its J_B reaches ~1e3, where plain central differences (h = 1e-6) miss the correct kernel by 7e-4
# absolute, and even Richardson at h = 1e-3 by 2e-3 relative (the function turns on a smaller scale)
WIDE_LEAP = [1.2722, 0.5794, 0.9597, 1.8429, -0.2133, 0.0599, 0.5923, -0.2159, 1.3175, 0.7384, 0.9117,
             0.2603, 1.7028, 1.0142, 0.3838, 1.0848]


class _Planted:
    """A generated module whose C kernel ``kernel`` returns output ``index`` scaled by ``factor`` on
    one path ("single" or "batch"), and which records every q the kernels are called with."""

    def __init__(self, module, kernel: str, index: int, factor: float, path: str) -> None:
        self.manifest, self.casadi, self.seen = module.manifest, module.casadi, []
        planted, seen = (kernel, index, factor, path), self.seen

        class _C:
            def __getattr__(self, name):
                real = getattr(module.c, name)

                def scaled(out, on):
                    out = tuple(np.array(o, dtype=float) for o in (out if isinstance(out, tuple) else (out,)))
                    if (name, on) == (planted[0], planted[3]):
                        out[planted[1]][...] *= planted[2]
                    return out

                def single(*inputs):
                    seen.append(np.array(inputs[0], dtype=float))
                    return scaled(real(*inputs), "single")

                single.batch = lambda *inputs: scaled(real.batch(*inputs), "batch")
                return single

        self.c = _C()


@pytest.fixture(scope="module")
def panda():
    system, configurations = load_system(ROOT / "robots/panda_point.yaml")
    return system, configurations, bundled_module("panda_point")


PLANTED = [
    ("arm0_fk_jacobian", "J_S", 1 + 1e-7, "single", check.INTERPRETER),
    ("arm0_fk", "P", 1.01, "batch", check.INTERPRETER),
    ("similarity", "J_G", 1 + 1e-5, "batch", check.DIFFERENCES),
]


@pytest.mark.parametrize(("kernel", "output", "factor", "path", "reference"), tiered(PLANTED, PLANTED[:1]))
def test_a_planted_error_is_caught_and_named(panda, kernel, output, factor, path, reference):
    system, configurations, module = panda
    index = [p["name"] for p in next(k for k in module.manifest["kernels"] if k["name"] == kernel)["outputs"]]
    planted = _Planted(module, kernel, index.index(output), factor, path)
    report = check_module(planted, system, configurations, count=2)
    failed = check.failures(report)
    assert [(d.kernel, d.output) for d in failed] == [(kernel, output)]
    d = failed[0]
    assert d.reference == reference
    assert d.worst == pytest.approx(factor - 1, rel=0.05)  # relative to the output's magnitude
    assert d.path == {"single": "C single", "batch": "C batched"}[path]
    message = d.message()
    for part in (kernel, output, d.path, d.sample, f"{d.worst:.2e}"):
        assert part in message


@pytest.mark.slow
def test_the_cli_check_names_the_failing_kernel_and_reports_progress(panda, monkeypatch, capsys):
    from gagen.apps.cooperative.check import check_spec

    module = panda[2]
    planted = _Planted(module, "arm0_fk", 1, 1 + 1e-6, "single")
    monkeypatch.setattr("gagen.apps.cooperative.check.load", lambda folder: planted)
    assert check_spec(str(ROOT / "robots/panda_point.yaml"), "unused", 1, 1e-10) == 1
    out, err = capsys.readouterr()
    kernels = [k["name"] for k in module.manifest["kernels"]]
    progress = [line for line in out.splitlines() if "worst relative error" in line]
    assert len(progress) == len(kernels)
    for line, name in zip(progress, kernels, strict=True):
        assert f"] {name}: " in line
    assert "arm0_fk: worst relative error" in out and "FAILED" in progress[0]
    assert "kernel arm0_fk, output P: relative error" in err
    assert "C single" in err


@pytest.mark.compiling
@pytest.mark.slow
def test_correct_leap_jacobians_pass_with_relative_step_adapted_differences():
    system, _ = load_system(ROOT / "robots/leap_hand_sphere.yaml")
    module = bundled_module("leap_hand_sphere")
    q = np.array(WIDE_LEAP)
    # the old criterion: plain central differences (h = 1e-6) within 1e-6 absolute: fails this kernel
    entry = next(k for k in module.manifest["kernels"] if k["name"] == "similarity_jacobians")
    rows = next(p["rows"] for p in entry["outputs"] if p["name"] == "J_B")
    function = kernel_functions(system)["similarity_jacobians"]
    ports = [check._Entry(p) for p in entry["inputs"]]

    def log_v(x):
        value = function.values([x], ports)["log_V"]
        return np.array([value[b] for b in rows])

    steps = np.eye(q.size) * 1e-6
    plain = np.array([(log_v(q + h) - log_v(q - h)) / 2e-6 for h in steps]).T
    kernel_jb = np.asarray(module.c.similarity_jacobians(q)[2]).reshape(plain.shape)
    assert np.max(np.abs(plain - kernel_jb)) > 1e-6
    # the new one: every output within its relative tolerance, the differences well inside theirs
    report = check_module(module, system, {"wide": WIDE_LEAP}, count=0)
    assert check.failures(report) == []
    assert max(d.worst for d in report if d.reference == check.DIFFERENCES) < 1e-8


def _urdf_limits(path: Path) -> dict[str, tuple[float, float]]:
    """(lower, upper) of each revolute/prismatic joint, read straight from the XML."""
    out = {}
    for joint in ET.parse(path).getroot().iter("joint"):
        limit = joint.find("limit")
        if joint.get("type") in ("revolute", "prismatic") and limit is not None:
            out[joint.get("name")] = (float(limit.get("lower")), float(limit.get("upper")))
    return out


def test_samples_lie_within_the_urdf_limits_and_start_with_every_named_configuration():
    system, _ = load_system(ROOT / "robots/leap_hand_sphere.yaml")
    lower, upper, _ = check.joint_limits(system)
    expected = _urdf_limits(ROOT / "robots/leap_hand/leap_hand.urdf")
    assert list(zip(lower, upper, strict=True)) == [expected[j] for _, j in system.joint_keys]
    named = {"first": np.clip(np.full(system.dof, 0.1), lower, upper), "second": np.array(WIDE_LEAP)}
    drawn = check.samples(system, named, count=40, seed=3)
    assert [s.label for s in drawn[:2]] == ["first", "second"]
    np.testing.assert_array_equal(drawn[0].q, named["first"])
    np.testing.assert_array_equal(drawn[1].q, named["second"])
    for sample in drawn[2:]:
        assert np.all(sample.q >= lower) and np.all(sample.q <= upper), sample
        centre = named[sample.label.split("~")[0]]
        assert np.all(np.abs(sample.q - centre) <= check.ANGLE_SPREAD + 1e-12)
    assert {s.label.split("~")[0] for s in drawn[2:]} == {"first", "second"}


def test_prismatic_joints_are_sampled_in_metres_within_their_limits():
    slide = Joint("slide", "prismatic", axis=(1.0, 0.0, 0.0), limits=(0.0, 0.02))
    turn = Joint("turn", "revolute", limits=(-0.1, 0.1))
    system = System("s", "point", (Chain("c", (slide, turn)),))
    drawn = check.samples(system, {"home": [0.01, 0.0]}, count=200, seed=0)
    q = np.array([s.q for s in drawn[1:]])
    assert q[:, 0].min() >= 0 and q[:, 0].max() <= 0.02 and np.ptp(q[:, 0]) > 0.015  # metres, not ±0.4
    assert q[:, 1].min() >= -0.1 and q[:, 1].max() <= 0.1
    free = System("f", "point", (Chain("c", (Joint("slide", "prismatic", axis=(1.0, 0.0, 0.0)),)),))
    q = np.array([s.q for s in check.samples(free, None, count=100, seed=0)])
    assert np.max(np.abs(q)) <= check.SPREAD["prismatic"]


@pytest.mark.slow
def test_every_named_configuration_is_checked(panda):
    system, _, module = panda
    named = {"ready": [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785],
             "stretched": [0.3, 0.2, -0.1, -1.0, 0.2, 1.2, 0.0],
             "folded": [-0.5, -1.2, 0.4, -2.8, -0.3, 2.5, 1.0]}
    recorder = _Planted(module, "none", 0, 1.0, "single")
    report = check_module(recorder, system, named, count=1)
    assert check.failures(report) == []
    for q in named.values():
        assert sum(np.array_equal(seen, q) for seen in recorder.seen) == len(module.manifest["kernels"])
