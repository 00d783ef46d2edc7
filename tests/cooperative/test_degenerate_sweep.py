"""Every primitive kind swept through its degenerate configurations, on the generated formulas.

The task-space function of the kernels (``gagen.apps.cooperative.catalogue._task_space``: X_c, V_Sc,
conditioning,
log V_Sc, e and their derivatives by the end positions, before the chain rule) is evaluated directly
on end positions that approach coincident, collinear, coplanar, concyclic and antiparallel
configurations (distance ε = 1e-1 … 1e-15, then exactly degenerate), plus one end-to-end check through
the ``similarity`` and ``task`` kernels of the bundled two-Panda point pair with coincident hands.

Required: every output finite at every ε; the conditioning 0 at the exact degeneracy, decreasing as
ε → 0 and bounded by a multiple of ε² (squared distance, area, volume or (1 − cos) of an angle);
nothing beyond 1e40 (the old kernels gave NaN and |J_G| up to 1e74 for pairs 1e-9 … 1e-15 long).
What stays unbounded is the true derivative (|J_G| grows like 1/ε, J_B of a nearly collinear circle
like 1/ε²); the measured growth is pinned below (see ``similarity._dilator_between``).
"""

from __future__ import annotations

import functools

import casadi as ca
import numpy as np
import pytest

from gagen.apps.cooperative.catalogue import _Graph, _task_space
from gagen.model.conformal import SIMILARITY
from gagen.model.kinematics import Joint
from gagen.model.primitives import points_needed
from gagen.robots.system import Chain, System

NAMES = ("X_c", "V_Sc", "conditioning", "log_V", "e", "dX_c", "dV_Sc", "dG", "dlog_V", "de")
EPSILONS = (1e-1, 1e-3, 1e-5, 1e-7, 3e-9, 1e-9, 1e-10, 1e-12, 1e-14, 1e-15)
LARGEST = 1e40


@functools.cache
def task_function(kind: str, count: int) -> ca.Function:
    """The kernels' task space of ``kind`` on end positions p (3 per point) and V_Sd, mapped over
    ``count`` samples (columns)."""
    n = points_needed(kind)
    chains = tuple(Chain(f"c{i}", (Joint(f"j{i}", "revolute"),)) for i in range(n))
    graph = _Graph(System("sweep", kind, chains))
    p, vsd = ca.SX.sym("p", 3 * n), ca.SX.sym("V_Sd", len(SIMILARITY))
    task = _task_space(graph, p, vsd)
    return ca.Function("task_space", [p, vsd], [task[k] for k in NAMES]).map(count)


def evaluate(kind: str, points: np.ndarray, vsd: np.ndarray) -> dict[str, np.ndarray]:
    """points (samples × 3n), vsd (samples × 12) → name → (samples, rows, cols)."""
    count = len(points)
    out = task_function(kind, count)(points.T, vsd.T)
    result = {}
    for name, value in zip(NAMES, out, strict=True):
        v = np.array(value)
        result[name] = v.reshape(v.shape[0], count, v.shape[1] // count).transpose(1, 0, 2)
    return result


def unit(v):
    return v / np.linalg.norm(v)


def perpendicular(d, hint):
    w = hint - (hint @ unit(d)) * unit(d)
    return unit(w)


def turned(v, axis, angle):
    return (v * np.cos(angle) + np.cross(axis, v) * np.sin(angle)
            + axis * (axis @ v) * (1 - np.cos(angle)))


def circumcentre(a, b, c):
    u, v = b - a, c - a
    w = np.cross(u, v)
    return a + np.cross(u @ u * v - v @ v * u, w) / (2 * w @ w)


E1, E3 = np.array([1.0, 0, 0]), np.array([0, 0, 1.0])


def _antiparallel_pair(b, eps):
    """Direction −e1 (opposite to X_u's +e1), turned by ε about an axis ⟂ e1."""
    return [b[0], b[0] + turned(-E1, unit(np.cross(E1, b[2] - b[0])), eps) * 0.5]


def _antiparallel_triangle(b, eps):
    """Normal −e3 (opposite to X_u's +e3), turned by ε about an in-plane axis."""
    axis = unit(np.array([1.0, 1.0, 0]))
    u, v = turned(E1, axis, eps), turned(np.array([0, -1.0, 0]), axis, eps)
    return [b[0], b[0] + 0.5 * u, b[0] + 0.5 * (0.25 * u + v)]


def _lifted_midpoint(b, eps):
    """The midpoint of b0 b1, moved ε off their line towards b2."""
    return (b[0] + b[1]) / 2 + eps * perpendicular(b[1] - b[0], b[2] - b[0])


# kind -> family -> (b, ε) -> spanning points; ε = 0 is the exact degeneracy
FAMILIES = {
    "point_pair": {
        "coincident": lambda b, e: [b[0], b[0] + e * unit(b[1] - b[0])],
        "antiparallel": _antiparallel_pair,
    },
    "line": {
        "coincident": lambda b, e: [b[0], b[0] + e * unit(b[1] - b[0])],
        "antiparallel": _antiparallel_pair,
    },
    "circle": {
        "coincident": lambda b, e: [b[0], b[0] + e * unit(b[1] - b[0]), b[2]],
        "collinear": lambda b, e: [b[0], b[1], _lifted_midpoint(b, e)],
        "collinear outside": lambda b, e: [b[0], b[1], 2 * b[1] - b[0] + e * perpendicular(b[1] - b[0],
                                                                                            b[2] - b[0])],
        "antiparallel": _antiparallel_triangle,
    },
    "plane": {
        "coincident": lambda b, e: [b[0], b[0] + e * unit(b[1] - b[0]), b[2]],
        "collinear": lambda b, e: [b[0], b[1], _lifted_midpoint(b, e)],
        "antiparallel": _antiparallel_triangle,
    },
    "sphere": {
        "coincident": lambda b, e: [b[0], b[0] + e * unit(b[1] - b[0]), b[2], b[3]],
        "collinear": lambda b, e: [b[0], b[1], _lifted_midpoint(b, e), b[3]],
        "coplanar": lambda b, e: [b[0], b[1], b[2], b[0] + 0.25 * (b[1] - b[0]) + 0.5 * (b[2] - b[0])
                                  + e * unit(np.cross(b[1] - b[0], b[2] - b[0]))],
        "concyclic": lambda b, e: [b[0], b[1], b[2], 2 * circumcentre(b[0], b[1], b[2]) - b[0]
                                   + e * unit(np.cross(b[1] - b[0], b[2] - b[0]))],
    },
}
CASES = [(kind, family) for kind in FAMILIES for family in FAMILIES[kind]]


def _bases() -> np.ndarray:
    """Well-spread base configurations (4 points each): random ones, and ones on a quarter grid, where
    the exact degeneracies are exact in floating point and the cancellations are the worst (the old
    kernels' NaN cases)."""
    rng = np.random.default_rng(12)
    out = []
    while len(out) < 48:
        grid = len(out) % 2 == 0
        b = np.round(rng.uniform(-1.5, 1.5, (4, 3)) * 4) / 4 if grid else rng.uniform(-1.5, 1.5, (4, 3))
        d = [np.linalg.norm(b[i] - b[j]) for i in range(4) for j in range(i)]
        if min(d) > 0.4 and abs(np.linalg.det(b[1:] - b[0])) > 0.3:
            out.append(b)
    return np.array(out)


BASES = _bases()
GRID = np.arange(len(BASES)) % 2 == 0
VSD = np.array([[1.0, 0.1, -0.2, 0.05, 0.3, 0.2, -0.1, 0.0, 0.4, 0.0, 0.0, 0.0]] * len(BASES))


@functools.cache
def sweep(kind: str, family: str) -> dict[float, dict[str, np.ndarray]]:
    make = FAMILIES[kind][family]
    return {eps: evaluate(kind, np.array([np.concatenate(make(b, eps)) for b in BASES]), VSD)
            for eps in (*EPSILONS, 0.0)}


@pytest.mark.parametrize(("kind", "family"), CASES)
def test_every_output_is_finite_and_bounded_at_and_near_degeneracy(kind, family):
    for eps, out in sweep(kind, family).items():
        for name, value in out.items():
            assert np.all(np.isfinite(value)), (kind, family, eps, name)
            assert np.max(np.abs(value)) < LARGEST, (kind, family, eps, name, np.max(np.abs(value)))


@pytest.mark.parametrize(("kind", "family"), CASES)
def test_conditioning_vanishes_at_the_degeneracy_and_decreases_towards_it(kind, family):
    runs = sweep(kind, family)
    cond = np.array([runs[eps]["conditioning"].ravel() for eps in EPSILONS])  # (ε, sample)
    exact = runs[0.0]["conditioning"].ravel()
    # exactly 0 where the degenerate configuration is exact in floating point (the quarter grid; not
    # the concyclic point, whose circumcentre divides); within rounding of 0 elsewhere
    if family != "concyclic":
        assert np.all(exact[GRID] == 0), exact[GRID]
    assert np.all(np.abs(exact) <= 1e-28), exact
    assert np.all(cond >= 0)
    # decreasing while the conditioning is above its rounding floor, and O(ε²) throughout
    resolved = [i for i, eps in enumerate(EPSILONS) if eps >= 1e-7]
    assert np.all(np.diff(cond[resolved], axis=0) < 0), cond[resolved]
    scale = cond[0] / EPSILONS[0] ** 2
    for row, eps in zip(cond, EPSILONS, strict=True):
        assert np.all(row <= 4 * scale * eps ** 2 + 1e-28), (eps, row / (scale * eps ** 2))


# max |J_G| · ε^power measured on these bases (ε ≥ 1e-9), pinned with a factor ~3 of margin so that a
# regression in the guards shows. J_G grows like 1/ε towards coincident, collinear, coplanar or
# concyclic points (the radius, axis or centre moves like 1/ε), like 1/ε² towards antiparallel flats
# (Eq. 21's screw axis runs ~1/ε away), and drops to O(1) past the antiparallel switch (the guarded
# half turn). Measured max |J_G| (all bases) at ε = 1e-1, 1e-5, 1e-9, 1e-12, 1e-15:
#   point pair coincident 1.4e2, 9.4e7, 1.2e16, 1.5e13, 6.8e15 (2.5e27 at 1e-14): past ε ≈ 1e-4 its r²
#     numerator −⟨XX~⟩ has lost every digit (relative error ≈ 1e-16/ε³ at |x| ≈ 1 m), so the dilation
#     row is rounding noise there: finite and < 1e40, but not bounded by 1/ε;
#   line coincident 7.7e2 … 1.3e16; circle collinear 2.5e1, 2.5e5, 2.5e9, 2.5e12, 1.4e18;
#   sphere coplanar 9.9, 9.9e4, 9.9e8, 1.4e12, 1.6e18; plane antiparallel 6.3e2, 6.0e10, then 4.6.
JG_PIN = {"point_pair": 50, "line": 250, "circle": 20, "plane": 25, "sphere": 30}


@pytest.mark.parametrize(("kind", "family"), CASES)
def test_geometric_jacobian_grows_no_faster_than_the_geometry_says(kind, family):
    power = 2 if family == "antiparallel" and kind in ("line", "plane") else 1
    smallest = 1e-3 if (kind, family) == ("point_pair", "coincident") else 1e-9
    runs = sweep(kind, family)
    for eps in EPSILONS:
        if eps >= smallest:
            worst = np.max(np.abs(runs[eps]["dG"]))
            assert worst * eps ** power <= JG_PIN[kind], (eps, worst)


def test_coincident_hands_of_two_pandas_through_the_kernels():
    """End to end: the two Pandas' hands placed 1e-3 … 1e-14 m apart (Gauss-Newton on arm1's end
    point), then the ``similarity`` and ``task`` kernels (CasADi Functions) with V_Sd = V_Sc(q)."""
    from gagen.apps.cooperative.catalogue import build_kernels
    from gagen.robots.spec import load_system

    system, configurations = load_system("robots/two_pandas_point_pair.yaml")
    kernels = build_kernels(system)
    q0 = np.array(configurations["ready"])
    fk0, fk1 = kernels["arm0_fk"].function, kernels["arm1_jacobians"].function
    qa = q0[:7] + np.array([0.3, 0.4, 0.0, 0.6, 0.0, -0.3, 0.0])
    target = np.array(fk0(qa)[1]).ravel()[1:4]
    qb = q0[7:].copy()
    for eps in (1e-3, 1e-6, 3e-9, 1e-9, 1e-12, 1e-14):
        goal = target + eps * np.array([0.6, 0.64, 0.48])
        for _ in range(60):  # Gauss-Newton on the e1, e2, e3 rows of the point Jacobian J_P
            out = fk1(qb)
            err = np.array(out[1]).ravel()[1:4] - goal
            if np.linalg.norm(err) < 1e-16:
                break
            qb = qb - np.linalg.lstsq(np.array(out[5])[1:4], err, rcond=None)[0]
        q = np.r_[qa, qb]
        v, cond, jg = (np.array(x) for x in kernels["similarity"].function(q))
        e, jbe = (np.array(x) for x in kernels["task"].function(q, v))
        dist = np.linalg.norm(np.array(fk1(qb)[1]).ravel()[1:4] - target)
        for name, value in {"V_Sc": v, "conditioning": cond, "J_G": jg, "e": e, "J_Be": jbe}.items():
            assert np.all(np.isfinite(value)), (eps, dist, name)
        assert 0 <= cond.item() <= 2 * dist ** 2 + 1e-30
        assert np.max(np.abs(e)) < 1e-6 or cond.item() < 1e-20, (eps, e)
