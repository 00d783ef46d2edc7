"""The single-call C kernels take the sines and cosines of their joint angles in one vector call
(glibc's libmvec, where gagen finds it) [issue 19, item 2]: the same kernel source compiled with
``-DGAGEN_SCALAR_TRIG`` (libm's sin and cos, CasADi's doubles) is the reference.

Stated tolerance: every output entry of a vector-trig call is within
``TOLERANCE * max(1, max |output|)`` of the scalar call's, on 10 000 configurations of which a fifth
have large angles (|q| up to 1e4 rad, a few up to 1e6), where libmvec switches to its slow path.
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from conftest import bundled_module

from gagen.codegen.compiler import compile_shared, library_name, vector_math
from gagen.runtime import load

TOLERANCE = 1e-14
SAMPLES = 10_000


def _configurations(dof: int, rng: np.random.Generator) -> np.ndarray:
    """(SAMPLES, dof): four fifths in ±π, the rest large, some very large."""
    q = rng.uniform(-np.pi, np.pi, (SAMPLES, dof))
    large = rng.random(SAMPLES) < 0.2
    q[large] = rng.uniform(-1e4, 1e4, (int(large.sum()), dof))
    q[:20] = rng.uniform(-1e6, 1e6, (20, dof))
    return q


def _targets(module, rng: np.random.Generator) -> np.ndarray:
    """(SAMPLES, 8) similarities V_Sc of the system at random configurations."""
    q = rng.uniform(-np.pi, np.pi, (SAMPLES, module.manifest["dof"]))
    return np.asarray(module.c.similarity.batch(q)[0]).reshape(SAMPLES, -1)


def _libraries(folder: Path, name: str, tmp_path: Path) -> tuple[ctypes.CDLL, ctypes.CDLL]:
    """The module's C compiled twice: as gagen compiles it, and with libm's sine and cosine."""
    libraries = []
    for tag, defines in (("vector", ()), ("scalar", ("GAGEN_SCALAR_TRIG",))):
        target = tmp_path / library_name(f"{name}_{tag}")
        compile_shared(folder / f"{name}.c", target, defines)
        libraries.append(ctypes.CDLL(str(target)))
    return libraries[0], libraries[1]


def _columns(library: ctypes.CDLL, c_name: str, inputs: list[np.ndarray],
             sizes: list[int]) -> list[np.ndarray]:
    """``<c_name>_columns_from(0, n, n, …)``: one single call per sample, in the column layout."""
    n = inputs[0].shape[1]
    outputs = [np.zeros((size, n)) for size in sizes]
    arrays = [np.ascontiguousarray(a) for a in inputs] + outputs
    function = getattr(library, f"{c_name}_columns_from")
    function.restype = None
    function(ctypes.c_long(0), ctypes.c_long(n), ctypes.c_long(n),
             *[a.ctypes.data_as(ctypes.POINTER(ctypes.c_double)) for a in arrays])
    return outputs


def _compare(folder: Path, kernels: list[str], tmp_path: Path) -> int:
    """Vector-trig calls against scalar ones for these kernels of the module in ``folder``, and the
    scalar ones against the CasADi Functions bit for bit (on the first 50 samples); returns how many
    output entries of the two builds differ at all (0 where the platform has no libmvec)."""
    module = load(folder)
    name = module.manifest["module"]
    vector, scalar = _libraries(folder, name, tmp_path)
    rng = np.random.default_rng(19)
    differing = 0
    for entry in module.manifest["kernels"]:
        if entry["name"] not in kernels:
            continue
        c_name = f"{name}_{entry['name']}"
        # the joint angles, rates of moderate size, and targets that are similarities (V_Sc elsewhere)
        inputs = [(_configurations(len(p["rows"]) * p["cols"], rng) if p["name"] == "q" else
                   _targets(module, rng) if p["name"] == "V_Sd" else
                   rng.uniform(-1, 1, (SAMPLES, len(p["rows"]) * p["cols"]))).T for p in entry["inputs"]]
        sizes = [len(p["rows"]) * p["cols"] for p in entry["outputs"]]
        function = getattr(module.casadi, entry["name"])
        exact = [[np.asarray(o).ravel(order="F") for o in function(*[a[:, s] for a in inputs])]
                 for s in range(50)]
        for o, (port, a, b) in enumerate(zip(entry["outputs"], _columns(vector, c_name, inputs, sizes),
                                             _columns(scalar, c_name, inputs, sizes), strict=True)):
            np.testing.assert_array_equal(b[:, :50].T, np.stack([e[o] for e in exact]))
            np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
            a, b = np.nan_to_num(a), np.nan_to_num(b)
            scale = np.maximum(1.0, np.abs(b).max(axis=0))
            error = (np.abs(a - b) / scale).max()
            assert error <= TOLERANCE, f"{entry['name']} {port['name']}: {error:.2e} of its scale"
            differing += int((a != b).sum())
    return differing


@pytest.mark.compiling
def test_panda_kernels_with_vector_trig_equal_the_scalar_ones(tmp_path):
    module = bundled_module("panda_point")
    kernels = [entry["name"] for entry in module.manifest["kernels"]]
    differing = _compare(module.folder, kernels, tmp_path)
    if vector_math():  # libmvec is in use: the test must see its doubles, not libm's again
        assert differing > 0


@pytest.mark.compiling
@pytest.mark.slow
def test_three_panda_similarity_with_vector_trig_equals_the_scalar_one(tmp_path):
    _compare(bundled_module("three_pandas_circle").folder, ["similarity", "task"], tmp_path)


@pytest.mark.compiling
def test_scalar_trig_gives_casadis_doubles_and_angles_of_any_form_are_batched(tmp_path):
    """A kernel whose angles are the inputs, a product, a square root and a sine (the last one is not
    batched: it depends on another sine): the scalar build gives CasADi's doubles exactly, the vector
    build the same within the tolerance, and both the closed form."""
    from gagen.codegen.backends.base import Context
    from gagen.codegen.backends.c import BACKEND as C
    from gagen.codegen.backends.c.printer import emit_body
    from gagen.codegen.ir import ModuleSource, Port, make_kernel

    x = ca.SX.sym("x", 4)
    r = ca.sqrt(x[0] * x[0] + x[1] * x[1])
    y = ca.vertcat(ca.sin(x[0]) * ca.cos(x[1]), ca.sin(r) + ca.cos(0.5 * x[2]), ca.cos(ca.sin(x[3])),
                   ca.sin(x[3]) * ca.cos(x[0]))
    kernel = make_kernel("f", "angles of every form", [(Port("x", ("a", "b", "c", "d")), x)],
                         [(Port("y", ("0", "1", "2", "3")), y)])
    function = kernel.function
    body = emit_body(function, ["in_x"], ["out_y"])
    assert body.trig and body.trig[-1].startswith("gagen_sincos(5,")  # x0, x1, r, x2 / 2, x3
    source = ModuleSource("trig", "a test module", {"f": kernel}, "test", "0" * 16)
    variables = {"name": "trig", "title": "a test module", "version": "test", "source_name": "test",
                 "source_hash": "0" * 16, "rebuild": ""}
    for path, data in C.render(source, Context(variables, lambda _: None)).files.items():
        (tmp_path / path).write_bytes(data)
    libraries = []
    for tag, defines in (("vector", ()), ("scalar", ("GAGEN_SCALAR_TRIG",))):
        target = tmp_path / library_name(f"trig_{tag}")
        compile_shared(tmp_path / "trig.c", target, defines)
        libraries.append(ctypes.CDLL(str(target)))
    rng = np.random.default_rng(7)
    pointer = ctypes.POINTER(ctypes.c_double)
    for _ in range(200):
        xs = rng.uniform(-50, 50, 4)
        expected = np.array([np.sin(xs[0]) * np.cos(xs[1]),
                             np.sin(np.hypot(xs[0], xs[1])) + np.cos(0.5 * xs[2]),
                             np.cos(np.sin(xs[3])), np.sin(xs[3]) * np.cos(xs[0])])
        outs = []
        for library in libraries:
            out = np.zeros(4)
            library.trig_f(xs.ctypes.data_as(pointer), out.ctypes.data_as(pointer))
            outs.append(out)
        np.testing.assert_array_equal(outs[1], np.asarray(function(xs)).ravel())
        np.testing.assert_allclose(outs[0], outs[1], rtol=0, atol=TOLERANCE)
        np.testing.assert_allclose(outs[1], expected, rtol=0, atol=1e-13)
