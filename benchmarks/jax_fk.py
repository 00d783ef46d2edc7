"""Panda FK + 6×7 Jacobian over many configurations: gagen's C batch, gagen's JAX kernel
(``gagen.codegen.backends.jax.printer``, jit(vmap) on the CPU) and the peers, adam-robotics' JAX backend
(jit(vmap)) and pytorch-kinematics (batched, float64; eager and under torch.compile) [issue 19, item 4].

    python benchmarks/jax_fk.py [--sizes 100000 1000000] [--repeats 5] [--budget 60]

All backends read the same URDF and chain (``robots/panda_point.yaml``: panda_link0 → panda_link8) and
compute the flange pose and the Jacobian of the 7 joints at the same uniformly drawn configurations.
Medians of the repeats after a first call (reported on its own: for the jit rows, JAX and
torch.compile, it traces and compiles), configurations per second, the ratio to gagen's C batch, and
each backend's largest deviation from gagen's C batch over every configuration: the flange position and
the Jacobian, both brought to one convention (below); a backend beyond its tolerance stops the run. A
peer that is not installed (the ``bench`` extra) gets a row saying so. Not part of the test suite.

Conventions: gagen's ``J_S`` column is the joint's spatial twist on rows e12 e13 e23 e1∞ e2∞ e3∞, i.e.
(v, ω) = ((e1∞, e2∞, e3∞), (e23, −e13, e12)) with v the velocity of the point at the base origin
(tests/model/test_pinocchio.py maps it onto Pinocchio's WORLD Jacobian the same way). adam is asked for
that representation (INERTIAL_FIXED); pytorch-kinematics gives the flange origin's velocity v_o in base
axes, which is v + ω × p at the flange position p.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
from typing import Any

import numpy as np
import yaml

BENCH = Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH))

from run import machine, table  # noqa: E402 -- benchmarks/ is not a package

from gagen.apps.cooperative.bundled import system_module  # noqa: E402
from gagen.robots.urdf import load_chain  # noqa: E402

ROBOTS = BENCH.parent / "robots"
SYSTEM = "panda_point"
JAX_TOLERANCE = 1e-12  # the same operations in the same order as the C kernel: rounding only
PEER_TOLERANCE = 1e-10  # other formulas for the same quantities (as tests/model/test_pinocchio.py)
# pytorch-kinematics parses the URDF's origins in float32 (its urdf.py ``_convert_transform``) and
# ``.to(float64)`` keeps the rounded values (0.316 → 0.31600001454): the Panda's lengths are off by up
# to 1.5e-8 m, its positions by ~2.5e-8; parsed in float64 instead it agrees to ~1e-15
FLOAT32_ORIGINS_TOLERANCE = 1e-7


@dataclass(frozen=True)
class Chain:
    urdf: Path
    base: str
    tip: str
    joints: list[str]  # the moving joints, base to tip: the columns of every Jacobian here


@dataclass(frozen=True)
class Backend:
    """One row group: ``run`` is what is timed (configurations (n, 7) in, the library's own outputs out,
    finished); ``convert`` turns those outputs into (flange positions (n, 3), Jacobians (n, 6, 7) as
    (v, ω) spatial twists) for the check."""

    name: str
    run: Callable[[np.ndarray], Any]
    convert: Callable[[Any], tuple[np.ndarray, np.ndarray]]
    tolerance: float
    about: str  # versions, for the header


def panda_chain() -> Chain:
    spec = yaml.safe_load((ROBOTS / f"{SYSTEM}.yaml").read_text())
    (chain,) = spec["chains"]
    urdf = ROBOTS / chain["urdf"]
    joints = [j.name for j in load_chain(urdf, chain["base_link"], chain["tip_link"]) if j.moves]
    return Chain(urdf, chain["base_link"], chain["tip_link"], joints)


def twists_from_gagen(J_S: np.ndarray) -> np.ndarray:
    """(n, 6, 7) rows e12 e13 e23 e1∞ e2∞ e3∞ → (v, ω) rows."""
    return np.stack([J_S[:, 3], J_S[:, 4], J_S[:, 5], J_S[:, 2], -J_S[:, 1], J_S[:, 0]], axis=1)


def gagen_c(module: Any) -> Backend:
    kernel = module.c.arm0_fk_jacobian

    def convert(out: Any) -> tuple[np.ndarray, np.ndarray]:
        _, P, J_S = out
        return P[:, 1:4] / P[:, :1], twists_from_gagen(J_S)  # P on e0 e1 e2 e3 e∞, e0 weight 1

    return Backend("gagen C batch", kernel.batch, convert, 0.0, "")


def gagen_jax(module: Any, reference: Backend) -> Backend:
    import jax

    batched = jax.jit(jax.vmap(module.jax.arm0_fk_jacobian))  # the module's committed JAX backend

    def convert(out: Any) -> tuple[np.ndarray, np.ndarray]:
        M, P, J_S = (np.asarray(o) for o in out)  # (n, 8), (n, 5), (n, 6, 7): the C kernels' shapes
        return reference.convert((M, P, J_S))

    return Backend("gagen JAX jit(vmap)", lambda Q: jax.block_until_ready(batched(Q)), convert,
                   JAX_TOLERANCE, f"JAX {jax.__version__} on {jax.devices()[0].platform}, float64")


def adam_jax(chain: Chain) -> list[Backend]:
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)
    from adam.core.constants import Representations
    from adam.jax import KinDynComputations

    kd = KinDynComputations(str(chain.urdf), chain.joints)
    if kd.rbdalgos.model.tree.root != chain.base:  # adam's FK starts at the URDF's root link
        raise ValueError(f"adam's root is {kd.rbdalgos.model.tree.root}, not {chain.base}")
    # adam 0.5.0 passes the array's device to jnp.asarray inside traced code, which current JAX rejects
    # ("'SingleDeviceSharding' object has no attribute 'spec'"); all of it runs on the one CPU anyway
    kd.rbdalgos.math.factory._device = None
    kd.set_frame_velocity_representation(Representations.INERTIAL_FIXED_REPRESENTATION)  # = gagen's J_S
    eye = jnp.eye(4)

    def fk_and_jacobian(q: Any) -> tuple[Any, Any]:
        # the fixed-base calls: the flange pose and the 6×7 joint Jacobian (no floating-base columns)
        return kd.forward_kinematics(chain.tip, eye, q), kd.relative_jacobian(chain.tip, q)

    batched = jax.jit(jax.vmap(fk_and_jacobian))

    def convert(out: Any) -> tuple[np.ndarray, np.ndarray]:
        H, J = (np.asarray(o) for o in out)
        return H[:, :3, 3], J  # adam's rows are (v, ω)

    return [Backend("adam-robotics JAX jit(vmap)", lambda Q: jax.block_until_ready(batched(Q)), convert,
                    PEER_TOLERANCE, f"adam-robotics {version('adam-robotics')}")]


def pytorch_kinematics(chain: Chain) -> list[Backend]:
    """Eager, and its documented compilable kernel (``jacobian_tensor``) under torch.compile (inductor,
    C++ on the CPU), the counterpart of jit."""
    # the first call's compile is reported: inductor's on-disk caches would hide it on a second run
    os.environ.setdefault("TORCHINDUCTOR_FORCE_DISABLE_CACHES", "1")
    import pytorch_kinematics as pk
    import torch

    serial = pk.build_serial_chain_from_urdf(chain.urdf.read_text(), chain.tip, chain.base)
    serial = serial.to(dtype=torch.float64)
    if serial.get_joint_parameter_names() != chain.joints:
        raise ValueError(f"pytorch-kinematics' joints {serial.get_joint_parameter_names()} ≠ {chain.joints}")
    compiled = torch.compile(lambda th: serial.jacobian_tensor(th, ret_eef_pose=True), fullgraph=True)

    def eager(Q: np.ndarray) -> Any:
        with torch.no_grad():  # plain evaluation, as the other backends
            return serial.jacobian(torch.from_numpy(Q), ret_eef_pose=True)  # one FK pass for both

    def run_compiled(Q: np.ndarray) -> Any:
        with torch.no_grad():
            return compiled(torch.from_numpy(Q))

    def convert(out: Any) -> tuple[np.ndarray, np.ndarray]:
        J, H = (o.numpy() for o in out)
        p = H[:, :3, 3]
        v_origin, omega = J[:, :3], J[:, 3:]
        return p, np.concatenate([v_origin - np.cross(omega, p[:, :, None], axis=1), omega], axis=1)

    about = (f"pytorch-kinematics {version('pytorch-kinematics')}, torch {torch.__version__} "
             f"({torch.get_num_threads()} threads)")
    return [Backend("pytorch-kinematics eager", eager, convert, FLOAT32_ORIGINS_TOLERANCE, about),
            Backend("pytorch-kinematics torch.compile", run_compiled, convert, FLOAT32_ORIGINS_TOLERANCE, "")]


def timed(f: Callable[[], Any], repeats: int, budget: float) -> tuple[float, int]:
    """The median of up to ``repeats`` calls, fewer (≥ 1) once ``budget`` seconds are spent; and how many."""
    times: list[float] = []
    while len(times) < repeats and sum(times) < budget:
        started = time.perf_counter()
        f()
        times.append(time.perf_counter() - started)
    return statistics.median(times), len(times)


def per_configuration(seconds: float) -> str:
    return f"{seconds * 1e9:.1f} ns" if seconds < 1e-6 else f"{seconds * 1e6:.2f} µs"


def rate(per_second: float) -> str:
    return f"{per_second / 1e6:.2f} M/s" if per_second >= 1e6 else f"{per_second / 1e3:.1f} k/s"


def deviation(got: tuple[np.ndarray, np.ndarray], expected: tuple[np.ndarray, np.ndarray]) -> float:
    return max(float(np.abs(g - e).max()) for g, e in zip(got, expected, strict=True))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--budget", type=float, default=60.0,
                        help="seconds of timed calls per backend and size: fewer repeats past it (≥ 1)")
    args = parser.parse_args()
    started = time.perf_counter()
    module = system_module(SYSTEM)
    chain = panda_chain()
    reference = gagen_c(module)
    backends: list[Backend | tuple[str, str]] = [reference, gagen_jax(module, reference)]
    for name, build in (("adam-robotics", adam_jax), ("pytorch-kinematics", pytorch_kinematics)):
        try:
            backends += build(chain)
        except ImportError as missing:  # a peer is optional: the row says why it is absent
            backends.append((name, f"skipped: {missing.name} is not installed (`pip install -e .[bench]`)"))
    rows, c_seconds = [], {}
    for backend in backends:
        if isinstance(backend, tuple):
            rows.append([backend[0], "—", backend[1], "", "", "", "", ""])
            continue
        for n in args.sizes:
            Q = np.random.default_rng(0).uniform(-2.8, 2.8, (n, 7))
            first = time.perf_counter()
            try:
                out = backend.run(Q)
            except Exception as error:  # a peer that cannot run here (torch.compile without a compiler)
                if backend is reference:
                    raise
                rows.append([backend.name, f"{n:,}", f"failed: {type(error).__name__}: "
                             f"{str(error).splitlines()[0][:120]}", "", "", "", "", ""])
                continue
            first_s = time.perf_counter() - first
            worst = deviation(backend.convert(out), reference.convert(reference.run(Q)))
            del out
            if worst > backend.tolerance:
                raise SystemExit(f"{backend.name} disagrees with gagen's C batch by {worst:.2e} at n = {n}")
            seconds, repeats = timed(lambda Q=Q, run=backend.run: run(Q), args.repeats, args.budget)
            c_seconds.setdefault(n, seconds)  # the reference backend comes first
            check = "reference" if backend is reference else f"{worst:.1e}"
            rows.append([backend.name, f"{n:,}", per_configuration(seconds / n), rate(n / seconds),
                         f"{seconds / c_seconds[n]:.1f}×", check, f"{first_s:.2f} s", repeats])
    print("# Panda FK + J: gagen C batch, gagen JAX and peers\n\n`python benchmarks/jax_fk.py`\n")
    print(machine())
    print("- " + "; ".join(b.about for b in backends if isinstance(b, Backend) and b.about))
    print(f"- median of up to {args.repeats} calls after the first, fewer past {args.budget:.0f} s of calls "
          f"(column repeats); gagen's C batch runs on one thread; "
          f"whole run {time.perf_counter() - started:.1f} s")
    if any(isinstance(b, Backend) and b.tolerance == FLOAT32_ORIGINS_TOLERANCE for b in backends):
        print("- pytorch-kinematics' deviation: it parses the URDF's origins in float32 "
              "(lengths off by ≤ 1.5e-8 m)")
    print()
    print(table(["backend", "configurations", "time per configuration", "configurations per second",
                 "÷ gagen C batch", "max deviation vs gagen C", "first call (jit: trace + compile)",
                 "repeats"], "lrrrrrrr", rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
