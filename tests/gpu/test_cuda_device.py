"""On a machine with an NVIDIA GPU and CuPy (``pip install 'gagen[cuda]'``; skipped elsewhere):
``module.cuda`` on the device against the C kernels, float64 to 1e-14 and float32 to 1e-5 of each
output's scale, on the committed cooperative modules; the outputs hand over to PyTorch by DLPack. The
same checks on every committed module, without CasADi on the GPU machine: benchmarks/cuda_gpu.py."""

from __future__ import annotations

import numpy as np
import pytest

cupy = pytest.importorskip("cupy")
try:
    if cupy.cuda.runtime.getDeviceCount() < 1:
        pytest.skip("no CUDA device", allow_module_level=True)
except cupy.cuda.runtime.CUDARuntimeError as e:  # no driver
    pytest.skip(f"no CUDA device ({e})", allow_module_level=True)

from gagen.apps.cooperative.bundled import system_module  # noqa: E402 -- after the skip


def _relative(got, want) -> float:
    return float(np.abs(got - want).max()) / max(1.0, float(np.abs(want).max()))


@pytest.mark.parametrize("name", ["panda_point", "three_pandas_circle"])
def test_every_kernel_on_the_device_equals_the_c_kernels(name):
    module = system_module(name)
    rng = np.random.default_rng(0)
    n = 1000
    for entry in module.manifest["kernels"]:
        kernel = entry["name"]
        inputs = []
        for port in entry["inputs"]:
            if port["name"] == "V_Sd":
                q = rng.uniform(-1, 1, (module.manifest["dof"], n))
                inputs.append(np.ascontiguousarray(module.c.similarity.batch_columns(q)[0]))
            else:
                inputs.append(rng.uniform(-1.2, 1.2, (len(port["rows"]) * port["cols"], n)))
        want = getattr(module.c, kernel).batch_columns(*inputs)
        want = want if isinstance(want, tuple) else (want,)
        for dtype, tolerance in ((np.float64, 1e-14), (np.float32, 1e-5)):
            got = getattr(module.cuda, kernel)(*(cupy.asarray(a, dtype=dtype) for a in inputs))
            got = got if isinstance(got, tuple) else (got,)
            for g, w in zip(got, want, strict=True):
                assert g.dtype == dtype and g.shape == w.shape
                assert _relative(cupy.asnumpy(g).astype(float), w) <= tolerance, (kernel, dtype)


def test_outputs_hand_over_to_torch_by_dlpack():
    torch = pytest.importorskip("torch")
    module = system_module("panda_point")
    q = cupy.asarray(np.random.default_rng(1).uniform(-1, 1, (7, 64)))
    _, P, J = module.cuda.arm0_fk_jacobian(q)
    assert torch.from_dlpack(J).shape == (6, 7, 64)
    assert np.array_equal(torch.from_dlpack(P).cpu().numpy(), cupy.asnumpy(P))
