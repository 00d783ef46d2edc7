"""The CUDA backend without a GPU (``gagen.codegen.backends.cuda``).

- The committed modules' ``.cu`` (every application and the example file) compile with nvcc (the
  ``nvidia-cuda-nvcc`` wheel of the test extra, or the machine's) for sm_90, warnings as errors, and
  with NVRTC; every bundled module's compiles as host C++.
- Compiled as host C++, the same per-sample bodies (the ``*_host_f64`` loops) are the C kernels' to
  1e-14 and pass ``gagen build --check``'s comparison with the interpreter in place of the C kernels;
  the float32 instance is within float precision of them.
- The launcher (``loader.CudaKernel``: shapes, layouts, precision, grid) runs its kernels through a host
  stand-in for CuPy whose "device functions" are the host loops.
- Constants beyond float's range stay guards in float32; a user's port names that are CUDA or C++
  names compile.

On a GPU, ``tests/gpu`` holds the device results to the C kernels (skipped elsewhere).
"""

from __future__ import annotations

import json
import types
from pathlib import Path

import numpy as np
import pytest
from conftest import BACKEND_MODULES, BUNDLED, bundled_module, committed_modules, tiered

import gagen
from gagen.apps.cooperative.bundled import system_module
from gagen.codegen.backends.cuda import loader
from gagen.codegen.backends.cuda.toolchain import HostKernel, compile_device, compile_host, host_kernels
from gagen.codegen.compiler import CompilerNotFound

RTOL = 1e-14


def _nvcc_or_skip() -> None:
    from gagen.codegen.backends.cuda.toolchain import find_nvcc

    try:
        find_nvcc()
    except CompilerNotFound as e:
        pytest.skip(str(e))


def _cu(module) -> Path:
    return module.folder / module.manifest["cuda_source"]


def _inputs(module, entry, n: int, rng: np.random.Generator) -> list[np.ndarray]:
    """(n, size) inputs: V_Sd a unit similarity (the module's own V_Sc elsewhere), the rest uniform."""
    arrays = []
    for port in entry["inputs"]:
        size = len(port["rows"]) * port.get("cols", 1)
        if port["name"] == "V_Sd" and "dof" in module.manifest:
            q = rng.uniform(-1, 1, (n, module.manifest["dof"]))
            arrays.append(np.asarray(module.c.similarity.batch(q)[0]).reshape(n, size))
        else:
            arrays.append(rng.uniform(-1.2, 1.2, (n, size)))
    return arrays


def _close(got, want, rtol: float, what: str) -> None:
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    assert got.shape == want.shape, what
    finite = np.isfinite(want)
    assert np.array_equal(finite, np.isfinite(got)), f"{what}: NaN/inf in other places"
    scale = max(1.0, float(np.abs(want[finite]).max(initial=0.0)))
    error = float(np.abs(got[finite] - want[finite]).max(initial=0.0))
    assert error <= rtol * scale, f"{what}: {error:.3g} > {rtol:g} x {scale:.3g}"


def _hosts(module, tmp_path: Path, float32: bool = True
           ) -> tuple[types.SimpleNamespace, types.SimpleNamespace | None]:
    """The float64 and (``float32``) float32 host loops of the module's .cu, compiled once."""
    library = tmp_path / f"lib{module.manifest['module']}_cuda_host.so"
    host64 = host_kernels(_cu(module), library, module.manifest, "f64", float32=float32)
    return host64, host_kernels(None, library, module.manifest, "f32") if float32 else None


def _against_c(module, tmp_path: Path, n: int = 40, float32: bool = True) -> None:
    """Every kernel's host loop (float64) on n samples: the same doubles as the CasADi Function (the C
    printer replays its instructions in its order, libm's trigonometry, no contraction: what the C
    kernels give with -DGAGEN_SCALAR_TRIG), and within 1e-14 of the default C batch (glibc's vector sine
    and cosine, within 4 ulp); float32 finite where float64 is moderate."""
    host64, host32 = _hosts(module, tmp_path)
    rng = np.random.default_rng(7)
    for entry in module.manifest["kernels"]:
        name = entry["name"]
        inputs = _inputs(module, entry, n, rng)
        got = getattr(host64, name).batch(*inputs)
        got = got if isinstance(got, tuple) else (got,)
        function = getattr(module.casadi, name)
        for s in range(n):
            want = function(*(a[s] for a in inputs))
            want = want if isinstance(want, tuple) else (want,)
            for g, w, port in zip(got, want, entry["outputs"], strict=True):
                w = w.full().reshape(g[s].shape)
                assert np.array_equal(g[s], w, equal_nan=True), \
                    f"{module.manifest['module']}.{name}.{port['name']} sample {s}"
        single = getattr(host64, name)(*(a[0] for a in inputs))
        single = single if isinstance(single, tuple) else (single,)
        for g, w in zip(single, got, strict=True):
            assert np.array_equal(np.reshape(g, np.shape(w[0])), w[0], equal_nan=True), f"{name} one sample"
        if module.manifest["module"] in ("panda_point", "three_pandas_circle"):  # well-conditioned kernels
            batch = getattr(module.c, name).batch(*inputs)
            for g, w, port in zip(got, batch if isinstance(batch, tuple) else (batch,), entry["outputs"],
                                  strict=True):
                _close(g, w, RTOL, f"{name}.{port['name']} against the C batch")
        if host32 is None:
            continue
        got32 = getattr(host32, name).batch(*inputs)
        got32 = got32 if isinstance(got32, tuple) else (got32,)
        for g, w, port in zip(got32, got, entry["outputs"], strict=True):
            ok = np.isfinite(w) & (np.abs(w) < 1e6)  # float32 near a singularity is not float64
            assert np.isfinite(g[ok]).all(), f"{name}.{port['name']} float32 not finite"


def test_panda_point_host_bodies_equal_the_c_kernels(tmp_path):
    _against_c(system_module("panda_point"), tmp_path)


def test_host_bodies_pass_the_interpreter_check(tmp_path):
    """``gagen build --check`` of panda_point with the host loops in the place of the C kernels: every
    output against the interpreter on the spec's configurations and random ones (1e-10 relative)."""
    from gagen.apps.cooperative.check import check_module
    from gagen.check import failures
    from gagen.robots.spec import load_system

    module = system_module("panda_point")
    standin = types.SimpleNamespace(manifest=module.manifest, c=_hosts(module, tmp_path)[0],
                                    casadi=module.casadi)
    system, configurations = load_system(BUNDLED["panda_point"])
    report = check_module(standin, system, configurations, count=4)
    assert report and not failures(report), [d.message() for d in failures(report)]


def test_float32_tracks_float64_on_the_flange(tmp_path):
    """float32 FK + Jacobian of the Panda within 1e-5 relative of float64 (the issue's acceptance for the
    device's float32 results)."""
    module = system_module("panda_point")
    host64, host32 = _hosts(module, tmp_path)
    q = np.random.default_rng(3).uniform(-2.5, 2.5, (1000, 7))
    for a, b in zip(host32.arm0_fk_jacobian.batch(q), host64.arm0_fk_jacobian.batch(q), strict=True):
        assert np.abs(a - b).max() <= 1e-5 * max(1.0, np.abs(b).max())


@pytest.mark.compiling
@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(set(BACKEND_MODULES) - {"panda_point"}))
def test_every_bundled_module_host_bodies_equal_the_c_kernels(name, tmp_path):
    """Every representative bundled module (``BACKEND_MODULES``): the host bodies equal the C kernels."""
    _against_c(bundled_module(name), tmp_path, n=8, float32=False)  # (float32: panda_point's test)


@pytest.mark.parametrize("name", tiered(sorted(committed_modules()), {"panda_point"}, pytest.mark.compiling,
                                        pytest.mark.slow))
def test_nvcc_compiles_every_committed_cu(name, tmp_path):
    """nvcc for sm_90, warnings as errors: to PTX (front end and NVVM) for the committed modules (every
    application, the example file; the other bundled modules' bodies differ only in their statements,
    which the host compiler checks for every one), and panda_point through ptxas into a cubin too."""
    _nvcc_or_skip()
    source = _cu(bundled_module(name))
    compile_device(source, tmp_path / f"{name}.ptx", ptx=True)
    assert b".entry" in (tmp_path / f"{name}.ptx").read_bytes()
    if name == "panda_point":
        compile_device(source, tmp_path / f"{name}.cubin")
        assert (tmp_path / f"{name}.cubin").stat().st_size > 0


@pytest.mark.parametrize("name", tiered(sorted(committed_modules()), {"panda_point"}, pytest.mark.compiling,
                                        pytest.mark.slow))
def test_nvrtc_compiles_every_committed_cu(name):
    """NVRTC, the compiler ``module.cuda`` uses on the GPU machine (through CuPy), with the loader's own
    options: a cubin for panda_point, PTX for the other committed modules. NVRTC has no libc headers,
    so this is what checks the source's NVRTC branch (its NAN and INFINITY, no host loops)."""
    from gagen.codegen.backends.cuda.toolchain import compile_nvrtc

    try:
        code = compile_nvrtc(_cu(bundled_module(name)).read_text(), name, ptx=name != "panda_point")
    except CompilerNotFound as e:
        pytest.skip(str(e))
    assert (b".entry" in code) if name != "panda_point" else code.startswith(b"\x7fELF")


def test_the_committed_cu_files_are_the_rendered_ones():
    """What the build renders now is what generated/ holds (the generic committed-output test covers the
    bytes; this names the .cu files, so that a module committed without its .cu fails here)."""
    for name in committed_modules():
        folder = Path(__file__).resolve().parents[2] / "generated" / name
        manifest = json.loads((folder / "manifest.json").read_text())
        assert "cuda" in manifest["backends"] and (folder / manifest["cuda_source"]).is_file(), name


# -- the launcher, through a host stand-in for CuPy -----------------------------------------------------

class _HostFunction:
    """A "device function": the host loop of the same kernel, called as CuPy calls a RawKernel."""

    def __init__(self, kernel: HostKernel) -> None:
        self.kernel = kernel
        self.launches: list[tuple[tuple[int, ...], tuple[int, ...]]] = []

    def __call__(self, grid, block, args) -> None:
        n, ld = int(args[0]), int(args[1])
        assert grid[0] * block[0] >= n > (grid[0] - 1) * block[0] and ld == n
        self.launches.append((grid, block))
        arrays = args[2:]
        for a in arrays:
            assert a.flags.c_contiguous and a.dtype == self.kernel.dtype
        outs = self.kernel.columns(*arrays[:len(self.kernel.inputs)])
        for target, value in zip(arrays[len(self.kernel.inputs):], outs, strict=True):
            target[...] = value


def _standin(module, tmp_path: Path):
    """``CudaKernel``s over a raw module whose functions are the host loops, with numpy as CuPy."""
    library = tmp_path / "libstandin.so"
    compile_host(_cu(module), library)
    import ctypes

    loaded = ctypes.CDLL(str(library))
    entries = {e["cuda_name"]: e for e in module.manifest["kernels"]}
    functions: dict[str, _HostFunction] = {}

    class Raw:
        def get_function(self, symbol: str) -> _HostFunction:
            stem, precision = symbol.rsplit("_cuda_", 1)
            return functions.setdefault(symbol, _HostFunction(HostKernel(loaded, entries[stem], precision)))

    return {e["name"]: loader.CudaKernel(Raw(), e) for e in module.manifest["kernels"]}, functions


@pytest.fixture
def numpy_as_cupy(monkeypatch):
    monkeypatch.setattr(loader, "import_cupy", lambda: np)


def test_launcher_layouts_precisions_and_errors(tmp_path, numpy_as_cupy):
    module = system_module("panda_point")
    kernels, functions = _standin(module, tmp_path)
    rng = np.random.default_rng(5)
    n = 300  # three blocks of 128, the last partial
    q = rng.uniform(-2, 2, (7, n))
    motors, points = kernels["arm0_fk"](q)
    want_m, want_p = module.c.arm0_fk.batch_columns(q)
    _close(motors, want_m, RTOL, "arm0_fk M")
    _close(points, want_p, RTOL, "arm0_fk P")
    assert functions["panda_point_arm0_fk_cuda_f64"].launches == [((3,), (128,))]
    # a matrix output comes back (rows, cols, n): the C batch_columns layout
    last = len(kernels["arm0_fk_jacobian"].outputs) - 1
    assert kernels["arm0_fk_jacobian"].outputs[last].cols == 7
    jacobian = kernels["arm0_fk_jacobian"](q)[last]
    _close(jacobian, module.c.arm0_fk_jacobian.batch_columns(q)[last], RTOL, "J")
    assert jacobian.shape[-1] == n and jacobian.ndim == 3
    # float32 in, the f32 kernel and float32 out
    m32 = kernels["arm0_fk"](q.astype(np.float32))[0]
    assert m32.dtype == np.float32 and "panda_point_arm0_fk_cuda_f32" in functions
    assert np.abs(m32 - want_m).max() < 1e-5
    # a non-contiguous view is made contiguous, not misread
    wide = rng.uniform(-2, 2, (7, 2 * n))
    _close(kernels["arm0_fk"](wide[:, ::2])[0], module.c.arm0_fk.batch_columns(wide[:, ::2])[0], RTOL,
           "strided input")
    # V_Sd and q of the task kernel: two inputs, one sample count
    q21 = rng.uniform(-1, 1, (module.manifest["dof"], 5))
    v = np.ascontiguousarray(module.c.similarity.batch_columns(q21)[0])
    task = kernels["task"](q21, v)
    want = module.c.task.batch_columns(q21, v)
    for got, expected in zip(task, want, strict=True):
        _close(got, expected, RTOL, "task")
    with pytest.raises(ValueError, match=r"input q needs shape \(7, n\)"):
        kernels["arm0_fk"](q.T)
    with pytest.raises(TypeError, match="mix float32 and float64"):
        kernels["task"](q21, v.astype(np.float32))
    with pytest.raises(TypeError, match="float64 or float32"):
        kernels["arm0_fk"](q.astype(np.int64))
    with pytest.raises(TypeError, match="takes 1 inputs"):
        kernels["arm0_fk"](q, q)
    empty = kernels["arm0_fk"](np.zeros((7, 0)))
    assert empty[0].shape == (8, 0)


def test_without_cupy_one_line_naming_the_extra(monkeypatch):
    import builtins

    real = builtins.__import__

    def no_cupy(name, *args, **kwargs):
        if name == "cupy":
            raise ImportError("No module named 'cupy'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_cupy)
    with pytest.raises(ImportError, match=r"gagen\[cuda\]") as info:
        system_module("panda_point").cuda.arm0_fk(np.zeros((7, 1)))
    assert "\n" not in str(info.value)


# -- what the dialect changes ------------------------------------------------------------------------

FORMULA = '''
import gagen
from gagen.kinds import point, scalar


@gagen.kernel(algebra="cga3d")
def threadIdx(T: point, blockIdx: point, gagen_ld: scalar):
    """names that are CUDA's and the template's own"""
    return {"sincos": (T ^ blockIdx) * gagen_ld}


@gagen.kernel(algebra="cga3d")
def guards(X: point):
    """a double guard beyond float's range"""
    m = X.math
    s = X.sp(X)
    return {"y": s / (s * s + 1e-300) + m.sin(s) * m.cos(s)}
'''


@pytest.mark.compiling
def test_cuda_and_template_names_as_ports_and_tiny_guards(tmp_path):
    """Ports named T, blockIdx and gagen_ld and a kernel named threadIdx compile (host and nvcc); the
    guard x / (x² + 1e-300) stays finite at x = 0 in float32 (1e-300 becomes float's smallest normal,
    not 0)."""
    from gagen.build import build

    spec = tmp_path / "names.py"
    spec.write_text(FORMULA)
    module = gagen.load(build(spec, tmp_path / "names").folder)
    host64, host32 = _hosts(module, tmp_path)
    rng = np.random.default_rng(1)
    args = [rng.uniform(-1, 1, (6, len(p["rows"]))) for p in module.manifest["kernels"][0]["inputs"]]
    _close(host64.threadIdx.batch(*args), module.c.threadIdx.batch(*args), RTOL, "threadIdx")
    x = np.zeros((3, 5))
    x[1, 1], x[2, 2] = 0.5, -2.0
    assert np.isfinite(host32.guards.batch(x)).all()
    _close(host64.guards.batch(x), module.c.guards.batch(x), RTOL, "guards")
    _nvcc_or_skip()
    compile_device(_cu(module), tmp_path / "names.ptx", ptx=True)
