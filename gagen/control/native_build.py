"""gagen's own C++ sources (``gagen/control/*.cpp``) compiled against the installed Pinocchio wheels.

The pip wheels of Pinocchio and Crocoddyl (cmeel) carry their headers, Eigen's, Boost's and their
libraries under one prefix; ``cmeel_prefix`` finds it. ``compile_cached`` builds a source into gagen's
cache once per content (the source, the library versions, the flags): under a temporary name, then
renamed, so concurrent builds of the same content never see a partial file.
"""

from __future__ import annotations

import hashlib
import os
import threading
from collections.abc import Sequence
from pathlib import Path

from gagen.codegen.compiler import CompileError, extension_path, library_name

# the wheel's libraries are built for baseline x86-64: keep Eigen's layout and allocator theirs
EIGEN_ABI = ("-DEIGEN_MAX_ALIGN_BYTES=16", "-DEIGEN_MALLOC_ALREADY_ALIGNED=1")


def cmeel_prefix() -> Path:
    """The cmeel prefix of the installed ``pin`` wheel (include/, lib/); a CompileError without it."""
    try:
        import pinocchio
    except ImportError as e:
        raise CompileError("the native code needs Pinocchio: pip install 'gagen[dynamics]' (package pin)") \
            from e
    prefix = Path(pinocchio.__file__).resolve().parents[4]  # …/cmeel.prefix/lib/pythonX.Y/site-packages/
    if not (prefix / "include" / "pinocchio").is_dir():
        raise CompileError(f"no Pinocchio headers under {prefix / 'include'} (the pin wheel's cmeel layout)")
    return prefix


def compile_cached(source: Path, kind: str, flags: Sequence[str], libraries: Sequence[str], versions: str,
                   *, extension: bool) -> tuple[str, Path]:
    """(name, path) of ``source`` compiled with $CXX (else c++) into ``<cache>/<kind>/``: a CPython
    extension module (``extension``; its name is given to the source as ``-DGAGEN_MODULE``) or a plain
    shared library. The name is ``gagen_<kind>_<hash>`` of the source, ``versions`` and the flags."""
    from gagen.build import cache_root

    text = source.read_bytes()
    key = f"{versions} {' '.join([*flags, *libraries])}"
    name = f"gagen_{kind}_{hashlib.sha256(text + key.encode()).hexdigest()[:12]}"
    folder = cache_root() / kind
    target = extension_path(folder, name) if extension else folder / library_name(name)
    if target.exists():
        return name, target
    folder.mkdir(parents=True, exist_ok=True)
    compiler = os.environ.get("CXX", "c++")
    partial = target.with_name(f"{target.name}.{os.getpid()}.{threading.get_ident()}.partial")
    command = [compiler, *flags, f"-DGAGEN_MODULE={name}", "-o", str(partial), str(source), *libraries]
    import subprocess

    try:
        done = subprocess.run(command, capture_output=True, text=True)
    except OSError as e:
        raise CompileError(f"no C++ compiler ({compiler}): {e}") from e
    if done.returncode != 0:
        partial.unlink(missing_ok=True)
        raise CompileError(f"{' '.join(command)} failed:\n{done.stderr.strip()[-2000:]}")
    partial.replace(target)
    return name, target
