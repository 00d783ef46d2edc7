"""The geometric nullspace demo [COOP Section 4.3]: arm0 slides along the circle without moving it."""

import struct

import numpy as np
import pytest

from gagen.apps.cooperative import nullspace_demo as nd
from gagen.cli import main as gagen_main

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def runs():
    return {projected: nd.run(projected) for projected in (True, False)}


def test_circumcircle_and_target_lie_on_the_kernels_circle(runs):
    from gagen.algebra.signature import cga3d
    from gagen.interp import MultiVector
    from gagen.model.conformal import EUCLID, location
    from gagen.model.primitives import centre, radius, unit_normal

    r = runs[True]
    m = nd.module()
    kernel = next(k for k in m.manifest["kernels"] if k["name"] == "primitive")
    rows = next(port["rows"] for port in kernel["outputs"] if port["name"] == "X_c")
    X = MultiVector.from_blades(cga3d(), dict(zip(rows, np.array(m.c.primitive(r.q[0])[0]), strict=True)))
    c = np.array([location(centre(X))[k] for k in EUCLID])
    n = np.array([unit_normal(X)[k] for k in EUCLID])
    assert np.allclose(r.circle.centre, c, atol=1e-12)
    assert abs(r.circle.radius - float(radius(X))) < 1e-12
    assert abs(abs(r.circle.normal @ n) - 1.0) < 1e-12
    start = r.points[0]
    assert max(r.circle.distance(p) for p in start) < 1e-12
    assert r.circle.distance(r.target) < 1e-12
    u, v, w = start[0] - c, r.target - c, start[1] - c
    assert np.isclose(np.arccos(u @ v / np.linalg.norm(u) / np.linalg.norm(v)), np.pi / 3, atol=1e-12)
    assert np.cross(u, v) @ r.circle.normal > 0 and np.cross(u, w) @ r.circle.normal > 0  # toward arm1
    assert np.isclose(r.target_distance[0], r.circle.radius)  # the 60° chord


def test_projected_run_reaches_the_target_and_keeps_the_circle(runs):
    r = runs[True]
    # exponential convergence along the arc at rate ≈ k: 0.493 m → 1.2e-3 m in 4 s (k = 1.5)
    assert r.target_distance[-1] < 0.01 * r.target_distance[0]
    assert np.all(np.diff(r.target_distance) < 0)
    # the exact flow keeps V_Sc; what is left is the RK4 error (2.3e-9 at dt = 0.01)
    assert r.similarity_distance.max() < 1e-6
    assert r.circle_distance.max() < 1e-6
    # N(J_G) is block diagonal: arm1 and arm2 do not move, only arm0 slides along the circle
    assert np.abs(r.q[:, 7:] - r.q[0, 7:]).max() < 1e-12
    assert np.abs(r.points[:, 1:] - r.points[0, 1:]).max() < 1e-12
    # the recorded similarity distance is the task kernel's ‖e‖ w.r.t. the initial V_Sc
    m = nd.module()
    V_Sd = np.array(m.c.similarity(r.q[0])[0])
    for k in (0, 57, len(r.t) - 1):
        assert r.similarity_distance[k] == np.linalg.norm(np.array(m.c.task(r.q[k], V_Sd)[0]))
        J_G = np.array(m.c.similarity(r.q[k])[2])
        qdot = nd.velocity(m, r.q[k], r.target, r.gain, projected=True)
        assert np.linalg.norm(J_G @ qdot) < 1e-12 * max(1.0, np.linalg.norm(qdot))


def test_unprojected_run_moves_the_circle(runs):
    r = runs[False]
    assert r.target_distance[-1] < 0.01 * r.target_distance[0]  # the secondary task alone is reached too
    assert r.similarity_distance.max() > 1e-2  # 0.116 at t = 0.53 s
    assert r.circle_distance.max() > 1e-2  # 0.066 m inside the circle
    assert r.similarity_distance[-1] < 0.1 * r.similarity_distance.max()  # back on the circle at the target


def test_remaining_similarity_drift_is_fourth_order_in_dt():
    coarse = nd.run(True, steps=100, dt=0.04).similarity_distance.max()
    fine = nd.run(True, steps=200, dt=0.02).similarity_distance.max()
    assert 1e-8 < fine < coarse
    assert 10 < coarse / fine < 25  # 2⁴ = 16: the drift is the integrator's, not the projector's


def _png_size(path):
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    return struct.unpack(">II", data[16:24])


def test_plot_shows_the_recorded_numbers(runs, tmp_path):
    results = [runs[True], runs[False]]
    path = nd.plot(results, tmp_path)
    assert path == tmp_path / nd.PLOT_NAME
    assert _png_size(path) == (1200, 800)
    fig = nd.figure(results)
    lines = {line.get_gid(): line for ax in fig.axes for line in ax.get_lines() if line.get_gid()}
    for r in results:
        for name in ("similarity_distance", "target_distance", "circle_distance"):
            x, y = lines[f"{name}:{r.projected}"].get_data()
            assert np.array_equal(x, r.t) and np.array_equal(y, getattr(r, name))
        assert np.array_equal(np.array(lines[f"path:{r.projected}"].get_data_3d()).T, r.points[:, 0])
    circle = np.array(lines["circle"].get_data_3d()).T
    assert max(results[0].circle.distance(p) for p in circle) < 1e-12
    log_axes = [ax for ax in fig.axes if ax.name != "3d" and ax.get_yscale() == "log"]
    assert len(log_axes) == 2


def test_main_prints_the_final_numbers(tmp_path, capsys):
    assert gagen_main(["nullspace", "--out", str(tmp_path), "--steps", "100", "--dt", "0.04"]) == 0
    out = capsys.readouterr().out
    assert "projected" in out and "not projected" in out and "similarity distance max" in out
    assert _png_size(tmp_path / nd.PLOT_NAME) == (1200, 800)


def test_the_demo_takes_a_users_circle_spec_and_refuses_another_primitive(tmp_path, capsys):
    """``gagen nullspace SPEC``: a spec spanning a point is one line and exit status 2 before anything is
    built; the bundled three-Panda circle's own spec file gives the bundled run exactly."""
    from gagen.apps.cooperative import nullspace_demo
    from gagen.cli import main
    from gagen.registry import bundled_specs

    bundled = bundled_specs("cooperative")
    assert main(["nullspace", str(bundled["panda_point"]), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "moves a point along its circle; this system spans a point" in err[0]
    by_path = nullspace_demo.run(True, steps=3, system=str(bundled["three_pandas_circle"]))
    by_name = nullspace_demo.run(True, steps=3)
    np.testing.assert_array_equal(by_path.q, by_name.q)
