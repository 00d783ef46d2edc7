"""The core's verbs: ``demo`` (the compiler core on CGA formulas), ``algebra`` (a preset's metric and blade
order), ``kernels`` (a spec's or a Python file's kernel catalogue with op counts) and ``build`` (the
generated module of specs or Python files of kernels, optionally checked against the interpreter).
Light at import; each verb imports what it needs when it runs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from gagen.arguments import non_negative_float, positive_int
from gagen.errors import print_error
from gagen.registry import Verb

if TYPE_CHECKING:
    from gagen.build import BuildResult


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
        print_error(e.args[0])
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

    from gagen.build import load_source
    from gagen.errors import SpecError
    from gagen.frontend import KernelError
    from gagen.report import op_count_table

    start = time.perf_counter()
    try:
        source = load_source(args.spec)
        kernels = [source.kernels[name] for name in source.kernels]
    except (SpecError, KernelError, FileNotFoundError) as e:
        print_error(e)
        return 2
    print(f"{source.name}: {source.title}; {len(kernels)} kernels built in "
          f"{time.perf_counter() - start:.2f} s\n")
    print(op_count_table(kernels))
    return 0


def _cmd_build(args: argparse.Namespace) -> int:
    from gagen.build import OutputError, build_many, spec_checker
    from gagen.codegen.backends import TemplateNotFound
    from gagen.codegen.compiler import CompileError
    from gagen.errors import SpecError

    if args.output and len(args.spec) > 1:
        print("error: -o/--output takes one file; several go to generated/<name>", file=sys.stderr)
        return 2
    if args.name and (len(args.spec) > 1 or Path(args.spec[0]).suffix != ".py"):
        print("error: --name names the module of one Python file (a spec names its system)", file=sys.stderr)
        return 2
    from gagen.frontend import KernelError

    errors: tuple[type[BaseException], ...] = (SpecError, KernelError, FileNotFoundError)
    try:
        results = build_many(args.spec, force=args.force, compile_c=not args.no_compile, jobs=args.jobs,
                             outputs=[args.output] if args.output else None,
                             names=[args.name] if args.name else None)
    except errors as e:
        print_error(e)
        return 2
    except (CompileError, OutputError, TemplateNotFound) as e:  # OutputError: "cannot write <path>: <reason>"
        print_error(e)
        return 1
    status = 0
    if args.check:
        for spec, result in zip(args.spec, results, strict=True):
            if result.source.functions:  # front-end kernels (a Python file, a hexapod spec)
                status = max(status, _check_kernels(result, args.samples, args.tolerance))
            else:  # a spec kind whose application checks its modules itself
                status = max(status, spec_checker(spec)(spec, result.folder, args.samples, args.tolerance))
    return status


def _check_kernels(result: BuildResult, samples: int, tolerance: float) -> int:
    """The kernels of a Python file against their functions run on the interpreter (``gagen.check``)."""
    from gagen.check import check_kernels, failures, format_report
    from gagen.runtime import load

    source = result.source
    print(f"{source.name}: checking every kernel (C single, C batched, CasADi) against the interpreter on "
          f"{samples} random samples", flush=True)
    report = check_kernels(load(result.folder), source.functions, count=samples, rtol=tolerance,
                           progress=lambda line: print(line, flush=True))
    print(format_report(report))
    failed = failures(report)
    for d in failed:
        print_error(f"{source.name}: {d.message()}")
    return 1 if failed else 0


def _demo_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--samples", type=positive_int, default=1000, help="random inputs per formula "
                                                                           "(default 1000)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tolerance", type=non_negative_float, default=1e-12,
                        help="fail above this relative error (default 1e-12)")


def _algebra_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", help="cga3d, cga2d, pga3d or ga3d")


def _kernels_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("spec", help="a spec (YAML: a robot system, a hexapod, a linkage, a stereo "
                                     "rig), e.g. "
                        "robots/three_pandas_circle.yaml, or a Python file of @gagen.kernel functions")


def _build_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("spec", nargs="+", help="spec(s) (YAML: robot systems, hexapods, linkages, stereo "
                        "rigs), e.g. robots/three_pandas_circle.yaml, or Python files of @gagen.kernel "
                        "functions")
    parser.add_argument("-o", "--output", help="output folder (one file only; default generated/<name>)")
    parser.add_argument("--name", help="the module name of a Python file (default: the file's stem)")
    parser.add_argument("--force", action="store_true", help="rebuild even if the cached build is up to date")
    parser.add_argument("--no-compile", action="store_true", help="write the C source but do not compile it")
    parser.add_argument("--check", action="store_true",
                        help="evaluate every kernel against the interpreter and print the maximum error")
    parser.add_argument("-j", "--jobs", type=positive_int, help="parallel C compilations (default: CPU "
                                                                "count)")
    parser.add_argument("--samples", type=positive_int, default=5, help="random inputs for --check "
                                                                        "(default 5)")
    parser.add_argument("--tolerance", type=non_negative_float, default=1e-10,
                        help="--check fails above this error (default 1e-10)")


VERBS = (
    Verb("demo", "flatten a few CGA formulas and check them against the interpreter", _demo_arguments,
         _cmd_demo),
    Verb("algebra", "print an algebra preset: metric and blade order", _algebra_arguments, _cmd_algebra),
    Verb("kernels", "build a spec's kernels and print their shapes and op counts", _kernels_arguments,
         _cmd_kernels),
    Verb("build", "generate a module of kernels: CasADi Functions, C kernels, library, JAX", _build_arguments,
         _cmd_build),
)
