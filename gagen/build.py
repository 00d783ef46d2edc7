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
over exactly those (and "up to date" also means every file the manifest lists is there with its
sha256), and atomic: everything is written to a temporary sibling folder ``.<name>.partial-<pid>``
that replaces the old one only when complete, so a failed build leaves the previous module untouched.
On Linux the two folders are swapped by one ``renameat2(RENAME_EXCHANGE)``: at no instant is the
output folder missing or half-written. Elsewhere the old folder is renamed aside and the new one in
(two renames: between them, microseconds long, the folder is missing). Builds of one output folder
are serialised by ``flock`` on ``.<name>.lock`` beside it; sibling folders left by dead processes
are removed when a build starts.

Names reach the generated code only as checked identifiers (``[A-Za-z_][A-Za-z0-9_]*``, no C, C++
or Python keyword), and labels (docs, joint names, the spec's file name) only through the escaping
filters of their context (``c_comment``, ``c_string``, ``py_doc``, ``py_string``), whatever the
spec loader let through; every file is written inside the output folder.
"""

from __future__ import annotations

import ctypes
import errno
import functools
import gzip
import hashlib
import json
import os
import platform
import re
import shutil
import sys
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
from gagen.errors import SpecError
from gagen.kernels import Kernel, Port, build_kernels
from gagen.model.cooperative import System
from gagen.runtime import MANIFEST
from gagen.spec.loader import load_system
from gagen.spec.names import RESERVED_WORDS

TEMPLATES = Path(__file__).resolve().parent.parent / "templates"
TEMPLATE_FILES = ("kernels.h.j2", "kernels.c.j2", "simd.c.j2", "binding.c.j2", "module.py.j2")
DEFAULT_ROOT = Path("generated")
# kernels up to this many C statements also get a SIMD batch (the chains' FK and FK + Jacobian): it
# runs GAGEN_W samples at once, and doubles the kernel's code and compile time
SIMD_MAX_STATEMENTS = 1500
# the modules that generation runs through (editing any other one does not rebuild)
IN_KEY = {"algebra", "symbolic", "model", "codegen", "spec", "robots", "kernels.py", "build.py", "errors.py",
          "__init__.py"}


IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
# system names prefix every C symbol and name files: bounded well below file-name limits (255 bytes)
MAX_NAME = 100


RESERVED = RESERVED_WORDS  # C, C++ and Python keywords: one list, the loader's


class OutputError(RuntimeError):
    """The output cannot be written (read-only folder, full disk, a folder that is no module):
    ``cannot write <path>: <reason>``. The previous module, if any, is untouched."""

    def __init__(self, path: str | Path, reason: str) -> None:
        self.path, self.reason = str(path), reason
        super().__init__(f"cannot write {path}: {reason}")


def check_identifier(name: object, what: str, spec: str | Path = "<system>", field: str = "name") -> str:
    """``name`` if it can be a C and Python identifier (and a file name) as is, else a SpecError."""
    if not isinstance(name, str) or not IDENTIFIER.fullmatch(name):
        raise SpecError(spec, field, f"{what} {name!r} is not an identifier: expected letters, digits and "
                                     f"underscores, not starting with a digit")
    if name in RESERVED or name.startswith("__") or re.match(r"_[A-Z]", name):
        raise SpecError(spec, field, f"{what} {name!r} is a C, C++ or Python keyword or a reserved name")
    if len(name) > MAX_NAME:
        raise SpecError(spec, field, f"{what} {name!r} is longer than {MAX_NAME} characters")
    return name


# -- escaping, one filter per context (the templates pass every label through one) --------------------

def _escape_char(ch: str) -> str:
    code = ord(ch)
    named = {"\n": "\\n", "\t": "\\t", "\r": "\\r"}
    if ch in named:
        return named[ch]
    if code < 0x100:
        return f"\\x{code:02x}"
    return f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def c_comment(text: object) -> str:
    """``text`` inside a C block comment, on one line: printable ASCII stays, except ``*`` (so no
    ``*/`` or ``/*`` can form), ``?`` (trigraphs such as ``??/``) and ``\\`` (line splices), which
    are written as escapes like every control and non-ASCII character (``\\x2a``, ``\\u00e9``)."""
    return "".join(ch if " " <= ch <= "~" and ch not in "*?\\" else _escape_char(ch) for ch in str(text))


def c_string(text: object) -> str:
    """``text`` as the inside of a C string literal: ``"``, ``\\`` and ``?`` escaped, every byte of
    anything but printable ASCII as an octal escape (three digits: never merges with what follows)."""
    out = []
    for byte in str(text).encode():
        ch = chr(byte)
        out.append("\\" + ch if ch in '"\\?' else ch if 0x20 <= byte < 0x7F else f"\\{byte:03o}")
    return "".join(out)


def py_doc(text: object) -> str:
    """``text`` inside a (non-raw) triple-quoted Python docstring or a comment, on one line: ``"`` and
    ``\\`` escaped (no ``\"\"\"`` can close it), control and non-ASCII characters as escapes."""
    return "".join(ch if " " <= ch <= "~" and ch not in '"\\' else
                   "\\" + ch if ch in '"\\' else _escape_char(ch) for ch in str(text))


def py_string(text: object) -> str:
    """``text`` as a complete Python string literal (quotes included), ASCII only."""
    return ascii(str(text))


@dataclass
class BuildResult:
    folder: Path
    key: str
    cached: bool
    compiled: bool
    seconds: float


def _templates() -> jinja2.Environment:
    return _environment(TEMPLATES)


@functools.cache
def _environment(folder: Path) -> jinja2.Environment:
    """One environment per templates folder: it compiles each template once (and again if edited)."""
    missing = [t for t in TEMPLATE_FILES if not (folder / t).is_file()]
    if missing:
        raise FileNotFoundError(f"gagen templates not found in {folder}: {', '.join(missing)} "
                                "(gagen must be installed from its source tree, e.g. pip install -e .)")
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(folder), keep_trailing_newline=True,
                             undefined=jinja2.StrictUndefined, autoescape=False)
    env.filters.update(c_comment=c_comment, c_string=c_string, py_doc=py_doc, py_string=py_string)
    return env


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


def _check_names(system: System, kernels: dict[str, Kernel], spec: Path) -> None:
    """Every name that becomes C or Python code or a file name is an identifier (whatever built the
    System: the spec loader refuses these first, with the field; this is the builder's own check)."""
    check_identifier(system.name, "system name", spec)
    for name, kernel in kernels.items():
        check_identifier(name, "kernel name", spec, "chains")
        check_identifier(kernel.name, "kernel name", spec, "chains")
        check_identifier(f"{system.name}_{kernel.name}", "C function name", spec, "chains")
        for port in (*kernel.inputs, *kernel.outputs):
            check_identifier(port.name, f"port name of kernel {kernel.name}", spec, "chains")


def _render(system: System, kernels: dict[str, Kernel], spec_path: Path, key: str,
            progress: Callable[[str], None]) -> tuple[dict, dict[str, str]]:
    """The manifest (without its file list) and every other file of the module, as text, by relative
    path."""
    _check_names(system, kernels, spec_path)
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
    return manifest, files


def _contents(system: System, kernels: dict[str, Kernel], spec_path: Path, key: str,
              progress: Callable[[str], None]) -> dict[str, bytes]:
    """Every file of the module as bytes, by relative path; the manifest lists the others with their
    sha256 (what "up to date" checks)."""
    manifest, texts = _render(system, kernels, spec_path, key, progress)
    files = {name: text.encode() for name, text in texts.items()}
    for kernel in kernels.values():  # serialised and gzipped (about 10x smaller), mtime 0: deterministic
        files[f"casadi/{kernel.name}.casadi.gz"] = gzip.compress(kernel.function.serialize().encode(),
                                                                 compresslevel=9, mtime=0)
    manifest["files"] = {name: hashlib.sha256(data).hexdigest() for name, data in sorted(files.items())}
    return {MANIFEST: (json.dumps(manifest, indent=1, sort_keys=False) + "\n").encode(), **files}


def _inside(root: Path, relative: str) -> Path:
    """``root / relative``, refused unless it stays inside ``root`` (names are identifiers already:
    this is the last line of defence for every path the build writes or trusts)."""
    path = root / relative
    if Path(relative).is_absolute() or ".." in Path(relative).parts or \
            not path.resolve().is_relative_to(root.resolve()):
        raise OutputError(path, f"outside the output folder {root}")
    return path


def _write(path: Path, data: bytes) -> None:
    with open(path, "xb") as f:  # exclusive: never through a link or over a file left in the folder
        f.write(data)


def _cached(folder: Path, key: str) -> bool:
    """Whether ``folder`` holds the build ``key``: its manifest says so and every file it lists is
    there with the listed sha256 (a deleted or damaged file rebuilds)."""
    try:
        manifest = json.loads((folder / MANIFEST).read_text())
        if manifest["build_key"] != key or not manifest["files"]:
            return False
        for name, digest in manifest["files"].items():
            if hashlib.sha256(_inside(folder, name).read_bytes()).hexdigest() != digest:
                return False
        return True
    except (OSError, ValueError, KeyError, TypeError, AttributeError, OutputError):
        return False


# -- the swap, the lock and stale folders --------------------------------------------------------------

_AT_FDCWD = -100
_RENAME_EXCHANGE = 2
# renameat2's system call number, for a glibc older than 2.28 (no wrapper)
_RENAMEAT2_SYSCALL = {"x86_64": 316, "aarch64": 276}


def _renameat2() -> Callable[[bytes, bytes, int], int] | None:
    """``renameat2(AT_FDCWD, old, AT_FDCWD, new, flags)`` (0 or -1 with errno), or None off Linux."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None, use_errno=True)
    except OSError:
        return None
    function = getattr(libc, "renameat2", None)
    if function is not None:
        function.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
        function.restype = ctypes.c_int
        return lambda old, new, flags: function(_AT_FDCWD, old, _AT_FDCWD, new, flags)
    number = _RENAMEAT2_SYSCALL.get(platform.machine())
    if number is None or not hasattr(libc, "syscall"):
        return None
    syscall = libc.syscall
    syscall.restype = ctypes.c_long
    at = ctypes.c_int(_AT_FDCWD)
    return lambda old, new, flags: syscall(ctypes.c_long(number), at, ctypes.c_char_p(old), at,
                                           ctypes.c_char_p(new), ctypes.c_uint(flags))


_RENAMEAT2 = _renameat2()


def _exchange(a: Path, b: Path) -> bool:
    """Swap two folders in one step; False where the system or file system cannot."""
    if _RENAMEAT2 is None:
        return False
    if _RENAMEAT2(os.fsencode(a), os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    error = ctypes.get_errno()
    if error in (errno.ENOSYS, errno.EINVAL, errno.EOPNOTSUPP, errno.EPERM):
        return False  # an old kernel, or a file system without the exchange
    raise OSError(error, os.strerror(error), str(b))


def _replace(partial: Path, folder: Path) -> None:
    """Swap the finished folder in. Linux: one atomic exchange, so the folder is never missing; then
    the old module (now at ``partial``) is removed. Elsewhere: the old one is renamed aside and the
    new one in, which leaves a window of two renames where the folder is missing."""
    if not folder.exists():
        partial.rename(folder)
        return
    if _exchange(partial, folder):
        shutil.rmtree(partial, ignore_errors=True)
        return
    old = folder.with_name(f".{folder.name}.old-{os.getpid()}")
    folder.rename(old)
    try:
        partial.rename(folder)
    except BaseException:
        if old.exists():
            old.rename(folder)
        raise
    shutil.rmtree(old, ignore_errors=True)


class _Lock:
    """An exclusive ``flock`` on ``.<name>.lock`` beside the output folder: builds of one folder, in
    threads or processes, run one after another. The lock file stays (removing it would race)."""

    def __init__(self, folder: Path, progress: Callable[[str], None]) -> None:
        self.path = folder.with_name(f".{folder.name}.lock")
        self.fd: int | None = os.open(self.path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
        try:
            import fcntl
        except ImportError:  # no flock (Windows): builds are not serialised
            return
        try:
            try:
                fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                progress(f"  waiting for another build of {folder} ({self.path})")
                fcntl.flock(self.fd, fcntl.LOCK_EX)
        except BaseException:
            self.release()
            raise

    def release(self) -> None:
        if self.fd is not None:
            os.close(self.fd)  # closing the last descriptor releases the flock
            self.fd = None


def _alive(pid: int) -> bool:
    if os.name == "nt":  # os.kill(pid, 0) would terminate it there: never clean another's folder
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # e.g. EPERM: it exists
        return True
    return True


def _clean_stale(folder: Path) -> None:
    """Remove ``.<name>.partial-<pid>`` and ``.<name>.old-<pid>`` beside ``folder`` whose process is
    gone (a killed build). Called with the lock held, so this process's own are stale too."""
    pattern = re.compile(rf"\.{re.escape(folder.name)}\.(?:partial|old)-([0-9]+)")
    for entry in folder.parent.iterdir():
        match = pattern.fullmatch(entry.name)
        if match and (int(match[1]) == os.getpid() or (int(match[1]) > 0 and not _alive(int(match[1])))):
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)


def _output_folder(out: str | Path | None, name: str) -> Path:
    """The output folder, absolute and with links resolved (its siblings are made beside the real
    folder); refused when it cannot be replaced by a module: the root, a file, or a folder holding
    something other than a gagen module."""
    folder = (Path(out) if out is not None else DEFAULT_ROOT / name).resolve()
    if not folder.name:
        raise OutputError(folder, "not a folder a module can replace")
    return folder


def _check_replaceable(folder: Path) -> None:
    if not folder.exists():
        return
    if not folder.is_dir():
        raise OutputError(folder, "it exists and is not a folder")
    if not (folder / MANIFEST).is_file() and any(folder.iterdir()):
        raise OutputError(folder, "it exists and is not a gagen module (no manifest.json)")


def _compile(folder: Path, name: str, key: str, library: str, progress: Callable[[str], None]) -> bool:
    """Compile the library and the CPython binding of the sources in ``folder``; False without a
    compiler (reported). Each file is written under a temporary name and renamed."""
    t = time.perf_counter()
    try:
        compile_shared(folder / f"{name}.c", folder / library)
    except CompilerNotFound as e:
        progress(f"  warning: {e}; the CasADi module and the C source were still written")
        return False
    try:
        compile_binding(folder / f"_gagen_{name}_{key[:12]}.c")
    except CompileError as e:  # e.g. no Python headers: the runtime falls back to ctypes
        progress(f"  warning: the CPython binding did not compile; calls go through ctypes ({e})")
    progress(f"  {name}: compiled {library} ({time.perf_counter() - t:.2f} s)")
    return True


@dataclass
class _Prepared:
    """A module written to its partial folder, waiting for its library and the swap (the lock held)."""

    system: System
    folder: Path
    partial: Path
    key: str
    library: str
    start: float
    lock: _Lock


def _prepare(spec: str | Path, out: str | Path | None, force: bool, compile_c: bool,
             progress: Callable[[str], None]) -> BuildResult | _Prepared:
    start = time.perf_counter()
    spec_path = Path(spec)
    system, _ = load_system(spec_path)
    check_identifier(system.name, "system name", spec_path)  # before it names any folder or file
    folder = _output_folder(out, system.name)
    key = build_key(system)
    library = library_name(f"{system.name}_{key[:12]}")
    partial = folder.with_name(f".{folder.name}.partial-{os.getpid()}")
    lock = None
    try:
        try:
            folder.parent.mkdir(parents=True, exist_ok=True)
            lock = _Lock(folder, progress)
        except OSError:
            if not force and _cached(folder, key) and (not compile_c or (folder / library).exists()):
                # a read-only copy that is up to date: nothing to write, nothing to lock
                progress(f"{system.name}: up to date ({folder})")
                compiled = (folder / library).exists()
                return BuildResult(folder, key, True, compiled, time.perf_counter() - start)
            raise
        _clean_stale(folder)
        if not force and _cached(folder, key):
            compiled = (folder / library).exists()
            if compile_c and not compiled:  # the sources are current: only the library is missing
                compiled = _compile(folder, system.name, key, library, progress)
            progress(f"{system.name}: up to date ({folder})")
            lock.release()
            return BuildResult(folder, key, True, compiled, time.perf_counter() - start)
        _check_replaceable(folder)
        progress(f"{system.name}: a {system.kind} of {len(system.chains)} chains, {system.dof} joints "
                 f"-> {folder}")
        t = time.perf_counter()
        kernels = build_kernels(system)
        progress(f"  model and {len(kernels)} kernel graphs built ({time.perf_counter() - t:.2f} s)")
        files = _contents(system, kernels, spec_path, key, progress)
        paths = {name: _inside(partial, name) for name in files}  # all checked before anything is written
        partial.mkdir()
        (partial / "casadi").mkdir()
        for name, data in files.items():
            _write(paths[name], data)
    except BaseException as e:
        if lock is not None:  # (without it, the partial folder may be another thread's)
            shutil.rmtree(partial, ignore_errors=True)
            lock.release()
        if isinstance(e, OSError):
            raise OutputError(e.filename or partial, e.strerror or str(e)) from e
        raise
    return _Prepared(system, folder, partial, key, library, start, lock)


def _finish(prepared: _Prepared, compile_c: bool, progress: Callable[[str], None]) -> BuildResult:
    name, partial = prepared.system.name, prepared.partial
    compiled = False
    try:
        if compile_c:
            compiled = _compile(partial, name, prepared.key, prepared.library, progress)
        _replace(partial, prepared.folder)
    except BaseException as e:
        shutil.rmtree(partial, ignore_errors=True)
        if isinstance(e, OSError):
            raise OutputError(e.filename or prepared.folder, e.strerror or str(e)) from e
        raise
    finally:
        prepared.lock.release()
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
                prepared = _prepare(spec, out, force, compile_c, progress)
                results.append(prepared if isinstance(prepared, BuildResult)
                               else pool.submit(_finish, prepared, compile_c, progress))
        finally:  # on a failure, let the started compilations finish and swap in (they are complete)
            done = [r.result() if isinstance(r, Future) else r for r in results]
    return done


def build(spec: str | Path, out: str | Path | None = None, *, force: bool = False, compile_c: bool = True,
          progress: Callable[[str], None] = print) -> BuildResult:
    """Build the module of ``spec`` into ``out`` (default ``generated/<system>/``).

    A malformed spec, or a name that cannot be an identifier, raises ``SpecError`` before anything is
    written. An output that cannot be written raises ``OutputError`` (``cannot write <path>:
    <reason>``) and leaves the previous module as it was. With no C compiler the module is still
    written (CasADi Functions and C source) and the missing library is reported.
    """
    return build_many([spec], force=force, compile_c=compile_c, progress=progress, outputs=[out])[0]


__all__ = ["BuildResult", "CompileError", "OutputError", "build", "build_key", "build_many",
           "check_identifier"]
