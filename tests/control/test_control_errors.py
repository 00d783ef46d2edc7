"""Control entry points say why they stopped, and refuse what they cannot run [issue 12, finding 7].

- ``solve_ik`` reports a ``status`` and a ``message``: from a degenerate start (two Pandas whose end
  points coincide: conditioning < 1e-30, J_Be = 0) it says ``degenerate_primitive``, where it used
  to stop after 0 iterations with no reason;
- ``reach`` succeeds only when IPOPT returns Solve_Succeeded / Solved_To_Acceptable_Level and the
  final error is within tol, and its ``message`` says why not;
- NaN, inf, zero and negative horizons, N, durations and rates are refused by the command line with
  one message line and exit code 2 (``gagen smc --duration 1e-4`` raised IndexError), and by the
  library functions with a ValueError, before anything is built.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import bundled_module
from scipy.optimize import brentq

from gagen.cli import main
from gagen.control import smc
from gagen.control.ik import STATUSES, solve_ik
from gagen.control.ocp import reach
from gagen.control.smc import runner as _runner  # noqa: F401  (smc.runner, patched below)


def _module(name: str):
    return bundled_module(name)


def _cli(argv: list[str], capsys) -> tuple[int, str]:
    """(exit code, stderr) of ``gagen argv``: argparse's refusals exit, the commands return."""
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code
    return code, capsys.readouterr().err


# -- the command line -----------------------------------------------------------------------------------
@pytest.mark.parametrize(("argv", "message"), [
    (["reach", "circle", "--horizon", "0"], "argument --horizon: expected a finite number > 0, got '0'"),
    (["reach", "circle", "--horizon", "nan"], "argument --horizon: expected a finite number > 0, got 'nan'"),
    (["reach", "circle", "--horizon=-inf"], "argument --horizon: expected a finite number > 0"),
    (["reach", "circle", "--horizon", "1e999"], "argument --horizon: expected a finite number > 0"),
    (["reach", "circle", "--N", "0"], "argument --N: expected an integer >= 1, got '0'"),
    (["reach", "circle", "--N", "-5"], "argument --N: expected an integer >= 1, got '-5'"),
    (["reach", "circle", "--N", "2.5"], "argument --N: expected an integer, got '2.5'"),
    (["smc", "--rate", "0"], "argument --rate: expected a finite number > 0, got '0'"),
    (["smc", "--rate", "inf"], "argument --rate: expected a finite number > 0, got 'inf'"),
    (["smc", "--duration", "inf"], "argument --duration: expected a finite number > 0, got 'inf'"),
    (["smc", "--duration", "nan"], "argument --duration: expected a finite number > 0, got 'nan'"),
    (["smc", "--duration", "-1"], "argument --duration: expected a finite number > 0, got '-1'"),
    (["smc", "--duration", "1e-4"], "error: a duration of 0.0001 s at 1000 Hz is less than one tick"),
    (["smc", "--duration", "0.002", "--rate", "100"], "is less than one tick: give at least 0.005 s"),
])
def test_cli_refuses_bad_horizons_durations_and_rates_with_one_line(argv, message, capsys, tmp_path):
    code, err = _cli([*argv, "--out", str(tmp_path / "out")], capsys)
    assert code == 2
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert message in last, err
    assert not (tmp_path / "out").exists()  # refused before anything was written


# -- the library ----------------------------------------------------------------------------------------
@pytest.mark.parametrize(("duration", "rate", "transient", "ticks"), [
    (10.0, 1000.0, 0.5, 10_000), (0.0015, 1000.0, 0.0, 2), (0.0005, 1000.0, 0.0, 1), (0.001, 1000.0, 0.0, 1),
])
def test_loop_ticks_counts_as_the_c_loop(duration, rate, transient, ticks):
    """round half away from zero of duration × rate (the C loop's llround)."""
    assert smc.loop_ticks(duration, rate, transient) == ticks


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"duration": 1e-4}, "less than one tick"),
    ({"duration": float("nan")}, "duration must be a finite number of s > 0, got nan"),
    ({"rate": 0.0}, "rate must be a finite number of Hz > 0, got 0.0"),
    ({"rate": float("inf")}, "rate must be a finite number of Hz > 0, got inf"),
    ({"duration": 0.3}, "transient 0.5 s leaves no tick"),
    ({"transient": -1.0}, "transient must be a finite number of s >= 0"),
    ({"q0": [float("nan")] * 7}, "q0 must be finite"),
])
def test_run_loop_refuses_before_building(kwargs, message, monkeypatch):
    def no_build(*args, **kw):
        raise AssertionError("built before the arguments were checked")

    monkeypatch.setattr(smc.runner, "build", no_build)
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        smc.run_loop(**kwargs)


def test_simulate_refuses_runs_shorter_than_one_tick():
    def step(q, x_ref):
        raise AssertionError("stepped")

    with pytest.raises(ValueError, match="less than one tick"):
        smc.simulate(step, np.zeros(7), 1e-4, 1e-3)
    with pytest.raises(ValueError, match="dt must be a finite number of s > 0"):
        smc.simulate(step, np.zeros(7), 1.0, 0.0)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"horizon": float("nan")}, "horizon must be a finite number of seconds > 0, got nan"),
    ({"horizon": 0.0}, "horizon must be a finite number of seconds > 0, got 0.0"),
    ({"horizon": float("inf")}, "horizon must be a finite number of seconds > 0, got inf"),
    ({"N": 0}, "N must be an integer >= 1"),
    ({"N": 2.5}, "N must be an integer >= 1"),
    ({"q0": np.full(7, np.nan)}, "q0 must be finite"),
    ({"V_Sd": np.full(12, np.inf)}, "V_Sd must be finite"),
    ({"tol": float("nan")}, "tol must be a finite number >= 0"),
])
def test_reach_refuses_non_finite_or_empty_problems(kwargs, message):
    m = _module("panda_point")
    args = {"q0": np.zeros(7), "V_Sd": np.eye(12)[0], "N": 3, **kwargs}
    with pytest.raises(ValueError, match=message):
        reach(m, args.pop("q0"), args.pop("V_Sd"), **args)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"q0": [np.nan, 0.0]}, "q0 must be finite"),
    ({"V_Sd": np.full(12, np.nan)}, "V_Sd must be finite"),
    ({"tol": float("nan")}, "tol and damping must be finite"),
    ({"damping": float("inf")}, "tol and damping must be finite"),
    ({"max_iterations": 1.5}, "max_iterations must be an integer"),
])
def test_solve_ik_refuses_non_finite_inputs(kwargs, message):
    def task(q, v):
        raise AssertionError("evaluated")

    args = {"q0": [0.0, 0.0], "V_Sd": np.eye(12)[0], **kwargs}
    with pytest.raises(ValueError, match=message):
        solve_ik(task, args.pop("q0"), args.pop("V_Sd"), **args)


# -- why IK stopped -------------------------------------------------------------------------------------
def _coincident_start() -> np.ndarray:
    """two_pandas_point_pair with both arms in one planar pose whose flange lies on the x = 0 plane
    between the bases: the mirrored arms' end points coincide (to 1e-16 m)."""
    m = _module("two_pandas_point_pair")

    def pose(q2: float) -> np.ndarray:
        return np.array([0.0, q2, 0.0, -0.3, 0.0, 2.5, 0.785])

    def x(q2: float) -> float:
        return float(np.array(m.casadi.arm0_fk(pose(q2))[1]).ravel()[1])  # P rows: e0, e1, e2, e3, einf

    q = pose(brentq(x, 0.5, 1.4, xtol=1e-16, rtol=1e-15))
    return np.concatenate([q, q])


def test_ik_from_a_degenerate_start_says_the_primitive_is_degenerate():
    m = _module("two_pandas_point_pair")
    q0 = _coincident_start()
    ends = [np.array(getattr(m.casadi, f"arm{i}_fk")(q0[7 * i:7 * i + 7])[1]).ravel()[1:4] for i in (0, 1)]
    assert np.linalg.norm(ends[0] - ends[1]) < 1e-15
    assert float(np.array(m.casadi.similarity(q0)[1]).ravel()[0]) < 1e-30
    target = np.array(m.casadi.similarity(q0 + 0.1)[0]).ravel()
    result = solve_ik(m.casadi.task, q0, target)
    assert result.iterations == 0 and not result.converged
    assert result.status == "degenerate_primitive"
    assert result.message.startswith("degenerate_primitive after 0 iterations")
    assert "conditioning 0" in result.message and "degenerate" in result.message


def test_ik_statuses_on_a_real_system():
    """converged and max_iterations on panda_point (CasADi task on numbers)."""
    m = _module("panda_point")
    rng = np.random.default_rng(3)
    ready = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    target = np.array(m.casadi.similarity(ready + rng.uniform(-0.3, 0.3, 7))[0]).ravel()
    q0 = ready + rng.uniform(-0.3, 0.3, 7)
    done = solve_ik(m.casadi.task, q0, target, tol=1e-10)
    assert done.converged and done.status == "converged" and done.message.startswith("converged after")
    short = solve_ik(m.casadi.task, q0, target, tol=1e-10, max_iterations=1)
    assert short.status == "max_iterations" and short.iterations == 1 and not short.converged


def _linear(A: np.ndarray, b: np.ndarray):
    """A task with e = A q − b and J_Be = A."""
    return lambda q, v: (A @ q - b, A)


@pytest.mark.parametrize(("task", "status"), [
    (_linear(np.zeros((7, 2)), np.ones(7)), "degenerate_primitive"),  # J_Be = 0, e ≠ 0
    (_linear(np.eye(7, 2), np.ones(7)), "stationary"),  # least-squares minimum with e ≠ 0
    (lambda q, v: (np.full(7, np.nan), np.zeros((7, 2))), "non_finite"),
    (_linear(np.eye(7, 2), np.array([1.0, 2.0, 0, 0, 0, 0, 0])), "converged"),
])
def test_ik_status_of_each_stop(task, status):
    result = solve_ik(task, [0.0, 0.0], np.eye(12)[0])
    assert result.status == status, result.message
    assert result.status in STATUSES and STATUSES[status] in result.message


def test_ik_conditioning_tells_a_degenerate_stop_where_j_is_not_zero():
    task = _linear(np.eye(7, 2), np.ones(7))  # stationary, J_Be ≠ 0
    result = solve_ik(task, [0.0, 0.0], np.eye(12)[0], conditioning=lambda q: 0.0)
    assert result.status == "degenerate_primitive"
    assert solve_ik(task, [0.0, 0.0], np.eye(12)[0], conditioning=lambda q: 0.5).status == "stationary"


# -- reach agrees with IPOPT ----------------------------------------------------------------------------
def _reach_problem():
    m = _module("panda_point")
    q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    target = np.array(m.casadi.similarity(q0 + 0.05)[0]).ravel()
    return m, q0, target


def test_reach_success_follows_ipopt_status_and_tolerance():
    m, q0, target = _reach_problem()
    ok = reach(m, q0, target, N=5)
    assert ok.success and ok.status == "Solve_Succeeded" and ok.error_norm <= 1e-9
    assert ok.message.startswith("IPOPT Solve_Succeeded; ‖e(q_N)‖ = ") and "<= tol 1e-09" in ok.message
    # IPOPT stopped early: no success, whatever the error
    stopped = reach(m, q0, target, N=5, options={"ipopt.max_iter": 1})
    assert stopped.status == "Maximum_Iterations_Exceeded" and not stopped.success
    assert stopped.message.startswith("IPOPT stopped with Maximum_Iterations_Exceeded")
    # IPOPT solved, but the final error is above the tolerance: no success, and why
    strict = reach(m, q0, target, N=5, tol=1e-300)
    assert strict.status in ("Solve_Succeeded", "Solved_To_Acceptable_Level") and not strict.success
    assert "> tol 1e-300 after 5 of at most 5 multiplier updates" in strict.message


@pytest.mark.compiling
def test_a_one_tick_smc_run_is_valid(capsys, tmp_path):
    """The shortest valid run (1 ms at 1 kHz: one tick) runs, logs one row, plots, and reports its
    tracking error from t = 0 (the default 0.5 s transient would leave no tick to report on)."""
    code = main(["smc", "--duration", "0.001", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0
    log = smc.read_log(tmp_path / "smc_log.csv")
    assert log["t"].tolist() == [0.0]
    # the reported error is the logged tick's: max over the pose and its reference, coordinate by coordinate
    s = max(abs(log[f"{k}"][0] - log[f"ref_{k}"][0]) for k in ("px", "py", "pz", "dx", "dy", "dz"))
    assert "over 1 ticks" in out and f"tracking after 0 s: max |s_i| {s:.2e}" in out
    assert (tmp_path / "pose.png").is_file()
