"""Sliding-mode pose tracking [SMC V-VI]: the generated step against independent computations, the closed
loop against the boundary-layer bound, and the C real-time runner against the Python simulation."""

import math

import numpy as np
import pytest

from gagen.algebra.signature import cga3d
from gagen.apps.cooperative.bundled import bundled_systems
from gagen.codegen.compiler import CompilerNotFound, find_compiler
from gagen.control import smc
from gagen.interp import MultiVector
from gagen.model import kinematics as kin
from gagen.symbolic.flatten import casadi_op_count

try:
    find_compiler()
    HAVE_CC = True
except CompilerNotFound:
    HAVE_CC = False

needs_cc = pytest.mark.skipif(not HAVE_CC, reason="no C compiler")

JOINTS = tuple(bundled_systems()["panda_point"].chains[0].joints)
N = 7


@pytest.fixture(scope="module")
def kernel():
    return smc.step_kernel(JOINTS)


@pytest.fixture(scope="module")
def function(kernel):
    return kernel.trace().function


@pytest.fixture(scope="module")
def built():
    return smc.build(JOINTS)


def interp_pose(q):
    """x = [end position; tool z-axis direction] from gagen's dense float interpreter."""
    zero = MultiVector.zero(cga3d())
    motor, _, position = kin.chain_pose(zero, JOINTS, [float(v) for v in q])
    line = motor.sandwich(zero.make({"e12": 1.0}))
    return np.array([position["e1"], position["e2"], position["e3"], line["e23"], -line["e13"], line["e12"]])


def numpy_u(J, x, x_ref, K=smc.GAIN, epsilon=smc.EPSILON, damping=smc.DAMPING):
    r = K * np.tanh(epsilon * (x - x_ref))
    return -J.T @ np.linalg.solve(J @ J.T + damping**2 * np.eye(J.shape[0]), r)


def configurations(count=6, seed=3):
    rng = np.random.default_rng(seed)
    return [np.array(smc.PANDA_Q0)] + [rng.uniform(-2.5, 2.5, N) for _ in range(count - 1)]


def test_pose_is_a_point_and_a_unit_direction():
    x = interp_pose(smc.PANDA_Q0)
    assert np.linalg.norm(x[3:]) == pytest.approx(1.0, abs=1e-14)
    # Panda ready pose: flange 0.307 m in front, tool z axis pointing down; the start turns it by 2.5 rad
    ready = interp_pose([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    assert ready[:3] == pytest.approx([0.3070, 0.0, 0.5903], abs=1e-3)
    assert ready[3:] == pytest.approx([0.0, 0.0, -1.0], abs=1e-6)
    c, s = math.cos(2.5), math.sin(2.5)
    assert x[:2] == pytest.approx([c * ready[0], s * ready[0]], abs=1e-12)


@pytest.mark.parametrize("q", configurations())
def test_step_kernel_matches_interpreter_finite_differences_and_numpy(function, q):
    x_ref = smc.reference(0.3)
    x, J, u = (np.asarray(v, dtype=float) for v in function(q, x_ref))
    x, u = x.ravel(), u.ravel()
    assert x == pytest.approx(interp_pose(q), abs=1e-12)
    h = 1e-6
    fd = np.column_stack([(interp_pose(q + h * e) - interp_pose(q - h * e)) / (2 * h) for e in np.eye(N)])
    assert np.abs(J - fd).max() < 1e-6
    assert np.linalg.matrix_rank(J, tol=1e-9) == 5  # ḋ ⊥ d: the direction rows lose one rank
    assert np.abs(J[3:].T @ x[3:]).max() < 1e-12
    reference = numpy_u(J, x, x_ref)  # |u| reaches ~500 rad/s when saturated: compare relatively
    assert np.abs(u - reference).max() < 1e-12 * max(1.0, np.abs(reference).max())


@pytest.mark.compiling
@needs_cc
def test_compiled_step_gives_casadis_doubles(function, built):
    """CasADi's doubles but for the joint angles' sines and cosines, which the C step takes from
    libmvec (within 4 ulp): x and J agree to 1e-13 of their scale; u, through the damped solve (|u| up
    to ~30 here), to 1e-11 of its scale (5e-11 / 30 seen)."""
    step = built.step()
    for q in configurations(4, seed=11):
        x_ref = smc.reference(1.1)
        ours = step(q, x_ref)
        theirs = [np.asarray(v, dtype=float) for v in function(q, x_ref)]
        for a, b, tolerance in zip(ours, theirs, (1e-13, 1e-13, 1e-11), strict=True):
            b = b.reshape(a.shape)
            assert np.abs(a - b).max() <= tolerance * max(1.0, np.abs(b).max())


def test_damped_solve_needs_damping():
    with pytest.raises(ValueError, match="damping"):
        smc.smc_step_function(JOINTS, damping=0.0)
    with pytest.raises(ValueError, match="damping"):
        smc.damped_solve([[1.0]], [1.0], 0.0)


def test_damped_solve_on_floats_is_the_damped_least_squares_solution():
    rng = np.random.default_rng(7)
    J = rng.normal(size=(6, 7))
    J[5] = J[4]  # rank 5, like the pose Jacobian
    r = rng.normal(size=6)
    w = smc.damped_solve(J.tolist(), r.tolist(), 1e-2)
    assert all(isinstance(v, float) for v in w)
    expected = np.linalg.solve(J @ J.T + 1e-4 * np.eye(6), r)
    assert np.abs(np.array(w) - expected).max() < 1e-9 * np.abs(expected).max()


def test_step_is_a_front_end_kernel(kernel):
    traced = kernel.trace()
    assert [(p.name, p.shape) for p in traced.inputs] == [("q", (N, 1)), ("x_ref", (6, 1))]
    assert [(p.name, p.shape) for p in traced.outputs] == [("x", (6, 1)), ("J", (6, N)), ("u", (N, 1))]
    assert traced.outputs[1].rows == smc.POSE and traced.inputs[0].rows[0] == "panda_joint1"


def test_step_costs_no_more_than_the_previous_sx_construction(function):
    """The kernel (the plain function, traced) against the step as gagen built it before, directly in
    CasADi SX (``sx_step_function``): the same values, no more flops, the same calls."""
    ours, previous = casadi_op_count(function), casadi_op_count(smc.sx_step_function(JOINTS))
    # the previous build reported mul=522 add=417 neg=21 div=21 cos=7 sin=7 tanh=6 (flops=981) for the Panda
    assert previous.flops == 981
    assert ours.flops <= previous.flops and ours.calls == previous.calls
    q, x_ref = np.array(smc.PANDA_Q0), smc.reference(0.7)
    for a, b in zip(function(q, x_ref), smc.sx_step_function(JOINTS)(q, x_ref), strict=True):
        a, b = np.asarray(a), np.asarray(b)
        assert np.abs(a - b).max() <= 1e-11 * max(1.0, np.abs(b).max())


@pytest.mark.compiling
@needs_cc
def test_compiled_step_equals_the_interpreter_reference(kernel, built):
    """The compiled step (C through the binding) against the same function on the reference
    interpreter, at random configurations. x and J agree to 1e-12 relative; u = −Jᵀ (J Jᵀ + λ² I)⁻¹ r
    goes through a solve whose condition number κ is |J|²/λ² ≈ 3e4 (J has rank 5: the smallest
    eigenvalue is λ² = 1e-4), so two evaluation orders differ by up to ~κ ε ≈ 7e-12 relative (0.44 κ ε
    was the largest of 300 random configurations): u is held to κ ε."""
    step = built.step()
    rng = np.random.default_rng(2024)
    for q in [np.array(smc.PANDA_Q0)] + [rng.uniform(-2.8, 2.8, N) for _ in range(8)]:
        x_ref = smc.reference(rng.uniform(0.0, math.pi))
        x, J, u = step(q, x_ref)
        rx, rJ, ru = kernel.reference(q, x_ref)
        rx, ru = rx.ravel(), ru.ravel()
        assert np.abs(x - rx).max() <= 1e-12 * max(1.0, np.abs(rx).max())
        assert np.abs(J - rJ).max() <= 1e-12 * max(1.0, np.abs(rJ).max())
        kappa = np.linalg.cond(rJ @ rJ.T + smc.DAMPING**2 * np.eye(6))
        assert np.abs(u - ru).max() <= max(1e-12, kappa * np.finfo(float).eps) * max(1.0, np.abs(ru).max())


@pytest.mark.compiling
@needs_cc
def test_header_declares_the_step(built):
    header = built.header.read_text()
    assert "void smc_step(const double *GAGEN_RESTRICT in_q, const double *GAGEN_RESTRICT in_x_ref, " \
           "double *GAGEN_RESTRICT out_x, double *GAGEN_RESTRICT out_J, " \
           "double *GAGEN_RESTRICT out_u);" in header
    assert "#define SMC_STEP_Q_SIZE 7" in header and "#define SMC_STEP_X_REF_SIZE 6" in header
    assert built.header.name == "smc.h" and built.source.name == "smc.c"
    assert built.meta["flops"] < 1500  # the LDLᵀ solve keeps the step near 1k flops
    assert built.meta["q0"] == list(smc.PANDA_Q0)


@pytest.mark.compiling
@needs_cc
def test_build_reuses_the_module(built):
    again = smc.build(JOINTS)
    assert again.folder == built.folder and again.runner.stat().st_mtime == built.runner.stat().st_mtime


# The boundary-layer bound: inside it tanh(ε s) ≈ ε s and J J⁺ ≈ I on the reachable directions, so
# ṡ ≈ −K ε s − ẋ_ref and each coordinate settles at |s_i| ≈ |ẋ_ref,i| / (K ε) ≤ 0.2 / (7.5 · 50)
# = 5.33e-4 (the Euler discretisation s_{k+1} = (1 − K ε dt) s_k − ẋ_ref dt has the same fixed
# point). 1.2× that leaves room for the damping (J J⁺ = s²/(s² + λ²) ≥ 0.998 here).
BOUND = 1.2 * 0.2 / (smc.GAIN * smc.EPSILON)
TRANSIENT = 0.5


@pytest.mark.compiling
@needs_cc
def test_closed_loop_tracks_within_the_boundary_layer(built, tmp_path):
    run = smc.simulate(built.step(), smc.PANDA_Q0, 2.0, 1e-3)
    s = run.s
    assert np.abs(s[0]).max() > 0.5  # starts far away (tool down, reference horizontal)
    settled = run.t >= TRANSIENT
    error = np.abs(s[settled]).max()
    assert error < BOUND
    assert error > 0.8 * 0.2 / (smc.GAIN * smc.EPSILON)  # the bound is tight: tanh's boundary layer
    assert np.abs(s[settled, 3:]).max() < 1e-5  # the direction reference is constant: no lag
    assert np.abs(run.u[settled]).max() < 2.0  # after the transient the arm moves smoothly
    # with a bounded joint-velocity disturbance d (λ = J d in Eq. 32) the error stays bounded
    disturbed = smc.simulate(built.step(), smc.PANDA_Q0, 2.0, 1e-3,
                             disturbance=lambda t: 0.05 * np.sin(3 * t + np.arange(N)))
    assert disturbed.error_after(TRANSIENT) < 3 * BOUND
    paths = smc.plot_run(run.write_csv(tmp_path / "sim.csv"), tmp_path / "plots")
    assert all(p.stat().st_size > 10_000 for p in paths) and len(paths) == 4


@pytest.fixture(scope="module")
def loop(built, tmp_path_factory):
    """The C runner for 0.5 s at 1 kHz, with SCHED_FIFO when permitted (root or CAP_SYS_NICE): on the
    2 shared, loaded cores here a SCHED_OTHER process is sometimes woken ms late, and 5 ms late on the
    last tick is already 1% of 0.5 s."""
    csv = tmp_path_factory.mktemp("smc") / "loop.csv"
    return smc.run_loop(0.5, 1000.0, csv, smc=built, transient=0.3, fifo=True)


@pytest.mark.compiling
@needs_cc
def test_c_loop_matches_simulation(built, loop):
    # the runner integrates with nominal tick times, so its log is deterministic: the same doubles
    # as the Python loop on the same compiled step
    assert loop.ticks == 500
    log = smc.read_log(loop.csv)
    run = smc.simulate(built.step(), smc.PANDA_Q0, 0.5, 1.0 / 1000.0)
    q = np.column_stack([log[f"q{i + 1}"] for i in range(N)])
    x = np.column_stack([log[p] for p in smc.POSE])
    u = np.column_stack([log[f"u{i + 1}"] for i in range(N)])
    assert np.array_equal(log["t"], run.t)
    assert np.abs(q - run.q).max() <= 1e-9
    assert np.abs(x - run.x).max() <= 1e-9
    assert np.abs(u - run.u).max() <= 1e-9
    assert loop.final_q == pytest.approx(run.q[-1] + run.u[-1] * 1e-3, abs=1e-9)
    assert loop.error_max == pytest.approx(run.error_after(0.3), rel=1e-6)
    assert loop.error_max < BOUND


@pytest.mark.realtime
@pytest.mark.compiling
@needs_cc
def test_c_loop_runs_at_rate(loop):
    assert loop.work_mean_us < 100.0  # ~3 us per tick: step, integration, logging
    # the schedule is absolute (clock_nanosleep TIMER_ABSTIME), so a late tick delays nothing after it
    if loop.scheduler != "SCHED_FIFO" and loop.jitter_max_us > 2000.0:
        pytest.skip(f"no SCHED_FIFO and the OS woke a tick {loop.jitter_max_us:.0f} us late: the rate "
                    f"measures the machine's load (achieved {loop.achieved_rate_hz:.2f} Hz)")
    assert loop.achieved_rate_hz == pytest.approx(1000.0, rel=0.01), loop


@pytest.mark.compiling
def test_the_loop_drives_the_arm_of_a_users_spec(tmp_path, capsys):
    """``gagen smc --spec``: an iiwa 14 written here, started at its spec's ready configuration (the log's
    first row; the step is the generic one, built for these joints); a two-arm spec is one line, exit 2."""
    from gagen.cli import main
    from gagen.registry import bundled_specs

    urdf = bundled_specs("cooperative")["two_iiwas_line"].parent / "iiwa14" / "iiwa14.urdf"
    ready = [0.3, 0.5, 0.0, -1.2, 0.0, 0.9, 0.0]
    spec = tmp_path / "my_iiwa.yaml"
    spec.write_text(f"name: my_iiwa\nprimitive: point\nchains:\n  - {{name: arm, urdf: {urdf}, base_link: "
                    f"iiwa_link_0, tip_link: iiwa_link_ee}}\nconfigurations:\n  ready: {ready}\n")
    out = tmp_path / "smc"
    assert main(["smc", "--spec", str(spec), "--duration", "0.05", "--rate", "200", "--out", str(out)]) == 0
    log = smc.read_log(out / "smc_log.csv")
    first = np.array([log[f"q{i + 1}"][0] for i in range(7)])
    assert np.max(np.abs(first - ready)) < 0.05  # one tick of 5 ms from the ready configuration
    two = bundled_specs("cooperative")["two_iiwas_line"]
    capsys.readouterr()
    assert main(["smc", "--spec", str(two), "--duration", "0.05", "--out", str(tmp_path / "two")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "drives one arm; the spec has 2 chains" in err[0]
