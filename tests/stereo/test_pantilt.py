"""The pan-tilt head (``pantilt``, ``pantilt_loop``): its kinematics against an independent rotation-matrix
chain, the line Jacobian against finite differences, L_Vref (Eq. 29) and the law against numpy, the ideal
loop's reaching time against the closed-form bound, and the loop closed through rendering and the
estimator converging below 2 px with the object moving, with and without image noise."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import gagen
from gagen.apps.stereo import pantilt, pantilt_loop, scene
from gagen.apps.stereo.calibration import Camera, load_rig
from gagen.apps.stereo.pipeline import Estimator
from gagen.errors import SpecError

RIG = Path(__file__).resolve().parents[2] / "gagen" / "apps" / "stereo" / "robots" / "stereo_rig.yaml"


@pytest.fixture(scope="module")
def rig():
    return load_rig(RIG)


@pytest.fixture(scope="module")
def head(rig):
    return pantilt.Head(rig)


@pytest.fixture(scope="module")
def reference(rig):
    return pantilt.Head(rig, interpreted=True)


def matrix_chain(rig, q, pan_behind=0.08, tilt_offset=(0.0, 0.04, 0.03)):
    """The left camera's pose in H by 4×4 matrices: T(pan offset) R(−y, q0) T(tilt offset) R(x, q1) T(mount),
    the offsets restated from the head's description (the rig file's defaults unless given), the
    rotations by scipy."""
    b = rig.right_in_left.t

    def T(p):
        h = np.eye(4)
        h[:3, 3] = p
        return h

    def R(axis, angle):
        h = np.eye(4)
        h[:3, :3] = Rotation.from_rotvec(np.asarray(axis, float) * angle).as_matrix()
        return h

    pan = b / 2 + [0, 0, -pan_behind]
    tilt = np.array(tilt_offset)
    return T(pan) @ R([0, -1, 0], q[0]) @ T(tilt) @ R([1, 0, 0], q[1]) @ T(-pan - tilt)


def bivector(point, direction):
    """A line as the kernels' bivector rows (e12, e13, e23, e1∞, e2∞, e3∞) = (d_z, −d_y, d_x, p × d)."""
    d = np.asarray(direction, float)
    return np.concatenate([[d[2], -d[1], d[0]], np.cross(point, d)])


angles = st.floats(-1.2, 1.2)
targets = st.tuples(st.floats(-0.5, 0.7), st.floats(-0.4, 0.4), st.floats(0.5, 1.5))


@settings(max_examples=20, deadline=None)
@given(pan=angles, tilt=angles, target=targets)
def test_kinematics_and_reference_line_match_an_independent_matrix_chain(rig, head, pan, tilt, target):
    q, x = np.array([pan, tilt]), np.array(target)
    step = head(q, x)
    H = matrix_chain(rig, q)
    np.testing.assert_allclose(step.camera.R, H[:3, :3], atol=1e-12)
    np.testing.assert_allclose(step.centre, H[:3, 3], atol=1e-12)
    np.testing.assert_allclose(step.camera.t, H[:3, 3], atol=1e-12)
    np.testing.assert_allclose(step.line, bivector(H[:3, 3], H[:3, 2]), atol=1e-12)  # the optical axis
    towards = (x - H[:3, 3]) / np.linalg.norm(x - H[:3, 3])
    np.testing.assert_allclose(step.reference, bivector(H[:3, 3], towards), atol=1e-12)  # Eq. 29
    np.testing.assert_allclose(step.s, step.line - step.reference, atol=1e-15)
    assert step.conditioning == pytest.approx(math.cos(tilt) ** 2, abs=1e-12)  # perpendicular axes


def test_a_users_head_from_the_rig_file(tmp_path):
    """A rig file with its own ``head:`` (pan axis 20 cm behind, tilt offset (1, −5, 2) cm): the head's
    kinematics on the interpreter against the matrix chain with those numbers; bad head fields are
    refused naming the field."""
    text = RIG.read_text() + "head: {pan_behind: 0.2, tilt_offset: [0.01, -0.05, 0.02], tilt_limit: 1.0}\n"
    (tmp_path / "rig.yaml").write_text(text)
    rig = load_rig(tmp_path / "rig.yaml")
    assert rig.head.pan_limit == 2.6 and rig.head.tilt_limit == 1.0
    head = pantilt.Head(rig, interpreted=True)
    for q in ([0.3, -0.4], [-1.1, 0.7]):
        H = matrix_chain(rig, np.array(q), 0.2, (0.01, -0.05, 0.02))
        step = head(np.array(q), np.array([0.1, 0.0, 1.0]))
        np.testing.assert_allclose(step.camera.R, H[:3, :3], atol=1e-12)
        np.testing.assert_allclose(step.centre, H[:3, 3], atol=1e-12)
    for bad, field in (("{pan_behind: .nan}", "head.pan_behind"), ("{tilt_limit: 4}", "head.tilt_limit"),
                       ("{tilt_offset: [0, 1]}", "head.tilt_offset"), ("{roll: 1}", "roll"), ("3", "head")):
        (tmp_path / "bad.yaml").write_text(RIG.read_text() + f"head: {bad}\n")
        with pytest.raises(SpecError, match=field.replace(".", r"\.")):
            load_rig(tmp_path / "bad.yaml")


def test_compiled_kernel_matches_the_interpreter(head, reference):
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, x = rng.uniform(-1, 1, 2), rng.uniform([-0.4, -0.3, 0.6], [0.6, 0.3, 1.4])
        a, b = head(q, x), reference(q, x)
        for name in ("motor", "line", "reference", "s", "J", "sigma", "u", "u_paper"):
            np.testing.assert_allclose(getattr(a, name), getattr(b, name), atol=1e-12, err_msg=name)


def test_line_jacobian_against_finite_differences_and_the_law_against_numpy(head):
    rng = np.random.default_rng(7)
    h = 1e-6
    k, eps = head.gains
    for _ in range(5):
        q, x = rng.uniform(-1, 1, 2), rng.uniform([-0.4, -0.3, 0.6], [0.6, 0.3, 1.4])
        step = head(q, x)
        for j in range(2):
            dq = np.zeros(2)
            dq[j] = h
            fd = (head(q + dq, x).line - head(q - dq, x).line) / (2 * h)
            np.testing.assert_allclose(step.J[:, j], fd, atol=1e-9)
        sigma = np.linalg.lstsq(step.J, step.s, rcond=None)[0]
        np.testing.assert_allclose(step.sigma, sigma, atol=1e-12)
        np.testing.assert_allclose(step.u, -k * np.tanh(eps * sigma), atol=1e-12)
        paper = -k * np.linalg.lstsq(step.J, np.tanh(eps * step.s), rcond=None)[0]
        np.testing.assert_allclose(step.u_paper, paper, atol=1e-10)
        assert step.conditioning == pytest.approx(np.linalg.det(step.J[:3].T @ step.J[:3]), abs=1e-12)


def test_looking_along_the_pan_axis_is_reported_not_a_nan(rig, head):
    """Tilted by −90° the optical axis runs along the pan axis (−y): the pan column's direction part
    vanishes."""
    step = head(np.array([0.3, -math.pi / 2]), np.array([0.1, -1.0, 0.0]))
    assert np.isfinite(step.u).all() and np.isfinite(step.sigma).all()
    assert step.conditioning < 1e-20 < head(np.array([0.3, -1.0]), np.array([0.1, -1.0, 0.0])).conditioning


def test_ideal_loop_reaches_the_boundary_layer_within_the_closed_form_bound(rig, head):
    path = pantilt_loop.for_rig(rig)
    bound = pantilt_loop.reaching_bound(head, path)
    run = pantilt_loop.run_ideal(rig, 1.5, head=head, trajectory=path)
    reached = pantilt_loop.reaching_time(run, bound.layer)
    assert bound.earliest <= reached <= bound.bound, (bound, reached)
    after = run.t >= reached
    assert np.abs(run.sigma[after]).max() <= bound.layer  # it stays in the layer
    # inside the layer σ̇ ≈ −kε σ + d: |σ| ≲ D / (kε), the object's lag
    k, eps = head.gains
    assert np.abs(run.sigma[run.t >= 0.5]).max() <= bound.drift / (k * eps)
    assert run.line_offset_px[run.sample_t >= 0.5].max() < 1.0


def test_static_object_reaching_time_without_drift(rig, head):
    """With the object at rest (D = 0) the bound narrows to [σ0/(γ_max k), σ0/(γ_min k tanh 1)]."""
    still = dataclasses.replace(pantilt_loop.for_rig(rig), omega=0.0)
    bound = pantilt_loop.reaching_bound(head, still)
    assert bound.drift == 0.0
    run = pantilt_loop.run_ideal(rig, 0.6, head=head, trajectory=still)
    assert bound.earliest <= pantilt_loop.reaching_time(run, bound.layer) <= bound.bound
    assert run.angle_deg[-1] < 1e-3  # settled on the object


@pytest.fixture(scope="module")
def small_rig(rig):
    """The bundled rig with 320 × 240 images (f = 300 px): the same geometry, a quarter of the pixels."""
    cam = Camera(300.0, 300.0, 159.5, 119.5, 320, 240)
    return dataclasses.replace(rig, left=cam, right=cam)


@pytest.mark.parametrize("noise", [0.0, 1.0])
def test_vision_loop_centres_the_moving_axis_below_2_px(small_rig, head, noise):
    estimator = Estimator(small_rig, gagen.load("generated/stereo_rig").c)
    options = scene.SceneOptions(vertex_jitter=noise, pixel_noise=2 * noise)
    run = pantilt_loop.run_vision(small_rig, 1.2, head=head, estimator=estimator, options=options, seed=1)
    assert not run.failures
    assert run.line_offset_px[0] > 50  # it starts far off the centre
    m = run.summary(transient=0.5)
    assert m["line_offset_px_max"] < 2.0 and m["centre_offset_px_max"] < 2.0 and m["angle_deg_max"] < 0.5
    assert m["estimate_mm_max"] < 10.0 and m["estimate_deg_max"] < 5.0


def test_track_head_refuses_a_bad_rig_file(tmp_path):
    bad = tmp_path / "rig.yaml"
    bad.write_text("app: stereo\nname: x\n")
    command = [sys.executable, "-m", "gagen.cli", "track-head", str(bad), "--out", str(tmp_path)]
    result = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1 and "rig.yaml" in result.stderr
