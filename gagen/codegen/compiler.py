"""The system C compiler: find it, and build a generated source into a shared library."""

from __future__ import annotations

import ctypes.util
import os
import platform
import shlex
import shutil
import subprocess
import sys
import sysconfig
import threading
from collections.abc import Sequence
from pathlib import Path

# -O1: straight-line kernels run as fast as at -O3 (three-Panda circle: FK+J 180 vs 189 ns, V_Sc+J_G
# 2.8 vs 2.55 µs) and compile 3x faster (11 vs 30 s). -ffp-contract=off: no fused multiply-add, so
# the C kernels give CasADi's doubles exactly. -mtune=generic on x86-64: -march=native on AMD Zen
# tunes for cheap moves between vector and integer registers, and GCC then spills the kernels' many
# live doubles through integer registers (749 vmovq in panda_point.c): the Panda FK + J took 109
# against 95 ns, the three-Panda similarity Jacobians 3.6 against 2.1 µs, on an EPYC (Zen 3).
_TUNE = ("-mtune=generic",) if platform.machine() in ("x86_64", "AMD64") else ()
FLAGS = ("-std=c99", "-O1", "-march=native", *_TUNE, "-ffp-contract=off", "-fPIC", "-shared")


class CompilerNotFound(RuntimeError):
    """No C compiler on this machine (set CC to one)."""


class CompileError(RuntimeError):
    """The C compiler rejected a generated source."""


def find_compiler() -> list[str]:
    """$CC if set, else the first of cc, gcc, clang on PATH."""
    if os.environ.get("CC"):
        command = shlex.split(os.environ["CC"])
        if not shutil.which(command[0]):
            raise CompilerNotFound(f"CC={os.environ['CC']!r} is not an executable on PATH")
        return command
    for name in ("cc", "gcc", "clang"):
        if path := shutil.which(name):
            return [path]
    raise CompilerNotFound("no C compiler found (looked for $CC, cc, gcc, clang); install one or set CC")


def library_name(stem: str) -> str:
    return f"lib{stem}.dylib" if sys.platform == "darwin" else f"lib{stem}.so"


def vector_math() -> list[str]:
    """Flags for glibc's vector sin/cos (libmvec) on x86-64 Linux, when it is installed, and its
    vector atan2 (glibc 2.35 and later)."""
    if sys.platform.startswith("linux") and platform.machine() in ("x86_64", "AMD64") \
            and ctypes.util.find_library("mvec"):
        libc, version = platform.libc_ver()
        numbers = tuple(int(v) for v in version.split(".")[:2] if v.isdigit())
        atan2 = ["-DGAGEN_HAVE_LIBMVEC_ATAN2"] if libc == "glibc" and numbers >= (2, 35) else []
        return ["-DGAGEN_HAVE_LIBMVEC", *atan2, "-lmvec"]
    return []


def vector_math_defines() -> list[str]:
    return [f for f in vector_math() if f.startswith("-D")]


def vector_math_libraries() -> list[str]:
    return [f for f in vector_math() if not f.startswith("-D")]


def compile_shared(source: Path, library: Path, defines: Sequence[str] = ()) -> None:
    """Compile ``source`` (and its ``<stem>_simd.c`` companion, if any, at -O3: the vector blocks'
    gathers and scatters gain from it, and they are small) into ``library``, written under a
    temporary name and then renamed. The two objects compile in parallel. ``defines``: extra macro
    names (``GAGEN_SCALAR_TRIG``: libm's sine and cosine in the single calls, CasADi's doubles)."""
    for name in defines:
        if not (isinstance(name, str) and name.isidentifier() and name.isascii()):
            raise ValueError(f"a define must be a C identifier, got {name!r}")
    partial = library.with_name(library.name + f".{os.getpid()}.{threading.get_ident()}.partial")
    compiler = find_compiler()
    simd = source.with_name(f"{source.stem}_simd.c")
    units = [(source, list(FLAGS))]
    if simd.exists():
        units.append((simd, ["-O3" if f.startswith("-O") else f for f in FLAGS]))
    objects, jobs = [], []
    for unit, flags in units:
        obj = partial.with_name(f"{partial.name}.{unit.stem}.o")
        objects.append(obj)
        command = [*compiler, *[f for f in flags if f != "-shared"], *vector_math_defines(),
                   *(f"-D{name}" for name in defines), "-c", "-o",
                   str(obj), str(unit)]
        jobs.append((command, subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                               text=True)))
    try:
        for command, job in jobs:
            _, err = job.communicate()
            if job.returncode != 0:
                raise CompileError(f"{' '.join(command)} failed:\n{err.strip()}")
        link = [*compiler, "-shared", "-o", str(partial), *map(str, objects), *vector_math_libraries(), "-lm"]
        result = subprocess.run(link, capture_output=True, text=True)
        if result.returncode != 0:
            raise CompileError(f"{' '.join(link)} failed:\n{result.stderr.strip()}")
        partial.replace(library)
    finally:
        partial.unlink(missing_ok=True)
        for obj in objects:
            obj.unlink(missing_ok=True)


def extension_path(folder: Path, module: str) -> Path:
    """Where the CPython extension ``module`` lives in ``folder``."""
    return folder / (module + (sysconfig.get_config_var("EXT_SUFFIX") or ".so"))


def compile_binding(source: Path, module: str | None = None) -> Path:
    """Compile the CPython binding ``source`` into the extension module ``module`` (default: the
    source's stem) beside it, its name given to the source as ``-DGAGEN_MODULE=<module>``. The binding
    reaches the kernels through function addresses from the loaded library, so it does not link to it."""
    module = module or source.stem
    include = Path(sysconfig.get_paths()["include"])
    if not (include / "Python.h").is_file():
        raise CompileError(f"no Python.h in {include} (install the Python development headers)")
    import numpy  # the binding uses numpy's C API (headers only; the API table is imported at load)

    target = extension_path(source.parent, module)
    partial = target.with_name(target.name + f".{os.getpid()}.{threading.get_ident()}.partial")
    command = [*find_compiler(), "-std=c99", "-O2", "-fPIC", "-shared", f"-I{include}",
               f"-I{numpy.get_include()}", f"-I{source.parent}", f"-DGAGEN_MODULE={module}", "-o",
               str(partial), str(source)]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        partial.unlink(missing_ok=True)
        raise CompileError(f"{' '.join(command)} failed:\n{result.stderr.strip()}")
    partial.replace(target)
    return target
