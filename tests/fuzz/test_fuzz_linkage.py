"""Fuzz tier (issue 29): planar linkage specs. A mutated copy of a bundled linkage, and a linkage built
from random bodies, joints and lengths with hostile names, is refused in one line naming the file and
a field, or loaded and solved (assembled and driven a few steps on the interpreter, no C compiler) to
finite points, or its failure to close or move is reported by the solver."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from gagen.apps.linkage.demo import driver_path
from gagen.apps.linkage.kernels import linkage_kernels
from gagen.apps.linkage.solver import Kernels, Trajectory, simulate
from gagen.apps.linkage.spec import MAX_COORDINATE, load_linkage
from gagen.limits import limit
from gagen.names import identifier_problem

from .harness import HOSTILE_NAMES, HOSTILE_VALUES, all_finite, examples, mutated_file, run_case, run_document

ROBOTS = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "linkage" / "robots"
BUNDLED = {path.name: path.read_text() for path in sorted(ROBOTS.glob("*.yaml"))}


def interpreted(linkage) -> Kernels:
    """The solver's kernels on the interpreter (each kernel's ``reference``): no C compiler."""
    by_name = {k.name: k for k in linkage_kernels(linkage)}
    constraints, retract, positions = by_name["constraints"], by_name["retract"], by_name["positions"]
    return Kernels(lambda R, theta: constraints.reference(R, theta),
                   lambda R, step: retract.reference(R, step)[0],
                   lambda R, theta: positions.reference(R, theta)[0])


def solve(path: Path) -> Trajectory:
    """Load the spec, then assemble it at its initial configuration and drive it two steps along its
    driver's path (a crank 60° at a time, a slider over a sixth of its stroke cycle). At most two
    halvings of a step: on the interpreter, a step into a dead point costs seconds per halving."""
    linkage = load_linkage(path)
    values, phases = driver_path(linkage, 6)
    return simulate(interpreted(linkage), linkage, values[:3], phases=phases[:3], max_halvings=2)


def check(trajectory: Trajectory) -> None:
    """Finite points and motors, unless the solver reports why it could not assemble or move it."""
    assert trajectory.failures or all_finite([trajectory.points, trajectory.motors, trajectory.residuals]), \
        "non-finite points without a reported failure"


@examples(fast=40, full=250)
@given(st.data())
def test_mutated_bundled_linkage(data):
    name = data.draw(st.sampled_from(sorted(BUNDLED)))
    with tempfile.TemporaryDirectory() as folder:
        what, path = mutated_file(data.draw, BUNDLED[name], Path(folder), name)
        run_case("linkage", (path,), lambda: solve(path), check, what=f"{name}: {what}")


# -- schema level: a four-bar (or a chain) from random names, lengths and joints -------------------------

NAMES = ["crank", "coupler", "rocker", "A", "B", "C", "D"]  # the bodies, then the points
LENGTH = st.floats(0.05, 10)
HOSTILE_LENGTHS = [0.0, -1.0, 1e-9, 1e4, 1e5, float("nan"), float("inf")]  # beyond MAX_COORDINATE too
# one kind of hostility per case, or none (a plausible four-bar, which may or may not close)
HOSTILITIES = ["none", "none", "none", "lengths", "lengths", "names", "add", "drop", "rate", "name", "limit"]


def _valid_name(name: Any) -> bool:
    return identifier_problem(name) is None and name != "ground"


def _four_bar(ground: float, crank: float, coupler: float, rocker: float) -> list[list[float]]:
    """A, B, C, D of a four-bar from its lengths: assembled at the first crank angle where the loop
    closes, else (lengths that never close it) a rough guess the solver must fail to assemble."""
    with np.errstate(all="ignore"):
        for theta in np.linspace(0.0, np.pi, 37):
            B = crank * np.array([np.cos(theta), np.sin(theta)])
            D = np.array([ground, 0.0])
            d = float(np.linalg.norm(D - B))
            if abs(coupler - rocker) < d < coupler + rocker:
                a = (coupler ** 2 - rocker ** 2 + d ** 2) / (2 * d)
                C = B + a * (D - B) / d + np.sqrt(coupler ** 2 - a ** 2) * np.array([B[1], D[0] - B[0]]) / d
                return [[0.0, 0.0], B.tolist(), C.tolist(), D.tolist()]
    return [[0.0, 0.0], [crank, 0.0], [crank + coupler, 1.0], [ground, 0.0]]


def _number(value: float) -> Any:
    """A coordinate as the spec writes it: YAML has .nan and .inf; huge ints stay exact."""
    return value if np.isfinite(value) else float(value)


@st.composite
def linkage_schema(draw) -> tuple[str, dict[str, Any], bool]:
    """(description, spec, certainly invalid) of a four-bar of random lengths, with one kind of
    hostility or none: hostile lengths, hostile or repeated names, a joint added or removed, a hostile
    driver rate or linkage name, or more bodies than the limit allows."""
    hostility = draw(st.sampled_from(HOSTILITIES))
    if hostility == "limit":  # a chain of limit + 1 bodies
        n = limit("linkage_bodies") + 1
        bodies = {f"b{i}": {"P": [i, 0], "Q": [i + 1, 0]} for i in range(n)}
        joints = [{"revolute": [f"b{i - 1}.Q", f"b{i}.P"]} for i in range(1, n)]
        spec = {"app": "linkage", "name": "chain", "ground": {"A": [0, 0]}, "bodies": bodies,
                "joints": [{"revolute": ["b0.P", "ground.A"]}, *joints], "driver": {"body": "b0"}}
        return f"{n} bodies", spec, True
    lengths = [draw(LENGTH) for _ in range(4)]
    if hostility == "lengths":
        for _ in range(draw(st.integers(1, 2))):
            lengths[draw(st.integers(0, 3))] = draw(st.sampled_from(HOSTILE_LENGTHS))
    A, B, C, D = _four_bar(*lengths)
    names = list(NAMES)
    if hostility == "names":  # a hostile name (or a valid one given twice) or two
        for _ in range(draw(st.integers(1, 2))):
            names[draw(st.integers(0, 6))] = draw(st.sampled_from(HOSTILE_NAMES + NAMES))
    crank, coupler, rocker, pa, pb, pc, pd = names
    bodies = {crank: {pa: A, pb: B}, coupler: {pb: B, pc: C}, rocker: {pc: C, pd: D}}
    joints: list[Any] = [{"revolute": [f"{crank}.{pa}", f"ground.{pa}"]},
                         {"revolute": [f"{crank}.{pb}", f"{coupler}.{pb}"]},
                         {"revolute": [f"{coupler}.{pc}", f"{rocker}.{pc}"]},
                         {"revolute": [f"{rocker}.{pd}", f"ground.{pd}"]}]
    invalid = hostility in ("add", "drop")  # Grübler–Kutzbach: 0 or 3 degrees of freedom, never 1
    if hostility == "add":
        joints.append({"revolute": [f"{coupler}.{pb}", f"ground.{pd}"]})
    elif hostility == "drop":
        joints.pop(draw(st.integers(0, 3)))
    driver: dict[str, Any] = {"body": crank, "pivot": f"ground.{pa}"}
    rate: Any = 1.0
    if hostility == "rate":
        rate = driver["rate"] = draw(st.sampled_from(HOSTILE_VALUES))
    name = draw(st.sampled_from(HOSTILE_NAMES)) if hostility == "name" else "fuzzed"
    spec = {"app": "linkage", "name": name, "ground": {pa: A, pd: D}, "bodies": bodies, "joints": joints,
            "driver": driver}
    numbers_ok = all(np.isfinite(v) and abs(v) <= MAX_COORDINATE for p in (A, B, C, D) for v in p)
    rate_ok = (isinstance(rate, int | float) and not isinstance(rate, bool) and rate != 0
               and bool(np.isfinite(rate)) and abs(rate) <= 1e4)
    # (a point name given twice merges two points of a body: a degenerate but valid spec)
    names_ok = all(map(_valid_name, (name, crank, coupler, rocker, pa, pb, pc, pd))) \
        and len({crank, coupler, rocker}) == 3
    invalid = invalid or not (numbers_ok and rate_ok and names_ok)
    what = f"four-bar {lengths}, names {(name, crank, coupler, rocker, pa, pb, pc, pd)!r}, {hostility}"
    return what, spec, invalid


@examples(fast=40, full=250)
@given(st.data())
def test_random_linkage_schema(data):
    what, spec, invalid = data.draw(linkage_schema())
    run_document("linkage schema", "linkage.yaml", spec, solve, check, must_refuse=invalid, what=what)
