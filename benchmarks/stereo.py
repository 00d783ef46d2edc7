"""Stereo benchmarks [SMC IV]: the generated per-frame geometry kernel (``<rig>_estimate``: two image
symmetry lines and two image mass centres → the 3D symmetry axis, its conditioning and the position
reference) in C, the OpenCV detection per 640×480 image, and the whole per-frame pipeline (detection
in both images, the kernel through the CPython binding), with frames per second; markdown on stdout.

    python benchmarks/stereo.py            # ≈ 1 min
    python benchmarks/stereo.py --quick    # fewer frames and repeats

- C: benchmarks/stereo_bench.c (harness.h), linked to the committed module's C (generated/stereo_rig,
  gagen's flags): single calls over 1000 observations drawn from random well-conditioned scenes, and
  the batched kernel over the same observations; medians of the repeats.
- Python: the kernel through the binding (``k(obs)``, and ``k.fast(obs)`` with preallocated outputs);
  the detection (``vision.detect``) per image and the pipeline (``pipeline.Estimator``) per frame pair
  on rendered frames of random poses at 1 px vertex noise; the rendering itself for reference.

Not part of the test suite.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

BENCH = Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH))

import programs  # noqa: E402 -- benchmarks/ is not a package
from run import machine, table  # noqa: E402

from gagen.apps.stereo import scene, vision  # noqa: E402
from gagen.apps.stereo.calibration import load_rig  # noqa: E402
from gagen.apps.stereo.kernels import random_scene  # noqa: E402
from gagen.apps.stereo.pipeline import Estimator, FrameEstimate  # noqa: E402
from gagen.codegen.compiler import vector_math_libraries  # noqa: E402
from gagen.runtime import load  # noqa: E402

RIG = programs.ROOT / "gagen" / "apps" / "stereo" / "robots" / "stereo_rig.yaml"
MODULE = programs.GENERATED / "stereo_rig"
KERNEL_TARGET_NS = 200


def observations(n: int, seed: int = 7) -> np.ndarray:
    rig, rng = load_rig(RIG), np.random.default_rng(seed)
    return np.array([np.concatenate([s.lines, s.centres]) for s in (random_scene(rig, rng, noise=1e-3)
                                                                    for _ in range(n))])


def build_c() -> Path:
    """stereo_bench linked to the committed module's C (gagen's flags; its _simd.c at -O3)."""
    programs.BUILD.mkdir(parents=True, exist_ok=True)
    cc, name = programs.c_compiler(), "stereo_rig"
    header = MODULE / f"{name}.h"
    steps = []
    for source, flags in ((MODULE / f"{name}.c", programs.gagen_cflags()),
                          (MODULE / f"{name}_simd.c", programs.gagen_cflags("-O3"))):
        obj = programs.BUILD / f"stereo_{source.stem}.o"
        steps.append(programs.Step(obj, [*cc, *flags, f"-I{MODULE}", "-c", str(source), "-o", str(obj)],
                                   [source, header]))
    driver, obj = BENCH / "stereo_bench.c", programs.BUILD / "stereo_bench.o"
    defines = [f'-DSTEREO_HEADER="{name}.h"', f"-DSTEREO_ESTIMATE={name}_estimate"]
    command = [*cc, *programs.DRIVER_CFLAGS, *defines, f"-I{BENCH}", f"-I{MODULE}", "-c", str(driver), "-o",
               str(obj)]
    steps.append(programs.Step(obj, command, [driver, BENCH / "harness.h", header]))
    for step in steps:
        step.run(False)
    objects = [s.output for s in steps]
    program = programs.BUILD / "stereo_bench"
    programs.Step(program, [*cc, *map(str, objects), "-o", str(program), *vector_math_libraries(), "-lm"],
                  objects).run(False)
    return program


def run_c(program: Path, obs: np.ndarray, repeats: int) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "obs.bin"
        path.write_bytes(np.ascontiguousarray(obs, dtype=np.float64).tobytes())
        done = subprocess.run([str(program), str(path), str(repeats)], capture_output=True, text=True,
                              check=True)
    return json.loads(done.stdout)


def per_call(fn, args_list, repeats: int) -> float:
    """Median over ``repeats`` passes of the mean seconds per call of fn(*args) over the list."""
    for args in args_list[:3]:
        fn(*args)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for args in args_list:
            fn(*args)
        times.append((time.perf_counter() - t0) / len(args_list))
    return statistics.median(times)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer frames and repeats")
    args = ap.parse_args()
    frames, repeats, c_repeats = (10, 3, 21) if args.quick else (40, 5, 51)
    start = time.perf_counter()
    rig = load_rig(RIG)
    obs = observations(1000)
    program = build_c()
    c = [run_c(program, obs, c_repeats) for _ in range(3)]
    single = statistics.median(r["single_ns"] for r in c)
    batch = statistics.median(r["batch_ns"] for r in c)
    kernel = load(MODULE).c.estimate
    py_call = per_call(kernel, [(o,) for o in obs[:200]], repeats)
    bound = kernel.bind()  # preallocated outputs, reused by every call
    py_bound = per_call(bound, [(o,) for o in obs[:200]], repeats)

    rng = np.random.default_rng(11)
    options = scene.SceneOptions(vertex_jitter=1.0, pixel_noise=2.0)
    poses = [scene.random_pose(rig, rng) for _ in range(frames)]
    t0 = time.perf_counter()
    rendered = [scene.render(rig, p, options, k) for k, p in enumerate(poses)]
    render_s = (time.perf_counter() - t0) / frames
    estimator = Estimator(rig, load(MODULE).c)
    detect = per_call(lambda image: vision.detect(image, rig.left, rig.hsv_low, rig.hsv_high),
                      [(f.left,) for f in rendered], repeats)
    pipeline = per_call(estimator, [(f.left, f.right) for f in rendered], repeats)
    ok = sum(isinstance(estimator(f.left, f.right), FrameEstimate) for f in rendered)

    print("# Stereo benchmarks\n\n`python benchmarks/stereo.py`\n\n" + machine())
    print(f"- rig: {rig.name}, {rig.left.width}×{rig.left.height}, baseline {rig.baseline:g} m; kernel from "
          f"generated/stereo_rig with gagen's `{' '.join(programs.gagen_cflags())}`\n"
          f"- C: medians of {c_repeats} passes over 1000 observations, three runs; Python: medians of "
          f"{repeats} passes; frames: {frames} random poses ≈ 1 m away, 1 px vertex noise\n")
    rows = [
        ["`estimate` kernel, C single call", f"{single:.0f} ns", f"≤ {KERNEL_TARGET_NS} ns "
         + ("✓" if single <= KERNEL_TARGET_NS else "✗")],
        ["`estimate` kernel, C batch, per observation", f"{batch:.0f} ns", ""],
        ["`estimate` through the binding, `k(obs)`", f"{py_call * 1e9:.0f} ns", ""],
        ["`estimate` through the binding, bound (`k.bind()`)", f"{py_bound * 1e9:.0f} ns", ""],
        ["detection per 640×480 image (`vision.detect`)", f"{detect * 1e3:.1f} ms", ""],
        ["whole pipeline per frame pair (detect ×2 + kernel)", f"{pipeline * 1e3:.1f} ms "
         f"({1 / pipeline:.1f} frame pairs/s)", "30 Hz " + ("✓" if pipeline <= 1 / 30 else "✗")],
        ["rendering a frame pair (the synthetic scene, for reference)", f"{render_s * 1e3:.1f} ms", ""],
    ]
    print(table(["what", "measured", "goal"], "lrl", rows))
    print(f"\n{ok} of {frames} frame pairs estimated. _whole run {time.perf_counter() - start:.0f} s_")
    return 0


if __name__ == "__main__":
    sys.exit(main())
