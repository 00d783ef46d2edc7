"""`gagen build`: the committed generated modules (regenerated and compared byte for byte), every
bundled module against the interpreter, determinism, the cache, atomic replacement, missing compilers,
corrupted kernels caught by --check, and a generated CasADi Function inside IPOPT.

The committed modules (a representative few: ``generated/README.md``) are golden files:
``test_committed_module_is_what_gagen_generates`` renders each one again in memory and compares the
committed (text) files' bytes; ``GAGEN_UPDATE_GOLDEN=1`` rewrites them instead
(``GAGEN_UPDATE_GOLDEN=1 pytest tests/codegen/test_build.py -k what_gagen_generates --full``). Every
other bundled module is built on first use into the gagen cache (``conftest.bundled_module``)."""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from conftest import BUNDLED, FAST_MODULES, bundled_module, committed_modules, tiered

from gagen.apps.cooperative.bundled import bundled_specs, bundled_systems, ready_configuration
from gagen.apps.cooperative.check import check_module
from gagen.build import build, build_source, load_source, render
from gagen.check import check_kernels, failures
from gagen.errors import SpecError
from gagen.runtime import load

REPO = Path(__file__).resolve().parents[2]
GENERATED = REPO / "generated"
SYSTEMS = bundled_systems()
QUIET = {"progress": lambda _: None}


def _module(name: str):
    return bundled_module(name)


UPDATE_GOLDEN = os.environ.get("GAGEN_UPDATE_GOLDEN", "").strip() not in ("", "0")
HEX = re.compile(r"[0-9a-f]{12}")


def _binary(data: bytes) -> bool:
    """A file git would not diff: the CasADi serialisations (gzip). Never committed."""
    return b"\0" in data


def _committed(folder: Path) -> dict[str, bytes]:
    """The files of a module folder that are committed: its text files, not the compiled ones, the
    build key, a first-use compilation's temporary files (another test process may be compiling the
    module) nor the CasADi serialisations (``casadi/``: binary, rebuilt on demand)."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.name.endswith((".so", ".dylib")) and p.name != ".build-key"
            and ".partial" not in p.name and "__pycache__" not in p.parts
            and p.relative_to(folder).parts[0] != "casadi"}


def _golden() -> dict[str, Path]:
    """Each committed module and the file it is generated from (its manifest names it): a bundled spec
    in an app's robots/, or a file of examples/."""
    origins = {}
    for name in committed_modules():
        source = json.loads((GENERATED / name / "manifest.json").read_text()).get("source", "")
        found = [path for path in BUNDLED.values() if path.name == source]
        origins[name] = found[0] if found else REPO / "examples" / f"{name}.py"
    return origins


GOLDEN = _golden()


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(GOLDEN))
def test_committed_module_is_what_gagen_generates(name):
    """generated/<name> is, byte for byte, what this gagen generates from its spec or Python file
    (rendered again in memory, nothing compiled): no hash of gagen's own source decides it, so an
    edit that changes no output (a comment) leaves it current. GAGEN_UPDATE_GOLDEN=1 rewrites it."""
    origin, folder = GOLDEN[name], GENERATED / name
    source = load_source(origin, name if origin.suffix == ".py" else None)
    if UPDATE_GOLDEN:
        build_source(source, folder, force=True, compile_c=False, **QUIET)
    expected = {path: data for path, data in render(source).items() if not _binary(data)}
    committed = _committed(folder)
    where = origin.relative_to(REPO) if origin.is_relative_to(REPO) else origin
    hint = f"regenerate: gagen build {where} (or GAGEN_UPDATE_GOLDEN=1 for this test)"
    assert sorted(committed) == sorted(expected), f"{name}: other files than generated; {hint}"
    different = [path for path, data in expected.items() if committed[path] != data]
    assert not different, f"{name}: {', '.join(different)} differ from what gagen generates; {hint}"


def test_committed_file_names_carry_no_hash():
    """Committed file names are fixed (compiled files carry the content tag, and are not committed)."""
    for name in committed_modules():
        hashed = [path for path in _committed(GENERATED / name) if HEX.search(path)]
        assert not hashed, f"{name}: {hashed}"


def _tracked(pattern: str = "generated") -> list[str]:
    import subprocess

    try:
        listed = subprocess.run(["git", "ls-files", "-z", pattern], cwd=REPO, capture_output=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    return [path for path in listed.stdout.decode().split("\0") if path]


def test_generated_is_lean_text_and_representative():
    """generated/ in git: text files only (no NUL byte: the CasADi serialisations are rebuilt on
    demand), at most 8 MB (5 MB before the CUDA sources, 1.5 MB of them; 7 MB before the interpolation
    example, 1.25 MB), and a representative set: a
    module of every application and of each
    example file, each folder complete (every text file its manifest lists), nothing else tracked."""
    tracked = _tracked()
    binary = [path for path in tracked if _binary((REPO / path).read_bytes())]
    assert not binary, f"binary files tracked under generated/: {binary}"
    size = sum((REPO / path).stat().st_size for path in tracked)
    assert size <= 8_000_000, f"generated/ tracks {size / 1e6:.2f} MB (at most 8 MB)"
    names = committed_modules()
    apps = {json.loads((GENERATED / n / "manifest.json").read_text()).get("app", "cooperative")
            for n in names if BUNDLED.get(n, Path()).suffix == ".yaml"}
    assert apps >= {"cooperative", "hexapod", "linkage", "stereo"}, apps
    assert {p.stem for p in (REPO / "examples").glob("*.py")} <= set(names)
    expected = {"generated/README.md"}
    for name in names:
        manifest = json.loads((GENERATED / name / "manifest.json").read_text())
        expected |= {f"generated/{name}/manifest.json"} | {
            f"generated/{name}/{path}" for path in manifest["files"] if not path.startswith("casadi/")}
    assert sorted(tracked) == sorted(expected)
    readme = (GENERATED / "README.md").read_text()
    assert all(f"`{name}`" in readme for name in names), "generated/README.md names every committed module"


@pytest.mark.slow  # 12-97 s a system (test_check plants errors into panda_point's kernels in the fast tier)
@pytest.mark.parametrize("name", tiered(sorted(SYSTEMS), FAST_MODULES, pytest.mark.compiling))
def test_every_kernel_c_single_batched_and_casadi_equal_the_interpreter(name):
    """Values and closed-form Jacobians to 1e-10; the AD Jacobians to central differences (1e-6)."""
    system = SYSTEMS[name]
    report = check_module(_module(name), system, ready_configuration(system), count=3, seed=7)
    assert {d.kernel for d in report} == {k["name"] for k in _module(name).manifest["kernels"]}
    for d in report:
        tolerance = 1e-10 if d.reference == "interpreter" else 1e-6
        assert d.worst <= tolerance, d


# the bundled sources whose kernels are front-end functions and that no other test file checks (the
# hexapod's: tests/hexapod/test_contact.py; the stereo rig's: tests/stereo/test_geometry.py)
FRONT_END = sorted(name for name, path in BUNDLED.items() if path.suffix == ".py" or "linkage" in path.parts)


@pytest.mark.slow
@pytest.mark.compiling
@pytest.mark.parametrize("name", FRONT_END)
def test_every_linkage_and_example_kernel_equals_the_interpreter(name):
    """The module of each bundled linkage and example file (the committed ones, the others built into
    the gagen cache on first use): every kernel (C single, C batched, CasADi) against its function on
    the interpreter, as ``gagen build --check`` does."""
    module = _module(name)
    report = check_kernels(module, load_source(BUNDLED[name]).functions, count=3, seed=7)
    assert {d.kernel for d in report} == set(module.kernel_names)
    assert not failures(report), [d.message() for d in failures(report)]


def test_c_and_casadi_agree_to_the_vector_trig_tolerance():
    """The emitter replays CasADi's instructions in order (no FMA); only the joint angles' sines and
    cosines may come from libmvec (within 4 ulp): the results agree to 1e-14 of each output's scale.
    (Bit for bit with -DGAGEN_SCALAR_TRIG: tests/codegen/test_vector_trig.py.)"""
    module = _module("three_pandas_circle")
    rng = np.random.default_rng(3)
    for name in ("arm1_jacobians", "similarity", "task"):
        entry = next(k for k in module.manifest["kernels"] if k["name"] == name)
        inputs = [rng.uniform(-1, 1, len(p["rows"]) * p["cols"]) for p in entry["inputs"]]
        c_out = getattr(module.c, name)(*inputs)
        ca_out = getattr(module.casadi, name)(*inputs)
        for c, ref in zip(c_out, ca_out, strict=True):
            c, ref = np.ravel(c, order="F"), np.asarray(ref).ravel(order="F")
            np.testing.assert_allclose(c, ref, rtol=0, atol=1e-14 * max(1.0, np.abs(ref).max()))


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.name.endswith((".so", ".dylib"))}


@pytest.mark.compiling
def test_two_builds_are_byte_identical_and_the_second_is_cached(tmp_path):
    spec = bundled_specs()["panda_point"]
    first = build(spec, tmp_path / "a", compile_c=False, **QUIET)
    second = build(spec, tmp_path / "b", compile_c=False, **QUIET)
    assert not first.cached and _files(tmp_path / "a") == _files(tmp_path / "b")
    again = build(spec, tmp_path / "a", compile_c=False, **QUIET)
    assert again.cached and again.key == first.key == second.key
    # the key lives in .build-key, not in the module's files
    assert (tmp_path / "a" / ".build-key").read_text().strip() == first.key
    assert not any(first.key[:12] in path or first.key[:12].encode() in data
                   for path, data in _committed(tmp_path / "a").items())


@pytest.mark.compiling
def test_a_build_failing_midway_leaves_the_previous_output_untouched(tmp_path, monkeypatch):
    spec, out = bundled_specs()["panda_point"], tmp_path / "panda_point"
    build(spec, out, compile_c=False, **QUIET)
    before = _files(out)

    def fail(*args, **kwargs):
        raise RuntimeError("injected failure while writing the C source")

    monkeypatch.setattr("gagen.codegen.backends.c.printer.emit_body", fail)
    with pytest.raises(RuntimeError, match="injected"):
        build(spec, out, force=True, compile_c=False, **QUIET)
    assert _files(out) == before
    # no partial folder left (the lock file that serialises builds stays)
    assert sorted(p.name for p in tmp_path.iterdir()) == [".panda_point.lock", "panda_point"]


def test_a_malformed_spec_writes_nothing(tmp_path):
    spec = tmp_path / "bad.yaml"
    spec.write_text("name: bad\nprimitive: circle\nchains: []\n")
    with pytest.raises(SpecError):
        build(spec, tmp_path / "out", **QUIET)
    assert [p.name for p in tmp_path.iterdir()] == ["bad.yaml"]


@pytest.mark.compiling
def test_without_a_c_compiler_the_casadi_module_is_still_written(tmp_path, monkeypatch):
    monkeypatch.setenv("CC", "no-such-c-compiler")
    messages = []
    result = build(bundled_specs()["panda_point"], tmp_path / "m", progress=messages.append)
    assert not result.compiled
    assert any("no-such-c-compiler" in m and "written, not compiled" in m for m in messages)
    module = load(tmp_path / "m")
    q = np.array(ready_configuration(SYSTEMS["panda_point"]))
    reference = _module("panda_point").c.arm0_fk(q)
    for ours, ref in zip(module.casadi.arm0_fk(q), reference, strict=True):
        np.testing.assert_allclose(np.asarray(ours).ravel(), ref, atol=1e-15)


@pytest.mark.compiling
def test_check_catches_a_wrong_constant_in_the_c_source(tmp_path):
    """Scale the last link-length constant of the Panda FK kernel by 1.01 in the C source: --check
    must see it in the C rows and not in the (untouched) CasADi ones."""
    out = tmp_path / "m"
    shutil.copytree(_module("panda_point").folder, out, ignore=shutil.ignore_patterns("*.so", "*.dylib"))
    source = out / "panda_point.c"
    text = source.read_text()
    start = text.index("void panda_point_arm0_fk(")
    body = text[start:text.index("\n}\n", start)]
    constants = re.findall(r"(w\d+ = (0\.\d+);)", body)
    statement, value = constants[-1]
    wrong = body.replace(statement, statement.replace(value, repr(float(value) * 1.01)))
    source.write_text(text.replace(body, wrong))
    report = check_module(load(out), SYSTEMS["panda_point"], count=2)
    by_output = {(d.kernel, d.output): d for d in report}
    assert by_output[("arm0_fk", "P")].c_single > 1e-5
    assert by_output[("arm0_fk", "P")].c_batch > 1e-5
    assert by_output[("arm0_fk", "P")].casadi < 1e-12
    assert by_output[("arm0_fk_jacobian", "P")].c_single < 1e-12  # other kernels untouched


def test_generated_casadi_function_inside_ipopt_solves_panda_ik_to_a_pose():
    """IK to a pose with the generated FK Function in casadi.nlpsol: ‖M(q) − M*‖² from the ready pose."""
    fk = _module("panda_point").casadi.arm0_fk
    rng = np.random.default_rng(11)
    ready = np.array(ready_configuration(SYSTEMS["panda_point"]))
    target_q = ready + rng.uniform(-0.3, 0.3, 7)
    target_motor = np.asarray(fk(target_q)[0]).ravel()
    q = ca.MX.sym("q", 7)
    motor, _ = fk(q)
    problem = {"x": q, "f": ca.sumsqr(motor - target_motor)}
    solver = ca.nlpsol("ik", "ipopt", problem, {"ipopt.print_level": 0, "print_time": False,
                                                 "ipopt.tol": 1e-14})
    solution = solver(x0=ready)
    assert solver.stats()["success"]
    reached = np.asarray(fk(np.asarray(solution["x"]).ravel())[0]).ravel()
    np.testing.assert_allclose(reached, target_motor, atol=1e-7)


def test_binding_and_ctypes_paths_agree_and_bad_inputs_are_named():
    """The CPython binding (the fast path) and the ctypes fallback give the same arrays; lists and
    strided arrays are converted; a wrong size names the input."""
    from gagen.codegen.backends.c.loader import CKernel

    module = _module("three_pandas_circle")
    entry = next(k for k in module.manifest["kernels"] if k["name"] == "task")
    fast = module.c.task
    assert fast.fast is not None  # the binding compiled on this machine
    slow = CKernel(module.library, entry, binding=None)
    rng = np.random.default_rng(5)
    q, vsd = rng.uniform(-1, 1, 21), rng.uniform(-1, 1, 12)
    expected = [np.array(a) for a in slow(q, vsd)]
    strided = np.repeat(q, 2)[::2]  # not contiguous: converted on the slow path
    for args in ((q, vsd), (list(q), list(vsd)), (q.reshape(21, 1), vsd), (strided, vsd)):
        for ours, ref in zip(fast(*args), expected, strict=True):
            assert np.array_equal(ours, ref)
    with pytest.raises(ValueError, match="input q needs 21 values"):
        fast(q[:20], vsd)
    with pytest.raises(TypeError, match="takes 2 inputs"):
        fast(q)


@pytest.mark.parametrize("name", tiered(sorted(SYSTEMS), FAST_MODULES, pytest.mark.compiling))
def test_simd_batch_equals_single_calls(name):
    """The batched chain kernels run GAGEN_W samples at once (vector extensions, vector sin/cos):
    59 samples (blocks, some with the outputs of a later block prefetched, plus a scalar remainder)
    against single calls, which equal CasADi exactly."""
    module = _module(name)
    system = SYSTEMS[name]
    rng = np.random.default_rng(17)
    for chain, indices in zip(system.chains, system.chain_indices(), strict=True):
        kernel = getattr(module.c, f"{chain.name}_fk_jacobian")
        qs = rng.uniform(-2.5, 2.5, (59, len(indices)))
        batched = kernel.batch(qs)
        for i, q in enumerate(qs):
            for b, single in zip(batched, kernel(q), strict=True):
                np.testing.assert_allclose(b[i], single, rtol=0, atol=4e-15)


@pytest.mark.parametrize("name", ["panda_point", "three_pandas_circle"])
def test_column_layout_batch_equals_the_sample_major_batch(name):
    """``batch_columns`` (samples last: whole-vector loads and stores in the SIMD kernels, streaming
    stores beyond 4 MiB of output) gives the same doubles as ``batch``: for every kernel of the
    system at 59 samples (SIMD blocks plus a scalar remainder; the large kernels have no SIMD form),
    and for a Panda FK + J batch large enough to stream (10 007 samples, 4.4 MB)."""
    module = _module(name)
    rng = np.random.default_rng(23)
    cases = [(entry["name"], 59) for entry in module.manifest["kernels"]]
    if name == "panda_point":
        cases.append(("arm0_fk_jacobian", 10_007))
    for kernel_name, n in cases:
        kernel = getattr(module.c, kernel_name)
        inputs = [rng.uniform(-2.5, 2.5, (n, rows * cols)) for rows, cols in kernel._in_shapes]
        by_sample = kernel.batch(*inputs)
        by_column = kernel.batch_columns(*[a.T for a in inputs])
        if len(kernel.outputs) == 1:
            by_sample, by_column = (by_sample,), (by_column,)
        for a, b, port in zip(by_sample, by_column, kernel.outputs, strict=True):
            np.testing.assert_array_equal(np.moveaxis(b, -1, 0), a, err_msg=f"{kernel_name} {port} n={n}")
