"""Statics of the hexapod (``gagen.apps.hexapod.statics``, ``gait_statics``): the stability margin against
closed forms (triangle inradius, rectangle, outside, a slope where the projection along gravity is not
the perpendicular foot) and scipy's convex hull, and its invariance under rigid motions; friction cones
and pyramids on hand-made forces; the force-distribution QP (ProxQP) against closed forms (three feet
under the CoM, a slope with the CoM in the support plane, the friction limit tan θ = μ), against the
pseudo-inverse where no inequality is active, against scipy's LP (feasibility) and SLSQP (optimum), and
its KKT conditions; with the generated module, the bundled walk (flat, 10°) and the kept margin."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog, minimize
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from gagen.apps.hexapod import gait, gait_statics
from gagen.apps.hexapod.mass import centre_of_mass, default_mass_model, total_mass
from gagen.apps.hexapod.spec import Hexapod
from gagen.apps.hexapod.statics import (
    GRAVITY,
    DegenerateSupport,
    InfeasibleForces,
    distribute_forces,
    force_problem,
    friction_pyramid,
    friction_ratio,
    inside_friction_cone,
    stability_margin,
    tangent_basis,
)
from gagen.cli import main

G = 9.81
MASS = 2.5


def triangle(side: float) -> np.ndarray:
    r = side / math.sqrt(3)  # circumradius
    angles = (0.0, 2 * math.pi / 3, 4 * math.pi / 3)
    return np.array([[r * math.cos(a), r * math.sin(a), 0.0] for a in angles])


def tilt(theta: float) -> np.ndarray:
    """The rotation taking the world z to the normal of a plane rising at theta towards +x."""
    return np.asarray(Rotation.from_rotvec([0.0, -theta, 0.0]).as_matrix(), dtype=float)


# -- the margin ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("side", [0.1, 0.55, 3.0])
def test_equilateral_triangle_with_the_com_at_its_centroid_gives_the_inradius(side: float) -> None:
    for height in (0.0, 0.2, 5.0):
        assert abs(stability_margin(triangle(side), np.array([0, 0, height]), GRAVITY)
                   - side / (2 * math.sqrt(3))) < 1e-15 * max(1, side) * 4


def test_rectangle_inside_and_outside() -> None:
    w, h = 0.6, 0.4
    # four corners, an interior foot and one on an edge (neither on the hull)
    feet = np.array([[0, 0, 0], [w, 0, 0], [w, h, 0], [0, h, 0], [0.3, 0.2, 0], [0.3, 0.0, 0]], dtype=float)
    rng = np.random.default_rng(1)
    for x, y in rng.uniform([0, 0], [w, h], size=(50, 2)):
        assert abs(stability_margin(feet, np.array([x, y, 0.3]), GRAVITY) - min(x, w - x, y, h - y)) < 1e-15
    # outside: beyond an edge the distance to it, beyond a corner the distance to the corner, negative
    assert abs(stability_margin(feet, np.array([-0.05, 0.1, 0.3]), GRAVITY) + 0.05) < 1e-15
    assert abs(stability_margin(feet, np.array([0.2, h + 0.07, 0.3]), GRAVITY) + 0.07) < 1e-15
    assert abs(stability_margin(feet, np.array([w + 0.03, -0.04, 0.3]), GRAVITY) + 0.05) < 1e-15
    assert stability_margin(feet, np.array([w, 0.1, 0.3]), GRAVITY) == 0.0  # on the edge


@pytest.mark.parametrize("theta_deg", [5.0, 10.0, 25.0])
def test_slope_projects_along_gravity_not_along_the_normal(theta_deg: float) -> None:
    """Feet on a plane rising at θ towards +x, the CoM h above the in-plane point (x0, y0) along the
    normal: along gravity it lands h tan θ downhill, at u = x0 − h tan θ; the margin is min(u, w − u,
    y0, d − y0). The perpendicular foot (x0) would give another number."""
    theta = math.radians(theta_deg)
    r = tilt(theta)
    w, d = 0.6, 0.4
    offset = np.array([0.1, -0.3, 0.0])
    corners = np.array([[0, 0, 0], [w, 0, 0], [w, d, 0], [0, d, 0]], dtype=float) + offset
    for x0, y0, height in [(0.45, 0.2, 0.15), (0.3, 0.05, 0.3), (0.1, 0.3, 0.4), (0.59, 0.1, 0.02)]:
        com = r @ (np.array([x0, y0, height]) + offset)
        u = x0 - height * math.tan(theta)
        expected = min(u, w - u, y0, d - y0) if 0 <= u <= w else -max(-u, u - w)
        got = stability_margin(corners @ r.T, com, GRAVITY)
        assert abs(got - expected) < 1e-14
    # the perpendicular foot x0 = 0.45 would give 0.15; along gravity the CoM is further from the +x edge
    com = r @ (np.array([0.45, 0.2, 0.15]) + offset)
    assert stability_margin(corners @ r.T, com, GRAVITY) - 0.15 > 0.01


def test_degenerate_stances_are_reported() -> None:
    com = np.array([0.0, 0, 0.2])
    with pytest.raises(DegenerateSupport, match="2 feet"):
        stability_margin(np.array([[0, 0, 0], [1, 0, 0.0]]), com, GRAVITY)
    with pytest.raises(DegenerateSupport, match="in a line"):
        stability_margin(np.array([[0, 0, 0], [1, 1, 0], [2, 2, 0.0], [3, 3, 0]]), com, GRAVITY)
    with pytest.raises(DegenerateSupport, match="gravity lies in the support plane"):
        stability_margin(np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1.0]]), com, GRAVITY)
    with pytest.raises(ValueError, match="feet: expected an array of shape k×3"):
        stability_margin(np.zeros((3, 2)), com, GRAVITY)
    with pytest.raises(ValueError, match="com: expected finite numbers"):
        stability_margin(triangle(1.0), np.array([0, np.nan, 0]), GRAVITY)
    with pytest.raises(ValueError, match="gravity: expected a non-zero vector"):
        stability_margin(triangle(1.0), com, np.zeros(3))


def _hull_margin(feet: np.ndarray, com: np.ndarray, gravity: np.ndarray) -> float:
    """An independent margin for an inside CoM: scipy's hull facets in the feet's plane (basis by QR)."""
    n = np.cross(feet[1] - feet[0], feet[2] - feet[0])
    n /= np.linalg.norm(n)
    basis = np.linalg.qr(np.column_stack([n, np.eye(3)]))[0][:, 1:3]
    c = com + (n @ (feet[0] - com)) / (n @ gravity) * gravity
    hull = ConvexHull((feet - feet[0]) @ basis)
    return float(-(hull.equations @ np.r_[(c - feet[0]) @ basis, 1.0]).max())


stances = st.tuples(st.integers(3, 6), st.integers(0, 2**31), st.floats(0.0, 0.5))


@settings(max_examples=25, deadline=None)
@given(stances)
def test_margin_is_invariant_under_rigid_motions_and_matches_scipy(case: tuple[int, int, float]) -> None:
    k, seed, slope = case
    rng = np.random.default_rng(seed)
    r0 = Rotation.from_rotvec([slope * math.cos(seed), slope * math.sin(seed), 0.0]).as_matrix()
    angles = np.sort(rng.uniform(0, 2 * math.pi, k))
    radii = rng.uniform(0.2, 0.4, k)
    feet = np.column_stack([radii * np.cos(angles), radii * np.sin(angles), np.zeros(k)]) @ r0.T
    com = r0 @ np.r_[rng.uniform(-0.15, 0.15, 2), 0.15]
    try:
        m = stability_margin(feet, com, GRAVITY)
    except DegenerateSupport:
        return
    motion = Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
    shift = rng.normal(size=3)
    moved = stability_margin(feet @ motion.T + shift, motion @ com + shift, 3.7 * motion @ GRAVITY)
    assert abs(moved - m) < 1e-13
    if m > 0:
        assert abs(_hull_margin(feet, com, GRAVITY) - m) < 1e-13


# -- friction cones ------------------------------------------------------------------------------------

def test_cone_on_hand_made_forces() -> None:
    up = np.array([0.0, 0, 1])
    assert inside_friction_cone([0, 0, 10.0], up, 0.0)
    assert inside_friction_cone([3.0, 4.0, 10.0], up, 0.5)  # |f_t| = 5 = 0.5 · 10: on the cone
    assert not inside_friction_cone([3.0, 4.0, 10.0], up, 0.49)
    assert not inside_friction_cone([0.0, 0.0, -1.0], up, 10.0)  # pulling
    assert friction_ratio([3.0, 4.0, 10.0], 2 * up) == 0.5
    assert friction_ratio([1.0, 0.0, 0.0], up) == math.inf
    # a tilted normal: the same force in the rotated frame, arrays of forces
    r = Rotation.from_rotvec([0.3, -0.5, 0.2]).as_matrix()
    forces = np.array([[3.0, 4.0, 10.0], [0.0, 6.0, 10.0], [0.0, 0.0, 1.0], [1.0, 0.0, -0.1]]) @ r.T
    assert inside_friction_cone(forces, r @ up, 0.55).tolist() == [True, False, True, False]
    assert np.allclose(friction_ratio(forces[:3], r @ up), [0.5, 0.6, 0.0], atol=1e-15, rtol=0)
    with pytest.raises(ValueError, match="mu"):
        inside_friction_cone(forces, up, -0.1)


@pytest.mark.parametrize("facets", [3, 4, 8, 16])
def test_pyramid_is_inscribed_with_its_edges_on_the_cone(facets: int) -> None:
    rng = np.random.default_rng(facets)
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    mu = 0.6
    rows = friction_pyramid(n, mu, facets)
    t1, t2 = tangent_basis(n)
    assert abs(np.linalg.det(np.stack([t1, t2, n])) - 1) < 1e-14
    for j in range(facets):  # edge j: on the cone, on two facets, inside the others
        phi = 2 * math.pi * j / facets
        edge = n + mu * (math.cos(phi) * t1 + math.sin(phi) * t2)
        assert abs(friction_ratio(edge, n) - mu) < 1e-14
        values = rows @ edge
        assert (values <= 1e-14).all() and (np.abs(values) < 1e-14).sum() == 2
    forces = rng.normal(size=(20000, 3))
    inside = (forces @ rows.T <= 0).all(axis=1) & (forces @ n >= 0)
    assert inside.sum() > 100 and inside_friction_cone(forces[inside], n, mu).all()
    # a force along a facet's middle with ratio mu cos(pi/m) lies on that facet
    half = math.pi / facets
    mid = n + mu * math.cos(half) * (math.cos(half) * t1 + math.sin(half) * t2)
    assert abs(rows[0] @ mid) < 1e-14


# -- the force distribution -----------------------------------------------------------------------------

def _balance(feet: np.ndarray, com: np.ndarray, forces: np.ndarray, mass: float) -> tuple[float, float]:
    force = forces.sum(axis=0) + mass * GRAVITY
    moment = np.cross(feet - com, forces).sum(axis=0)
    return float(np.abs(force).max()), float(np.abs(moment).max())


def _lp(p: dict[str, np.ndarray]) -> tuple[Any, np.ndarray, np.ndarray]:
    """scipy's LP (HiGHS) on the QP's constraints (zero objective): status 0 feasible, 2 infeasible;
    and the inequalities as C x <= b."""
    upper, lower = p["u"] < 1e19, p["l"] > -1e19
    c_ub, b_ub = np.vstack([p["C"][upper], -p["C"][lower]]), np.r_[p["u"][upper], -p["l"][lower]]
    size = p["A"].shape[1]
    lp = linprog(np.zeros(size), A_ub=c_ub, b_ub=b_ub, A_eq=p["A"], b_eq=p["b"], bounds=[(None, None)] * size,
                 method="highs")
    return lp, c_ub, b_ub


def test_three_feet_under_the_com_share_the_weight() -> None:
    feet = triangle(0.5)
    for height in (0.0, 0.15, 1.0):
        com = np.array([0.0, 0.0, height])
        d = distribute_forces(feet, com, MASS, mu=0.5)
        assert np.abs(d.forces - [0.0, 0.0, MASS * G / 3]).max() < 1e-12
        assert max(_balance(feet, com, d.forces, MASS)) < 1e-12
        assert d.residual_force < 1e-12 and d.residual_moment < 1e-12


def test_slope_with_the_com_in_the_support_plane_holds_it_with_vertical_forces() -> None:
    """CoM at the centroid in the feet's plane: min Σ|f|² with Σ f = −m g is the equal split, and its
    moment Σ (p − c) × (−m g / 3) vanishes; each foot −m g / 3 (normal m g cos θ / 3, tangential
    m g sin θ / 3)."""
    for theta in np.radians([5.0, 15.0, 25.0]):
        r = tilt(theta)
        feet, n = triangle(0.5) @ r.T, r @ [0, 0, 1.0]
        d = distribute_forces(feet, np.zeros(3), MASS, normals=n, mu=0.5)
        assert np.abs(d.forces + MASS * GRAVITY / 3).max() < 1e-12
        assert np.abs(d.ratios - math.tan(theta)).max() < 1e-12


@pytest.mark.parametrize("mu", [0.3, 0.5, 0.8])
def test_slope_needs_m_g_sin_theta_of_friction_and_is_infeasible_beyond_mu(mu: float) -> None:
    """Σ f_t = m g sin θ; inside the cones iff tan θ ≤ μ (the pyramid's edge points uphill, so its
    limit is the cone's); beyond, InfeasibleForces, and scipy's LP agrees there is no solution."""
    for tan in (0.5 * mu, 0.9 * mu, 0.999 * mu, 1.001 * mu, 1.2 * mu):
        theta = math.atan(tan)
        r = tilt(theta)
        feet, n = triangle(0.5) @ r.T, r @ [0, 0, 1.0]
        com = 0.15 * n + r @ [0.02, -0.01, 0]
        lp = _lp(force_problem(feet, com, MASS, GRAVITY, n, mu))[0]
        if tan <= mu:
            d = distribute_forces(feet, com, MASS, normals=n, mu=mu)
            tangential = d.forces - np.outer(d.normal_forces, n)
            assert abs(np.linalg.norm(tangential.sum(axis=0)) - MASS * G * math.sin(theta)) < 1e-10
            assert abs(d.normal_forces.sum() - MASS * G * math.cos(theta)) < 1e-10
            assert max(_balance(feet, com, d.forces, MASS)) < 1e-9
            assert inside_friction_cone(d.forces, n, mu, atol=1e-9).all() and lp.status == 0
        else:
            with pytest.raises(InfeasibleForces, match=f"no foot forces hold the body .*mu = {mu:g}"):
                distribute_forces(feet, com, MASS, normals=n, mu=mu)
            assert lp.status == 2  # infeasible


def test_min_norm_forces_equal_the_pseudo_inverse_when_no_bound_is_active() -> None:
    rng = np.random.default_rng(5)
    angles = np.linspace(0, 2 * math.pi, 6, endpoint=False) + rng.uniform(-0.2, 0.2, 6)
    feet = np.column_stack([0.35 * np.cos(angles), 0.35 * np.sin(angles), rng.uniform(-0.01, 0.01, 6)])
    com = np.array([0.02, -0.03, 0.15])
    problem = force_problem(feet, com, MASS)
    expected = (np.linalg.pinv(problem["A"]) @ problem["b"]).reshape(6, 3)
    assert inside_friction_cone(expected, [0, 0, 1.0], 0.3).all() and expected[:, 2].min() > 1
    d = distribute_forces(feet, com, MASS, mu=0.5)
    assert np.abs(d.forces - expected).max() < 1e-10


def test_bad_inputs_and_f_min() -> None:
    feet = triangle(0.5)
    with pytest.raises(ValueError, match="mass"):
        distribute_forces(feet, np.zeros(3), -1.0)
    with pytest.raises(ValueError, match="normals"):
        distribute_forces(feet, np.zeros(3), 1.0, normals=np.zeros((2, 3)))
    # f_min above the equal share cannot balance the weight
    with pytest.raises(InfeasibleForces):
        distribute_forces(feet, np.array([0, 0, 0.1]), MASS, f_min=MASS * G / 3 + 0.1)
    # near the edge opposite foot 0 (at x = R), on flat ground only the normal forces have moments about
    # horizontal axes: foot 0 carries m g (c + R/2) / (3R/2) whatever f_min, and an f_min above it fails
    r, com = 0.5 / math.sqrt(3), np.array([-0.13, 0, 0.1])
    share = MASS * G * (com[0] + r / 2) / (1.5 * r)
    for f_min in (0.0, share - 1e-6):
        d = distribute_forces(feet, com, MASS, f_min=f_min)
        assert abs(d.normal_forces[0] - share) < 1e-12 and max(_balance(feet, com, d.forces, MASS)) < 1e-12
    with pytest.raises(InfeasibleForces, match=r"f_min = 0\.82 N"):
        distribute_forces(feet, com, MASS, f_min=0.82)
    assert _lp(force_problem(feet, com, MASS, f_min=0.82))[0].status == 2


@settings(max_examples=25, deadline=None)
@given(stances, st.floats(0.2, 1.0), st.floats(0.0, 2.0))
def test_random_stances_balance_satisfy_kkt_and_match_lp_and_slsqp(case: tuple[int, int, float], mu: float,
                                                                   f_min: float) -> None:
    k, seed, slope = case
    rng = np.random.default_rng(seed)
    r = Rotation.from_rotvec([slope * math.cos(seed), slope * math.sin(seed), 0.0]).as_matrix()
    angles = np.sort(rng.uniform(0, 2 * math.pi, k))
    feet = np.column_stack([0.3 * np.cos(angles), 0.3 * np.sin(angles), rng.uniform(-0.02, 0.02, k)]) @ r.T
    n = r @ [0, 0, 1.0]
    com = r @ np.r_[rng.uniform(-0.1, 0.1, 2), 0.15]
    p = force_problem(feet, com, MASS, GRAVITY, n, mu, 8, f_min)
    lp, c_ub, b_ub = _lp(p)
    try:
        d = distribute_forces(feet, com, MASS, GRAVITY, n, mu, 8, f_min)
    except InfeasibleForces:
        assert lp.status == 2
        return
    assert lp.status == 0
    x = d.forces.reshape(-1)
    assert max(_balance(feet, com, d.forces, MASS)) < 1e-9
    assert (c_ub @ x - b_ub).max() < 1e-9
    y, z = d.duals  # KKT: H x + Aᵀ y + Cᵀ z = 0, z ≥ 0 only at an active upper bound, ≤ 0 at a lower one
    assert np.abs(p["H"] @ x + p["A"].T @ y + p["C"].T @ z).max() < 1e-8
    cx = p["C"] @ x
    assert (z[cx < p["u"] - 1e-7] <= 1e-9).all() and (z[cx > p["l"] + 1e-7] >= -1e-9).all()
    cons = [{"type": "eq", "fun": lambda v: p["A"] @ v - p["b"]},
            {"type": "ineq", "fun": lambda v: b_ub - c_ub @ v}]
    ref = minimize(lambda v: v @ v, lp.x, jac=lambda v: 2 * v, constraints=cons, method="SLSQP",
                   options={"ftol": 1e-14, "maxiter": 500})
    assert x @ x <= ref.fun * (1 + 1e-9) + 1e-9  # ProxQP's optimum is no worse than SLSQP's


# -- the walk (the generated module) ----------------------------------------------------------------------

@pytest.mark.compiling
@pytest.mark.parametrize("slope", [0.0, 10.0])
def test_bundled_walk_stands_with_forces_inside_the_cones(hexapod_module: Any, hexapod: Hexapod,
                                                         slope: float) -> None:
    result = gait.walk(hexapod_module, hexapod, ground=gait.Ground(math.radians(slope)))
    s = gait_statics.check_walk(result, mu=0.5)
    model = default_mass_model(hexapod)
    for k in (0, 123, 400, len(result.t) - 1):  # the batched CoM against mass.py's
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = result.body.rotation[k], result.body.position[k]
        assert np.abs(s.com[k] - centre_of_mass(hexapod, model, pose, result.q[k])).max() < 1e-15
    assert s.margin.min() > 0.1 and s.feasible.all() and s.inside_cones and s.ok
    assert s.mass == total_mass(model)
    n = result.ground.normal
    for k in range(0, len(result.t), 7):  # balance recomputed from the stored forces
        feet = result.toes[k, result.stance[k]]
        f = s.forces[k, result.stance[k]]
        assert max(_balance(feet, s.com[k], f, s.mass)) < 1e-9
        assert (f @ n > 0).all() and inside_friction_cone(f, n, 0.5, atol=1e-12).all()
        assert (s.forces[k, result.swing[k]] == 0).all()
    assert s.residual_force < 1e-9 and s.residual_moment < 1e-9
    if slope:  # the tangential forces hold m g sin θ
        k = 300
        f = s.forces[k].sum(axis=0)
        assert abs(np.linalg.norm(f - (f @ n) * n) - s.mass * G * math.sin(math.radians(slope))) < 1e-9


@pytest.mark.compiling
@pytest.mark.parametrize(("slope", "keep"), [(0.0, 0.15), (10.0, 0.15)])
def test_keep_margin_shortens_the_stride(hexapod_module: Any, hexapod: Hexapod, slope: float,
                                         keep: float) -> None:
    ground = gait.Ground(math.radians(slope))
    plan = gait_statics.keep_margin(hexapod_module, hexapod, gait.GaitParameters(), ground, keep)
    assert plan.params.stride < 0.1 and plan.margin >= keep
    s = gait_statics.check_walk(plan.result)  # the margin recomputed on the chosen walk
    assert s.margin.min() >= keep and s.ok
    failing = [stride for stride, m in plan.tries if m < keep]
    assert min(failing) - plan.params.stride <= 0.02 * 0.1 + 1e-12  # within the tolerance of the largest
    with pytest.raises(ValueError, match=r"cannot be kept: standing on either tripod gives at most 0\.1"):
        gait_statics.keep_margin(hexapod_module, hexapod, gait.GaitParameters(), ground, 0.2)


@pytest.mark.compiling
def test_walk_command_margin(hexapod_module: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = ["walk", "--module", str(hexapod_module.folder), "--out", str(tmp_path), "--no-animation"]
    assert main([*args, "--margin", "0.15"]) == 0
    text = capsys.readouterr().out
    line = next(x for x in text.splitlines() if x.startswith("min stability margin"))
    assert float(line.split()[3]) >= 0.15 and "max |f_t|/f_n" in text
    assert (tmp_path / "margin.png").stat().st_size > 10_000
    assert main([*args, "--margin", "0.3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot be kept" in err[0]


# -- leaning uphill ---------------------------------------------------------------------------------------

@pytest.mark.parametrize(("slope", "uphill"), [(10.0, 0.0), (20.0, 135.0), (0.0, 0.0)])
def test_the_uphill_direction_lies_in_the_ground_and_rises_by_sin_slope(slope: float, uphill: float) -> None:
    ground = gait.Ground(math.radians(slope), math.radians(uphill))
    d = ground.uphill_direction
    assert abs(np.linalg.norm(d) - 1) < 1e-15 and abs(d @ ground.normal) < 1e-16
    assert abs(d[2] - math.sin(math.radians(slope))) < 1e-16  # a metre along it rises sin θ
    assert abs(math.atan2(d[1], d[0]) - math.radians(uphill)) < 1e-15
    with pytest.raises(ValueError, match="lean must be a finite number"):
        gait.GaitParameters(lean=math.nan)


@pytest.mark.compiling
@pytest.mark.parametrize(("slope", "uphill"), [(10.0, 0.0), (20.0, 90.0), (15.0, 200.0)])
def test_balanced_lean_gives_the_flat_grounds_standing_margin(hexapod_module: Any, hexapod: Hexapod,
                                                              slope: float, uphill: float) -> None:
    """Leaning by ``balanced_lean`` puts the standing CoM's projection along gravity where flat ground
    puts it relative to the feet: the standing margin on the slope equals the flat ground's (the feet
    form the same polygon in their plane), which the unleaned body loses by about h tan θ; the lean is
    more than the CoM's h tan θ, as the legs' links move with the body only in part. (Uphill askew to
    the body, 200°, the legs' IK moves the CoM a few µm across the uphill direction, which a lean
    along it leaves.)"""
    params = gait.GaitParameters()
    ground = gait.Ground(math.radians(slope), math.radians(uphill))
    flat = gait_statics.standing_margin(hexapod_module, hexapod, gait.Ground(), params)
    lean = gait_statics.balanced_lean(hexapod_module, hexapod, params, ground)
    leaned = gait_statics.standing_margin(hexapod_module, hexapod, ground, replace(params, lean=lean))
    assert abs(leaned - flat) < (1e-9 if uphill % 90 == 0 else 1e-5)
    unleaned = gait_statics.standing_margin(hexapod_module, hexapod, ground, params)
    assert unleaned < flat - 0.01
    com, _ = gait_statics.standing(hexapod_module, hexapod, ground, params)
    assert float(ground.distance(com)) * math.tan(ground.slope) < lean < 0.1


@pytest.mark.compiling
@pytest.mark.parametrize("uphill", [90.0, 180.0])
def test_a_leaning_walk_across_or_down_a_slope_keeps_the_flat_grounds_margin(hexapod_module: Any,
                                                                             hexapod: Hexapod,
                                                                             uphill: float) -> None:
    """A straight walk on a 20° slope rising across the path (90°) or behind it (180°): the unleaned
    body loses 24-48 mm of margin against flat ground, the balanced lean keeps it within 5 mm."""
    params = gait.GaitParameters(straight=0.4, turn=0.0)
    ground = gait.Ground(math.radians(20.0), math.radians(uphill))

    def margin(p: gait.GaitParameters, g: gait.Ground) -> float:
        result = gait.walk(hexapod_module, hexapod, p, g)
        assert result.ok
        return float(gait_statics.check_walk(result).margin.min())

    flat = margin(params, gait.Ground())
    lean = gait_statics.balanced_lean(hexapod_module, hexapod, params, ground)
    leaned, unleaned = margin(replace(params, lean=lean), ground), margin(params, ground)
    assert abs(leaned - flat) < 0.005 and unleaned < flat - 0.02
