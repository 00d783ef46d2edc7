"""gagen's CUDA kernels on a GPU: device results against the C kernels, Panda FK + J and the
three-Panda circle ``task`` per second (fp64, fp32; kernel time and end to end), the GPU peers (gagen's
JAX kernels, adam-robotics' JAX, pytorch-kinematics on CUDA) and batched cooperative IK [issue 33].

    python benchmarks/cuda_gpu.py prepare .gpu          # here, with gagen: C-kernel test vectors
    python benchmarks/cuda_gpu.py device .gpu --out OUT # on the GPU machine: numpy, CuPy, JAX, torch

The device half imports no gagen package (CasADi is not needed there): it loads the committed
``generated/<module>/<module>.cu`` through ``gagen/codegen/backends/cuda/loader.py`` and the IK through
``gagen/control/batch_ik.py``, both by path. It prints markdown tables and writes ``OUT/cuda_gpu.json``.
Kernel times are CUDA-event medians over repeated launches; "end to end" adds the host → device copy
of the inputs and the device → host copy of the outputs.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import statistics
import sys
import time
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
GENERATED = REPO / "generated"
SAMPLES = 512  # test vectors per kernel


def _by_path(name: str, path: Path) -> Any:
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


# -- prepare (here, with gagen) ---------------------------------------------------------------------------

def prepare(folder: Path) -> None:
    from gagen.check import joint_limits
    from gagen.robots.spec import load_system
    from gagen.runtime import load

    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    for manifest_path in sorted(GENERATED.glob("*/manifest.json")):
        module = load(manifest_path.parent)
        arrays: dict[str, np.ndarray] = {}
        for entry in module.manifest["kernels"]:
            name, inputs = entry["name"], []
            for port in entry["inputs"]:
                size = len(port["rows"]) * port.get("cols", 1)
                if port["name"] == "V_Sd" and "dof" in module.manifest:
                    q = rng.uniform(-1, 1, (module.manifest["dof"], SAMPLES))
                    inputs.append(np.ascontiguousarray(module.c.similarity.batch_columns(q)[0]))
                else:
                    inputs.append(rng.uniform(-1.2, 1.2, (size, SAMPLES)))
            outputs = getattr(module.c, name).batch_columns(*inputs)
            outputs = outputs if isinstance(outputs, tuple) else (outputs,)
            for i, a in enumerate(inputs):
                arrays[f"{name}/in{i}"] = a
            for i, o in enumerate(outputs):
                arrays[f"{name}/out{i}"] = np.ascontiguousarray(o)  # (rows, n) or (rows, cols, n)
        np.savez_compressed(folder / f"{module.manifest['module']}.npz", **arrays)
        print(f"{module.manifest['module']}: {len(module.manifest['kernels'])} kernels", flush=True)
    system, _ = load_system(REPO / "robots" / "three_pandas_circle.yaml")
    lower, upper, _ = joint_limits(system)
    np.savez(folder / "limits.npz", lower=lower, upper=upper)


# -- device (the GPU machine: numpy, CuPy, JAX, torch; no gagen import) -----------------------------------

def _cuda_module(name: str, loader: Any, fmad: bool = True) -> dict[str, Any]:
    import os

    os.environ["GAGEN_CUDA_FMAD"] = "1" if fmad else "0"
    folder = GENERATED / name
    manifest = json.loads((folder / "manifest.json").read_text())
    raw = loader.raw_module((folder / manifest["cuda_source"]).read_text(), name)
    return {e["name"]: loader.CudaKernel(raw, e) for e in manifest["kernels"]}


def _relative(got: np.ndarray, want: np.ndarray) -> float:
    finite = np.isfinite(want) & np.isfinite(got)
    mismatch = int((np.isfinite(want) != np.isfinite(got)).sum())
    if mismatch:
        return float("inf")
    if not finite.any():
        return 0.0
    scale = max(1.0, float(np.abs(want[finite]).max()))
    return float(np.abs(got[finite] - want[finite]).max()) / scale


def check_modules(cupy: Any, loader: Any, data: Path) -> list[dict[str, Any]]:
    rows = []
    for vectors in sorted(data.glob("*.npz")):
        if vectors.stem == "limits":
            continue
        stored = np.load(vectors)
        for fmad in (True, False):
            kernels = _cuda_module(vectors.stem, loader, fmad)
            worst64 = worst32 = 0.0
            where64 = where32 = ""
            for name, kernel in kernels.items():
                inputs = [stored[f"{name}/in{i}"] for i in range(len(kernel.inputs))]
                wants = [stored[f"{name}/out{i}"] for i in range(len(kernel.outputs))]
                for dtype in (np.float64, np.float32):
                    outs = kernel(*(cupy.asarray(a.astype(dtype)) for a in inputs))
                    outs = outs if isinstance(outs, tuple) else (outs,)
                    for o, w, port in zip(outs, wants, kernel.outputs, strict=True):
                        got = cupy.asnumpy(o)
                        assert got.shape == w.shape, (name, port.name, got.shape, w.shape)
                        if dtype == np.float32:
                            ok = np.abs(w) < 1e6  # float32 near a singularity is not float64
                            error = _relative(np.where(ok, got, 0), np.where(ok, w, 0))
                            if error > worst32:
                                worst32, where32 = error, f"{name}.{port.name}"
                        else:
                            error = _relative(got, w)
                            if error > worst64:
                                worst64, where64 = error, f"{name}.{port.name}"
            rows.append({"module": vectors.stem, "fmad": fmad, "kernels": len(kernels), "f64": worst64,
                         "f64_at": where64, "f32": worst32, "f32_at": where32})
            print(f"| {vectors.stem} | {'on' if fmad else 'off'} | {len(kernels)} | "
                  f"{worst64:.2e} ({where64}) | "
                  f"{worst32:.2e} ({where32}) |", flush=True)
    return rows


def _event_time(cupy: Any, run: Any, repeats: int = 20) -> float:
    """Median seconds of one launch, by CUDA events around each of ``repeats`` launches."""
    run()
    cupy.cuda.Device().synchronize()
    times = []
    for _ in range(repeats):
        start, end = cupy.cuda.Event(), cupy.cuda.Event()
        start.record()
        run()
        end.record()
        end.synchronize()
        times.append(cupy.cuda.get_elapsed_time(start, end) / 1e3)
    return statistics.median(times)


def _wall(run: Any, repeats: int = 5) -> float:
    run()
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        run()
        times.append(time.perf_counter() - started)
    return statistics.median(times)


def _round_trip(cupy: Any, kernel: Any, staged: list[np.ndarray]) -> None:
    """Host inputs to the device, the kernel, every output back to the host."""
    outs = kernel(*(cupy.asarray(a) for a in staged))
    for o in outs if isinstance(outs, tuple) else (outs,):
        cupy.asnumpy(o)


def kernel_rates(cupy: Any, loader: Any, sizes: list[int]) -> list[dict[str, Any]]:
    rows = []
    cases = (("panda_point", "arm0_fk_jacobian", 7, "Panda FK + J (flange motor, point, 6×7 J)"),
             ("three_pandas_circle", "task", 21, "three-Panda circle task (e, J_Be 7×21)"))
    for module, name, _dof, what in cases:
        kernel = _cuda_module(module, loader)[name]
        for n in sizes:
            rng = np.random.default_rng(1)
            host = [rng.uniform(-2.5, 2.5, (p.size, n)) for p in kernel.inputs]
            if name == "task":
                host[1] = cupy.asnumpy(cupy.ascontiguousarray(
                    _cuda_module(module, loader)["similarity"](cupy.asarray(host[0]))[0]))
            for dtype, label in ((np.float64, "fp64"), (np.float32, "fp32")):
                staged = [a.astype(dtype) for a in host]
                device = [cupy.asarray(a) for a in staged]
                seconds = _event_time(cupy, partial(kernel, *device))
                total = _wall(partial(_round_trip, cupy, kernel, staged))
                rows.append({"kernel": what, "precision": label, "n": n, "kernel_s": seconds,
                             "per_second": n / seconds, "end_to_end_s": total,
                             "end_to_end_per_second": n / total})
                print(f"| {what} | {label} | {n:,} | {seconds * 1e3:.3f} ms | {n / seconds / 1e6:.1f} M/s | "
                      f"{total * 1e3:.1f} ms | {n / total / 1e6:.1f} M/s |", flush=True)
                del device
            cupy.get_default_memory_pool().free_all_blocks()
    return rows


def _gagen_twists(J_S: np.ndarray) -> np.ndarray:
    """(n, 6, 7) rows e12 e13 e23 e1∞ e2∞ e3∞ → (v, ω) (benchmarks/jax_fk.py)."""
    return np.stack([J_S[:, 3], J_S[:, 4], J_S[:, 5], J_S[:, 2], -J_S[:, 1], J_S[:, 0]], axis=1)


def peers(cupy: Any, loader: Any, n: int) -> list[dict[str, Any]]:
    """Panda FK + J per second, n configurations on the device, each peer checked against gagen CUDA."""
    import yaml

    rows: list[dict[str, Any]] = []
    kernel = _cuda_module("panda_point", loader)["arm0_fk_jacobian"]
    Q = np.random.default_rng(0).uniform(-2.8, 2.8, (n, 7))
    _, P, J = kernel(cupy.asarray(Q.T.copy()))
    P, J = cupy.asnumpy(P), cupy.asnumpy(J)
    ref_p = (P[1:4] / P[:1]).T
    ref_j = _gagen_twists(J.transpose(2, 0, 1))

    def add(name: str, seconds: float, p: np.ndarray | None, j: np.ndarray | None, note: str = "") -> None:
        error = (max(float(np.abs(p - ref_p).max()), float(np.abs(j - ref_j).max())) if p is not None
                 else float("nan"))
        rows.append({"backend": name, "n": n, "seconds": seconds, "per_second": n / seconds,
                     "vs_gagen": error,
                     "note": note})
        print(f"| {name} | {n:,} | {seconds * 1e3:.2f} ms | {n / seconds / 1e6:.2f} M/s | {error:.1e} | "
              f"{note} |",
              flush=True)

    for dtype, label in ((np.float64, "fp64"), (np.float32, "fp32")):
        q = cupy.asarray(Q.T.astype(dtype))
        _, P, J = (cupy.asnumpy(o).astype(np.float64) for o in kernel(q))
        add(f"gagen CUDA {label}", _event_time(cupy, lambda q=q: kernel(q)), (P[1:4] / P[:1]).T,
            _gagen_twists(J.transpose(2, 0, 1)), "kernel time")
    spec = yaml.safe_load((REPO / "robots" / "panda_point.yaml").read_text())
    (chain,) = spec["chains"]
    urdf = REPO / "robots" / chain["urdf"]
    joints = [f"panda_joint{i}" for i in range(1, 8)]
    try:
        import jax
        import jax.numpy as jnp

        jax.config.update("jax_enable_x64", True)
        jax_module = _by_path("panda_point_jax", GENERATED / "panda_point" / "panda_point_jax.py")
        batched = jax.jit(jax.vmap(jax_module.arm0_fk_jacobian))
        qj = jax.device_put(jnp.asarray(Q))
        out = jax.block_until_ready(batched(qj))
        _, Pj, Jj = (np.asarray(o) for o in out)
        add(f"gagen JAX jit(vmap) fp64 on {jax.devices()[0].platform}",
            _wall(lambda: jax.block_until_ready(batched(qj)), 10), Pj[:, 1:4] / Pj[:, :1], _gagen_twists(Jj))
        try:
            from adam.core.constants import Representations
            from adam.jax import KinDynComputations

            kd = KinDynComputations(str(urdf), joints)
            kd.rbdalgos.math.factory._device = None
            kd.set_frame_velocity_representation(Representations.INERTIAL_FIXED_REPRESENTATION)
            eye = jnp.eye(4)
            adam = jax.jit(jax.vmap(lambda q: (kd.forward_kinematics(chain["tip_link"], eye, q),
                                               kd.relative_jacobian(chain["tip_link"], q))))
            H, Ja = (np.asarray(o) for o in jax.block_until_ready(adam(qj)))
            add("adam-robotics JAX jit(vmap) fp64", _wall(lambda: jax.block_until_ready(adam(qj)), 10),
                H[:, :3, 3], Ja)
        except Exception as error:  # a peer that cannot run: its row says why
            rows.append({"backend": "adam-robotics",
                         "note": f"failed: {type(error).__name__}: {error}"[:200]})
            print(f"| adam-robotics | failed: {type(error).__name__}: {str(error)[:150]} |", flush=True)
    except Exception as error:
        print(f"| JAX | failed: {type(error).__name__}: {str(error)[:150]} |", flush=True)
    try:
        import pytorch_kinematics as pk
        import torch

        for dtype, label in ((torch.float64, "fp64"), (torch.float32, "fp32")):
            serial = pk.build_serial_chain_from_urdf(urdf.read_text(), chain["tip_link"], chain["base_link"])
            serial = serial.to(dtype=dtype, device="cuda")
            qt = torch.as_tensor(Q, dtype=dtype, device="cuda")

            def run(qt=qt, serial=serial) -> Any:
                with torch.no_grad():
                    out = serial.jacobian(qt, ret_eef_pose=True)
                torch.cuda.synchronize()
                return out

            Jt, Ht = (o.double().cpu().numpy() for o in run())
            p = Ht[:, :3, 3]
            v_origin, omega = Jt[:, :3], Jt[:, 3:]
            twist = np.concatenate([v_origin - np.cross(omega, p[:, :, None], axis=1), omega], axis=1)
            add(f"pytorch-kinematics CUDA {label}", _wall(run, 5), p, twist, f"torch {torch.__version__}")
        torch.cuda.empty_cache()
    except Exception as error:
        print(f"| pytorch-kinematics | failed: {type(error).__name__}: {str(error)[:150]} |", flush=True)
    return rows


def batched_ik(cupy: Any, loader: Any, data: Path, targets_counts: list[int], seeds: int,
               iterations: int) -> list[dict[str, Any]]:
    batch_ik = _by_path("gagen_batch_ik", REPO / "gagen" / "control" / "batch_ik.py")
    kernels = _cuda_module("three_pandas_circle", loader)
    limits = np.load(data / "limits.npz")
    lower, upper = cupy.asarray(limits["lower"]), cupy.asarray(limits["upper"])
    rows = []
    for T in targets_counts:
        rng = cupy.random.default_rng(2)
        m = lower.size
        q_target = lower[:, None] + (upper - lower)[:, None] * rng.random((m, T))
        targets = cupy.ascontiguousarray(kernels["similarity"](q_target)[0])
        q_seeds = lower[:, None] + (upper - lower)[:, None] * rng.random((m, seeds))
        task = kernels["task"]
        for compact in (5, 0):
            batch_ik.solve_batch(task, targets[:, :64], q_seeds, lower, upper, iterations=12, xp=cupy,
                                 compact_every=compact)  # warm-up: the element-wise kernels compile
            cupy.cuda.Device().synchronize()
            started = time.perf_counter()
            result = batch_ik.solve_batch(task, targets, q_seeds, lower, upper, iterations=iterations,
                                          xp=cupy, compact_every=compact)
            rate = result.success_rate  # synchronises
            seconds = time.perf_counter() - started
            errors = cupy.asnumpy(result.best_error)
            rows.append({"targets": T, "seeds": seeds, "iterations": iterations, "compact_every": compact,
                         "seconds": seconds, "targets_per_second": T / seconds, "success": rate,
                         "median_error": float(np.median(errors)), "max_error": float(errors.max())})
            print(f"| {T:,} | {seeds} | {iterations} | {compact or 'never'} | {seconds * 1e3:.1f} ms | "
                  f"{T / seconds:,.0f} | {rate:.2%} | {np.median(errors):.1e} | {errors.max():.1e} |",
                  flush=True)
            del result
            cupy.get_default_memory_pool().free_all_blocks()
    return rows


def interop(cupy: Any, loader: Any) -> dict[str, str]:
    """The outputs (a strided (6, 7, n) view among them) handed to PyTorch and JAX by DLPack."""
    _, P, J = _cuda_module("panda_point", loader)["arm0_fk_jacobian"](
        cupy.asarray(np.random.default_rng(3).uniform(-1, 1, (7, 256))))
    found = {}
    for name in ("torch", "jax"):
        try:
            if name == "torch":
                import torch

                to = torch.from_dlpack
                back = lambda x: x.cpu().numpy()  # noqa: E731
            else:
                import jax
                import jax.dlpack

                jax.config.update("jax_enable_x64", True)  # else JAX takes float64 as float32
                to = jax.dlpack.from_dlpack
                back = np.asarray
            same = all(np.array_equal(back(to(a)), cupy.asnumpy(a)) for a in (P, J))
            found[name] = "same values" if same else "DIFFERENT values"
        except Exception as error:
            found[name] = f"failed: {type(error).__name__}: {str(error)[:150]}"
        print(f"| DLPack to {name} | {found[name]} |", flush=True)
    return found


def device(data: Path, out: Path, quick: bool, parts: set[str]) -> None:
    import cupy

    loader = _by_path("gagen_cuda_loader", REPO / "gagen" / "codegen" / "backends" / "cuda" / "loader.py")
    properties = cupy.cuda.runtime.getDeviceProperties(0)
    card = properties["name"].decode()
    runtime = cupy.cuda.runtime.runtimeGetVersion()
    print(f"# {card}, CUDA runtime {runtime}, CuPy {cupy.__version__}\n", flush=True)
    report: dict[str, Any] = {"device": card}
    if "check" in parts:
        print("| module | FMA | kernels | fp64 vs C (relative) | fp32 vs C (relative) |\n"
              "|---|---|---:|---|---|")
        report["check"] = check_modules(cupy, loader, data)
    if "interop" in parts:
        report["interop"] = interop(cupy, loader)
    if "rates" in parts:
        sizes = [1 << 20] if quick else [1 << 20, 1 << 22]
        print("\n| kernel | precision | n | kernel time | per second | end to end | per second |\n"
              "|---|---|---:|---:|---:|---:|---:|")
        report["rates"] = kernel_rates(cupy, loader, sizes)
    if "peers" in parts:
        print("\n| Panda FK + J | n | time | per second | max dev. from gagen | note |\n"
              "|---|---:|---:|---:|---:|---|")
        report["peers"] = peers(cupy, loader, 1 << 20)
    if "ik" in parts:
        print("\n| targets | seeds | iterations | set aside every | time | targets/s | success | "
              "median ‖e‖ | max ‖e‖ |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        counts = [1000, 10000] if quick else [10000, 50000, 100000]
        report["ik"] = batched_ik(cupy, loader, data, counts, 16, 30)
    out.mkdir(parents=True, exist_ok=True)
    (out / "cuda_gpu.json").write_text(json.dumps(report, indent=1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mode", choices=("prepare", "device"))
    parser.add_argument("data", type=Path)
    parser.add_argument("--out", type=Path, default=Path("."))
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--parts", default="check,interop,rates,peers,ik",
                        help="what the device half runs (comma-separated; default all)")
    args = parser.parse_args()
    if args.mode == "prepare":
        prepare(args.data)
    else:
        device(args.data, args.out, args.quick, set(args.parts.split(",")))


if __name__ == "__main__":
    main()
