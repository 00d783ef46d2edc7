"""The generated step in C: the module ``smc`` and the real-time loop runner ``smc_loop`` (``smc_loop.c``
next to this package, compiled with the module's C), run at a fixed rate or benchmarked in a tight loop."""

from __future__ import annotations

import hashlib
import json
import math
import os
import subprocess
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.build import cache_root
from gagen.codegen.backends.c import library as c_library
from gagen.codegen.backends.c.printer import c_literal
from gagen.codegen.compiler import (
    FLAGS,
    CompileError,
    find_compiler,
    vector_math_defines,
    vector_math_libraries,
)
from gagen.control.smc.kernel import KERNEL, MODULE, step_source
from gagen.control.smc.law import DAMPING, EPSILON, GAIN, check_finite
from gagen.control.smc.simulation import CompiledStep
from gagen.model.kinematics import Joint

PANDA_Q0 = (2.5, -0.785, 0.0, -2.356, 1.5, 3.0, 0.785)
"""Default start for the 7-DOF Panda: its ``ready`` pose with joint 1 turned to 2.5 rad, facing the
paper's reference (behind the base at azimuth 143°), and the wrist turned (joints 5 and 6 to 1.5 and
3.0 rad). The reference lies near the base, where few configurations reach it within the joint limits;
from this start the loop settles on a branch that does, all along it (≥ 0.03 rad from every limit). From
the plain ``ready`` wrist (0, 1.571) it settles on one that needs the elbow, joint 4, at −3.19 rad,
past its −3.0718 limit: within the limits that branch cannot reach x = −0.2 m (its best is −3.14)."""
LOOP_SOURCE = Path(__file__).with_name("smc_loop.c")


# -- C: the module and the runner --------------------------------------------------------------------
@dataclass(frozen=True)
class SmcBuild:
    """A built step: the folder, the generated module (``module``: ``smc.h``/``smc.c`` with
    ``smc_step``, its library and CPython binding, built by ``gagen.build.build_source``), the loop
    runner, and the parameters (``meta``: n, k, K, epsilon, damping, the joint limits, q0, op count)."""

    folder: Path
    source: Path
    header: Path
    library: Path
    runner: Path
    meta: dict[str, Any] = field(default_factory=dict)
    module: Path | None = None

    @property
    def q0(self) -> NDArray[np.float64]:
        return np.array(self.meta["q0"], dtype=float)

    @property
    def limits(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(lower, upper) per joint, the step's and the runner's (±inf where a joint has none)."""
        return _limits(self.meta["lower"], self.meta["upper"])

    def step(self) -> CompiledStep:
        return CompiledStep(self.module or self.source.parent)


def _limits(lower: Sequence[float | None],
            upper: Sequence[float | None]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    return (np.array([-math.inf if v is None else v for v in lower], dtype=float),
            np.array([math.inf if v is None else v for v in upper], dtype=float))


def _start(q0: Sequence[float] | None, n: int) -> list[float]:
    if q0 is None:
        q0 = PANDA_Q0 if n == len(PANDA_Q0) else (0.0,) * n
    values = [float(v) for v in q0]
    if len(values) != n:
        raise ValueError(f"q0 needs {n} joint values, got {len(values)}")
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"q0 must be finite, got {values}")
    return values


def _compile_runner(module: Path, manifest: dict[str, Any], q0: Sequence[float], params: dict[str, Any],
                    runner: Path) -> None:
    """``smc_loop.c`` with the module's C (``smc.c`` and its SIMD companion) into the executable
    ``runner`` (gagen's compiler flags, so the step gives the library's doubles); the start q0 comes
    as ``-DSMC_LOOP_Q0=a,b,…`` (finite doubles, Python's repr: numbers only) and the joint limits
    (the manifest's ``smc`` parameters) as ``-DSMC_LOOP_LOWER`` / ``-DSMC_LOOP_UPPER``."""
    c_source = module / manifest["c_source"]
    units = [LOOP_SOURCE, c_source]
    simd = c_source.with_name(f"{c_source.stem}_simd.c")
    if simd.is_file():
        units.append(simd)
    flags = [f for f in FLAGS if f not in ("-shared", "-fPIC")]
    partial = runner.with_name(runner.name + f".{os.getpid()}.partial")
    command = [*find_compiler(), *flags, *vector_math_defines(), f"-I{module}",
               f"-DSMC_LOOP_Q0={','.join(map(repr, q0))}",
               *(f"-DSMC_LOOP_{name}={','.join(map(c_literal, values))}"
                 for name, values in zip(("LOWER", "UPPER"), _limits(params["lower"], params["upper"]),
                                         strict=True)),
               "-o", str(partial), *map(str, units), *vector_math_libraries(), "-lm"]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        partial.unlink(missing_ok=True)
        raise CompileError(f"{' '.join(command)} failed:\n{result.stderr.strip()}")
    partial.replace(runner)


def build(joints: Sequence[Joint] | None = None, *, K: float | Sequence[float] = GAIN,
          epsilon: float = EPSILON, damping: float = DAMPING, q0: Sequence[float] | None = None,
          folder: str | Path | None = None, force: bool = False,
          progress: Callable[[str], None] | None = None) -> SmcBuild:
    """Build (or reuse) the step module and the loop runner for ``joints`` (default: the bundled Panda,
    ``panda_point``'s arm) in ``folder``: the module ``smc/`` through ``gagen.build.build_source`` (its
    cache: rebuilt only when out of date) and the executable ``smc_loop`` beside it. Without ``folder``:
    ``gagen.frontend.cache_root() / "smc-<key>"``, keyed by the kernel's content, the start q0 and the
    loop's source; the runner is compiled when the module was (re)built or it is missing (and always
    with ``force`` or in a ``folder`` given here, which no key names). ``q0``: the runner's default
    start (the Panda's ``PANDA_Q0`` for 7 joints, else zeros)."""
    from gagen.build import build_source

    find_compiler()  # CompilerNotFound before anything is built: the runner needs the compiler
    source = step_source(joints, K=K, epsilon=epsilon, damping=damping)
    kernel = source.kernels[KERNEL]
    n, k = kernel.inputs[0].size, kernel.inputs[1].size
    start = _start(q0, n)
    key = hashlib.sha256(json.dumps([source.key, source.source_hash, start,
                                     hashlib.sha256(LOOP_SOURCE.read_bytes()).hexdigest()]).encode())
    root = Path(folder) if folder is not None else cache_root() / f"smc-{key.hexdigest()[:16]}"
    root.mkdir(parents=True, exist_ok=True)
    module, runner = root / MODULE, root / "smc_loop"
    result = build_source(source, module, force=force, compile_c=True, progress=progress or (lambda _: None))
    manifest = json.loads((result.folder / "manifest.json").read_text())
    if not result.compiled:
        raise CompileError(f"the step module in {result.folder} was written but not compiled")
    if force or folder is not None or not result.cached or not runner.is_file():
        _compile_runner(result.folder, manifest, start, source.meta["smc"], runner)
    ops = kernel.op_count
    meta = {**source.meta["smc"], "n": n, "k": k, "q0": start, "op_count": str(ops), "flops": ops.flops,
            "calls": ops.calls, "key": key.hexdigest()[:16]}
    return SmcBuild(root, result.folder / manifest["c_source"], result.folder / manifest["c_header"],
                    result.folder / c_library(manifest), runner, meta, result.folder)


@dataclass(frozen=True)
class LoopSummary:
    """What ``smc_loop`` printed: timing (rates in Hz, times in µs) and the tracking error after the
    transient (max |s_i|, its RMS, and the norms of the position and direction errors)."""

    scheduler: str
    rate_hz: float
    ticks: int
    wall_s: float
    achieved_rate_hz: float
    deadline_misses: int
    jitter_mean_us: float
    jitter_std_us: float
    jitter_max_us: float
    work_mean_us: float
    work_max_us: float
    transient_s: float
    settled_ticks: int
    error_max: float
    error_rms: float
    position_error_max: float
    direction_error_max: float
    final_q: tuple[float, ...]
    csv: Path | None = None


def _parse(output: str) -> dict[str, str]:
    return dict(line.split("=", 1) for line in output.splitlines() if "=" in line)


def loop_ticks(duration: float, rate: float, transient: float = 0.0) -> int:
    """The number of ticks of a ``duration`` s run at ``rate`` Hz, as the C loop counts them
    (round half away from zero); ValueError for a non-finite or non-positive duration or rate, a run
    shorter than one tick, or a ``transient`` (s) that is negative, non-finite or leaves no tick after it."""
    check_finite("duration", duration, "s", positive=True)
    check_finite("rate", rate, "Hz", positive=True)
    check_finite("transient", transient, "s", positive=False)
    ticks = math.floor(duration * rate + 0.5)
    if ticks < 1:
        raise ValueError(f"a duration of {duration:g} s at {rate:g} Hz is less than one tick: give at least "
                         f"{0.5 / rate:g} s (one tick is {1 / rate:g} s)")
    if transient > (ticks - 1) * (1.0 / rate):  # the last tick's t, as the C loop computes it
        raise ValueError(f"transient {transient:g} s leaves no tick to measure the tracking error in a "
                         f"run of {ticks} ticks ({duration:g} s at {rate:g} Hz): give a shorter transient")
    return ticks


def run_loop(duration: float = 10.0, rate: float = 1000.0, csv: str | Path | None = None, *,
             q0: Sequence[float] | None = None, transient: float = 0.5, fifo: bool = False,
             smc: SmcBuild | None = None, timeout: float | None = None) -> LoopSummary:
    """Build (cached) and run the C loop for ``duration`` s at ``rate`` Hz; log to ``csv`` if given.
    ``fifo``: ask for SCHED_FIFO and locked memory (best effort, reported in ``scheduler``). The
    arguments are checked first (``loop_ticks``), before anything is built."""
    loop_ticks(duration, rate, transient)
    if q0 is not None and not all(math.isfinite(float(v)) for v in q0):
        raise ValueError(f"q0 must be finite, got {list(q0)}")
    smc = smc or build()
    command = [str(smc.runner), "--rate", repr(float(rate)), "--duration", repr(float(duration)),
               "--transient", repr(float(transient))]
    if q0 is not None:
        command += ["--q0", ",".join(repr(float(v)) for v in q0)]
    if csv is not None:
        command += ["--csv", str(csv)]
    if fifo:
        command.append("--fifo")
    result = subprocess.run(command, capture_output=True, text=True,
                            timeout=timeout if timeout is not None else duration * 3 + 30)
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed ({result.returncode}):\n{result.stderr}")
    v = _parse(result.stdout)
    floats = ("rate_hz", "wall_s", "achieved_rate_hz", "jitter_mean_us", "jitter_std_us", "jitter_max_us",
              "work_mean_us", "work_max_us", "transient_s", "error_max", "error_rms", "position_error_max",
              "direction_error_max")
    return LoopSummary(scheduler=v["scheduler"], ticks=int(v["ticks"]),
                       deadline_misses=int(v["deadline_misses"]), settled_ticks=int(v["settled_ticks"]),
                       final_q=tuple(float(a) for a in v["final_q"].split(",")),
                       csv=Path(csv) if csv is not None else None, **{k: float(v[k]) for k in floats})


def bench_step(steps: int = 200_000, repeats: int = 21, smc: SmcBuild | None = None) -> dict[str, float]:
    """Steps per second of the C step (+ the Euler update) in a tight loop: the median over ``repeats``
    loops of ``steps`` (also ns_per_step, min and max)."""
    smc = smc or build()
    result = subprocess.run([str(smc.runner), "--bench", str(steps), "--repeats", str(repeats)],
                            capture_output=True, text=True, check=True)
    v = _parse(result.stdout)
    return {k: float(v[k]) for k in ("steps_per_second", "ns_per_step", "steps_per_second_min",
                                     "steps_per_second_max")}


def op_count(smc: SmcBuild) -> str:
    """The step kernel's operation count, as recorded at build time."""
    return str(smc.meta["op_count"])
