"""Sliding-mode pose tracking [SMC V-VI]: the generated step against independent computations, the closed
loop against the boundary-layer bound, and the C real-time runner against the Python simulation."""

import math

import numpy as np
import pytest

from gagen.algebra.signature import cga3d
from gagen.apps.cooperative.bundled import bundled_systems
from gagen.apps.cooperative.scenarios import joint_limits
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
# the joint limits from the Panda's URDF, read by yourdfpy (not gagen's URDF loader, which the step uses)
LOWER, UPPER = joint_limits("panda_point")
# the bundled run (`gagen smc`) before the joint-limit handling: max |s_i| after 0.5 s was 5.3427e-4
# (C loop and simulation alike) while joint 4 went to −3.2422 rad against its −3.0718 limit (0.170 rad
# past it) on 33.9 % of the 10 000 ticks; the run may not track worse now
BEFORE_ERROR = 5.3427e-4


def past_limits(q):
    """How far each row of q lies past the URDF limits (≤ 0 inside them), per joint: the largest."""
    return np.maximum(LOWER - q, q - UPPER).max(axis=0)


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


def numpy_u(J, x, x_ref, q, K=smc.GAIN, epsilon=smc.EPSILON, damping=smc.DAMPING):
    """The law in numpy, written from its description: the nullspace limit avoidance u0 = −k_n (depth into
    the zone ρ inside each URDF limit), the once-refined damped solve (iterated Tikhonov), the velocity
    bound γ (limit − q)."""
    rho, k_n, gamma = smc.LIMIT_ZONE, smc.LIMIT_GAIN, smc.LIMIT_RATE
    depth = np.where(q < LOWER + rho, q - (LOWER + rho), np.where(q > UPPER - rho, q - (UPPER - rho), 0.0))
    u0 = -k_n * depth
    r = K * np.tanh(epsilon * (x - x_ref)) + J @ u0
    A = J @ J.T + damping**2 * np.eye(J.shape[0])
    w = np.linalg.solve(A, r)
    w = w + damping**2 * np.linalg.solve(A, w)
    return np.clip(u0 - J.T @ w, gamma * (LOWER - q), gamma * (UPPER - q))


def configurations(count=6, seed=3):
    rng = np.random.default_rng(seed)
    return [np.array(smc.PANDA_Q0)] + [rng.uniform(-2.5, 2.5, N) for _ in range(count - 1)]


def test_pose_is_a_point_and_a_unit_direction():
    x = interp_pose(smc.PANDA_Q0)
    assert np.linalg.norm(x[3:]) == pytest.approx(1.0, abs=1e-14)
    # Panda ready pose: flange 0.307 m in front, tool z axis pointing down; turned by 2.5 rad about z
    ready = interp_pose([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    assert ready[:3] == pytest.approx([0.3070, 0.0, 0.5903], abs=1e-3)
    assert ready[3:] == pytest.approx([0.0, 0.0, -1.0], abs=1e-6)
    c, s = math.cos(2.5), math.sin(2.5)
    turned = interp_pose([2.5, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    assert turned[:2] == pytest.approx([c * ready[0], s * ready[0]], abs=1e-12)
    # the start is that pose with the wrist turned (joints 5, 6), inside every limit
    assert np.all((LOWER < smc.PANDA_Q0) & (np.array(smc.PANDA_Q0) < UPPER))


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
    reference = numpy_u(J, x, x_ref, q)  # |u| reaches ~500 rad/s when saturated: compare relatively
    # to the solve's condition number κ times ε, as in test_compiled_step_equals_the_interpreter_reference
    kappa = np.linalg.cond(J @ J.T + smc.DAMPING**2 * np.eye(6))
    assert np.abs(u - reference).max() <= max(1e-12, kappa * np.finfo(float).eps) \
        * max(1.0, np.abs(reference).max())


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


def test_refined_damped_solve_is_iterated_tikhonov():
    """One refinement: w₂ = w₁ + λ² A⁻¹ w₁ (A = J Jᵀ + λ² I). On J's range J Jᵀ w₂ matches r to
    (λ²/σ²)² instead of λ²/σ², and Jᵀ w₂ stays bounded on the rank-deficient direction."""
    rng = np.random.default_rng(7)
    J = rng.normal(size=(6, 7))
    J[5] = J[4]
    r = rng.normal(size=6)
    A = J @ J.T + 1e-4 * np.eye(6)
    w1 = np.linalg.solve(A, r)
    expected = w1 + 1e-4 * np.linalg.solve(A, w1)
    w = np.array(smc.damped_solve(J.tolist(), r.tolist(), 1e-2, refinements=1))
    assert np.abs(w - expected).max() < 1e-9 * np.abs(expected).max()
    on_range = np.linalg.svd(J)[0][:, :5]  # the directions J reaches
    residual = lambda v: np.abs(on_range.T @ (J @ J.T @ v - r)).max()  # noqa: E731
    assert residual(w) < 1e-3 * residual(w1)
    assert np.abs(J.T @ w).max() < 2 * np.abs(J.T @ w1).max() + 1.0


def test_joint_bounds_are_the_urdf_limits():
    lower, upper = smc.joint_bounds(JOINTS)
    assert np.array_equal(lower, LOWER) and np.array_equal(upper, UPPER)
    assert LOWER[3] == -3.0718 and UPPER[5] == 3.7525  # the elbow and wrist limits the run comes near
    free = tuple(kin.Joint(j.name, j.kind, j.xyz, j.rpy, j.axis) for j in JOINTS)  # no <limit>
    assert smc.joint_bounds(free) == ((None,) * N, (None,) * N)


def test_a_step_never_crosses_a_limit(function):
    """At configurations on, near and beyond the limits, with references far away (saturated tanh): one
    Euler step of dt < 1/γ (here the loop's 1 ms and 0.9/γ) keeps a joint inside its limits, or moves it
    toward them when outside."""
    rng = np.random.default_rng(5)
    for dt in [1e-3, 0.9 / smc.LIMIT_RATE] * 20:
        q = rng.uniform(LOWER, UPPER)
        near = rng.random(N) < 0.5
        q[near] = np.where(rng.random(N) < 0.5, LOWER, UPPER)[near] + rng.uniform(-0.05, 0.05, N)[near]
        x_ref = np.concatenate([rng.uniform(-0.6, 0.6, 3), [0.0, 1.0, 0.0]])
        u = np.asarray(function(q, x_ref)[2]).ravel()
        after = q + u * dt
        inside = np.maximum(LOWER - q, q - UPPER) <= 0
        assert np.all((LOWER[inside] <= after[inside]) & (after[inside] <= UPPER[inside]))
        assert np.all(np.abs(np.clip(after, LOWER, UPPER) - after)[~inside]
                      <= np.abs(np.clip(q, LOWER, UPPER) - q)[~inside])


def test_the_bundled_run_stays_within_the_joint_limits(function):
    """`gagen smc`'s run (10 s at 1 kHz from PANDA_Q0, the paper's reference), here on the step's CasADi
    Function and without the loop's hard stops: every tick's joints within the URDF limits, the tracking
    no worse than before the limit handling. (Before: joint 4 reached −3.2422 rad, 0.170 rad past its
    limit, on 33.9 % of the ticks; the compiled run is checked in ``test_gagen_smc_stays_within_...``.)"""
    run = smc.simulate(smc.casadi_step(function), smc.PANDA_Q0, 10.0, 1e-3)
    assert run.q.shape == (10_000, N)
    assert np.all(past_limits(run.q) <= 0), past_limits(run.q)
    assert run.error_after(0.5) <= BEFORE_ERROR


def test_step_is_a_front_end_kernel(kernel):
    traced = kernel.trace()
    assert [(p.name, p.shape) for p in traced.inputs] == [("q", (N, 1)), ("x_ref", (6, 1))]
    assert [(p.name, p.shape) for p in traced.outputs] == [("x", (6, 1)), ("J", (6, N)), ("u", (N, 1))]
    assert traced.outputs[1].rows == smc.POSE and traced.inputs[0].rows[0] == "panda_joint1"


def test_step_costs_no_more_than_the_previous_sx_construction(function):
    """The kernel (the plain function, traced) against the step as gagen built it before, directly in
    CasADi SX (``sx_step_function``): the same values, no more flops, the same calls."""
    ours, previous = casadi_op_count(function), casadi_op_count(smc.sx_step_function(JOINTS))
    # the SX build reports mul=626 add=549 neg=14 div=27 cos=7 if_else_zero=49 lt=28 not=21 sin=7 tanh=6
    # (flops=1216) for the Panda: 981 for the law alone, 78 for the refinement, 157 for the limits
    assert previous.flops == 1216
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
    run = smc.simulate(built.step(), smc.PANDA_Q0, 2.0, 1e-3, limits=built.limits)
    s = run.s
    assert np.abs(s[0]).max() > 0.5  # starts far away (tool down, reference horizontal)
    settled = run.t >= TRANSIENT
    error = np.abs(s[settled]).max()
    assert error < BOUND
    assert error > 0.8 * 0.2 / (smc.GAIN * smc.EPSILON)  # the bound is tight: tanh's boundary layer
    assert np.abs(s[settled, 3:]).max() < 1e-5  # the direction reference is constant: no lag
    assert np.abs(run.u[settled]).max() < 2.0  # after the transient the arm moves smoothly
    # with a bounded joint-velocity disturbance d (λ = J d in Eq. 32) the error stays bounded
    disturbed = smc.simulate(built.step(), smc.PANDA_Q0, 2.0, 1e-3, limits=built.limits,
                             disturbance=lambda t: 0.05 * np.sin(3 * t + np.arange(N)))
    assert disturbed.error_after(TRANSIENT) < 3 * BOUND
    assert np.all(past_limits(disturbed.q) <= 0)
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
    run = smc.simulate(built.step(), smc.PANDA_Q0, 0.5, 1.0 / 1000.0, limits=built.limits)
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


@pytest.mark.slow
@pytest.mark.compiling
@needs_cc
def test_gagen_smc_stays_within_the_joint_limits(tmp_path, capsys):
    """The acceptance run: ``gagen smc`` as bundled (10 s at 1 kHz, the generated C step in the C loop):
    every logged tick's joints within the URDF limits and the tracking no worse than before (the log
    is deterministic: the loop integrates on nominal tick times)."""
    from gagen.cli import main

    assert main(["smc", "--out", str(tmp_path)]) == 0
    log = smc.read_log(tmp_path / "smc_log.csv")
    q = np.column_stack([log[f"q{i + 1}"] for i in range(N)])
    assert q.shape == (10_000, N) and np.array_equal(q[0], smc.PANDA_Q0)
    assert np.all(past_limits(q) <= 0), past_limits(q)
    settled = log["t"] >= 0.5
    assert log["error_max"][settled].max() <= BEFORE_ERROR
    assert "max |s_i| 5.33e-04" in capsys.readouterr().out


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
