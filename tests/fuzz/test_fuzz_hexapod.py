"""Fuzz tier (issue 29): hexapod specs. A mutated copy of the bundled hexapod, and a hexapod built from
random legs (lengths, mounts, axes, limits, hostile names), is refused in one line naming the file and a
field, or loaded and its legs' kinematics evaluated on the interpreter (FK at a few configurations,
the analytic IK at reachable, far and non-finite targets, a DLS step where the analytic IK does not
apply; no C compiler) to finite numbers."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from gagen.apps.hexapod.bundled import SPEC
from gagen.apps.hexapod.kernels import analytic
from gagen.apps.hexapod.legs import analytic_ik, dls_step, leg_kinematics
from gagen.apps.hexapod.spec import BODY_KERNELS, LEG_KERNEL_SUFFIXES, MIN_LENGTH, Hexapod, Leg, load_hexapod
from gagen.interp import MultiVector, preset
from gagen.limits import limit
from gagen.model.euclidean import GEOMETRIES
from gagen.names import identifier_problem

from .harness import HOSTILE_NAMES, HOSTILE_VALUES, all_finite, examples, mutated_file, run_case, run_document

BUNDLED = SPEC.read_text()  # the bundled spec refers to no other file (its URDF is written from it)
PGA = GEOMETRIES["pga3d"]
MOTOR = ("1", "e12", "e01")  # a few of the FK motor's coefficients
FAR_TARGETS = ([float("nan"), 0.0, 0.0], [float("inf"), -float("inf"), 1.0], [1e308, 1e308, -1e308],
               [0.0, 0.0, 0.0], [5.0, -3.0, 2.0])


def _off(leg: Leg, toe: list[float], q: list[float]) -> float:
    """How far the FK toe of q is from ``toe`` (largest coordinate)."""
    like = MultiVector.zero(preset("pga3d"))
    return max(map(abs, np.subtract(toe, leg_kinematics(PGA, like, leg, q)["p"])))


def kinematics(hexapod: Hexapod) -> dict[str, Any]:
    """Every leg's FK at its limits' midpoint and corners, the analytic IK at the FK toes and at far and
    non-finite targets (or one DLS step towards the toe where the analytic IK does not apply)."""
    like = MultiVector.zero(preset("pga3d"))
    out: dict[str, Any] = {}
    for leg in hexapod.legs:
        lo, hi = np.array(leg.limits).T
        configurations = [(lo + hi) / 2, lo, hi]
        fk = [leg_kinematics(PGA, like, leg, [float(v) for v in q]) for q in configurations]
        toes = [list(map(float, kin["p"])) for kin in fk]
        out[f"{leg.name} fk"] = [[kin["p"], kin["J"], kin["S"], [kin["motor"][b] for b in MOTOR]]
                                 for kin in fk]
        if analytic(leg):
            solved = [analytic_ik(PGA, like, leg, t) for t in [*toes, *FAR_TARGETS]]
            out[f"{leg.name} ik"] = solved
            # the toes are reached: both branches' FK toes on them, relative to the leg's size
            scale = 1 + max(map(abs, leg.xyz)) + sum(leg.lengths)
            out[f"{leg.name} ik toes"] = [[s["reach"], _off(leg, toe, s["q_up"]) / scale,
                                           _off(leg, toe, s["q_down"]) / scale]
                                          for toe, s in zip(toes, solved[:3], strict=True)]
        else:
            out[f"{leg.name} dls"] = dls_step(PGA, like, leg, [float(v) for v in configurations[0]], toes[1],
                                              0.01)
    return out


def check(result: dict[str, Any]) -> None:
    bad = [key for key, value in result.items() if not all_finite(value)]
    assert not bad, f"non-finite kinematics of {bad}"
    for key, value in result.items():
        if key.endswith(" ik"):
            assert all(s["reach"] in (0.0, 1.0) and s["excess"] >= 0 for s in value), key
            assert [s["reach"] for s in value[-len(FAR_TARGETS):-2]] == [0.0, 0.0, 0.0], key  # non-finite
        if key.endswith(" ik toes"):  # reach 1, FK of either branch within 1e-9 of the leg's size
            assert all(reach == 1 and up <= 1e-9 and down <= 1e-9 for reach, up, down in value), (key, value)


def solve(path: Path) -> dict[str, Any]:
    return kinematics(load_hexapod(path))


@examples(fast=40, full=250)
@given(st.data())
def test_mutated_bundled_hexapod(data):
    with tempfile.TemporaryDirectory() as folder:
        what, path = mutated_file(data.draw, BUNDLED, Path(folder), "hexapod.yaml")
        run_case("hexapod", (path,), lambda: solve(path), check, what=what)


# -- schema level: six (or some other number of) legs from random lengths, mounts, axes, limits, names --

VALID = ["front_left", "middle_left", "rear_left", "rear_right", "middle_right", "front_right", "leg1", "L"]
# the values a valid spec may take, extremes included (a micron, 100 m links; mounts 1e6 m away, turned
# by 1000 rad; limits ±1000 rad), and those it may not
EXTREMES = [1e-6, 1e-3, 99.0, 100.0]
TINY = [1e-300, 1e-12]  # refused: under a micron


@st.composite
def three_lengths(draw) -> list[float]:
    """l1, l2, l3: mostly a few cm to dm, some extreme (one in ten all three alike: 2 l2 l3 may underflow)."""
    if draw(st.integers(0, 9)) == 0:
        return [draw(st.sampled_from(EXTREMES + TINY))] * 3
    return [draw(st.floats(0.01, 0.5)) if draw(st.integers(0, 3)) else draw(st.sampled_from(EXTREMES))
            for _ in range(3)]



BAD_LENGTHS = st.sampled_from([0.0, -0.1, -1e-300, 101.0, 1e9, float("nan"), float("inf"), -float("inf")])
COORDINATES = st.one_of(st.floats(-0.3, 0.3), st.sampled_from([0.0, 1e6, -1e6, 1e-300]))
ANGLES = st.one_of(st.floats(-math.pi, math.pi), st.sampled_from([0.0, 1e3, -1e3, math.pi / 2]))
BAD_NUMBERS = st.sampled_from([float("nan"), float("inf"), -float("inf"), 1e7, 1e308])
AXES = st.sampled_from([[[0, 0, 1], [0, 1, 0], [0, 1, 0]], [[0, 0, -1], [0, -1, 0], [0, 1, 0]],
                        [[0, 0, 1], [0, 1, 0], [0.1, 1, 0]], [[1, 0, 0], [0, 1, 0], [0, 1, 0]],
                        [[0, 0, 1e-9], [0, 1e5, 0], [0, 1, 0]], [[0, 0, 1], [0, 1, 1e-13], [0, 1, 0]],
                        [[1, 1, 1], [1, -1, 0], [1, -1, 0]]])
BAD_AXES = st.sampled_from([[[0, 0, 0], [0, 1, 0], [0, 1, 0]], [[0, 0, 1], [0, 1, 0]],
                            [[0, 0, 1e-13], [0, 1, 0], [0, 1, 0]], [[0, 0, 1e-300], [0, 1, 0], [0, 1, 0]],
                            [[0, 0, 1e300], [0, 1, 0], [0, 1, 0]]])
BOUNDS = st.one_of(st.tuples(st.floats(-3.5, 0.0, exclude_max=True), st.floats(0.0, 3.5, exclude_min=True)),
                   st.sampled_from([(-1e3, 1e3), (-1e3, 1e-9), (-1e-9, 1e-9), (-0.1, 7.0), (-7.0, 0.1)]))
BAD_BOUNDS = st.sampled_from([(1.0, -1.0), (0.0, 0.0), (-2e3, 0.0), (float("nan"), 1.0), (0.0, float("inf"))])
HOSTILITIES = ("none",) * 6 + ("lengths", "mount", "axes", "limits", "name", "names", "count", "value")


@st.composite
def hexapod_schema(draw) -> tuple[str, dict[str, Any], bool]:
    """(description, spec, certainly invalid) of a hexapod of random legs: valid extremes everywhere,
    and one hostile change in most cases (a bad length, mount, axis, limit, name or leg count, a hostile
    value anywhere, more legs than the limit allows)."""
    hostility = draw(st.sampled_from(HOSTILITIES))
    if draw(st.integers(0, 19)) == 0:  # over the leg limit
        n = limit("hexapod_legs") + 1
        spec = {"app": "hexapod", "name": "many", "leg": {"lengths": [0.05, 0.2, 0.2]},
                "legs": [{"name": f"leg{i}", "xyz": [0.1, 0, 0], "rpy": [0, 0, i]} for i in range(n)]}
        return f"{n} legs", spec, True
    count = draw(st.sampled_from([5, 7, 0])) if hostility == "count" else 6
    legs: list[dict[str, Any]] = []
    for i in range(count):
        leg: dict[str, Any] = {"name": VALID[i], "xyz": [draw(COORDINATES) for _ in range(3)],
                               "rpy": [draw(ANGLES) for _ in range(3)]}
        if draw(st.integers(0, 2)) == 0:
            leg["lengths"] = draw(three_lengths())
        if draw(st.integers(0, 2)) == 0:
            leg["axes"] = draw(AXES)
        if draw(st.integers(0, 2)) == 0:
            leg["limits"] = [list(draw(BOUNDS)) for _ in range(3)]
        legs.append(leg)
    spec: dict[str, Any] = {"app": "hexapod", "name": "fuzzed", "leg": {"lengths": draw(three_lengths())},
                            "legs": legs, "knee": draw(st.sampled_from(["up", "down"])),
                            "neutral": [0.0, 0.0, 0.0]}
    victim = legs[draw(st.integers(0, count - 1))] if legs else spec["leg"]
    # a link under a micron (1e-300: 2 l2 l3 underflows to 0) is refused; so is a missing count
    invalid = hostility == "count" or any(
        v < MIN_LENGTH for leg in [spec["leg"], *legs] for v in leg.get("lengths", []))
    change = ""
    if hostility == "lengths":
        victim.setdefault("lengths", [0.05, 0.2, 0.2])[draw(st.integers(0, 2))] = change = draw(BAD_LENGTHS)
        invalid = True
    elif hostility == "mount":
        victim[draw(st.sampled_from(["xyz", "rpy"]))][draw(st.integers(0, 2))] = change = draw(BAD_NUMBERS)
        invalid = True
    elif hostility == "axes":
        victim["axes"] = change = draw(BAD_AXES)
        invalid = True
    elif hostility == "limits":
        victim["limits"] = change = [[-1.0, 1.0], list(draw(BAD_BOUNDS)), [-1.0, 1.0]]
        invalid = True
    elif hostility in ("name", "names") and legs:
        change = draw(st.sampled_from(HOSTILE_NAMES))
        if hostility == "names":  # the same name twice, up to case
            change = draw(st.sampled_from(VALID[:count])).upper()
        victim["name"] = change
        names = [leg["name"] for leg in legs]
        invalid = (identifier_problem(change) is not None or len({str(n).lower() for n in names}) < len(names)
                   or any(f"{change}_{s}".lower() in BODY_KERNELS for s in LEG_KERNEL_SUFFIXES))
    elif hostility == "value":  # any hostile value in any field: may be refused, need not be
        field = draw(st.sampled_from(["name", "knee", "neutral", "leg", "legs"]))
        spec[field] = change = draw(st.sampled_from(HOSTILE_VALUES))
    what = f"{hostility} {change!r}: {spec!r}"[:2000]
    return what, spec, invalid


@examples(fast=40, full=250)
@given(st.data())
def test_random_hexapod_schema(data):
    what, spec, invalid = data.draw(hexapod_schema())
    run_document("hexapod schema", "hexapod.yaml", spec, solve, check, must_refuse=invalid, what=what)
