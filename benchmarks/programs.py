"""The C and C++ timing programs of run.py: compiler flags, Pinocchio's paths and cached builds.

Every program is built into benchmarks/build/, redone only when its command or an input file changes
(a hash stamp next to each output), objects in parallel on the machine's cores:

- ``pinocchio``: pinocchio_fk.cpp against the pip wheel's headers and libraries (pin), -O3;
- ``matrix_chain``: matrix_chain_bench.c and CasADi's C for matrix_chain.py's functions, -O3;
- ``gagen_fk``, ``gagen_fk_O3``: gagen_fk_bench.c linked to generated/panda_point/panda_point.c compiled
  with gagen's own flags (gagen.codegen.compiler.FLAGS), and with the same flags but -O3;
- ``circle``: circle_bench.c linked to generated/three_pandas_circle/three_pandas_circle.c, gagen's flags;
- ``impedance``: impedance_step.cpp (Pinocchio, Eigen) linked to generated/three_iiwas_circle's C;
- ``floor``: floor_bench.c, gagen's flags: 8 angles' vector sine and cosine, and one flop's time.

The drivers (the *_bench.c timing loops) are compiled with -O3 -march=native; only the kernels' flags
differ between gagen_fk and gagen_fk_O3.
"""

from __future__ import annotations

import hashlib
import os
import shlex
import subprocess
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

BENCH = Path(__file__).resolve().parent
ROOT = BENCH.parent
BUILD = BENCH / "build"
GENERATED = ROOT / "generated"
DRIVER_CFLAGS = ["-std=c99", "-O3", "-march=native"]
CXXFLAGS = ["-std=c++17", "-O3", "-march=native", "-DNDEBUG", "-w"]
PROGRAMS = ("pinocchio", "matrix_chain", "gagen_fk", "gagen_fk_O3", "circle", "impedance", "floor")


def bundled_folder(system: str) -> Path:
    """The folder of a bundled system's generated module, built on first use (``gagen.modules``: the
    committed ``generated/<system>``, else the gagen cache)."""
    from gagen.apps.cooperative.bundled import bundled_specs
    from gagen.modules import module_folder

    return module_folder(bundled_specs()[system])


def c_compiler() -> list[str]:
    """The C compiler gagen itself uses ($CC, else cc, gcc or clang)."""
    from gagen.codegen.compiler import find_compiler

    return find_compiler()


def gagen_cflags(optimisation: str | None = None) -> list[str]:
    """gagen's flags for its kernels (gagen.codegen.compiler.FLAGS) as an object's: no -shared; with
    ``optimisation`` (e.g. "-O3") in place of gagen's -O level."""
    from gagen.codegen.compiler import FLAGS, vector_math

    flags = [f for f in FLAGS if f != "-shared"] + [f for f in vector_math() if f.startswith("-D")]
    if optimisation:
        flags = [optimisation if f.startswith("-O") else f for f in flags]
    return flags


def _vector_libs() -> list[str]:
    """glibc's libmvec when gagen compiles its kernels against it (see gagen_cflags)."""
    from gagen.codegen.compiler import vector_math

    return [f for f in vector_math() if not f.startswith("-D")]


def compiler_version(command: list[str]) -> str:
    try:
        out = subprocess.run([*command, "--version"], capture_output=True, text=True).stdout
    except OSError:
        return "?"
    return out.splitlines()[0].strip() if out else "?"


def pinocchio_paths() -> dict:
    """Include/lib folders and defines for the pip wheel's Pinocchio (cmeel layout) and Eigen."""
    import casadi
    import pinocchio

    prefix = Path(pinocchio.__file__).resolve().parents[4]  # …/cmeel.prefix/lib/python3.X/site-packages
    eigen = Path(casadi.__file__).resolve().parent / "include" / "eigen3"  # the wheels bring no other
    urdfdom_headers = prefix / "include" / "urdfdom_headers"
    needed = (prefix / "include" / "pinocchio", eigen / "Eigen", urdfdom_headers / "urdf_model")
    missing = [str(p) for p in needed if not p.exists()]
    if missing:
        raise SystemExit("missing headers: " + ", ".join(missing) +
                         "\n(pip install -e '.[bench]' brings cmeel-urdfdom-headers, which pinocchio's URDF "
                         "parser header needs)")
    defines = ["-DBOOST_MPL_LIMIT_LIST_SIZE=30", "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
               "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
               "-DPINOCCHIO_WITH_URDFDOM", "-DPINOCCHIO_URDFDOM_HEADERS_MAJOR_VERSION=3",
               "-DPINOCCHIO_URDFDOM_HEADERS_MINOR_VERSION=0", "-DPINOCCHIO_URDFDOM_HEADERS_PATCH_VERSION=0",
               # the wheel's libraries are built for baseline x86-64: keep Eigen's layout and allocator
               "-DEIGEN_MAX_ALIGN_BYTES=16", "-DEIGEN_MALLOC_ALREADY_ALIGNED=1"]
    return {"prefix": prefix, "version": pinocchio.__version__,
            "includes": [f"-I{prefix / 'include'}", f"-I{urdfdom_headers}", f"-I{eigen}"],
            "defines": defines,
            "libs": [f"-L{prefix / 'lib'}", f"-Wl,-rpath,{prefix / 'lib'}", "-lpinocchio_parsers",
                     "-lpinocchio_default"]}


@dataclass
class Step:
    """One compiler command producing ``output``, redone only when its command or inputs change."""

    output: Path
    command: list[str]
    inputs: list[Path] = field(default_factory=list)

    def key(self) -> str:
        h = hashlib.sha256(shlex.join(self.command).encode())
        for p in self.inputs:
            h.update(p.read_bytes())
        return h.hexdigest()

    def run(self, force: bool) -> float:
        stamp = self.output.with_name(self.output.name + ".key")
        key = self.key()
        if not force and self.output.exists() and stamp.exists() and stamp.read_text() == key:
            return 0.0
        start = time.perf_counter()
        done = subprocess.run(self.command, capture_output=True, text=True)
        if done.returncode:
            raise SystemExit(f"build failed: {shlex.join(self.command)}\n{done.stderr[-4000:]}")
        stamp.write_text(key)
        return time.perf_counter() - start


def _compile(compiler: list[str], flags: list[str], source: Path, output: Path, deps: list[Path]) -> Step:
    return Step(output, [*compiler, *flags, "-c", str(source), "-o", str(output)], [source, *deps])


def _link(compiler: list[str], objects: list[Path], output: Path, libs: list[str]) -> Step:
    return Step(output, [*compiler, *map(str, objects), "-o", str(output), *libs], objects)


def build(wanted: set[str], force: bool = False) -> tuple[dict[str, Path], list[str], float]:
    """Compile the wanted programs (of PROGRAMS); returns their paths, the commands and the seconds."""
    unknown = wanted - set(PROGRAMS)
    if unknown:
        raise ValueError(f"unknown programs: {', '.join(sorted(unknown))}")
    BUILD.mkdir(parents=True, exist_ok=True)
    cc = c_compiler()
    harness = BENCH / "harness.h"
    objects: list[Step] = []
    links: list[Step] = []
    programs: dict[str, Path] = {}

    if "pinocchio" in wanted:
        pin = pinocchio_paths()
        src = BENCH / "pinocchio_fk.cpp"
        flags = [*CXXFLAGS, *pin["defines"], *pin["includes"], f"-I{BENCH}"]
        parts = [BUILD / "pinocchio_fk_load.o", BUILD / "pinocchio_fk_main.o"]
        # the loader and the algorithms are independent instantiations: two objects, compiled in parallel
        objects += [_compile(["g++"], [*flags, "-DPINFK_PART=1"], src, parts[0], []),
                    _compile(["g++"], [*flags, "-DPINFK_PART=2"], src, parts[1], [harness])]
        links.append(_link(["g++"], parts, BUILD / "pinocchio_fk", pin["libs"]))
        programs["pinocchio"] = BUILD / "pinocchio_fk"

    if "circle" in wanted:
        folder = GENERATED / "three_pandas_circle"
        src, hdr = folder / "three_pandas_circle.c", folder / "three_pandas_circle.h"
        kernels, driver = BUILD / "circle_kernels.o", BUILD / "circle_bench.o"
        simd = BUILD / "circle_kernels_simd.o"  # gagen compiles its _simd.c companion at -O3
        objects += [_compile(cc, [*gagen_cflags(), f"-I{folder}"], src, kernels, [hdr]),
                    _compile(cc, [*gagen_cflags("-O3"), f"-I{folder}"], folder / "three_pandas_circle_simd.c",
                             simd, [hdr]),
                    _compile(cc, [*DRIVER_CFLAGS, f"-I{BENCH}", f"-I{folder}"], BENCH / "circle_bench.c",
                             driver, [harness, hdr])]
        links.append(_link(cc, [kernels, simd, driver], BUILD / "circle_bench", [*_vector_libs(), "-lm"]))
        programs["circle"] = BUILD / "circle_bench"

    if "impedance" in wanted:
        pin = pinocchio_paths()
        folder = bundled_folder("three_iiwas_circle")  # not committed: the gagen cache
        src, hdr = folder / "three_iiwas_circle.c", folder / "three_iiwas_circle.h"
        kernels, simd = BUILD / "impedance_kernels.o", BUILD / "impedance_kernels_simd.o"
        driver = BUILD / "impedance_step.o"
        cxx = [*CXXFLAGS, *pin["defines"], *pin["includes"], f"-I{BENCH}", f"-I{folder}"]
        objects += [_compile(cc, [*gagen_cflags(), f"-I{folder}"], src, kernels, [hdr]),
                    _compile(cc, [*gagen_cflags("-O3"), f"-I{folder}"], folder / "three_iiwas_circle_simd.c",
                             simd, [hdr]),
                    _compile(["g++"], cxx, BENCH / "impedance_step.cpp", driver, [harness, hdr])]
        links.append(_link(["g++"], [kernels, simd, driver], BUILD / "impedance_step",
                           [*pin["libs"], *_vector_libs(), "-lm"]))
        programs["impedance"] = BUILD / "impedance_step"

    if "floor" in wanted:  # with gagen's flags: the vector sine and cosine its kernels call
        floor = BUILD / "floor_bench.o"
        objects.append(_compile(cc, [*gagen_cflags(), f"-I{BENCH}"], BENCH / "floor_bench.c", floor,
                                [harness]))
        links.append(_link(cc, [floor], BUILD / "floor_bench", [*_vector_libs(), "-lm"]))
        programs["floor"] = BUILD / "floor_bench"

    if "matrix_chain" in wanted:
        import matrix_chain

        mc_dir = BUILD / "matrix_chain"
        mc_c, mc_h = matrix_chain.emit_c(matrix_chain.functions(), mc_dir)
        parts = [BUILD / "matrix_chain.o", BUILD / "matrix_chain_bench.o"]
        objects += [_compile(cc, DRIVER_CFLAGS, mc_c, parts[0], [mc_h]),
                    _compile(cc, [*DRIVER_CFLAGS, f"-I{BENCH}", f"-I{mc_dir}"],
                             BENCH / "matrix_chain_bench.c", parts[1], [harness, mc_h])]
        links.append(_link(cc, parts, BUILD / "matrix_chain_bench", ["-lm"]))
        programs["matrix_chain"] = BUILD / "matrix_chain_bench"

    fk_variants = [v for v in ("gagen_fk", "gagen_fk_O3") if v in wanted]
    if fk_variants:
        folder = GENERATED / "panda_point"
        src, hdr = folder / "panda_point.c", folder / "panda_point.h"
        driver = BUILD / "gagen_fk_bench.o"
        objects.append(_compile(cc, [*DRIVER_CFLAGS, f"-I{BENCH}", f"-I{folder}"], BENCH / "gagen_fk_bench.c",
                                driver, [harness, hdr]))
        for variant in fk_variants:
            kernels, simd = BUILD / f"{variant}_kernels.o", BUILD / f"{variant}_kernels_simd.o"
            flags = gagen_cflags("-O3" if variant.endswith("_O3") else None)
            objects.append(_compile(cc, [*flags, f"-I{folder}"], src, kernels, [hdr]))
            objects.append(_compile(cc, [*gagen_cflags("-O3"), f"-I{folder}"], folder / "panda_point_simd.c",
                                    simd, [hdr]))  # as gagen does: its _simd.c companion at -O3
            links.append(_link(cc, [kernels, simd, driver], BUILD / f"{variant}_bench",
                               [*_vector_libs(), "-lm"]))
            programs[variant] = BUILD / f"{variant}_bench"

    start = time.perf_counter()
    with ThreadPoolExecutor(max_workers=max(1, os.cpu_count() or 1)) as pool:  # slowest objects first
        list(pool.map(lambda s: s.run(force), objects))
    for step in links:
        step.run(force)
    commands = [shlex.join(s.command) for s in (*objects, *links)]
    return programs, commands, time.perf_counter() - start
