"""Batches across topologies: mechanisms of five linkages (four_bar, slider_crank, six_bar, jansen,
ten_bar; N random mechanisms each) followed through one crank revolution (1° steps, Newton to
max |F| < 1e-12 per mechanism), three ways, in one run; a markdown table on stdout.

    python benchmarks/linkage_topologies.py                 # ≈ 1 min (+ ≈ 30 s the first time: the module)
    python benchmarks/linkage_topologies.py --count 64 --rounds 1
    python benchmarks/linkage_topologies.py --figure docs/images/linkage_topologies.png

- C per topology: ``batch.sweep`` of each group in turn (one SIMD-batched ``newton_step`` call per
  Newton iteration over the group's mechanisms);
- C, multi-topology: ``topologies.sweep_topologies``, every group advanced together (the same calls,
  interleaved; its results equal the per-topology ones bitwise, checked here);
- JAX: ``topologies.jax_sweep``, the whole batch one jitted XLA call (``lax.scan`` over the angles of a
  ``lax.while_loop`` of Newton iterations, ``jax.vmap`` of the module's JAX ``newton_step`` per group),
  on the CPU, float64; its jit compilation timed apart; its results checked against C (1e-12).

The mechanisms: four-bars of random link lengths (Grashof classes mixed: some cranks stop, and those
mechanisms freeze), the others their spec scaled by a random factor in [0.8, 1.25]. Throughput is
mechanism-steps per second (N × 5 groups × 361 angles over the time of the whole sweep); medians over
the rounds. Not part of the test suite.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from gagen.apps.linkage.batch import four_bar_points, sweep
from gagen.apps.linkage.bundled import BUNDLED
from gagen.apps.linkage.kernels import initial_points, point_labels
from gagen.apps.linkage.spec import load_linkage
from gagen.apps.linkage.topologies import (
    Group,
    jax_sweep,
    jax_sweep_function,
    sweep_topologies,
    topology_module,
)

NAMES = ("four_bar", "slider_crank", "six_bar", "jansen", "ten_bar")


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def cpu_model() -> str:
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
        return next(line.split(":", 1)[1].strip() for line in lines if line.startswith("model name"))
    except (OSError, StopIteration):
        return "unknown CPU"


def groups(count: int, seed: int = 0) -> list[Group]:
    rng = np.random.default_rng(seed)
    out = []
    for name in NAMES:
        linkage = load_linkage(BUNDLED / f"{name}.yaml")
        if name == "four_bar":
            points: list[np.ndarray] = []
            while len(points) < count:
                x = four_bar_points(*rng.uniform(0.5, 3.0, 4))
                if x is not None:
                    points.append(x)
            out.append(Group(linkage, np.array(points)))
        else:
            out.append(Group(linkage, np.outer(rng.uniform(0.8, 1.25, count), initial_points(linkage))))
    return out


def timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    start = time.perf_counter()
    result = fn()
    return time.perf_counter() - start, result


def figure(module: Any, batch: list[Group], results: list[Any], path: Path) -> None:
    """Every mechanism's trace point over the revolution, one panel per topology (at most 24 each)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(batch), figsize=(3.0 * len(batch), 3.0))
    for ax, group, result in zip(axes, batch, results, strict=True):
        linkage = group.linkage
        assert linkage.trace is not None
        column = point_labels(linkage).index(f"{linkage.trace[0]}_{linkage.trace[1]}_x")
        positions = getattr(module.c, f"{linkage.name}_positions").batch
        for k in range(min(24, len(group.initial))):
            solved = result.reached[k]
            if solved < 2:
                continue
            P = positions(result.motors[:solved, k], result.angles[:solved, None],
                          np.tile(group.initial[k], (solved, 1)))
            ax.plot(P[:, column], P[:, column + 1], lw=0.7)
        ax.set_title(f"{linkage.name}: {len(group.initial)} mechanisms ({min(24, len(group.initial))} drawn)",
                     fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.tick_params(labelsize=7)
    fig.suptitle("One call, five topologies: each mechanism's trace point over a crank revolution",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    log(f"wrote {path} ({path.stat().st_size // 1024} KB)")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=256, help="mechanisms per topology (default 256)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--no-jax", action="store_true")
    ap.add_argument("--figure", type=Path, help="write the trace points of the batch to this PNG")
    args = ap.parse_args()
    batch = groups(args.count)
    angles = np.radians(np.arange(0.0, 361.0, 1.0))
    log("module of the five topologies (built once into gagen's cache) ...")
    seconds, module = timed(lambda: topology_module([g.linkage for g in batch]))
    log(f"  {seconds:.1f} s")
    run = None
    compile_seconds = float("nan")
    if not args.no_jax:
        try:
            import jax
        except ImportError:
            log("jax is not installed: pip install 'gagen[jax]'; timing C only")
        else:
            run = jax_sweep_function(module, [g.linkage for g in batch])
            compile_seconds, _ = timed(lambda: jax_sweep(module, batch, angles, function=run))
            log(f"JAX {jax.__version__} on {jax.devices()[0].platform}: jit compilation + first call "
                f"{compile_seconds:.1f} s")

    def per_topology() -> list[Any]:
        return [sweep(SimpleNamespace(newton_step=getattr(module.c, f"{g.linkage.name}_newton_step")),
                      g.linkage, g.initial, angles) for g in batch]

    methods = {"C SIMD, one batch.sweep per topology": per_topology,
               "C SIMD, multi-topology (sweep_topologies)": lambda: sweep_topologies(module, batch, angles)}
    if run is not None:
        methods["JAX jit, the whole batch one XLA call (CPU)"] = lambda: jax_sweep(module, batch, angles,
                                                                                  function=run)
    times: dict[str, list[float]] = {name: [] for name in methods}
    results: dict[str, list[Any]] = {}
    for r in range(args.rounds):
        log(f"round {r + 1} of {args.rounds} ...")
        for name, fn in methods.items():
            seconds, results[name] = timed(fn)
            times[name].append(seconds)
    c_alone, c_multi = (results[name] for name in list(methods)[:2])
    for a, b in zip(c_alone, c_multi, strict=True):
        assert np.array_equal(a.motors, b.motors, equal_nan=True)  # (a frozen mechanism: its last iterate)
        assert np.array_equal(a.residuals, b.residuals, equal_nan=True)
    agreement = ""
    if run is not None:
        jaxed = results[list(methods)[2]]
        worst, differ = [], 0
        for c, j in zip(c_multi, jaxed, strict=True):
            assert np.array_equal(c.reached, j.reached)
            differ += int(np.count_nonzero(c.iterations != j.iterations))
            solved = np.arange(len(angles))[:, None] < c.reached[None, :]
            worst.append(f"{float(np.abs(c.motors - j.motors)[solved].max()):.1e}")
        agreement = (f"; JAX agrees with C to {' / '.join(worst)} (motors where solved, per topology), "
                     f"the same iterations at all but {differ} of {len(angles) * len(batch)} group steps")
    steps = args.count * len(batch) * len(angles)
    iterations = sum(int(r.iterations.sum()) for r in c_multi)
    print(f"\n{args.count} mechanisms × {len(batch)} topologies ({', '.join(NAMES)}), {len(angles)} crank "
          f"angles (1°); {cpu_model()}; medians of {args.rounds} round(s); {iterations} batched Newton "
          f"iterations over the groups{agreement}; multi-topology results = per-topology, bitwise\n")
    print("| method | time per revolution of the batch | mechanism-steps/s | µs per mechanism-step |")
    print("|---|---:|---:|---:|")
    for name, values in times.items():
        t = statistics.median(values)
        print(f"| {name} | {t:.3f} s | {steps / t:.3g} | {1e6 * t / steps:.2f} |")
    if run is not None:
        print(f"\nJAX: jit compilation and first call {compile_seconds:.1f} s (once per set of topologies "
              f"and batch shapes).")
    if args.figure is not None:
        figure(module, batch, c_multi, args.figure)
    return 0


if __name__ == "__main__":
    sys.exit(main())
