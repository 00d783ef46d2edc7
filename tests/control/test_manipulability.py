"""Velocity and force manipulability of the cooperative similarity [COOP Sec. 3.11, Eq. 59], its nullspace
ascent, the sweep's columns and the Fig. 18 line and plane nullspace demos."""

import math
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import gagen
from gagen.apps.cooperative.catalogue import build_kernels
from gagen.control import force_manipulability as fm
from gagen.robots.spec import load_system

READY = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785] * 3)
R0 = 0.5  # the prismatic points' base radius


@pytest.fixture(scope="module")
def pandas():
    return gagen.load("generated/three_pandas_circle")


def _prismatic_spec(r0: float = R0) -> str:
    """Three points on prismatic joints along the radii of a horizontal circle of radius r0 at 0°, 120°,
    240°: at q = (s, s, s) they span the circle of radius r0 + s about the origin."""
    chains = []
    for i in range(3):
        a = 2 * math.pi * i / 3
        chains.append(f"  - name: arm{i}\n    base: {{xyz: [{r0 * math.cos(a)!r}, {r0 * math.sin(a)!r}, "
                      f"0.0], rpy: [0.0, 0.0, {a!r}]}}\n    joints:\n"
                      "      - {name: slide, type: prismatic, axis: [1, 0, 0]}\n")
    return "name: prisms\nprimitive: circle\nchains:\n" + "".join(chains)


@pytest.fixture(scope="module")
def prisms():
    """The prismatic system's ``similarity`` kernel as a CasADi Function (the interpreter's path, no C)."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "prisms.yaml"
        path.write_text(_prismatic_spec())
        system, _ = load_system(path)
    return build_kernels(system)["similarity"].function


def _similarity(function):
    return lambda q: [np.array(v) for v in function(q)]


def _random_q(seed: int) -> np.ndarray:
    return READY + 0.4 * np.random.default_rng(seed).standard_normal(21)


# -- the ellipsoids against numpy ----------------------------------------------------------------------
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_ellipsoids_against_numpy(pandas, seed):
    J = np.array(pandas.c.similarity(_random_q(seed))[2])
    M = fm.velocity_ellipsoid(J)
    np.testing.assert_allclose(M, J @ J.T, rtol=0, atol=1e-15)
    P = fm.force_ellipsoid(J, rank=6)
    np.testing.assert_allclose(P, np.linalg.pinv(J @ J.T, rcond=1e-10, hermitian=True), rtol=0,
                               atol=1e-9 * np.abs(P).max())
    np.testing.assert_allclose(M @ P @ M, M, atol=1e-12)  # the Moore-Penrose conditions on range J_G
    np.testing.assert_allclose(P @ M @ P, P, atol=1e-10 * np.abs(P).max())
    found = fm.ellipsoids(J, rank=6)
    s = np.linalg.svd(J, compute_uv=False)
    np.testing.assert_allclose(found.velocity_lengths, s[:6], rtol=1e-13)
    np.testing.assert_allclose(found.force_lengths, 1 / s[:6], rtol=1e-13)
    # F on the force ellipsoid's axis i: unit torque norm ‖J_Gᵀ F‖ = 1 at the length 1/σ_i
    for i in range(6):
        np.testing.assert_allclose(np.linalg.norm(J.T @ (found.axes[:, i] * found.force_lengths[i])), 1.0,
                                   rtol=1e-12)
    assert math.isclose(fm.force_volume(J, 6), math.pi**3 / 6 / np.prod(s[:6]), rel_tol=1e-13)
    # β_D = (e_Dᵀ M_S e_D)^(-1/2) and the largest pure dilation force per unit torque
    e_D = np.eye(7)[3]
    beta = fm.dilation_force_index(J)
    assert math.isclose(beta, 1 / math.sqrt(e_D @ M @ e_D), rel_tol=1e-14)
    assert math.isclose(np.linalg.norm(J.T @ (beta * e_D)), 1.0, rel_tol=1e-14)


def test_singular_and_bad_inputs_are_reported():
    J = np.zeros((7, 3))
    J[3] = [1.0, 0.0, 0.0]
    J[4] = [0.0, 2.0, 0.0]
    with pytest.raises(ValueError, match="singular configuration"):
        fm.force_ellipsoid(J, rank=3)
    assert fm.force_volume(J, rank=3) == math.inf
    assert fm.ellipsoids(J, rank=3).force_lengths[-1] == math.inf
    assert fm.dilation_force_index(np.ones((7, 2)) * np.eye(7, 2)[:, [1, 0]]) == math.inf  # zero e0∞ row
    with pytest.raises(ValueError, match="J_G: expected the 7 × n"):
        fm.velocity_ellipsoid(np.zeros((6, 3)))
    with pytest.raises(ValueError, match="rank: expected an integer between 1 and 3"):
        fm.ellipsoids(J, rank=4)
    with pytest.raises(ValueError, match="objective: expected one of dilation, volume"):
        fm.objective("speed", J)


# -- a closed form: three prismatic points on a circle --------------------------------------------------
@settings(max_examples=25, deadline=None)
@given(s=st.floats(-0.3, 0.6))
def test_prismatic_points_in_closed_form(prisms, s):
    """At q = (s, s, s) the circle has radius r = r0 + s about the origin and δr = mean δq, δc = (2/3)
    Σ δq_i u_i, so J_G's e0∞ row is −(1, 1, 1)/(3r) (λ e0∞ scales by e^−λ), its e1∞ e2∞ rows are
    (2/(3r)) u_i and the rest is 0: M_S = diag(0, 0, 0, 1/(3r²), 2/(3r²), 2/(3r²), 0), β_D = √3 r, and by
    symmetry ∇β_D = (1, 1, 1)/√3 (all three slide out by δ: r → r + δ)."""
    r = R0 + s
    q = np.full(3, s)
    similarity = _similarity(prisms)
    J = np.array(similarity(q)[2])
    u = np.array([[math.cos(2 * math.pi * i / 3), math.sin(2 * math.pi * i / 3)] for i in range(3)])
    expected = np.zeros((7, 3))
    expected[3] = -1 / (3 * r)
    expected[4:6] = 2 / (3 * r) * u.T
    np.testing.assert_allclose(J, expected, atol=1e-12)
    np.testing.assert_allclose(fm.velocity_ellipsoid(J), np.diag([0, 0, 0, 1, 2, 2, 0]) / (3 * r * r),
                               atol=1e-11)
    np.testing.assert_allclose(fm.force_ellipsoid(J, rank=3), np.diag([0, 0, 0, 3, 1.5, 1.5, 0]) * r * r,
                               atol=1e-10)
    beta = fm.dilation_force_index(J)
    assert math.isclose(beta, math.sqrt(3) * r, rel_tol=1e-12)
    assert math.isclose(beta, math.sqrt(fm.force_ellipsoid(J, rank=3)[3, 3]), rel_tol=1e-12)  # e_D: an axis
    assert math.isclose(fm.force_volume(J, 3), 4 * math.pi / 3 * 3 * math.sqrt(3) * r**3 / 2, rel_tol=1e-12)
    J0, dJ = fm.jacobian_derivatives(similarity, q)
    np.testing.assert_allclose(fm.dilation_force_gradient(J0, dJ), np.full(3, 1 / math.sqrt(3)), atol=1e-9)


def test_gradient_against_casadi_ad(prisms):
    """Away from symmetry: the central-difference gradient against CasADi's exact AD of the kernel."""
    q = ca.MX.sym("q", 3)
    g = prisms(q)[2][3, :]
    beta = 1 / ca.norm_2(g)
    exact = ca.Function("grad", [q], [beta, ca.gradient(beta, q)])
    x = np.array([0.13, -0.21, 0.32])
    value, gradient = (np.array(v).ravel() for v in exact(x))
    J, dJ = fm.jacobian_derivatives(_similarity(prisms), x)
    assert math.isclose(fm.dilation_force_index(J), float(value[0]), rel_tol=1e-14)
    np.testing.assert_allclose(fm.dilation_force_gradient(J, dJ), gradient, rtol=1e-8)


@pytest.mark.parametrize("name", fm.OBJECTIVES)
def test_objective_gradients_against_central_differences(pandas, name):
    similarity = pandas.c.similarity
    q = _random_q(7)
    J, dJ = fm.jacobian_derivatives(similarity, q)
    _, gradient = fm.objective(name, J, dJ, rank=6)
    h = 1e-6
    numeric = np.array([(fm.objective(name, similarity(q + h * e)[2], rank=6)[0]
                         - fm.objective(name, similarity(q - h * e)[2], rank=6)[0]) / (2 * h)
                        for e in np.eye(21)])
    np.testing.assert_allclose(gradient, numeric, atol=1e-7 * np.abs(numeric).max())


# -- the nullspace ascent ---------------------------------------------------------------------------------
def test_ascent_raises_the_index_and_holds_the_circle(pandas):
    from gagen.apps.cooperative.nullspace_demo import circumcircle
    from gagen.robots.points import end_points

    result = fm.maximise(pandas.c.similarity, pandas.c.task, READY, rank=6, steps=40, step_size=0.05)
    assert len(result.objective) == 41
    assert np.all(np.diff(result.dilation) > 0)  # every step climbs
    assert result.dilation[-1] > 1.06 * result.dilation[0]  # 3.0526 -> 3.2606 (60 steps: 3.2821)
    assert result.error_norm.max() <= 1e-8  # measured 1.1e-13
    np.testing.assert_allclose(result.objective, np.log(result.dilation), rtol=1e-14)
    # independent of the task kernel: the circle through the end points is the start's
    start, end = (circumcircle(*end_points(pandas, q)) for q in (result.q[0], result.q[-1]))
    assert np.abs(start.centre - end.centre).max() < 1e-10 and abs(start.radius - end.radius) < 1e-10
    assert abs(start.normal @ end.normal - 1) < 1e-12
    assert np.abs(result.q[-1] - READY).max() > 0.3  # the arms did move


# -- the sweep's columns ---------------------------------------------------------------------------------
def test_sweep_columns_equal_direct_computations(pandas):
    pytest.importorskip("pyarrow")
    from gagen.sweep.problems import Manipulability

    sweep = Manipulability(samples=40, chunk=40, seed=3)
    table = sweep.compute(0)
    q = sweep.configurations(0)
    J = [np.array(pandas.c.similarity(x)[2]) for x in q]
    np.testing.assert_allclose(table.column("dilation_force").to_numpy(),
                               [fm.dilation_force_index(j) for j in J], rtol=1e-13)
    np.testing.assert_allclose(table.column("force_volume").to_numpy(), [fm.force_volume(j, 6) for j in J],
                               rtol=1e-12)


# -- the command -------------------------------------------------------------------------------------------
def test_command_on_a_spec_file_and_refusals(tmp_path, capsys):
    from gagen.apps.cooperative import manipulability_command as mc
    from gagen.cli import main
    from gagen.registry import bundled_specs

    specs = bundled_specs("cooperative")
    spec = str(specs["three_pandas_circle"])  # a path, as a user's spec file is given
    assert main(["manipulability", spec, "--out", str(tmp_path), "--steps", "5"]) == 0
    out = capsys.readouterr().out
    assert "β_D 3.0526" in out and "objective dilation" in out
    assert (tmp_path / mc.PLOT_NAME).stat().st_size > 10_000
    assert main(["manipulability", "two_iiwas_line", "--objective", "dilation", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "two_iiwas_line spans a line, which has no dilation" in err[0]
    analysis = mc.analyse("three_pandas_circle", steps=3)
    fig = mc.figure(analysis)
    lines = {line.get_gid(): line for ax in fig.axes for line in ax.get_lines() if line.get_gid()}
    x, y = lines["force:start"].get_data()
    # the force section meets the e0∞ axis (y = 0 on the drawn plane) at ±β_D
    crossing = np.abs(x[np.argmin(np.abs(y) + (x < 0))])
    assert math.isclose(crossing, analysis.result.dilation[0], rel_tol=1e-3)
    np.testing.assert_array_equal(lines["dilation"].get_data()[1], analysis.result.dilation)


# -- Fig. 18: the line and plane nullspaces -----------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("system", ["two_iiwas_line", "three_iiwas_plane"])
def test_fig18_tangential_objective_keeps_the_primitive(system):
    from gagen.apps.cooperative import geometric_nullspace as gn

    projected, free = (gn.run(system, p, steps=100, dt=0.04) for p in (True, False))
    assert projected.similarity_distance.max() <= 1e-8  # line 7.6e-12, plane 5.4e-12 (dt = 0.01)
    assert projected.off_distance.max() <= 1e-8
    # ṗ_0 = k P_T (p* − p_0): the tangential target is approached as 0.15 e^(−k t)
    np.testing.assert_allclose(projected.tangential_distance, gn.ALONG * np.exp(-1.5 * projected.t),
                               rtol=1e-5)
    assert abs(projected.target_distance[-1] - gn.OFF) < 1e-3  # the normal part is rejected
    assert np.abs(projected.q[:, 7:] - projected.q[0, 7:]).max() < 1e-12  # N is block diagonal
    assert free.similarity_distance.max() >= 1e-2  # line 0.062, plane 0.058
    assert free.target_distance[-1] < 1e-3 and free.off_distance[-1] > 0.09


@pytest.mark.slow  # builds the two iiwas' module on first use
def test_nullspace_verb_picks_the_primitive(tmp_path, capsys):
    from gagen.cli import main

    assert main(["nullspace", "three_pandas_circle", "--primitive", "line", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--primitive line: three_pandas_circle spans a circle" in err[0]
    assert main(["nullspace", "--primitive", "line", "--steps", "5", "--dt", "0.04",
                 "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "similarity distance max" in out and (tmp_path / "nullspace_line.png").is_file()
