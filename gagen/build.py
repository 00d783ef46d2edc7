"""``gagen build``: a module of kernels as generated files (CasADi Functions, C source, CPython binding),
compiled.

What is built is a :class:`gagen.codegen.ir.ModuleSource`: a robot spec's (``.yaml``: the cooperative
system's kernel catalogue, ``gagen.apps.cooperative.module``) or a Python file's (``.py``: its
``@gagen.kernel`` functions, ``gagen.frontend.module_from_file``). Every backend of the registry
(``gagen.codegen.backends``, or those asked for) renders its files into the output folder
``generated/<name>/`` (or ``-o``), which holds:

- ``manifest.json``: the module, its backends, kernels, ports (row labels, shapes, layout), op counts
  and every other file with its sha256;
- the backends' files: ``casadi/<kernel>.casadi.gz``; ``<name>.h``, ``<name>.c``, ``<name>_simd.c``;
  ``<name>_binding.c``; ``<name>_jax.py``;
- ``__init__.py``: the Python module (a namespace per backend that has one: ``casadi``, ``c``, ``jax``);
- not committed: the compiled ``lib<name>_<tag>.so`` and binding ``_gagen_<name>_<tag>`` (``<tag>``:
  12 hex digits over the files' sha256; compiled on first use if absent), ``.build-key`` and the
  CasADi files (binary; a committed module is rebuilt on first use, ``gagen.modules``).

Builds are deterministic (same source and gagen version → same bytes; nothing in the files depends on
gagen's own source bytes, so a committed module is checked by regenerating it and comparing), cached
by a key over the source and gagen's code generator kept in ``.build-key`` (a fresh clone has none,
and rebuilds to the same bytes; "up to date" also means every file the manifest lists is there with
its sha256), and atomic: everything is written to a temporary sibling folder ``.<name>.partial-<pid>``
that replaces the old one only when complete, so a failed build leaves the previous module untouched.
On Linux the two folders are swapped by one ``renameat2(RENAME_EXCHANGE)``: at no instant is the
output folder missing or half-written. Elsewhere the old folder is renamed aside and the new one in
(two renames: between them, microseconds long, the folder is missing). Builds of one output folder
are serialised by ``flock`` on ``.<name>.lock`` beside it; sibling folders left by dead processes
are removed when a build starts.

Names reach the generated code only as checked identifiers (``gagen.names``: ``[A-Za-z][A-Za-z0-9_]*``,
no C, C++ or Python keyword), and labels (docs, joint names, the source's file name) only through the
escaping filters of their context (``c_comment``, ``c_string``, ``py_doc``, ``py_string``), whatever
the front-end let through; every file is written inside the output folder.

``gagen.compile`` (``compile`` here) builds kernels declared with ``gagen.kernel`` into a module in the
cache folder (``cache_root()``), once per content, and loads it.
"""

from __future__ import annotations

import ctypes
import errno
import functools
import hashlib
import json
import os
import platform
import re
import shutil
import sys
import time
import weakref
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gagen import __version__, registry
from gagen.code_digest import code_digest
from gagen.codegen.backends import Backend, Context, select
from gagen.codegen.backends.base import template
from gagen.codegen.compiler import CompileError, CompilerNotFound
from gagen.codegen.escape import c_comment, c_string, py_doc, py_string
from gagen.codegen.ir import Kernel, ModuleSource, Port
from gagen.errors import SpecError
from gagen.frontend import KernelFunction, as_kernel, module_from_file, source_of
from gagen.limits import over_limit
from gagen.names import RESERVED_WORDS, identifier_problem
from gagen.runtime import MANIFEST, load

PACKAGE = Path(__file__).resolve().parent
CODEGEN = PACKAGE / "codegen"  # the code generator: its sources and templates are in the build key
MODULE_TEMPLATES = CODEGEN / "templates"  # module.py.j2: the module's __init__.py
DEFAULT_ROOT = Path("generated")
BUILD_KEY = ".build-key"  # the cache key of the build in a module folder (not committed)
# the manifest's own entries (neither a source's meta nor a backend may set them)
MANIFEST_KEYS = ("module", "title", "gagen_version", "source", "source_sha256", "backends", "kernels",
                 "files")


# module names prefix every C symbol and name files: bounded well below file-name limits (255 bytes)
MAX_NAME = 100


class OutputError(RuntimeError):
    """The output cannot be written (read-only folder, full disk, a folder that is no module):
    ``cannot write <path>: <reason>``. The previous module, if any, is untouched."""

    def __init__(self, path: str | Path, reason: str) -> None:
        self.path, self.reason = str(path), reason
        super().__init__(f"cannot write {path}: {reason}")


def check_identifier(name: object, what: str, spec: str | Path = "<system>", field: str = "name") -> str:
    """``name`` if it can be a C and Python identifier (and a file name) as is, by the identifier rule
    of ``gagen.names`` (any underscores after the first letter, at most ``MAX_NAME`` characters: the C
    function names ``<module>_<kernel>`` join two names), else a SpecError."""
    problem = identifier_problem(name, single_underscores=False, max_length=MAX_NAME)
    if not isinstance(name, str) or problem == "not an identifier":
        raise SpecError(spec, field, f"{what} {name!r} is not an identifier: expected a letter, then "
                                     f"letters, digits and underscores")
    if problem is not None and name in RESERVED_WORDS:
        raise SpecError(spec, field, f"{what} {name!r} is a C, C++ or Python keyword")
    if problem is not None:
        raise SpecError(spec, field, f"{what} {name!r} is longer than {MAX_NAME} characters")
    return name


@dataclass
class BuildResult:
    folder: Path
    key: str
    cached: bool
    compiled: bool
    seconds: float
    source: ModuleSource


# -- the key and the files ------------------------------------------------------------------------------

def key_files(backends: Sequence[Backend] | None = None) -> list[Path]:
    """The files of gagen that decide a module's bytes besides its source: this module, the code
    generator (``gagen/codegen``: printers, backends, templates) and every template a backend uses."""
    files = {Path(__file__).resolve(), *CODEGEN.rglob("*.py"), *CODEGEN.rglob("*.j2"),
             *MODULE_TEMPLATES.glob("*.j2")}
    for backend in backends if backends is not None else select():
        if backend.templates is not None:
            files.update(backend.templates.glob("*.j2"))
    return sorted(files)


def _kernels_digest(kernels: Iterable[Kernel]) -> str:
    digest = hashlib.sha256()
    for k in kernels:
        digest.update(repr((k.name, k.doc, k.inputs, k.outputs)).encode())
        digest.update(k.function.serialize().encode())
    return digest.hexdigest()


def build_key(source: ModuleSource, backends: Sequence[str] | None = None) -> str:
    """The cache key of a build: the source (everything it says about itself, and its ``key``, or,
    without one, the kernels' content), the sources of the gagen modules that made its kernels and of
    everything they import (``source.code``, ``gagen.code_digest``), the backends, gagen's version and
    the bytes of every file of ``key_files``. It is kept in the module folder's ``.build-key``, never in
    the module's files."""
    chosen = select(backends)
    digest = hashlib.sha256()
    digest.update(json.dumps([source.name, source.title, source.source_name, source.source_hash, source.meta,
                              source.rebuild, source.key or _kernels_digest(source.kernels.values()),
                              code_digest(source.code), __version__, [b.name for b in chosen]],
                             default=repr).encode())
    for path in key_files(chosen):
        name = path.relative_to(PACKAGE).as_posix() if path.is_relative_to(PACKAGE) else path.name
        digest.update(name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def _port_entry(port: Port) -> dict[str, Any]:
    return {"name": port.name, "rows": list(port.rows), "cols": port.cols, "layout": "column-major"}


def _kernel_entry(kernel: Kernel) -> dict[str, Any]:
    ops = kernel.op_count
    return {"name": kernel.name, "doc": kernel.doc, "inputs": [_port_entry(p) for p in kernel.inputs],
            "outputs": [_port_entry(p) for p in kernel.outputs],
            "op_count": {"mul": ops.mul, "add": ops.add, "neg": ops.neg, "div": ops.div, "flops": ops.flops,
                         "calls": ops.calls}}


def _check_names(source: ModuleSource) -> None:
    """Every name that becomes C or Python code or a file name is an identifier (whatever made the
    source: the spec loader and the front-end refuse these first; this is the builder's own check)."""
    origin = source.source_name
    check_identifier(source.name, "module name", origin)
    if not source.kernels:
        raise SpecError(origin, "kernels", f"module {source.name} has no kernels")
    for name, kernel in source.kernels.items():
        check_identifier(name, "kernel name", origin, "kernels")
        check_identifier(kernel.name, "kernel name", origin, "kernels")
        if name != kernel.name:
            raise SpecError(origin, "kernels", f"kernel {kernel.name!r} is listed as {name!r}")
        check_identifier(f"{source.name}_{kernel.name}", "C function name", origin, "kernels")
        for port in (*kernel.inputs, *kernel.outputs):
            check_identifier(port.name, f"port name of kernel {kernel.name}", origin, "kernels")
        problem = over_limit("kernel_nodes", kernel.function.n_instructions())
        if problem:  # before the C compiler spends minutes on it
            raise SpecError(origin, "kernels", f"kernel {kernel.name}: {problem}")
    _check_clashes(source)


def _check_clashes(source: ModuleSource) -> None:
    """No two kernels whose names differ only in case (files of one folder on a case-insensitive disk)
    and no global name a backend defines for one kernel equal to one it defines for another (``f`` and
    ``f_batch``: ``<module>_f_batch`` twice): one line naming both, before anything is written."""
    origin = source.source_name
    seen: dict[str, str] = {}  # symbol -> the kernel that defines it
    # the backends whose symbols share one C namespace (the library and its binding) and its reserved names
    linked = [backend for backend in select() if backend.symbols(source.name, "k")]
    lowered: dict[str, str] = {}  # kernel name in lower case -> the kernel
    for kernel in source.kernels:
        other = lowered.setdefault(kernel.lower(), kernel)
        if other != kernel:
            raise SpecError(origin, "kernels", f"kernels {other!r} and {kernel!r} differ only in case: their "
                                               "files would collide on a case-insensitive disk; rename one")
        for backend in linked:
            for symbol in backend.symbols(source.name, kernel):
                owner = seen.setdefault(symbol, kernel)
                if owner != kernel:
                    raise SpecError(origin, "kernels", f"kernels {owner!r} and {kernel!r} both define the "
                                                       f"{backend.name} symbol {symbol}; rename one")
                taken = _reserved_by(linked, backend, symbol, source.name, kernel)
                if taken is not None:
                    raise SpecError(origin, "kernels", f"kernel {kernel!r} of module {source.name!r} defines "
                                                       f"the {backend.name} symbol {symbol}, a name the "
                                                       f"{taken.name} code of every module uses for itself; "
                                                       "rename the kernel or the module (the file)")


def _reserved_by(linked: list[Backend], backend: Backend, symbol: str, module: str,
                 kernel: str) -> Backend | None:
    """The backend whose generated code uses ``symbol`` for itself (an exact name, or a prefix of its
    names: ``gagen_``, ``M_``), or None. A backend's prefix before the kernel's own name (the binding's
    ``make_<module>_<kernel>``) is that kernel's symbol, not a clash."""
    for other in linked:
        names = other.reserved()
        if symbol in names.exact:
            return other
        for prefix in names.prefixes:
            own = other is backend and symbol[len(prefix):] in (f"{module}_{kernel}", kernel)
            if symbol.startswith(prefix) and not own:
                return other
    return None


def _merge(into: dict[str, Any], entries: dict[str, Any], what: str) -> None:
    clash = [k for k in entries if k in into or k in MANIFEST_KEYS]
    if clash:
        raise ValueError(f"{what} sets manifest entries that are taken: {', '.join(clash)}")
    into.update(entries)


def render(source: ModuleSource, backends: Sequence[str] | None = None,
           progress: Callable[[str], None] = lambda _: None) -> dict[str, bytes]:
    """Every file of the module ``source`` as bytes, by relative path (the manifest included, listing
    the others with their sha256), from every backend asked for (default: all): what a build writes,
    without writing or compiling anything."""
    chosen = select(backends)
    _check_names(source)
    kernels = source.kernels
    variables = {"name": source.name, "title": source.title, "version": __version__,
                 "source_name": source.source_name, "source_hash": source.source_hash[:16],
                 "rebuild": source.rebuild}
    context = Context(variables, progress)
    entries = {name: _kernel_entry(kernel) for name, kernel in kernels.items()}
    manifest: dict[str, Any] = {"module": source.name, "title": source.title}
    _merge(manifest, dict(source.meta), f"the meta of module {source.name}")
    manifest.update({"gagen_version": __version__, "source": source.source_name,
                     "source_sha256": source.source_hash, "backends": [b.name for b in chosen]})
    files: dict[str, bytes] = {}
    for backend in chosen:
        output = backend.render(source, context)
        context.earlier[backend.name] = output
        taken = [path for path in output.files if path in files or path in (MANIFEST, "__init__.py")]
        if taken:
            raise ValueError(f"backend {backend.name} writes {', '.join(taken)}, which another file is")
        files.update(output.files)
        _merge(manifest, output.manifest, f"backend {backend.name}")
        for name, extra in output.kernels.items():
            _merge(entries[name], extra, f"backend {backend.name} (kernel {name})")
    names = list(kernels)
    files["__init__.py"] = template(MODULE_TEMPLATES, "module.py.j2").render(
        **variables, namespaces=[b.namespace for b in chosen if b.namespace],
        backends=[b.name for b in chosen], kernel_names=names, example=names[-1]).encode()
    manifest["kernels"] = list(entries.values())
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


def _manifest(folder: Path) -> dict[str, Any] | None:
    try:
        manifest = json.loads((folder / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    return manifest if isinstance(manifest, dict) else None


def _cached(folder: Path, key: str) -> dict[str, Any] | None:
    """The manifest of ``folder`` if it holds the build ``key`` (its ``.build-key`` says so and every
    file its manifest lists is there with the listed sha256: a deleted or damaged file rebuilds), else
    None."""
    try:
        if (folder / BUILD_KEY).read_text().strip() != key:
            return None
        manifest = _manifest(folder)
        if not manifest or not manifest["files"]:
            return None
        for name, digest in manifest["files"].items():
            if hashlib.sha256(_inside(folder, name).read_bytes()).hexdigest() != digest:
                return None
        return manifest
    except (OSError, ValueError, KeyError, TypeError, AttributeError, OutputError):
        return None


def _compiled(folder: Path, manifest: dict[str, Any], backends: Sequence[Backend]) -> bool:
    """Whether every compiled file of the backends that the module cannot do without is there."""
    return all(path.exists() for b in backends if not b.optional for path in b.artefacts(folder, manifest))


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


def _compile(folder: Path, manifest: dict[str, Any], backends: Sequence[Backend],
             progress: Callable[[str], None]) -> bool:
    """Compile what the backends compile from the sources in ``folder`` (the library, the CPython
    binding); False without a compiler (reported). A backend that is optional only warns when it
    fails. Each file is written under a temporary name and renamed."""
    t = time.perf_counter()
    made = []
    for backend in backends:
        artefacts = backend.artefacts(folder, manifest)
        if not artefacts:
            continue
        try:
            backend.compile(folder, manifest)
        except CompilerNotFound as e:
            progress(f"  warning: {e}; the module's files were written, not compiled")
            return False
        except CompileError as e:  # e.g. no Python headers for the binding: calls go through ctypes
            if not backend.optional:
                raise
            progress(f"  warning: the {backend.name} backend did not compile; {backend.optional} ({e})")
            continue
        made += [path.name for path in artefacts]
    if made:
        progress(f"  {manifest['module']}: compiled {' and '.join(made)} ({time.perf_counter() - t:.2f} s)")
    return True


@dataclass
class _Prepared:
    """A module written to its partial folder, waiting for its compilation and the swap (the lock held)."""

    source: ModuleSource
    folder: Path
    partial: Path
    key: str
    manifest: dict[str, Any]
    backends: list[Backend]
    start: float
    lock: _Lock


def _prepare(source: ModuleSource, out: str | Path | None, force: bool, compile_c: bool,
             backends: Sequence[str] | None, progress: Callable[[str], None]) -> BuildResult | _Prepared:
    start = time.perf_counter()
    name = check_identifier(source.name, "module name", source.source_name)  # before it names anything
    chosen = select(backends)
    folder = _output_folder(out, name)
    key = build_key(source, [b.name for b in chosen])
    partial = folder.with_name(f".{folder.name}.partial-{os.getpid()}")
    lock = None
    try:
        try:
            folder.parent.mkdir(parents=True, exist_ok=True)
            lock = _Lock(folder, progress)
        except OSError:
            current = None if force else _cached(folder, key)
            if current is not None and (not compile_c or _compiled(folder, current, chosen)):
                # a read-only copy that is up to date: nothing to write, nothing to lock
                progress(f"{name}: up to date ({folder})")
                return BuildResult(folder, key, True, _compiled(folder, current, chosen),
                                   time.perf_counter() - start, source)
            raise
        _clean_stale(folder)
        current = None if force else _cached(folder, key)
        if current is not None:
            compiled = _compiled(folder, current, chosen)
            if compile_c and not compiled:  # the sources are current: only compiled files are missing
                compiled = _compile(folder, current, chosen, progress)
            progress(f"{name}: up to date ({folder})")
            lock.release()
            return BuildResult(folder, key, True, compiled, time.perf_counter() - start, source)
        _check_replaceable(folder)
        progress(f"{name}: {source.title} -> {folder}")
        t = time.perf_counter()
        count = len(source.kernels)  # (a spec's kernel graphs are built here, on first use)
        progress(f"  {count} kernel graph{'s' if count != 1 else ''} ready ({time.perf_counter() - t:.2f} s)")
        files = render(source, [b.name for b in chosen], progress)
        paths = {path: _inside(partial, path) for path in files}  # all checked before anything is written
        partial.mkdir()
        for path, data in files.items():
            paths[path].parent.mkdir(parents=True, exist_ok=True)
            _write(paths[path], data)
        _write(partial / BUILD_KEY, f"{key}\n".encode())
        manifest = json.loads(files[MANIFEST])
    except BaseException as e:
        if lock is not None:  # (without it, the partial folder may be another thread's)
            shutil.rmtree(partial, ignore_errors=True)
            lock.release()
        if isinstance(e, OSError):
            raise OutputError(e.filename or partial, e.strerror or str(e)) from e
        raise
    return _Prepared(source, folder, partial, key, manifest, chosen, start, lock)


def _finish(prepared: _Prepared, compile_c: bool, progress: Callable[[str], None]) -> BuildResult:
    partial = prepared.partial
    compiled = False
    try:
        if compile_c:
            compiled = _compile(partial, prepared.manifest, prepared.backends, progress)
        _replace(partial, prepared.folder)
    except BaseException as e:
        shutil.rmtree(partial, ignore_errors=True)
        if isinstance(e, OSError):
            raise OutputError(e.filename or prepared.folder, e.strerror or str(e)) from e
        raise
    finally:
        prepared.lock.release()
    seconds = time.perf_counter() - prepared.start
    progress(f"{prepared.source.name}: built in {seconds:.2f} s")
    return BuildResult(prepared.folder, prepared.key, False, compiled, seconds, prepared.source)


def _build_all(work: Iterable[tuple[Callable[[], ModuleSource], str | Path | None]], force: bool,
               compile_c: bool, backends: Sequence[str] | None, progress: Callable[[str], None],
               jobs: int | None) -> list[BuildResult]:
    """Make each source and write its files one after another, while the C compiler runs on the
    previous ones in up to ``jobs`` (default: CPU count) parallel threads."""
    results: list[BuildResult | Future[BuildResult]] = []
    with ThreadPoolExecutor(max_workers=jobs or os.cpu_count() or 1) as pool:
        try:
            for make, out in work:
                prepared = _prepare(make(), out, force, compile_c, backends, progress)
                results.append(prepared if isinstance(prepared, BuildResult)
                               else pool.submit(_finish, prepared, compile_c, progress))
        finally:  # on a failure, let the started compilations finish and swap in (they are complete)
            done = [r.result() if isinstance(r, Future) else r for r in results]
    return done


def build_source(source: ModuleSource, out: str | Path | None = None, *, force: bool = False,
                 compile_c: bool = True, progress: Callable[[str], None] = print,
                 backends: Sequence[str] | None = None) -> BuildResult:
    """Build the module ``source`` into ``out`` (default ``generated/<name>/``) with the backends
    ``backends`` (default: every registered one). See ``build`` for the errors."""
    return _build_all([(lambda: source, out)], force, compile_c, backends, progress, None)[0]


def load_source(path: str | Path, name: str | None = None) -> ModuleSource:
    """The ModuleSource of a file: a Python file of ``@gagen.kernel`` functions (``.py``; ``name``
    overrides the module name, default the file's stem) or a robot spec (anything else)."""
    path = Path(path)
    if path.suffix == ".py":
        return module_from_file(path, name)
    if name is not None:
        raise SpecError(path, "name", "a spec names its system itself (a module name is for .py files)")
    app, kind = registry.spec_kinds()[spec_kind(path).name]
    source: ModuleSource = registry.function(kind.source)(path)
    source.code = source.code or app.kernel_modules  # the code that made its kernels, for the cache key
    return source


def spec_kind(path: str | Path) -> registry.SpecKind:
    """The registered kind of a spec: its ``app`` key, or ``cooperative``; a SpecError for an unknown one
    (or a malformed document)."""
    from gagen.yaml_document import Document, show

    spec = Document(Path(path), "a mapping (a spec)")
    kinds = registry.spec_kinds()
    kind = spec.data.get("app", registry.DEFAULT_SPEC_KIND)
    if not isinstance(kind, str) or kind not in kinds:
        raise spec.error("app", f"got {show(kind)}; expected one of {', '.join(kinds)}")
    return kinds[kind][1]


def spec_checker(path: str | Path) -> Callable[[str | Path, Path, int, float], int]:
    """``gagen build --check`` of the module of a spec whose kernels are not front-end kernels (its kind's
    ``check``)."""
    kind = spec_kind(path)
    if not kind.check:
        raise SpecError(path, "app", f"the {kind.name} kind names no check for its modules")
    return registry.function(kind.check)


def _checked_source(path: str | Path, name: str | None) -> ModuleSource:
    """``load_source`` with its names checked at once, so that an error names the path the user gave
    (the source knows its file by name only: ``formulas.py``)."""
    source = load_source(path, name)
    try:
        _check_names(source)
    except SpecError as e:
        if e.file != source.source_name:
            raise
        raise SpecError(path, e.field, e.message) from e
    return source


def build_many(paths: Sequence[str | Path], *, force: bool = False, compile_c: bool = True,
               progress: Callable[[str], None] = print, jobs: int | None = None,
               outputs: Sequence[str | Path | None] | None = None,
               names: Sequence[str | None] | None = None) -> list[BuildResult]:
    """Build several files (specs or Python files): sources and files one after another, while the C
    compiler runs on the previous ones in up to ``jobs`` (default: CPU count) parallel processes."""
    outputs = outputs or [None] * len(paths)
    names = names or [None] * len(paths)
    work = [(functools.partial(_checked_source, path, name), out)
            for path, out, name in zip(paths, outputs, names, strict=True)]
    return _build_all(work, force, compile_c, None, progress, jobs)


def build(path: str | Path, out: str | Path | None = None, *, name: str | None = None, force: bool = False,
          compile_c: bool = True, progress: Callable[[str], None] = print) -> BuildResult:
    """Build the module of ``path`` (a robot spec, or a Python file of kernels named ``name``) into
    ``out`` (default ``generated/<name>/``).

    A malformed spec or kernel, or a name that cannot be an identifier, raises a ValueError
    (``SpecError``, ``KernelError``) before anything is written. An output that cannot be written
    raises ``OutputError`` (``cannot write <path>: <reason>``) and leaves the previous module as it
    was. With no C compiler the module is still written (CasADi Functions and C source) and the
    missing compilation is reported.
    """
    return build_many([path], force=force, compile_c=compile_c, progress=progress, outputs=[out],
                      names=[name])[0]


# -- gagen.compile: kernels built into the cache and loaded ----------------------------------------------

# the compiled kernel of each KernelFunction given to gagen.compile without options (weak: a kernel
# dropped by its user is not kept alive here)
_COMPILED: weakref.WeakKeyDictionary[KernelFunction, Any] = weakref.WeakKeyDictionary()


def cache_root() -> Path:
    """Where ``gagen.compile`` keeps its modules: $GAGEN_CACHE, else ~/.cache/gagen (XDG_CACHE_HOME)."""
    if os.environ.get("GAGEN_CACHE"):
        return Path(os.environ["GAGEN_CACHE"]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "gagen"


def compile_kernels(kernels: Sequence[KernelFunction], *, name: str | None = None,
                    folder: str | Path | None = None, progress: Callable[[str], None] | None = None) -> Any:
    """Build the kernels into a module in the cache (once per content) and return the compiled
    kernel (one) or the module's C namespace (several)."""
    source = source_of(kernels, name or kernels[0].name)
    target = Path(folder) if folder is not None else cache_root() / f"{source.name}-{source.key[:16]}"
    # (a no-op when the folder is current; after a gagen upgrade its code generator's key differs and
    # the module is rebuilt, so a cached module never outlives the generator that wrote it)
    build_source(source, target, progress=progress or (lambda _: None))
    module = load(target)
    return getattr(module.c, kernels[0].name) if len(kernels) == 1 else module.c


def compile(fn: Callable[..., Any] | None = None, **options: Any) -> Any:
    """Compile one function (a ``@gagen.kernel`` or a plain function plus its declaration as keyword
    arguments) to C behind the CPython binding, built once per content into the cache folder
    (``cache_root()``). Returns the kernel: ``k(*inputs)`` (numpy in, numpy out), ``k.batch``,
    ``k.casadi`` (the casadi.Function), ``k.c_source``, ``k.op_count``."""
    build_options = {k: options.pop(k) for k in ("folder", "progress") if k in options}
    if fn is None:
        return lambda f: compile(f, **options, **build_options)
    k = as_kernel(fn, options)
    if build_options:
        return compile_kernels([k], **build_options)
    if k not in _COMPILED:
        _COMPILED[k] = compile_kernels([k])
    return _COMPILED[k]


__all__ = ["BuildResult", "CompileError", "OutputError", "build", "build_key", "build_many", "build_source",
           "c_comment", "c_string", "cache_root", "check_identifier", "compile", "compile_kernels",
           "load_source", "py_doc", "py_string", "render"]
