"""The jax backend (``gagen.codegen.backends.jax``): ``<name>_jax.py`` rendered without jax and byte for
byte the same twice, hostile labels kept in comments and docstrings, the C kernels' calling convention
(shapes in and out), a modified file refused before it runs, a module without jax still loading
(its other kernels working, ``module.jax`` saying what to install); and, on modules built here, the
JAX kernels equal to the C kernels (1e-12 relative, entry by entry) for a cooperative system and the
user kernels of examples/formulas.py, with ``jax.jacfwd`` of a JAX kernel equal to the generated
Jacobian kernel."""

from __future__ import annotations

import ast
import hashlib
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from conftest import BACKEND_MODULES, bundled_module, tiered

from gagen.build import build_source, load_source, render
from gagen.codegen.backends import BACKENDS
from gagen.codegen.backends.jax import ModifiedFile
from gagen.codegen.ir import ModuleSource, Port, make_kernel
from gagen.model.primitives import points_needed
from gagen.runtime import load

REPO = Path(__file__).resolve().parents[2]
QUIET = {"progress": lambda _: None}
RTOL = 1e-12
NO_C = ["casadi", "jax"]  # the fast tests build nothing to compile


@pytest.fixture(scope="module")
def jax():
    jax = pytest.importorskip("jax")
    jax.config.update("jax_enable_x64", True)
    return jax


def _small(name: str = "small", title: str = "a test module", doc: str = "y = A x, B = 2 A, s = sum(x)",
           kernel: str = "apply", port: str = "x", labels: tuple[str, ...] = ("a", "b", "c"),
           source_name: str = "<test>") -> ModuleSource:
    """One kernel over a vector input (3) and a matrix input (2 x 3): a vector, a matrix and a one-value
    output, so that every shape rule of the calling convention is exercised."""
    x, A = ca.SX.sym("x", 3), ca.SX.sym("A", 2, 3)
    k = make_kernel(kernel, doc, [(Port(port, labels), x), (Port("A", ("r", "s"), 3), A)],
                    [(Port("y", ("r", "s")), ca.mtimes(A, x) + ca.sin(x[0])),
                     (Port("B", ("r", "s"), 3), 2 * A), (Port("total", ("t",)), ca.sum1(x))])
    return ModuleSource(name, title, {k.name: k}, source_name, hashlib.sha256(title.encode()).hexdigest())


def _jax_file(folder: Path) -> Path:
    return folder / json.loads((folder / "manifest.json").read_text())["jax_source"]


def _close(got, expected, what: str, rtol: float = RTOL) -> None:
    expected = np.asarray(expected)
    got = np.asarray(got)
    assert got.shape == expected.shape, f"{what}: shape {got.shape}, C {expected.shape}"
    assert np.array_equal(np.isnan(got), np.isnan(expected)), f"{what}: NaN in other places"
    got, expected = np.nan_to_num(got), np.nan_to_num(expected)
    err = np.abs(got - expected) / np.maximum(1.0, np.abs(expected))
    assert float(err.max(initial=0.0)) <= rtol, f"{what}: relative error {err.max():.3g}"


def _outputs(result) -> tuple:
    return result if isinstance(result, tuple) else (result,)


def _same(module, kernel: str, inputs: list, what: str, rtol: float = RTOL) -> None:
    """module.jax.<kernel> = module.c.<kernel> on ``inputs``: as many outputs, each of the C shape."""
    got = _outputs(getattr(module.jax, kernel)(*inputs))
    expected = _outputs(getattr(module.c, kernel)(*inputs))
    assert len(got) == len(expected), what
    for g, e, port in zip(got, expected, getattr(module.c, kernel).outputs, strict=True):
        _close(g, e, f"{what} {kernel} {port}", rtol)


# systems with more chains than their primitive needs: X_c is a best fit through a closed-form 3 × 3 eigen
# solve (cos(acos(r)/3)), whose derivatives amplify XLA's and glibc's last-ulp differences in acos and cos
# (1.8e-12 measured on the LEAP hand with its palm point at a random configuration)
FITTED_RTOL = 1e-11


# -- registration and rendering -----------------------------------------------------------------------

def test_registered_last_with_a_namespace_and_no_requirement():
    backend = BACKENDS["jax"]
    assert list(BACKENDS)[-1] == "jax" and backend.namespace == "jax" and backend.requires == ()
    assert (backend.templates / "kernels.py.j2").is_file()


def test_rendering_needs_no_jax_and_is_deterministic(monkeypatch):
    """Two renders of two separately made sources: the same bytes, with jax unimportable throughout."""
    for name in [n for n in sys.modules if n == "jax" or n.startswith("jax.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "jax", None)  # import jax -> ImportError
    first, second = render(_small(), NO_C), render(_small(), NO_C)
    assert first == second
    text = first["small_jax.py"].decode("ascii")
    assert json.loads(first["manifest.json"])["files"]["small_jax.py"] == \
        hashlib.sha256(first["small_jax.py"]).hexdigest()
    assert text.startswith("# small_jax.py: a test module.\n#\n# Generated by gagen ")
    assert "Do not edit" in text and "def apply(in_x, in_A):" in text


HOSTILE = 'x"""\\\nimport os; os._exit(3)\r\x00 é """'


def test_hostile_labels_stay_in_comments_and_docstrings(jax, tmp_path):
    """A title, doc, source name and row labels that would close a docstring or start a statement,
    and kernel and port names that are the file's own module names (jnp, jax): the file is ASCII, its
    top-level statements are only its own, and the kernel computes."""
    source = _small("odd", title=HOSTILE, doc=HOSTILE, kernel="jnp", port="jnp",
                    labels=(HOSTILE, "b", "c"), source_name=HOSTILE)
    build_source(source, tmp_path / "odd", backends=NO_C, **QUIET)
    text = _jax_file(tmp_path / "odd").read_text(encoding="ascii")
    tree = ast.parse(text)
    kinds = [type(node).__name__ for node in tree.body]
    assert kinds == ["Import", "Import", "Expr", "Assign", "FunctionDef", "FunctionDef"], kinds
    assert [node.name for node in tree.body if isinstance(node, ast.FunctionDef)] == ["_Flat", "jnp"]
    assert all(line.startswith("#") for line in text.splitlines() if "os._exit" in line
               and not line.startswith("    "))
    module = load(tmp_path / "odd")
    x, A = np.array([0.3, -1.0, 2.0]), np.arange(6.0).reshape(2, 3)
    y, B, total = module.jax.jnp(x, A)
    _close(y, A @ x + np.sin(x[0]), "y")
    _close(B, 2 * A, "B")
    _close(total, [x.sum()], "total")
    assert module.casadi.jnp.name_in() == ["jnp", "A"]


def test_the_c_calling_convention(jax, tmp_path):
    """Inputs: a vector port as (n,), (n, 1) or (1, n); a matrix port as (rows, cols) or flat
    column-major; integers converted, bool and complex refused, other shapes a ValueError naming the
    input. Outputs: vectors (rows,), matrices (rows, cols), several as a tuple. jit and vmap apply."""
    build_source(_small(), tmp_path / "small", backends=NO_C, **QUIET)
    module = load(tmp_path / "small")
    apply = module.jax.apply
    rng = np.random.default_rng(0)
    x, A = rng.normal(size=3), rng.normal(size=(2, 3))
    expected = [np.asarray(o).reshape(-1) if o.shape[1] == 1 else np.asarray(o)
                for o in module.casadi.apply(x, A)]
    for xs in (x, x[:, None], x[None, :]):
        for As in (A, A.ravel(order="F")):
            got = apply(xs, As)
            assert isinstance(got, tuple) and len(got) == 3
            for g, e, what in zip(got, expected, ("y", "B", "total"), strict=True):
                _close(g, e, what)
    assert [np.shape(o) for o in apply(x, A)] == [(2,), (2, 3), (1,)]
    _close(apply([1, 2, 3], A)[0], A @ [1, 2, 3] + np.sin(1.0), "integer input")
    with pytest.raises(ValueError, match=r"apply: input A needs shape \(2, 3\)"):
        apply(x, A.T)
    with pytest.raises(ValueError, match=r"apply: input x needs 3 values"):
        apply(np.ones(4), A)
    with pytest.raises(TypeError, match="apply: input x: expected real numbers"):
        apply(np.ones(3, dtype=bool), A)
    with pytest.raises(TypeError, match="apply: input x: expected real numbers"):
        apply(np.ones(3, dtype=complex), A)
    X = rng.normal(size=(5, 3))
    ys, Bs, totals = jax.jit(jax.vmap(apply, in_axes=(0, None)))(X, A)
    assert ys.dtype == np.float64 and ys.shape == (5, 2) and Bs.shape == (5, 2, 3)
    _close(ys, X @ A.T + np.sin(X[:, :1]), "vmapped y")
    _close(totals[:, 0], X.sum(axis=1), "vmapped total")


def test_nan_and_signed_zero_as_the_c_kernels(jax, tmp_path):
    """fmin/fmax ignore a NaN operand (C's fmin, as CasADi evaluates them), sign keeps -0 and NaN,
    comparisons with NaN are false: the JAX kernel gives CasADi's numbers, NaN where it has NaN."""
    x = ca.SX.sym("x", 2)
    outputs = [ca.fmin(x[0], x[1]), ca.fmax(x[0], x[1]), ca.sign(x[0]), ca.if_else(x[0] < x[1], 1.0, 2.0),
               ca.sqrt(x[1]), ca.fabs(x[0]) * -1.0]
    k = make_kernel("edges", "NaN edges", [(Port("x", ("a", "b")), x)],
                    [(Port(f"o{i}", ("v",)), v) for i, v in enumerate(outputs)])
    source = ModuleSource("edges", "edge cases", {"edges": k}, "<test>", hashlib.sha256(b"edges").hexdigest())
    build_source(source, tmp_path / "edges", backends=NO_C, **QUIET)
    module = load(tmp_path / "edges")
    for value in ([np.nan, 1.0], [1.0, np.nan], [-0.0, -4.0], [0.0, np.inf], [-np.inf, 2.0],
                  [np.nan, np.nan]):
        expected = [float(o) for o in module.casadi.edges(value)]
        got = [float(o[0]) for o in module.jax.edges(np.array(value))]
        assert np.array_equal(got, expected, equal_nan=True), (value, got, expected)
        assert np.array_equal(np.signbit(got), np.signbit(expected)), (value, got, expected)


def test_a_modified_file_is_refused_before_it_runs(jax, tmp_path):
    folder = tmp_path / "small"
    build_source(_small(), folder, backends=NO_C, **QUIET)
    assert load(folder).jax.apply(np.ones(3), np.ones((2, 3)))[2][0] == 3.0
    marker = tmp_path / "ran"
    path = _jax_file(folder)
    path.write_text(path.read_text() + f"\nopen({str(marker)!r}, 'w').close()\n")
    module = load(folder)
    with pytest.raises(ModifiedFile, match=r"sha256 is not the one in .*manifest\.json"):
        module.jax.apply  # noqa: B018 -- the attribute access loads the file
    assert not marker.exists()
    assert module.casadi.apply(np.ones(3), np.ones((2, 3)))[2] == 3.0  # the rest of the module is fine


# a process where jax cannot be imported (as where it is not installed)
WITHOUT_JAX = textwrap.dedent("""
    import importlib.abc, json, sys

    class NoJax(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name in ("jax", "jaxlib") or name.startswith(("jax.", "jaxlib.")):
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)

    sys.meta_path.insert(0, NoJax())
    import numpy as np
    from gagen.runtime import load

    module = load(sys.argv[1])
    kernel, namespace = sys.argv[2], sys.argv[3]
    inputs = [np.linspace(0.1, 0.7, len(p["rows"]) * p["cols"]).reshape(p["cols"], len(p["rows"])).T
              for p in module.entry(kernel)["inputs"]]  # (rows, cols): what CasADi and C both take
    result = getattr(getattr(module, namespace), kernel)(*inputs)
    first = result[0] if isinstance(result, (tuple, list)) else result
    try:
        getattr(module.jax, kernel)
        error = None
    except ImportError as e:
        error = str(e)
    print(json.dumps({"value": float(np.asarray(first).ravel()[0]), "error": error,
                      "jax_loaded": any(n == "jax" or n.startswith("jax.") for n in sys.modules)}))
""")


def _without_jax(folder: Path, kernel: str, namespace: str) -> dict:
    done = subprocess.run([sys.executable, "-c", WITHOUT_JAX, str(folder), kernel, namespace],
                          capture_output=True, text=True, timeout=120, cwd=REPO)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


def test_a_module_loads_without_jax_and_says_what_to_install(tmp_path):
    folder = tmp_path / "small"
    build_source(_small(), folder, backends=NO_C, **QUIET)
    report = _without_jax(folder, "apply", "casadi")
    assert report["value"] == pytest.approx(np.linspace(0.1, 0.7, 6)[[0, 2, 4]] @ np.linspace(0.1, 0.7, 3)
                                            + np.sin(0.1), rel=1e-12)
    assert "module.jax needs the jax package" in report["error"] and "pip install jax" in report["error"]
    assert not report["jax_loaded"]


# -- bundled modules, against their C kernels ----------------------------------------------------------

@pytest.fixture(scope="module")
def panda():
    """robots/panda_point.yaml's module (every backend, compiled), built on first use."""
    return bundled_module("panda_point")


def _random_inputs(module, name: str, rng: np.random.Generator) -> list[np.ndarray]:
    """Uniform inputs in [-1.2, 1.2], but a cooperative system's V_Sd a unit similarity."""
    inputs = []
    for port in module.entry(name)["inputs"]:
        if port["name"] == "V_Sd":  # a unit similarity: the module's own V_Sc elsewhere
            inputs.append(np.asarray(module.c.similarity(rng.uniform(-1, 1, module.manifest["dof"]))[0]))
        else:
            inputs.append(rng.uniform(-1.2, 1.2, len(port["rows"]) * port["cols"]))
    return inputs


@pytest.mark.compiling
def test_cooperative_jax_kernels_are_the_c_kernels(jax, panda):
    rng = np.random.default_rng(1)
    assert panda.manifest["backends"][-1] == "jax"
    for name in panda.kernel_names:
        for _ in range(3):
            _same(panda, name, _random_inputs(panda, name, rng), "panda_point")


@pytest.mark.compiling
def test_jit_vmap_is_the_c_batch_and_jacfwd_the_generated_jacobian(jax, panda):
    rng = np.random.default_rng(2)
    Q = rng.uniform(-1.5, 1.5, (32, 7))
    motors, points = jax.jit(jax.vmap(panda.jax.arm0_fk))(Q)
    c_motors, c_points = panda.c.arm0_fk.batch(Q)
    _close(motors, c_motors, "vmapped M")
    _close(points, c_points, "vmapped P")
    names = panda.c.arm0_jacobians.outputs
    point_jacobian = jax.jit(jax.jacfwd(lambda q: panda.jax.arm0_fk(q)[1]))
    for q in Q[:4]:
        generated = panda.c.arm0_jacobians(q)[names.index("J_P")]
        _close(point_jacobian(q), generated, "jacfwd P vs J_P")


@pytest.mark.compiling
def test_a_compiled_module_without_jax_still_calls_c(panda):
    report = _without_jax(panda.folder, "arm0_fk", "c")
    assert report["value"] == pytest.approx(float(panda.c.arm0_fk(np.linspace(0.1, 0.7, 7))[0][0]), rel=1e-15)
    assert "pip install jax" in report["error"] and not report["jax_loaded"]


@pytest.mark.compiling
def test_user_kernels_jax_equals_c_and_jacfwd_the_authored_jacobian(jax):
    """examples/formulas.py: every kernel on its own samples (circle_distance also on real circles,
    through three sampled points); circle_distance's generated J_d is jax.jacfwd of its JAX d with
    respect to X."""
    module = bundled_module("formulas")
    functions = load_source(REPO / "examples" / "formulas.py").functions
    rng = np.random.default_rng(3)

    def circle_distance_inputs() -> list[np.ndarray]:  # a point, and the circle through three others
        return [functions["circle_distance"].sample(rng)[0],
                np.asarray(module.c.circle_through(*functions["circle_through"].sample(rng)))]

    for name in module.kernel_names:
        for i in range(10):
            inputs = circle_distance_inputs() if name == "circle_distance" and i % 2 else \
                functions[name].sample(rng)
            _same(module, name, inputs, "formulas")
    outputs = module.c.circle_distance.outputs
    for _ in range(5):
        X, C = circle_distance_inputs()
        assert np.all(np.isfinite(module.c.circle_distance(X, C)[outputs.index("J_d")]))  # a real circle
        jacobian = jax.jacfwd(lambda x, c=C: module.jax.circle_distance(x, c)[outputs.index("d")])(X)
        _close(np.asarray(jacobian).reshape(1, -1), module.c.circle_distance(X, C)[outputs.index("J_d")],
               "jacfwd d vs J_d")


# -- the bundled modules ------------------------------------------------------------------------------

@pytest.mark.parametrize("name", tiered(list(BACKEND_MODULES), {"panda_point"}, pytest.mark.compiling,
                                        pytest.mark.slow))
def test_every_kernel_of_every_bundled_module_is_its_c_kernel(jax, name):
    """Every representative bundled module (``BACKEND_MODULES``: every kind of graph; the committed
    generated/<name>, the others built into the gagen cache on first use): every kernel, JAX against C
    on random inputs (NaN where C has NaN); two draws for
    panda_point, one elsewhere (an eager JAX call of a large kernel dispatches every operation: the
    second draw cost 85 s of the full tier)."""
    module = bundled_module(name)
    assert "jax" in module.manifest["backends"], \
        f"{module.folder} was built before the jax backend: regenerate it (gagen build)"
    rng = np.random.default_rng(4)
    chains = sum(k.endswith("_fk") for k in module.kernel_names)
    fitted = "primitive" in module.manifest and chains > points_needed(module.manifest["primitive"])
    for kernel in module.kernel_names:
        for _ in range(2 if name == "panda_point" else 1):
            _same(module, kernel, _random_inputs(module, kernel, rng), name, FITTED_RTOL if fitted else RTOL)
