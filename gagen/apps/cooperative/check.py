"""``gagen build --check`` of a cooperative system's module: every kernel (C single, C batched, CasADi)
against the catalogue's functions on the interpreter (``gagen.check``), on the spec's named configurations and
random samples within the joint limits."""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from gagen.apps.cooperative.catalogue import kernel_functions
from gagen.check import (
    FD_RTOL,
    FD_STEPS,
    VALUE_RTOL,
    Discrepancy,
    check_kernels,
    failures,
    format_report,
    samples,
)
from gagen.model.conformal import SIMILARITY
from gagen.robots.spec import load_system
from gagen.robots.system import System
from gagen.runtime import GeneratedModule, load


def check_module(module: GeneratedModule, system: System,
                 configurations: Mapping[str, Sequence[float]] | Sequence[float] | None = None,
                 count: int = 5, seed: int = 0, progress: Callable[[str], None] = lambda _: None,
                 rtol: float = VALUE_RTOL, fd_rtol: float = FD_RTOL) -> list[Discrepancy]:
    """Every kernel of a cooperative system's module on the samples (see ``samples``): the chain
    kernels on each chain's joints, ``task`` also on a random V_Sd, ``similarity_rate`` on a random q̇
    (``check_kernels``)."""
    functions = kernel_functions(system)
    pairs = samples(system, configurations, count, seed)
    # a measured chain's joints (q_m, a leader's) get their own draws; empty without measured chains
    leader = np.random.default_rng(seed + 1)
    measured = [leader.uniform(-0.5, 0.5, system.measured_dof) for _ in pairs]
    chain_of = {f"{c.name}_{suffix}": i for i, c in enumerate(system.chains)
                for suffix in ("fk", "fk_jacobian", "jacobians")}
    inputs = {}
    for entry in module.manifest["kernels"]:
        name = entry["name"]
        points = []
        for sample, q_m in zip(pairs, measured, strict=True):
            if name in chain_of:
                arrays = [np.array(system.split(list(sample.q), list(q_m))[chain_of[name]], dtype=float)]
            else:
                by_port = {"q": sample.q, "q_m": q_m, "qd": sample.velocity,
                           "V_Sd": np.array([sample.desired[b] for b in SIMILARITY])}
                arrays = [by_port[p["name"]] for p in entry["inputs"]]
            points.append((sample.label, arrays))
        inputs[name] = points
    return check_kernels(module, functions, inputs, progress=progress, rtol=rtol, fd_rtol=fd_rtol)


def check_spec(spec: str | Path, folder: str | Path, samples: int, tolerance: float) -> int:
    """Every kernel against the interpreter on every named configuration and ``samples`` random ones
    within the joint limits; relative tolerances (``tolerance`` for values, 1e-6 for the Richardson
    differences of the AD Jacobians; see ``gagen.check``). Exit status 1 naming each failing output."""
    system, configurations = load_system(spec)
    named = ", ".join(configurations) or "none"
    print(f"{system.name}: checking every kernel (C single, C batched, CasADi) on {len(configurations)} "
          f"named configurations ({named}) and {samples} random samples within the joint limits", flush=True)
    report = check_module(load(folder), system, configurations, count=samples, rtol=tolerance,
                          progress=lambda line: print(line, flush=True))
    print(format_report(report))
    worst_value = max((d.worst for d in report if d.reference == "interpreter"), default=0.0)
    worst_fd = max((d.worst for d in report if d.reference != "interpreter"), default=0.0)
    print(f"max relative error: {worst_value:.2e} against the interpreter (tolerance {tolerance:g}), "
          f"{worst_fd:.2e} against Richardson central differences (steps {FD_STEPS[0]:g}…{FD_STEPS[-1]:g}, "
          f"tolerance {FD_RTOL:g})")
    failed = failures(report)
    for d in failed:
        print(f"error: {system.name}: {d.message()}", file=sys.stderr)
    return 1 if failed else 0
