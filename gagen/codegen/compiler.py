"""The system C compiler: find it, and build a generated source into a shared library."""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

# -ffp-contract=off: no fused multiply-add, so the C kernels give CasADi's doubles exactly
FLAGS = ("-std=c99", "-O3", "-march=native", "-ffp-contract=off", "-fPIC", "-shared")


class CompilerNotFound(RuntimeError):
    """No C compiler on this machine (set CC to one)."""


class CompileError(RuntimeError):
    """The C compiler rejected a generated source."""


def find_compiler() -> list[str]:
    """$CC if set, else the first of cc, gcc, clang on PATH."""
    if os.environ.get("CC"):
        return shlex.split(os.environ["CC"])
    for name in ("cc", "gcc", "clang"):
        if path := shutil.which(name):
            return [path]
    raise CompilerNotFound("no C compiler found (looked for $CC, cc, gcc, clang); install one or set CC")


def library_name(stem: str) -> str:
    return f"lib{stem}.dylib" if sys.platform == "darwin" else f"lib{stem}.so"


def compile_shared(source: Path, library: Path) -> None:
    """Compile ``source`` into ``library`` (written next to a temporary name, then renamed)."""
    partial = library.with_name(library.name + f".{os.getpid()}.partial")
    command = [*find_compiler(), *FLAGS, "-o", str(partial), str(source), "-lm"]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        partial.unlink(missing_ok=True)
        raise CompileError(f"{' '.join(command)} failed:\n{result.stderr.strip()}")
    partial.replace(library)
