"""`gagen sweep` throughput: the same sweeps serially (no Dask), then on a LocalCluster of 1 and 2 worker
processes, and the cost Dask adds per chunk [issue 19, item 3].

    python benchmarks/sweep.py [--samples 200000] [--grid 15] [--repeats 3]

Rows: the manipulability sweep (batched C kernels and a stacked SVD per chunk of 10 000 random
configurations of the three Pandas), the same over a regular grid of four joints (20 × 20 × 25 × 20 =
200 000 configurations, the others at ``ready``), the reach sweep (one cold iLQR solve per target
circle, chunks of 15), and an overhead row: the manipulability sweep in chunks of 10 configurations,
where the work per chunk is small and the time is Dask's (task submission, pickling, the transfer of the
rows) and the store's (one Parquet file written, fsync'd and renamed per chunk). Throughput counts the
chunks' wall time only: the cluster's start and the workers' loading of the module are reported apart.
Medians of ``--repeats``, each into a fresh folder. Not part of the test suite.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

BENCH = Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH))

from run import machine, table  # noqa: E402 -- benchmarks/ is not a package

from gagen.sweep.engine import connect, run, run_serial  # noqa: E402
from gagen.sweep.problems import Manipulability, Reach, Sweep, prepare  # noqa: E402

GRID = "arm0/panda_joint1=20,arm0/panda_joint2=20,arm1/panda_joint4=25,arm2/panda_joint6=20"


def seconds(sweep: Sweep, repeats: int, client: object | None) -> float:
    """Median wall time of the chunks of ``sweep`` (serially when ``client`` is None)."""
    times = []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as folder:
            outcome = (run_serial(sweep, folder) if client is None
                       else run(sweep, folder, client=client, progress=False))
            assert len(outcome.computed) == sweep.chunks and not outcome.failed
            times.append(outcome.seconds)
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=200_000, help="configurations of the manipulability sweep")
    ap.add_argument("--grid", type=int, default=15, help="target centres per axis of the reach sweep")
    ap.add_argument("--overhead-chunks", type=int, default=400, help="chunks of the overhead row")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    sweeps = {"manipulability (configurations/s)": Manipulability(samples=args.samples, chunk=10_000),
              "manipulability on a grid (configurations/s)": Manipulability(grid=GRID, chunk=10_000),
              "reach (iLQR solves/s)": Reach(grid=args.grid, chunk=15),
              "overhead: 10 configurations per chunk": Manipulability(samples=10 * args.overhead_chunks,
                                                                      chunk=10)}
    for sweep in sweeps.values():
        prepare(sweep)  # the serial runs load the module and compile the iLQR loop outside the timing
    measured: dict[str, dict[str, float]] = {name: {} for name in sweeps}
    for name, sweep in sweeps.items():
        measured[name]["serial"] = seconds(sweep, args.repeats, None)
    starts = {}
    for workers in (1, 2):
        started = time.perf_counter()
        with connect(workers=workers) as client:
            for sweep in sweeps.values():
                client.run(prepare, sweep)
            starts[workers] = time.perf_counter() - started
            for name, sweep in sweeps.items():
                measured[name][workers] = seconds(sweep, args.repeats, client)
                print(f"  {name}, {workers} workers: {measured[name][workers]:.3f} s", file=sys.stderr,
                      flush=True)
    rows = []
    for name, sweep in sweeps.items():
        count = sweep.rows
        t = measured[name]
        if name.startswith("overhead"):
            per_chunk = [(t[w] - t["serial"]) / sweep.chunks * 1e3 for w in (1, 2)]
            rows.append([name, f"{t['serial'] / sweep.chunks * 1e3:.2f} ms per chunk",
                         f"{t[1] / sweep.chunks * 1e3:.2f} ms per chunk (+{per_chunk[0]:.2f})",
                         f"{t[2] / sweep.chunks * 1e3:.2f} ms per chunk", f"{t[1] / t[2]:.2f}×"])
            continue
        rows.append([name, f"{count / t['serial']:,.0f}", f"{count / t[1]:,.0f}", f"{count / t[2]:,.0f}",
                     f"**{t[1] / t[2]:.2f}×**"])
    print("# `gagen sweep` throughput\n")
    print(machine())
    print(f"- chunks written as Parquet (fsync + rename) by the client; LocalCluster of single-threaded "
          f"worker processes, started in {starts[1]:.1f} s (1 worker) and {starts[2]:.1f} s (2 workers) "
          f"with the module loaded; medians of {args.repeats} runs\n")
    print(table(["sweep", "serial (no Dask)", "Dask, 1 worker", "Dask, 2 workers", "2 vs 1 worker"], "lrrrr",
                rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
