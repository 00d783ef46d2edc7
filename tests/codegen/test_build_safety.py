"""`gagen build` is safe by construction: hostile names cannot inject C or Python nor write outside the
output folder (even for a System that bypassed the spec loader), the output folder is never missing or
half-written (atomic exchange, a lock, stale folders cleaned), "up to date" checks the files, and
write failures are one-line errors that leave the previous module intact."""

from __future__ import annotations

import ast
import builtins
import dataclasses
import errno
import hashlib
import io
import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import textwrap
import threading
import time
from pathlib import Path

import numpy
import pytest

from gagen import build as build_module
from gagen.apps.cooperative import module as cooperative_module
from gagen.apps.cooperative.bundled import bundled_specs
from gagen.apps.cooperative.module import cooperative_source
from gagen.build import build, build_key
from gagen.cli import main
from gagen.codegen.backends import BACKENDS
from gagen.codegen.backends.c import library
from gagen.errors import SpecError
from gagen.robots.spec import load_system
from gagen.robots.system import Chain, System

SPEC = bundled_specs()["panda_point"]
QUIET = {"progress": lambda _: None}
REPO = Path(__file__).resolve().parents[2]
_KERNELS: dict[str, dict] = {}


@pytest.fixture
def cheap(monkeypatch):
    """Kernel graphs built once per system (the slow step), so a test can rebuild many times."""
    real = cooperative_module.build_kernels

    def cached(system):
        key = repr(system)
        if key not in _KERNELS:
            _KERNELS[key] = real(system)
        return _KERNELS[key]

    monkeypatch.setattr(cooperative_module, "build_kernels", cached)


def _hostile(system: System, name: str, chain_name: str, joint_name: str) -> System:
    """``system`` renamed: its chain and every joint carry hostile text (a System built directly,
    bypassing the spec loader's checks)."""
    chain = system.chains[0]
    joints = tuple(dataclasses.replace(j, name=f"{joint_name}{i}") for i, j in enumerate(chain.joints))
    return System(name, system.kind, (Chain(chain_name, joints, chain.robot),))


def _use(monkeypatch, system: System) -> None:
    monkeypatch.setattr(cooperative_module, "load_system", lambda path: (system, {}))


# Child processes build a tiny system (the Panda chain cut after its first two joints): quick to build
TINY = """
import gagen.apps.cooperative.module
from gagen.robots.system import Chain, System
from gagen.robots.spec import load_system


def tiny(path):
    system, _ = load_system(path)
    chain = system.chains[0]
    return System(system.name, system.kind, (Chain(chain.name, chain.joints[:3], chain.robot),)), {}


gagen.apps.cooperative.module.load_system = tiny
"""
_tiny: dict = {}
exec(TINY.replace("gagen.apps.cooperative.module.load_system = tiny", ""), _tiny)


def _use_tiny(monkeypatch) -> None:
    monkeypatch.setattr(cooperative_module, "load_system", _tiny["tiny"])


def _child(code: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", TINY + textwrap.dedent(code)], cwd=REPO,
                            stderr=subprocess.PIPE, text=True)


def _code_without_comments(text: str) -> str:
    """C source with its comments, string and character literals removed (a small lexer)."""
    out, i, n = [], 0, len(text)
    while i < n:
        if text.startswith("/*", i):
            end = text.find("*/", i + 2)
            assert end >= 0, "unterminated comment"
            i = end + 2
            out.append(" ")
        elif text.startswith("//", i):
            i = text.find("\n", i)
            i = n if i < 0 else i
        elif text[i] in "\"'":
            quote, i = text[i], i + 1
            while text[i] != quote:
                i += 2 if text[i] == "\\" else 1
            i += 1
            out.append('""')
        else:
            out.append(text[i])
            i += 1
    return "".join(out)


INJECTED_C = "*/ __attribute__((constructor)) static void pwned(void) { for (;;); } /*"
INJECTED_PP = "*/\n#error injected ??/\n/* \\"
SPEC_NAME = 'x"""; import os; os.system("touch PWNED") #\u00e9 \\ ??* #error s.yaml'  # no "/" in a file name


@pytest.mark.compiling
def test_hostile_labels_are_escaped_in_every_comment_docstring_and_string(tmp_path, monkeypatch, cheap):
    """A chain name with ``*/ __attribute__((constructor)) ... /*``, joint names with ``*/ #error``,
    newlines, trigraphs and backslashes, and a spec file name with ``\"\"\"``: the C files compile
    (-fsyntax-only, so no #error), none of the payload is left as code once comments and literals
    are removed, and __init__.py is a docstring and the usual imports and assignments only, its
    docstring naming the spec file exactly."""
    system, _ = load_system(SPEC)
    _use(monkeypatch, _hostile(system, "hostile", f"arm {INJECTED_C}", f"j {INJECTED_PP} \u00e9\x07"))
    spec = tmp_path / SPEC_NAME
    spec.write_bytes(SPEC.read_bytes())
    out = tmp_path / "out"
    build(spec, out, compile_c=False, **QUIET)
    sources = sorted(p for p in out.iterdir() if p.suffix in (".c", ".h", ".cu"))
    assert len(sources) == 5
    for path in sources:
        code = _code_without_comments(path.read_text())
        # (the chain name also reaches kernel names, as an identifier: "arm_attribute_constructor_...")
        for marker in ("__attribute__((constructor", "for (;;)", "#error", "import os", "??/"):
            assert marker not in code, (path.name, marker)
        assert path.read_text().isascii()
    include = sysconfig.get_paths()["include"]
    for path in sources:
        if path.suffix == ".c":
            result = subprocess.run(["cc", "-std=c99", "-fsyntax-only", "-Werror=comment", f"-I{include}",
                                     f"-I{out}", f"-I{numpy.get_include()}", str(path)],
                                    capture_output=True, text=True)
            assert result.returncode == 0, result.stderr
        if path.suffix == ".cu":  # the CUDA source as host C++ (its device half is guarded by __CUDACC__)
            result = subprocess.run(["c++", "-x", "c++", "-std=c++17", "-fsyntax-only", "-Werror=comment",
                                     str(path)], capture_output=True, text=True)
            assert result.returncode == 0, result.stderr
    init = ast.parse((out / "__init__.py").read_text())
    kinds = [type(s).__name__ for s in init.body]
    assert kinds == ["Expr", "ImportFrom", "ImportFrom", *["Assign"] * 6], kinds
    assert SPEC_NAME in ast.get_docstring(init)
    # the JAX kernels: two imports, the x64 switch, __all__, then functions of a docstring, assignments
    # and a return only (the labels are in comments and docstrings)
    jax_file = (out / "hostile_jax.py").read_text()
    assert jax_file.isascii() and "# Generated by gagen" in jax_file
    tree = ast.parse(jax_file)
    assert [type(s).__name__ for s in tree.body[:4]] == ["Import", "Import", "Expr", "Assign"]
    kernels = [s for s in tree.body[4:] if isinstance(s, ast.FunctionDef) and s.name != "_Flat"]
    assert len(kernels) == len(tree.body) - 5 and kernels
    for kernel in kernels:
        assert isinstance(kernel.body[0], ast.Expr) and isinstance(kernel.body[-1], ast.Return)
        assert all(isinstance(s, ast.Assign) for s in kernel.body[1:-1]), kernel.name
    assert not (tmp_path / "PWNED").exists()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["source"] == SPEC_NAME


@pytest.mark.parametrize("name", ["../escape", "ABS", "a b", "x-y", "1x", "", "int", "class", "static",
                                  'a"""b', "a*/b", "a\nb", "_Bool", "\u00e9t\u00e9"])
@pytest.mark.parametrize("explicit_out", [False, True])
def test_a_system_name_that_is_no_identifier_is_refused_before_anything_is_written(
        tmp_path, monkeypatch, name, explicit_out):
    """System names become C functions, an include guard, file names and a Python module name:
    anything but a non-keyword identifier is refused (a System built directly, bypassing the spec
    loader), and nothing is written anywhere: not into the working directory (``../escape``), not
    at an absolute path, not next to the output folder."""
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    if name == "ABS":
        name = str(tmp_path / "elsewhere" / "abs")
    system, _ = load_system(SPEC)
    _use(monkeypatch, dataclasses.replace(system, name=name))
    out = tmp_path / "out" / "module" if explicit_out else None
    with pytest.raises(ValueError, match="system name") as info:
        build(SPEC, out, compile_c=False, **QUIET)
    assert repr(name) in str(info.value)
    assert sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*")) == ["work"]


def test_an_existing_folder_that_is_no_module_is_not_replaced(tmp_path):
    """``-o`` naming a folder with other files in it (a typo, ``-o .``): refused, the files kept."""
    folder = tmp_path / "project"
    folder.mkdir()
    (folder / "notes.txt").write_text("keep me")
    code, _, err = _cli(["build", str(SPEC), "-o", str(folder), "--no-compile"])
    assert code == 1
    assert err == f"error: cannot write {folder}: it exists and is not a gagen module (no manifest.json)\n"
    assert (folder / "notes.txt").read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".lock")) == ["project"]


def _cli(argv: list[str]) -> tuple[int, str, str]:
    stdout, stderr = io.StringIO(), io.StringIO()
    real_out, real_err = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = stdout, stderr
    try:
        code = main(argv)
    finally:
        sys.stdout, sys.stderr = real_out, real_err
    return code, stdout.getvalue(), stderr.getvalue()


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


READER = """
import json, os, sys
folder, stop = sys.argv[1], sys.argv[2]
names = [os.path.join(folder, n) for n in ("manifest.json", "panda_point.c")]
expected = [open(n, "rb").read() for n in names]
reads = missing = different = 0
open(stop + ".ready", "w").close()
while not os.path.exists(stop):
    for name, data in zip(names, expected):
        try:
            with open(name, "rb") as f:
                different += f.read() != data
            reads += 1
        except FileNotFoundError:
            missing += 1
print(json.dumps({"reads": reads, "missing": missing, "different": different}))
"""


@pytest.mark.compiling
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="renameat2(RENAME_EXCHANGE) is Linux only")
def test_readers_never_see_the_folder_missing_or_half_written_during_rebuilds(tmp_path, monkeypatch, cheap):
    """A reader process polls manifest.json and the C source while the folder is rebuilt 6 times. Every
    os.rename here is followed by a 20 ms pause, which widens any window between two renames (the old
    builder's reader missed the folder thousands of times): with the atomic exchange there is none."""
    out, stop = tmp_path / "panda_point", tmp_path / "stop"
    build(SPEC, out, compile_c=False, **QUIET)
    real_rename = os.rename

    def slow_rename(*args, **kwargs):
        real_rename(*args, **kwargs)
        time.sleep(0.02)

    monkeypatch.setattr(os, "rename", slow_rename)
    reader = subprocess.Popen([sys.executable, "-c", READER, str(out), str(stop)], stdout=subprocess.PIPE,
                              text=True)
    try:
        while not Path(f"{stop}.ready").exists() and reader.poll() is None:
            time.sleep(0.01)
        for _ in range(6):
            build(SPEC, out, force=True, compile_c=False, **QUIET)
    finally:
        stop.touch()
        counts = json.loads(reader.communicate(timeout=60)[0])
    assert counts["missing"] == 0 and counts["different"] == 0, counts
    assert counts["reads"] > 100, counts


@pytest.mark.compiling
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="renameat2(RENAME_EXCHANGE) is Linux only")
def test_a_build_killed_at_the_swap_leaves_a_complete_folder_and_the_leftover_is_cleaned(tmp_path,
                                                                                       monkeypatch):
    """A child rebuilds from an edited spec and dies at its first os.rename (where a two-rename swap has
    moved the folder aside and not yet moved the new one in), or else as it removes the folder swapped
    out: the folder is there, holds the new build, and the next build removes the leftover."""
    _use_tiny(monkeypatch)
    out = tmp_path / "panda_point"
    build(SPEC, out, compile_c=False, **QUIET)
    edited = tmp_path / "panda_point.yaml"
    urdf = SPEC.parent / "panda" / "panda.urdf"
    edited.write_text(SPEC.read_text().replace("urdf: panda/panda.urdf", f"urdf: {urdf}") + "# edited\n")
    sha = hashlib.sha256(edited.read_bytes()).hexdigest()
    manifest = out / "manifest.json"
    child = _child(f"""
        import os, shutil
        from gagen.build import build
        real_rename = os.rename
        def die(*args, **kwargs):
            real_rename(*args, **kwargs)
            os._exit(3)
        os.rename = die
        real_rmtree = shutil.rmtree
        def rmtree(path, *args, **kwargs):
            if ".partial-" in os.path.basename(path) and {sha!r} in open({str(manifest)!r}).read():
                os._exit(4)
            return real_rmtree(path, *args, **kwargs)
        shutil.rmtree = rmtree
        build({str(edited)!r}, {str(out)!r}, force=True, compile_c=False, progress=lambda m: None)
        """)
    code, err = child.wait(timeout=120), child.stderr.read()
    assert code in (3, 4), err
    assert json.loads(manifest.read_text())["source_sha256"] == sha  # there, and the new build
    leftovers = sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".panda_point."))
    assert leftovers == [".panda_point.lock", f".panda_point.partial-{child.pid}"]
    assert build(edited, out, compile_c=False, **QUIET).cached  # up to date, and cleans the leftover
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == [".panda_point.lock", "panda_point", "panda_point.yaml"]


@pytest.mark.compiling
def test_stale_folders_of_dead_processes_are_removed_and_live_ones_kept(tmp_path, cheap):
    out = tmp_path / "panda_point"
    dead_pid = subprocess.Popen(["true"])
    dead_pid.wait()
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        stale = [f".panda_point.partial-{dead_pid.pid}", f".panda_point.old-{dead_pid.pid}"]
        kept = [f".panda_point.partial-{live.pid}", ".panda_point.partial-notapid", ".other.partial-1"]
        for name in stale + kept:
            (tmp_path / name / "casadi").mkdir(parents=True)
            (tmp_path / name / "casadi" / "x").write_text("x")
        build(SPEC, out, compile_c=False, **QUIET)
        left = sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".lock"))
        assert left == sorted([*kept, "panda_point"])
    finally:
        live.kill()
        live.wait()


@pytest.mark.compiling
def test_two_threads_building_one_spec_into_one_folder_are_serialised(tmp_path, cheap):
    out = tmp_path / "panda_point"
    build(SPEC, out, compile_c=False, **QUIET)  # warms the kernel cache
    errors: list[BaseException] = []

    def work():
        try:
            for _ in range(2):
                build(SPEC, out, force=True, compile_c=False, **QUIET)
        except BaseException as e:  # collected and asserted below
            errors.append(e)

    threads = [threading.Thread(target=work) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    assert build(SPEC, out, compile_c=False, **QUIET).cached  # complete: every file present and intact
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".lock")) == ["panda_point"]


@pytest.mark.compiling
def test_two_processes_building_one_spec_into_one_folder_both_succeed(tmp_path, monkeypatch):
    """Two processes rebuild one folder; each os.rename waits until both processes have reached one, and
    pauses after it (so two unserialised swaps collide: the old builder failed here). Both exit 0 and
    the folder is complete."""
    out, barrier = tmp_path / "m" / "panda_point", tmp_path / "barrier"
    barrier.mkdir()
    _use_tiny(monkeypatch)
    build(SPEC, out, compile_c=False, **QUIET)
    code = f"""
        import os, time
        from pathlib import Path
        real = os.rename
        def synchronised(*args, **kwargs):
            (Path({str(barrier)!r}) / str(os.getpid())).touch()
            deadline = time.monotonic() + 20
            while len(os.listdir({str(barrier)!r})) < 2 and time.monotonic() < deadline:
                time.sleep(0.01)
            real(*args, **kwargs)
            time.sleep(0.3)
        os.rename = synchronised
        from gagen.build import build
        build({str(SPEC)!r}, {str(out)!r}, force=True, compile_c=False, progress=lambda m: None)
        """
    children = [_child(code) for _ in range(2)]
    results = [(c.wait(timeout=120), c.stderr.read()) for c in children]
    assert [r for r, _ in results] == [0, 0], [e for _, e in results]
    assert build_module._cached(out, build_key(cooperative_source(SPEC)))
    assert sorted(p.name for p in out.parent.iterdir()) == [".panda_point.lock", "panda_point"]


@pytest.mark.compiling
@pytest.mark.parametrize("victim", ["panda_point.c", "panda_point_simd.c", "__init__.py",
                                    "casadi/arm0_fk.casadi.gz", "TRUNCATE panda_point.h"])
def test_up_to_date_means_every_file_is_there_and_intact(tmp_path, victim, cheap):
    out = tmp_path / "panda_point"
    build(SPEC, out, compile_c=False, **QUIET)
    before = _snapshot(out)
    if victim.startswith("TRUNCATE "):
        victim = victim.split()[1]
        (out / victim).write_bytes((out / victim).read_bytes()[:-100])
    else:
        (out / victim).unlink()
    result = build(SPEC, out, compile_c=False, **QUIET)
    assert not result.cached
    assert _snapshot(out) == before


@pytest.mark.compiling
def test_up_to_date_sources_without_the_asked_library_compile_it(tmp_path, monkeypatch, cheap):
    """Built with a (fake, fast) compiler, the library deleted: the next build compiles it again."""
    fake = tmp_path / "fakecc"
    fake.write_text('#!/bin/sh\n'  # creates the file named by -o, as a compiler would
                    'while [ $# -gt 0 ]; do if [ "$1" = -o ]; then shift; : > "$1"; fi; shift; done\n')
    fake.chmod(0o755)
    monkeypatch.setenv("CC", str(fake))
    out = tmp_path / "panda_point"
    first = build(SPEC, out, **QUIET)
    compiled = out / library(json.loads((out / "manifest.json").read_text()))
    assert first.compiled and compiled.exists()
    compiled.unlink()
    again = build(SPEC, out, **QUIET)
    assert again.compiled and compiled.exists()


def _fail_writes_under(monkeypatch, root: Path, error: int, full_disk: bool = False) -> None:
    """Every write under ``root`` fails with ``error``: opening a file for writing, and unless the disk is
    only full, making a folder or the (empty) lock file."""
    real_open, real_mkdir, real_os_open = builtins.open, os.mkdir, os.open

    def inside(path) -> bool:
        try:
            return Path(os.fspath(path)).resolve().is_relative_to(root.resolve())
        except TypeError:
            return False

    def fail(path):
        raise OSError(error, os.strerror(error), os.fspath(path))

    def fake_open(file, mode="r", *args, **kwargs):
        if any(c in mode for c in "wxa+") and inside(file):
            fail(file)
        return real_open(file, mode, *args, **kwargs)

    def fake_os_open(path, flags, *args, **kwargs):
        spared = full_disk and str(path).endswith(".lock")
        if flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT) and inside(path) and not spared:
            fail(path)
        return real_os_open(path, flags, *args, **kwargs)

    def fake_mkdir(path, *args, **kwargs):
        if not full_disk and inside(path):
            fail(path)
        return real_mkdir(path, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", fake_open)
    monkeypatch.setattr(io, "open", fake_open)
    monkeypatch.setattr(os, "open", fake_os_open)
    monkeypatch.setattr(os, "mkdir", fake_mkdir)


@pytest.mark.compiling
def test_a_full_disk_is_a_one_line_error_and_the_previous_module_stays(tmp_path, monkeypatch, cheap):
    out = tmp_path / "panda_point"
    build(SPEC, out, compile_c=False, **QUIET)
    before = _snapshot(out)
    _fail_writes_under(monkeypatch, tmp_path, errno.ENOSPC, full_disk=True)
    code, _, err = _cli(["build", str(SPEC), "-o", str(out), "--no-compile", "--force"])
    assert code == 1
    reason = os.strerror(errno.ENOSPC)
    assert re.fullmatch(rf"error: cannot write {re.escape(str(tmp_path))}/\S+: {reason}\n", err), err
    assert _snapshot(out) == before
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".lock")) == ["panda_point"]


def test_a_read_only_folder_is_a_one_line_error(tmp_path, monkeypatch, cheap):
    """As root, permissions do not stop writes: there a read-only file system is simulated (EROFS
    from every write under the folder); otherwise the folder is made read-only."""
    parent = tmp_path / "ro"
    parent.mkdir()
    if os.geteuid() == 0:
        _fail_writes_under(monkeypatch, parent, errno.EROFS)
        reason = os.strerror(errno.EROFS)
    else:
        parent.chmod(0o555)
        reason = os.strerror(errno.EACCES)
    try:
        code, _, err = _cli(["build", str(SPEC), "-o", str(parent / "panda_point"), "--no-compile"])
    finally:
        parent.chmod(0o755)
    assert code == 1
    assert re.fullmatch(rf"error: cannot write {re.escape(str(parent))}/\S+: {reason}\n", err), err
    assert "Traceback" not in err


@pytest.mark.compiling
def test_the_build_key_covers_every_template_and_stays_out_of_the_files(tmp_path, monkeypatch):
    """Every template a backend or the module renders is hashed into the build key, and editing one
    changes it; the key is kept in .build-key, and the files carry no part of it."""
    used = {p for b in BACKENDS.values() if b.templates for p in b.templates.glob("*.j2")}
    used |= set(build_module.MODULE_TEMPLATES.glob("*.j2"))
    assert {p.name for p in used} >= {"kernels.h.j2", "kernels.c.j2", "simd.c.j2", "binding.c.j2",
                                      "module.py.j2"}
    assert used <= set(build_module.key_files())
    source = cooperative_source(SPEC)
    copies = {path: tmp_path / path.name for path in used}
    for path, copy in copies.items():
        shutil.copyfile(path, copy)
    monkeypatch.setattr(build_module, "key_files", lambda backends=None: sorted(copies.values()))
    key = build_key(source)
    for path in copies.values():
        text = path.read_text()
        path.write_text(text + " ")
        assert build_key(source) != key, path.name
        path.write_text(text)
    assert build_key(source) == key
    out = tmp_path / "out"
    monkeypatch.undo()
    result = build(SPEC, out, compile_c=False, **QUIET)
    assert (out / ".build-key").read_text() == f"{result.key}\n"
    for path in out.rglob("*"):
        if path.is_file() and path.name != ".build-key":
            assert result.key[:12] not in path.name and result.key[:12].encode() not in path.read_bytes()


@pytest.mark.parametrize(("names", "message"), [
    (("f", "f_batch"), "kernels 'f' and 'f_batch' both define the c symbol clash_f_batch; rename one"),
    (("g_argv", "g"), "kernels 'g_argv' and 'g' both define the c symbol clash_g_argv; rename one"),
    (("pose", "Pose"), "kernels 'pose' and 'Pose' differ only in case"),
])
def test_kernel_names_that_collide_in_c_are_one_line_before_anything_is_written(tmp_path, names, message):
    """Names that pass every identifier check but collide in the generated C (a suffix the C backend adds)
    or in a case-insensitive folder: refused naming both, nothing written (gcc never sees them)."""
    kernels = "\n".join(f"@gagen.kernel(algebra='cga3d')\ndef {n}(X: point):\n    return {{'Y': X}}\n"
                        for n in names)
    user = tmp_path / "clash.py"
    user.write_text("import gagen\nfrom gagen.kinds import point\n\n" + kernels)
    out = tmp_path / "out"
    with pytest.raises(SpecError, match=re.escape(message)):
        build(user, out, compile_c=False, **QUIET)
    assert not out.exists()


@pytest.mark.parametrize(("module", "kernel", "symbol"), [
    ("gagen", "v", "gagen_v"),  # the SIMD vector type
    ("GAGEN", "W", "GAGEN_W"),  # the SIMD width macro
    ("GAGEN", "HAVE_LIBMVEC", "GAGEN_HAVE_LIBMVEC"),
    ("gagen", "anything", "gagen_anything"),  # gagen_<port> locals: the whole prefix is gagen's
    ("M", "PI", "M_PI"),  # libm's macros
    ("make", "f", "make_f"),  # the binding's constructors, make_<kernel>
    ("m", "f_in_shape", "m_f_in_shape"),  # the binding's shape table of kernel f
])
def test_module_and_kernel_names_that_meet_gagens_own_c_names_are_one_line(tmp_path, module, kernel, symbol):
    """A module (the file's stem) and kernel whose C symbol is a name the generated C or the C library
    uses for itself (issue 29: a module named gagen with kernel v was a multi-line gcc error) is refused
    in one line naming the kernel and the symbol, before anything is written."""
    kernels = f"@gagen.kernel(algebra='cga3d')\ndef {kernel}(X: point):\n    return {{'Y': X}}\n"
    if kernel == "f_in_shape":
        kernels += "\n@gagen.kernel(algebra='cga3d')\ndef f(X: point):\n    return {'Y': X}\n"
    user = tmp_path / f"{module}.py"
    user.write_text("import gagen\nfrom gagen.kinds import point\n\n" + kernels)
    out = tmp_path / "out"
    with pytest.raises(SpecError) as e:
        build(user, out, compile_c=False, **QUIET)
    assert "\n" not in str(e.value) and symbol in str(e.value) and e.value.field == "kernels", str(e.value)
    assert not out.exists()


def test_a_kernel_over_the_node_limit_is_refused_before_the_compiler(tmp_path, monkeypatch):
    """The limit on expression nodes per kernel (gagen.limits, issue 29): one line naming the kernel, the
    count and the variable that raises it; nothing written. The largest bundled kernel (two_g1_sphere's
    similarity_rate) has ≈ 14 000, far inside the default of 2 000 000."""
    user = tmp_path / "wide.py"
    user.write_text("import gagen\nfrom gagen.kinds import point\n\n@gagen.kernel(algebra='cga3d')\n"
                    "def meet(A: point, B: point):\n    return {'Y': A ^ B}\n")
    monkeypatch.setenv("GAGEN_LIMIT_KERNEL_NODES", "5")
    out = tmp_path / "out"
    with pytest.raises(SpecError) as e:
        build(user, out, compile_c=False, **QUIET)
    message = str(e.value)
    assert e.value.field == "kernels" and "\n" not in message and "kernel meet:" in message
    assert "expression nodes in one kernel, over the limit of 5" in message
    assert "GAGEN_LIMIT_KERNEL_NODES" in message
    assert not out.exists()
    monkeypatch.setenv("GAGEN_LIMIT_KERNEL_NODES", "100000")
    build(user, out, compile_c=False, **QUIET)
    assert (out / "manifest.json").is_file()
