"""The ``gagen`` command line: ``demo`` (the compiler core on CGA formulas), ``algebra`` (a preset's
metric and blade order) and ``kernels`` (a spec's kernel catalogue with op counts)."""

from __future__ import annotations

import argparse
import sys

from gagen import __version__


def _cmd_demo(args: argparse.Namespace) -> int:
    from gagen.demo import run

    worst = run(samples=args.samples, seed=args.seed)
    if worst > args.tolerance:
        print(f"error: kernels disagree with the interpreter beyond {args.tolerance:g}", file=sys.stderr)
        return 1
    return 0


def _cmd_algebra(args: argparse.Namespace) -> int:
    from gagen.algebra.signature import preset

    try:
        algebra = preset(args.name)
    except KeyError as e:
        print(f"error: {e.args[0]}", file=sys.stderr)
        return 2
    p, q, r = algebra.signature
    print(f"{algebra.name}: G({p},{q},{r}), {algebra.size} blades")
    print("metric (e_i . e_j):")
    names = ["e" + v for v in algebra.vector_labels]
    width = max(map(len, names)) + 1
    print(" " * width + "".join(f"{n:>{width}}" for n in names))
    for n, row in zip(names, algebra.metric, strict=True):
        print(f"{n:>{width}}" + "".join(f"{v!s:>{width}}" for v in row))
    print("blades by bitmask: " + ", ".join(f"{m}:{algebra.blade_name(m)}" for m in range(algebra.size)))
    return 0


def _cmd_kernels(args: argparse.Namespace) -> int:
    import time

    from gagen.errors import SpecError
    from gagen.kernels import build_kernels
    from gagen.report import op_count_table
    from gagen.spec.loader import load_system

    try:
        system, _ = load_system(args.spec)
    except SpecError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    start = time.perf_counter()
    kernels = build_kernels(system)
    print(f"{system.name}: a {system.kind} spanned by {len(system.chains)} chains, {system.dof} joints; "
          f"{len(kernels)} kernels built in {time.perf_counter() - start:.2f} s\n")
    print(op_count_table(kernels.values()))
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="gagen", description="Symbolic code generation for conformal "
                                     "geometric algebra in robotics.")
    parser.add_argument("--version", action="version", version=f"gagen {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="flatten a few CGA formulas and check them against the interpreter")
    demo.add_argument("--samples", type=int, default=1000, help="random inputs per formula (default 1000)")
    demo.add_argument("--seed", type=int, default=0)
    demo.add_argument("--tolerance", type=float, default=1e-12, help="fail above this relative error")
    demo.set_defaults(run=_cmd_demo)

    alg = sub.add_parser("algebra", help="print an algebra preset: metric and blade order")
    alg.add_argument("name", help="cga3d, cga2d, pga3d or ga3d")
    alg.set_defaults(run=_cmd_algebra)

    kernels = sub.add_parser("kernels", help="build a spec's kernels and print their shapes and op counts")
    kernels.add_argument("spec", help="robot spec (YAML), e.g. robots/three_pandas_circle.yaml")
    kernels.set_defaults(run=_cmd_kernels)

    args = parser.parse_args(argv)
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())
