"""``gagen build``: a spec's kernels as a generated module (CasADi Functions, C source, library).

The output folder ``generated/<system>/`` holds:

- ``manifest.json``: kernels, ports (row labels, shapes, layout), op counts, hashes;
- ``<system>.h`` / ``<system>.c``: the C kernels, from ``templates/`` by our emitter;
- ``<system>_simd.c``: the batched forms of the smaller kernels, GAGEN_W samples at a time;
- ``_gagen_<system>_<key>.c``: the CPython binding (no per-call conversion or allocation);
- ``casadi/<kernel>.casadi.gz``: the CasADi Functions, serialised and gzipped;
- ``__init__.py``: the Python module (``casadi.<kernel>``, ``c.<kernel>``);
- ``lib<system>_<key>.so`` and the binding's extension module: compiled (not committed; compiled on
  first use if absent).

Builds are deterministic (same spec, templates and gagen version → same bytes), cached by a key
over exactly those, and atomic: everything is written to a temporary sibling folder that replaces
the old one only when complete, so a failed build leaves the previous module untouched.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import os
import shutil
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import jinja2

from gagen import __version__
from gagen.codegen.c_emitter import emit_body
from gagen.codegen.compiler import (
    CompileError,
    CompilerNotFound,
    compile_binding,
    compile_shared,
    library_name,
)
from gagen.kernels import Kernel, Port, build_kernels
from gagen.model.cooperative import System
from gagen.runtime import MANIFEST
from gagen.spec.loader import load_system

TEMPLATES = Path(__file__).resolve().parent.parent / "templates"
TEMPLATE_FILES = ("kernels.h.j2", "kernels.c.j2", "simd.c.j2", "binding.c.j2", "module.py.j2")
DEFAULT_ROOT = Path("generated")
# kernels up to this many C statements also get a SIMD batch (the chains' FK and FK + Jacobian): it
# runs GAGEN_W samples at once, and doubles the kernel's code and compile time
SIMD_MAX_STATEMENTS = 1500
# the modules that generation runs through (editing any other one does not rebuild)
IN_KEY = {"algebra", "symbolic", "model", "codegen", "spec", "robots", "kernels.py", "build.py", "errors.py",
          "__init__.py"}


@dataclass
class BuildResult:
    folder: Path
    key: str
    cached: bool
    compiled: bool
    seconds: float


def _templates() -> jinja2.Environment:
    missing = [t for t in TEMPLATE_FILES if not (TEMPLATES / t).is_file()]
    if missing:
        raise FileNotFoundError(f"gagen templates not found in {TEMPLATES}: {', '.join(missing)} "
                                "(gagen must be installed from its source tree, e.g. pip install -e .)")
    return jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES), keep_trailing_newline=True,
                              undefined=jinja2.StrictUndefined, autoescape=False)


def build_key(system: System) -> str:
    """Hash of what decides the output: the loaded system (every joint constant, so URDF edits that
    change nothing do not rebuild), the templates, gagen's version and the source of every module
    that takes part in generation (the model, the symbolic layer, the emitter, ...)."""
    h = hashlib.sha256()
    h.update(repr(system).encode())
    for name in TEMPLATE_FILES:
        h.update((TEMPLATES / name).read_bytes())
    h.update(__version__.encode())
    package = Path(__file__).parent
    for module in sorted(package.rglob("*.py")):
        name = module.relative_to(package).as_posix()
        if name.split("/")[0] in IN_KEY:
            h.update(name.encode())
            h.update(module.read_bytes())
    return h.hexdigest()


def _port_entry(port: Port) -> dict:
    return {"name": port.name, "rows": list(port.rows), "cols": port.cols, "layout": "column-major"}


def _params(kernel: Kernel, restrict: str) -> str:
    ins = [f"const double *{restrict} {p.name}" for p in kernel.inputs]
    outs = [f"double *{restrict} {p.name}" for p in kernel.outputs]
    return ", ".join(ins + outs)


def _render(system: System, kernels: dict[str, Kernel], spec_path: Path, key: str,
            progress: Callable[[str], None]) -> dict[str, str]:
    """Every file of the module, as text, by relative path."""
    env = _templates()
    spec_hash = hashlib.sha256(spec_path.read_bytes()).hexdigest()
    entries, contexts = [], []
    for i, kernel in enumerate(kernels.values(), 1):
        start = time.perf_counter()
        c_name = f"{system.name}_{kernel.name}"
        names = ([p.name for p in kernel.inputs], [p.name for p in kernel.outputs])
        body = emit_body(kernel.function, *names)
        # the SIMD batch doubles a kernel's code: only kernels up to SIMD_MAX_STATEMENTS get one
        simd = len(body.statements) <= SIMD_MAX_STATEMENTS
        vector = emit_body(kernel.function, *names, vector=True) if simd else None
        ops = kernel.op_count
        contexts.append({"c_name": c_name, "doc": kernel.doc, "inputs": kernel.inputs,
                         "outputs": kernel.outputs, "ops": str(ops), "locals": body.locals,
                         "statements": body.statements,
                         "vector_locals": vector.locals if vector else (),
                         "vector_statements": vector.statements if vector else (),
                         "params": _params(kernel, "restrict"), "params_h": _params(kernel, "GAGEN_RESTRICT"),
                         "names": [p.name for p in (*kernel.inputs, *kernel.outputs)]})
        entries.append({"name": kernel.name, "c_name": c_name, "doc": kernel.doc,
                        "inputs": [_port_entry(p) for p in kernel.inputs],
                        "outputs": [_port_entry(p) for p in kernel.outputs],
                        "op_count": {"mul": ops.mul, "add": ops.add, "neg": ops.neg, "div": ops.div,
                                     "flops": ops.flops, "calls": ops.calls},
                        "casadi": f"casadi/{kernel.name}.casadi.gz"})
        progress(f"  [{i}/{len(kernels)}] {kernel.name}: {ops.flops} flops, "
                 f"{len(body.statements)} C statements ({time.perf_counter() - start:.2f} s)")
    binding = f"_gagen_{system.name}_{key[:12]}"
    common = {"system": system.name, "kind": system.kind, "dof": system.dof, "version": __version__,
              "spec_name": spec_path.name, "spec_hash": spec_hash[:16], "build_key": key[:16]}
    manifest = {"system": system.name, "primitive": system.kind, "dof": system.dof,
                "joints": [f"{r}/{j}" for r, j in system.joint_keys], "gagen_version": __version__,
                "spec": spec_path.name, "spec_sha256": spec_hash, "build_key": key,
                "c_source": f"{system.name}.c", "c_header": f"{system.name}.h",
                "library": library_name(f"{system.name}_{key[:12]}"),
                "binding": binding, "binding_source": f"{binding}.c", "kernels": entries}
    files = {
        MANIFEST: json.dumps(manifest, indent=1, sort_keys=False) + "\n",
        f"{system.name}.h": env.get_template("kernels.h.j2").render(
            **common, kernels=contexts, guard=f"GAGEN_{system.name.upper()}_H"),
        f"{system.name}.c": env.get_template("kernels.c.j2").render(**common, kernels=contexts),
        f"{system.name}_simd.c": env.get_template("simd.c.j2").render(**common, kernels=contexts),
        f"{binding}.c": env.get_template("binding.c.j2").render(
            **common, kernels=[{**c, "name": k} for c, k in zip(contexts, kernels, strict=True)],
            binding=binding, max_outputs=max(len(k.outputs) for k in kernels.values())),
        "__init__.py": env.get_template("module.py.j2").render(
            **common, kernel_names=list(kernels), example=next(reversed(kernels))),
    }
    return files


def _cached(folder: Path, key: str) -> bool:
    try:
        return json.loads((folder / MANIFEST).read_text())["build_key"] == key
    except (OSError, ValueError, KeyError):
        return False


def _replace(partial: Path, folder: Path) -> None:
    """Swap the finished folder in: the old one is moved aside first and removed last."""
    old = folder.with_name(f".{folder.name}.old-{os.getpid()}")
    if folder.exists():
        folder.rename(old)
    try:
        partial.rename(folder)
    except BaseException:
        if old.exists():
            old.rename(folder)
        raise
    shutil.rmtree(old, ignore_errors=True)


@dataclass
class _Prepared:
    """A module written to its partial folder, waiting for its library and the swap."""

    system: System
    folder: Path
    partial: Path
    key: str
    library: str
    start: float


def _prepare(spec: str | Path, out: str | Path | None, force: bool,
             progress: Callable[[str], None]) -> BuildResult | _Prepared:
    start = time.perf_counter()
    spec_path = Path(spec)
    system, _ = load_system(spec_path)
    folder = Path(out) if out is not None else DEFAULT_ROOT / system.name
    key = build_key(system)
    library = library_name(f"{system.name}_{key[:12]}")
    if not force and _cached(folder, key):
        progress(f"{system.name}: up to date ({folder})")
        return BuildResult(folder, key, True, (folder / library).exists(), time.perf_counter() - start)
    progress(f"{system.name}: a {system.kind} of {len(system.chains)} chains, {system.dof} joints "
             f"-> {folder}")
    folder.parent.mkdir(parents=True, exist_ok=True)
    partial = folder.with_name(f".{folder.name}.partial-{os.getpid()}")
    shutil.rmtree(partial, ignore_errors=True)
    try:
        t = time.perf_counter()
        kernels = build_kernels(system)
        progress(f"  model and {len(kernels)} kernel graphs built ({time.perf_counter() - t:.2f} s)")
        files = _render(system, kernels, spec_path, key, progress)
        (partial / "casadi").mkdir(parents=True)
        for name, text in files.items():
            (partial / name).write_text(text)
        for kernel in kernels.values():  # serialised and gzipped (about 10x smaller), mtime 0: deterministic
            data = gzip.compress(kernel.function.serialize().encode(), compresslevel=9, mtime=0)
            (partial / "casadi" / f"{kernel.name}.casadi.gz").write_bytes(data)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    return _Prepared(system, folder, partial, key, library, start)


def _finish(prepared: _Prepared, compile_c: bool, progress: Callable[[str], None]) -> BuildResult:
    name, partial = prepared.system.name, prepared.partial
    compiled = False
    try:
        if compile_c:
            t = time.perf_counter()
            try:
                compile_shared(partial / f"{name}.c", partial / prepared.library)
                compiled = True
                binding = f"_gagen_{name}_{prepared.key[:12]}"
                try:
                    compile_binding(partial / f"{binding}.c")
                except CompileError as e:  # e.g. no Python headers: the runtime falls back to ctypes
                    progress(f"  warning: the CPython binding did not compile; calls go through ctypes ({e})")
                progress(f"  {name}: compiled {prepared.library} ({time.perf_counter() - t:.2f} s)")
            except CompilerNotFound as e:
                progress(f"  warning: {e}; the CasADi module and the C source were still written")
        _replace(partial, prepared.folder)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    seconds = time.perf_counter() - prepared.start
    progress(f"{name}: built in {seconds:.2f} s")
    return BuildResult(prepared.folder, prepared.key, False, compiled, seconds)


def build_many(specs: list[str | Path], *, force: bool = False, compile_c: bool = True,
               progress: Callable[[str], None] = print, jobs: int | None = None,
               outputs: list[str | Path | None] | None = None) -> list[BuildResult]:
    """Build several specs: models and sources one after another, while the C compiler runs on the
    previous ones in up to ``jobs`` (default: CPU count) parallel processes."""
    outputs = outputs or [None] * len(specs)
    results: list[BuildResult | Future] = []
    with ThreadPoolExecutor(max_workers=jobs or os.cpu_count() or 1) as pool:
        try:
            for spec, out in zip(specs, outputs, strict=True):
                prepared = _prepare(spec, out, force, progress)
                results.append(prepared if isinstance(prepared, BuildResult)
                               else pool.submit(_finish, prepared, compile_c, progress))
        finally:  # on a failure, let the started compilations finish and swap in (they are complete)
            done = [r.result() if isinstance(r, Future) else r for r in results]
    return done


def build(spec: str | Path, out: str | Path | None = None, *, force: bool = False, compile_c: bool = True,
          progress: Callable[[str], None] = print) -> BuildResult:
    """Build the module of ``spec`` into ``out`` (default ``generated/<system>/``).

    A malformed spec raises ``SpecError`` before anything is written. With no C compiler the
    module is still written (CasADi Functions and C source) and the missing library is reported.
    """
    return build_many([spec], force=force, compile_c=compile_c, progress=progress, outputs=[out])[0]


__all__ = ["BuildResult", "CompileError", "build", "build_key", "build_many"]
