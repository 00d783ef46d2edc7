"""Panda FK + 6×7 Jacobian over many configurations: gagen's C batch against gagen's JAX kernel
(``gagen.codegen.jax_emit``, jit(vmap) on the CPU) [issue 19, item 4, first rows].

    python benchmarks/jax_fk.py [--sizes 100000 1000000] [--repeats 5]

Medians of the repeats after a warm-up call (the JAX compile is reported separately), configurations
per second, and the JAX results checked against the C batch (1e-12). Not part of the test suite.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

BENCH = Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH))

from run import machine, table  # noqa: E402 -- benchmarks/ is not a package

from gagen.apps.cooperative.bundled import generated_folder  # noqa: E402
from gagen.codegen.jax_emit import jax_kernel  # noqa: E402
from gagen.runtime import load  # noqa: E402


def median_seconds(f, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        f()
        times.append(time.perf_counter() - started)
    return statistics.median(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    import jax

    module = load(generated_folder() / "panda_point")
    c = module.c.arm0_fk_jacobian
    started = time.perf_counter()
    batched = jax.jit(jax.vmap(jax_kernel(module, "arm0_fk_jacobian")))
    rows = []
    for n in args.sizes:
        Q = np.random.default_rng(0).uniform(-2.8, 2.8, (n, 7))
        first = time.perf_counter()
        out = batched(Q)
        jax.block_until_ready(out)
        compile_s = time.perf_counter() - first
        expected = c.batch(Q)
        worst = max(float(np.abs(np.asarray(j).reshape(e.shape) - e).max())
                    for j, e in zip(out, expected, strict=True))
        if worst > 1e-12:
            raise SystemExit(f"JAX disagrees with the C batch by {worst:.2e}")
        c_s = median_seconds(lambda Q=Q: c.batch(Q), args.repeats)
        jax_s = median_seconds(lambda Q=Q: jax.block_until_ready(batched(Q)), args.repeats)
        rows.append([f"{n:,}", f"{c_s / n * 1e9:.1f} ns ({n / c_s / 1e6:.1f} M/s)",
                     f"{jax_s / n * 1e9:.1f} ns ({n / jax_s / 1e6:.1f} M/s)", f"{jax_s / c_s:.1f}×",
                     f"{compile_s:.2f} s", f"{worst:.1e}"])
    print("# Panda FK + J: C batch vs JAX\n\n`python benchmarks/jax_fk.py`\n\n" + machine())
    setup = time.perf_counter() - started
    print(f"- JAX {jax.__version__} on {jax.devices()[0].platform}, float64; whole run {setup:.1f} s\n")
    print(table(["configurations", "gagen C batch", "gagen JAX jit(vmap)", "JAX ÷ C", "JAX first call",
                 "max |JAX − C|"], "rrrrrr", rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
