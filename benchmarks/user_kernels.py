"""User kernels through the public front-end: compile time, call time from Python, and op counts vs kingdon.

    python benchmarks/user_kernels.py            # all three tables (markdown)
    python benchmarks/user_kernels.py --quick    # fewer repeats

(a) ``gagen.compile`` of a ~100-flop kernel (the distance of a point from a circle and its AD Jacobian,
    cga3d: 110 flops, 4 sqrt) into a fresh cache folder, split into its phases: the trace (the function
    run on symbolic multivectors, CasADi AD and CSE), the module's sources (``build_source(...,
    compile_c=False)``: the key, the C and binding sources, the manifest), the C compiler (as the build
    reports it), and the load. "Excluding the C compile" is the full ``gagen.compile`` minus the
    compiler's own time. Then a cached compile: a new ``KernelFunction`` of the same content finds the
    built module in the cache and loads it (the trace still runs: it gives the content key).
(b) One call from Python, ns (median over REPEATS loops of CALLS calls, the loop's own cost included,
    inputs cycling through 64 pre-made arrays): ``k(X, C)`` (fresh output arrays), ``k(X, C, out=outs)``
    and ``f(X, C)`` with ``f = k.bind()``.
(c) Scalar operations, gagen vs kingdon, for the formulas of tests/codegen/test_kingdon_ops.py (see its
    docstring for what is compared and how kingdon's code is counted).

The issue's targets: compile ≤ 1 s excluding the C compile; one call ≤ 0.4 µs.
"""

import argparse
import importlib.util
import os
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import gagen
from gagen.algebra.kinds import kind_blades
from gagen.algebra.signature import cga3d
from gagen.interp import MultiVector
from gagen.interp.multivector import conformal_point

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # examples/ and benchmarks/ as packages

from benchmarks.python_calls import median_ns  # noqa: E402
from examples.formulas import circle_distance  # noqa: E402  (the README's kernel)

CALLS = 20000
REPEATS = 9


def _sample(rng: np.random.Generator) -> list[np.ndarray]:
    """A normalised point and a circle through three random points."""
    alg = cga3d()
    x = conformal_point(alg, rng.normal(size=3))
    c = MultiVector.from_blades(alg, {0: 1.0})
    for _ in range(3):
        c = c ^ conformal_point(alg, rng.normal(size=3))
    return [np.array([x[b] for b in kind_blades(alg, "point")]),
            np.array([c[b] for b in kind_blades(alg, "circle")])]


def declare() -> gagen.KernelFunction:
    """A new KernelFunction of the same content each time (nothing traced or compiled yet)."""
    return gagen.kernel(algebra="cga3d", jacobians={"J_d": ("d", "X")}, sample=_sample)(circle_distance.fn)


# -- (a) compile time ---------------------------------------------------------------------------------------
def compile_times(repeats: int) -> dict[str, float]:
    from gagen.build import build_source
    from gagen.frontend import source_of

    phases: dict[str, list[float]] = {k: [] for k in ("trace", "sources", "compile_total", "c_compiler",
                                                      "excluding_c", "cached")}
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as tmp:
            k = declare()
            t0 = time.perf_counter()
            k.trace()
            t1 = time.perf_counter()
            build_source(source_of([k], k.name), Path(tmp) / "sources", compile_c=False,
                         progress=lambda _: None)
            t2 = time.perf_counter()
            phases["trace"].append(t1 - t0)
            phases["sources"].append(t2 - t0)

            os.environ["GAGEN_CACHE"] = str(Path(tmp) / "cache")
            lines: list[str] = []
            k = declare()
            t0 = time.perf_counter()
            compiled = gagen.compile(k, progress=lines.append)
            total = time.perf_counter() - t0
            reported = [re.findall(r"compiled .*\(([\d.]+) s\)", line) for line in lines]
            c_seconds = sum(float(m) for found in reported for m in found)
            phases["compile_total"].append(total)
            phases["c_compiler"].append(c_seconds)
            phases["excluding_c"].append(total - c_seconds)

            k = declare()
            t0 = time.perf_counter()
            again = gagen.compile(k)
            phases["cached"].append(time.perf_counter() - t0)
            x = _sample(np.random.default_rng(0))
            assert np.allclose(compiled(*x)[0], again(*x)[0])
    return {k: statistics.median(v) for k, v in phases.items()}


# -- (b) one call from Python --------------------------------------------------------------------------------
def call_times(calls: int, repeats: int) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["GAGEN_CACHE"] = tmp
        k = gagen.compile(declare())
        rng = np.random.default_rng(1)
        pool = [_sample(rng) for _ in range(64)]
        seq = [pool[i % len(pool)] for i in range(calls)]
        outs = k.empty()
        bound = k.bind()

        def fresh():
            for x, c in seq:
                k(x, c)

        def into():
            for x, c in seq:
                k(x, c, out=outs)

        def fast():
            for x, c in seq:
                bound(x, c)

        def empty_loop():
            for _x, _c in seq:
                pass

        return {"k(X, C)": median_ns(fresh, calls, repeats),
                "k(X, C, out=outs)": median_ns(into, calls, repeats),
                "f(X, C), f = k.bind()": median_ns(fast, calls, repeats),
                "(the loop alone)": median_ns(empty_loop, calls, repeats),
                "binding": float(bool(getattr(k, "binding", False)))}


# -- (c) op counts vs kingdon --------------------------------------------------------------------------------
def _kingdon_comparisons():
    path = ROOT / "tests" / "codegen" / "test_kingdon_ops.py"
    spec = importlib.util.spec_from_file_location("_gagen_kingdon_ops", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # (its dataclasses look their module up)
    spec.loader.exec_module(module)
    return module.COMPARISONS


def op_table() -> list[tuple[str, str, int, int]]:
    rows = []
    for c in _kingdon_comparisons():
        rows.append((c.formula, f"{'pga3d' if c.grade == 3 else 'cga3d'} {c.basis}", c.gagen_count().flops,
                     c.kingdon_count().flops))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    args = parser.parse_args()
    repeats = 3 if args.quick else 7
    calls, call_repeats = (5000, 5) if args.quick else (CALLS, REPEATS)

    k = declare().trace()
    print(f"kernel: circle_distance (cga3d, d and dd/dX): {k.op_count}\n")

    t = compile_times(repeats)
    print(f"(a) gagen.compile, median of {repeats} (s)\n")
    print("| phase | s |\n|---|---|")
    print(f"| trace (symbolic run, AD, CSE) | {t['trace']:.3f} |")
    print(f"| trace + sources (build_source, compile_c=False) | {t['sources']:.3f} |")
    print(f"| gagen.compile, fresh cache | {t['compile_total']:.3f} |")
    print(f"| of which the C compiler (library + binding) | {t['c_compiler']:.3f} |")
    print(f"| **gagen.compile excluding the C compile** (target ≤ 1 s) | **{t['excluding_c']:.3f}** |")
    print(f"| gagen.compile again, new KernelFunction, cached | {t['cached']:.3f} |\n")

    c = call_times(calls, call_repeats)
    binding = c.pop("binding")
    print(f"(b) one call from Python, ns (median of {call_repeats} × {calls} calls; "
          f"CPython binding: {'yes' if binding else 'no, ctypes'}; target ≤ 400 ns)\n")
    print("| call | ns |\n|---|---|")
    for name, ns in c.items():
        print(f"| {name} | {ns:.0f} |")
    print()

    print("(c) scalar operations (mul + add + neg + div), gagen vs kingdon\n")
    print("| formula | basis | gagen | kingdon |\n|---|---|---|---|")
    for formula, basis, ours, theirs in op_table():
        mark = "" if ours <= theirs else " (gagen higher)"
        print(f"| {formula} | {basis} | {ours}{mark} | {theirs} |")


if __name__ == "__main__":
    main()
