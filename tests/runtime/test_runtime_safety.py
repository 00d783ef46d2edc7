"""Kernel calls from Python are reentrant and thread-safe (issue 12, deliverable 2), inputs follow one
set of rules on both paths (the CPython binding and the ctypes fallback), and a generated module
loads from anywhere and says when its first use compiles (deliverable 8).

Everything runs on a Panda module built into a temporary folder from the current templates (the
committed generated/ may be stale), with --no-compile: the first load compiles it.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import io
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import gagen
from gagen.apps.cooperative.bundled import bundled_specs
from gagen.build import build
from gagen.codegen.backends.c.loader import CKernel, Signature
from gagen.runtime import load


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The module built without compiling, then loaded by two threads at once (the first use: both
    wait for one compilation); returns the folder, what the loads wrote to stderr, and the module."""
    folder = tmp_path_factory.mktemp("runtime") / "panda_point"
    build(bundled_specs()["panda_point"], folder, compile_c=False, progress=lambda _: None)
    stderr, modules, errors = io.StringIO(), [], []

    def first_use():
        try:
            module = load(folder)
            assert module.c.arm0_fk.fast is not None  # compiles the library and the binding
            modules.append(module)
        except Exception as e:  # reported by the test
            errors.append(e)

    with contextlib.redirect_stderr(stderr):
        threads = [threading.Thread(target=first_use) for _ in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    return folder, stderr.getvalue(), modules, errors


@pytest.fixture(scope="module")
def module(built):
    return load(built[0])


def _paths(module, name: str) -> dict[str, object]:
    """The kernel through the binding, and the same kernel through ctypes only."""
    entry = next(k for k in module.manifest["kernels"] if k["name"] == name)
    kernel = getattr(module.c, name)
    assert kernel.fast is not None, "the CPython binding did not compile on this machine"
    return {"binding": kernel, "ctypes": CKernel(module.library, entry, binding=None)}


@pytest.mark.compiling
def test_first_use_compiles_once_and_says_so(built):
    folder, stderr, modules, errors = built
    assert not errors and len(modules) == 2
    lines = [line for line in stderr.splitlines() if line.startswith("gagen: compiling")]
    assert len(lines) == 1, stderr  # two loaders racing: one compilation, one message
    assert str(folder) in lines[0] and "first use" in lines[0]
    assert not list(folder.glob("*.partial*"))
    q = np.linspace(-1, 1, 7)
    np.testing.assert_array_equal(modules[0].c.arm0_fk(q)[1], modules[1].c.arm0_fk(q)[1])


@pytest.mark.compiling
@pytest.mark.parametrize("path", ["binding", "ctypes"])
def test_single_calls_return_fresh_arrays(module, path):
    """[k(q)[1] for q in qs] held one row for 5 different q: each call now has its own outputs."""
    kernel = _paths(module, "arm0_fk")[path]
    qs = np.random.default_rng(1).uniform(-2, 2, (5, 7))
    points = [kernel(q)[1] for q in qs]
    for q, p in zip(qs, points, strict=True):  # CasADi's, to the vector sines and cosines (test_vector_trig)
        np.testing.assert_allclose(p, np.asarray(module.casadi.arm0_fk(q)[1]).ravel(), rtol=0, atol=1e-14)
    assert len({p.tobytes() for p in points}) == 5


@pytest.mark.compiling
@pytest.mark.parametrize("path", ["binding", "ctypes"])
def test_threads_get_their_own_results(module, path):
    """4 threads x 600 calls each of single, batched and column-layout FK + J, each thread with its
    own configurations, results kept without copying: every one equals the single-threaded result
    bit for bit."""
    kernel = _paths(module, "arm0_fk_jacobian")[path]
    threads, calls, distinct = 4, 600, 16
    rng = np.random.default_rng(7)
    qs = rng.uniform(-2.5, 2.5, (threads, distinct, 7))
    batches = rng.uniform(-2.5, 2.5, (threads, distinct, 3, 7))

    def run(t: int, i: int) -> list:
        k = i % distinct
        return [kernel(qs[t, k]), kernel.batch(batches[t, k]), kernel.batch_columns(batches[t, k].T)]

    expected = {(t, k): [[a.copy() for a in r] for r in run(t, k)]
                for t in range(threads) for k in range(distinct)}
    results: dict[int, list] = {}
    barrier = threading.Barrier(threads)

    def worker(t: int) -> None:
        barrier.wait()
        results[t] = [run(t, i) for i in range(calls)]

    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads as often as possible
    try:
        pool = [threading.Thread(target=worker, args=(t,)) for t in range(threads)]
        for th in pool:
            th.start()
        for th in pool:
            th.join()
    finally:
        sys.setswitchinterval(interval)
    wrong = 0
    for t in range(threads):
        assert len(results[t]) == calls
        for i, got in enumerate(results[t]):
            for g, e in zip(got, expected[t, i % distinct], strict=True):
                wrong += not all(np.array_equal(a, b) for a, b in zip(g, e, strict=True))
    assert wrong == 0, f"{wrong} of {threads * calls * 3} results differ from the single-threaded ones"


def _outcome(f, *args, **kwargs):
    try:
        result = f(*args, **kwargs)
    except Exception as e:  # compared between the paths
        return type(e).__name__, str(e)
    return "ok", [np.array(a) for a in (result if isinstance(result, tuple) else (result,))]


Q = np.linspace(-1.2, 1.3, 7)
V = np.linspace(0.1, 1.2, 12)
INPUTS = {  # task(q, V_Sd): q is a 7-vector, V_Sd a 12-vector; expected outcome
    "float64": ((Q, V), "ok"),
    "column (7, 1)": ((Q.reshape(7, 1), V.reshape(12, 1)), "ok"),
    "row (1, 7)": ((Q.reshape(1, 7), V.reshape(1, 12)), "ok"),
    "lists": ((list(Q), list(V)), "ok"),
    "ints": ((np.arange(7), [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11]), "ok"),
    "float32": ((Q.astype(np.float32), V.astype(np.float32)), "ok"),
    "strided": ((np.repeat(Q, 2)[::2], V), "ok"),
    "big-endian": ((Q.astype(">f8"), V), "ok"),
    "(3, 4)": ((Q, V.reshape(3, 4)), "ValueError"),
    "(4, 3)": ((Q, V.reshape(4, 3)), "ValueError"),
    "(3, 4) Fortran": ((Q, np.asfortranarray(V.reshape(3, 4))), "ValueError"),
    "(7, 1, 1)": ((Q.reshape(7, 1, 1), V), "ValueError"),
    "too short": ((Q[:6], V), "ValueError"),
    "bool": ((Q > 0, V), "TypeError"),
    "complex": ((Q + 0j, V), "TypeError"),
    "str": ((["1"] * 7, V), "TypeError"),
    "object": ((Q.astype(object), V), "TypeError"),
    "long double": ((Q.astype(np.longdouble), V), "TypeError" if np.longdouble(0).itemsize > 8 else "ok"),
    "ragged": (([[1.0], [2.0, 3.0]], V), "TypeError"),
    "None": ((None, V), "TypeError"),
    "one input": ((Q,), "TypeError"),
    "three inputs": ((Q, V, V), "TypeError"),
}


@pytest.mark.compiling
@pytest.mark.parametrize("case", sorted(INPUTS))
def test_inputs_follow_the_same_rules_on_both_paths(module, case):
    """Same results (bit for bit) or the same error, type and message, on the binding and the ctypes
    path; the shape is checked, not only the size."""
    args, expected = INPUTS[case]
    paths = _paths(module, "task")
    binding, via_ctypes = (_outcome(k, *args) for k in paths.values())
    assert binding[0] == expected, binding
    if expected == "ok":
        # the documented conversion: float64 values, in order
        reference = _outcome(paths["ctypes"], *[np.asarray(a, dtype=np.float64).ravel() for a in args])
        for a, b, r in zip(binding[1], via_ctypes[1], reference[1], strict=True):
            # bit for bit (V_Sd is not a similarity, so e has NaN entries: compared as equal)
            assert np.array_equal(a, b, equal_nan=True) and np.array_equal(a, r, equal_nan=True)
            assert np.isfinite(a).any()
    else:
        assert binding == via_ctypes
        if expected == "ValueError":
            assert "input" in binding[1] and "shape" in binding[1]


def test_matrix_ports_take_their_shape_or_flat_column_major():
    """No kernel has a matrix input yet; the rule (shared by both paths) on a (3, 7) port."""
    entry = {"name": "k", "inputs": [{"name": "A", "rows": list("abc"), "cols": 7}],
             "outputs": [{"name": "y", "rows": ["x"], "cols": 1}]}
    sig = Signature(entry)
    port = sig.inputs[0]
    a = np.arange(21.0).reshape(3, 7)
    np.testing.assert_array_equal(sig.single_input(port, a), a.ravel(order="F"))
    np.testing.assert_array_equal(sig.single_input(port, a.ravel(order="F")), a.ravel(order="F"))
    with pytest.raises(ValueError, match=r"input A needs shape \(3, 7\)"):
        sig.single_input(port, a.T)
    n, (flat,) = sig.samples((np.stack([a, 2 * a]),), columns=False)
    assert n == 2 and np.array_equal(flat, [a.ravel(order="F"), 2 * a.ravel(order="F")])
    with pytest.raises(ValueError, match=r"needs shape \(n, 21\) or \(n, 3, 7\)"):
        sig.samples((np.stack([a.T, a.T]),), columns=False)


@pytest.mark.compiling
@pytest.mark.parametrize("path", ["binding", "ctypes"])
def test_batches_check_shapes(module, path):
    kernel = _paths(module, "arm0_fk")[path]
    qs = np.random.default_rng(3).uniform(-1, 1, (5, 7))
    singles = [kernel(q)[1] for q in qs]
    # the SIMD batch equals single calls to 4e-15 (vector sin/cos), see test_build
    np.testing.assert_allclose(kernel.batch(qs)[1], singles, rtol=0, atol=4e-15)
    np.testing.assert_allclose(kernel.batch_columns(qs.T)[1], np.transpose(singles), rtol=0, atol=4e-15)
    q32 = qs.astype(np.float32)
    np.testing.assert_array_equal(kernel.batch(q32)[1], kernel.batch(q32.astype(float))[1])
    with pytest.raises(ValueError, match=r"batch: input q needs shape \(n, 7\)"):
        kernel.batch(qs.T)
    with pytest.raises(ValueError, match=r"batch_columns: input q needs shape \(7, n\)"):
        kernel.batch_columns(qs)
    with pytest.raises(TypeError, match="input q"):
        kernel.batch(qs > 0)


@pytest.mark.compiling
@pytest.mark.parametrize("path", ["binding", "ctypes"])
def test_out_writes_into_caller_arrays(module, path):
    kernel = _paths(module, "arm0_fk_jacobian")[path]
    q = np.linspace(-1, 1, 7)
    fresh = kernel(q)
    out = (np.empty(8), np.empty(5), np.empty((6, 7), order="F"))
    result = kernel(q, out=out)
    assert all(r is o for r, o in zip(result, out, strict=True))
    for a, b in zip(out, fresh, strict=True):
        assert np.array_equal(a, b)
    f = kernel.bind()
    first = f(q)
    assert f(q + 0.1)[2] is first[2]  # bound: the same arrays every call
    assert np.array_equal(kernel.bind(out)(q)[2], fresh[2])


BAD_OUT = {
    "C-ordered J": lambda o: (o[0], o[1], np.empty((6, 7))),
    "float32": lambda o: (o[0], o[1].astype(np.float32), o[2]),
    "two arrays": lambda o: o[:2],
    "(8, 1)": lambda o: (o[0].reshape(8, 1), o[1], o[2]),
    "read-only": lambda o: (o[0], np.frombuffer(bytes(40)), o[2]),
    "shared": lambda o: (o[0], o[0][:5], o[2]),
}


@pytest.mark.compiling
@pytest.mark.parametrize("case", sorted(BAD_OUT))
def test_bad_out_arrays_give_the_same_error_on_both_paths(module, case):
    paths = _paths(module, "arm0_fk_jacobian")
    q = np.linspace(-1, 1, 7)
    out = BAD_OUT[case]((np.empty(8), np.empty(5), np.empty((6, 7), order="F")))
    outcomes = [_outcome(k, q, out=out) for k in paths.values()]
    assert outcomes[0][0] in ("TypeError", "ValueError") and "out" in outcomes[0][1], outcomes[0]
    assert outcomes[0] == outcomes[1]


@pytest.mark.compiling
def test_an_out_array_overlapping_the_input_is_refused(module):
    for kernel in _paths(module, "arm0_fk").values():
        buffer = np.zeros(13)
        with pytest.raises(ValueError, match="out array for M overlaps input q"):
            kernel(buffer[:7], out=(buffer[:8], np.empty(5)))


@pytest.mark.compiling
def test_load_from_any_directory_and_a_clear_error(built, tmp_path, monkeypatch):
    folder = built[0]
    monkeypatch.chdir(folder.parent.parent)
    module = gagen.load(Path(folder.parent.name) / folder.name)  # relative to the cwd of the call
    monkeypatch.chdir(tmp_path)
    assert module.folder == folder.resolve()
    assert module.c.arm0_fk(np.zeros(7))[0].shape == (8,)
    with pytest.raises(FileNotFoundError, match=f"{tmp_path}.*manifest.json"):
        gagen.load(tmp_path)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        gagen.load(tmp_path / "nothing")


@pytest.mark.compiling
def test_the_output_folder_is_importable(built, monkeypatch):
    folder = built[0]
    spec = importlib.util.spec_from_file_location("panda_point_by_path", folder / "__init__.py",
                                                  submodule_search_locations=[str(folder)])
    by_path = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(by_path)
    monkeypatch.syspath_prepend(str(folder.parent))
    monkeypatch.delitem(sys.modules, folder.name, raising=False)
    by_name = importlib.import_module(folder.name)
    q = np.linspace(0, 1, 7)
    np.testing.assert_array_equal(by_path.c.arm0_fk(q)[0], by_name.c.arm0_fk(q)[0])
    sys.modules.pop(folder.name, None)


def test_import_gagen_stays_cheap():
    """gagen.load is there without importing numpy, casadi or the runtime."""
    code = ("import sys, gagen; assert callable(gagen.load); "
            "print(sorted({'numpy', 'casadi', 'gagen.runtime'} & set(sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
