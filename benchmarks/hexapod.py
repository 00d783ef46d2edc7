"""Hexapod benchmarks: analytic IK, body IK, DLS IK and FK + J per leg (PGA, CGA, 4×4 matrix chain,
Pinocchio), every peer measured side by side in one run; markdown tables on stdout.

    python benchmarks/hexapod.py            # ~10 s; ~25 s the first time (C compiles, cached)
    python benchmarks/hexapod.py --quick    # one round, fewer repeats

Uses the committed generated/hexapod module (built on first use, ``gagen.modules``; else the gagen
cache's). The FK + J peers that are not in it are compiled by the same compiler, through the
front-end (``gagen.compile``), into one cached module ``hexapod_fkj``:

- ``front_left_pj_pga``, ``front_left_pj_cga``: only p and J of ``leg_kinematics`` (the committed
  ``front_left_fk_*`` kernels also output M, toe and S);
- ``front_left_pj_matrix``: the same p and J from a plain 4×4 homogeneous-matrix chain
  T = T_mount · Π_j T(c_j − c_{j−1}) R(u_j, q_j) · T(toe − c_3), J_j = z_j × (p − o_j).

C timings: benchmarks/hexapod_bench.c (harness.h), linked to hexapod.c and hexapod_fkj.c compiled with
gagen's own flags (their ``_simd.c`` companions at -O3, as gagen does), built into benchmarks/build/.
Python timings: ``median_ns`` of benchmarks/python_calls.py (the loop's own cost included). Every number
is the median of 5 rounds that each time every row in turn (the machine is shared). Pinocchio runs on
the committed hexapod URDF reduced to the leg (else a one-leg URDF written from the spec), from Python
(its calls include the bindings' overhead) and in C++: benchmarks/pinocchio_fk.cpp (programs.py's cached
``pinocchio`` build, ~1-2 min to compile the first time) on the same configurations as the C rows. Every
peer's p and J are checked against ``front_left_fk_pga`` before timing. Not part of the test suite.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

BENCH = Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH))

import programs  # noqa: E402 -- benchmarks/ is not a package
from matrix_chain import rpy_matrix  # noqa: E402
from python_calls import median_ns  # noqa: E402
from run import fmt_ns, machine, table  # noqa: E402

import gagen  # noqa: E402
from gagen.apps.hexapod.kernels import XYZ, hexapod_kernels  # noqa: E402
from gagen.apps.hexapod.legs import leg_kinematics  # noqa: E402
from gagen.apps.hexapod.spec import Hexapod, Leg, load_hexapod  # noqa: E402
from gagen.build import cache_root, compile_kernels  # noqa: E402
from gagen.codegen.compiler import vector_math_libraries  # noqa: E402
from gagen.frontend import KernelFunction, source_of  # noqa: E402
from gagen.model.euclidean import GEOMETRIES, cross  # noqa: E402
from gagen.symbolic.backend import to_exact  # noqa: E402

ROOT = programs.ROOT
SPEC = ROOT / "gagen" / "apps" / "hexapod" / "robots" / "hexapod.yaml"
COMMITTED = programs.GENERATED / "hexapod"
LEG = "front_left"
N_CALL = 1000  # samples of the per-call loops (C and Python)
N_BATCH = 10_000  # targets of the IK batches
N_BODY = 200
N_DLS = 200
DAMPING = 1e-3  # λ of the DLS steps
TOLERANCE = 1e-12  # m: a DLS solve ends when |target − p| is below it
MAX_ITERATIONS = 200
DLS_SPREAD = 0.4  # rad: DLS targets are toes of the neutral pose moved this far per joint at most (a step)
IK_TARGET_NS = 40


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


# -- FK + J peers through the front-end ---------------------------------------------------------------

def _matmul(a: list[list[Any]], b: list[list[Any]]) -> list[list[Any]]:
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def _translation(v: Any) -> list[list[Any]]:
    return [[1, 0, 0, v[0]], [0, 1, 0, v[1]], [0, 0, 1, v[2]], [0, 0, 0, 1]]


def _rotation(u: tuple[float, float, float], c: Any, s: Any) -> list[list[Any]]:
    """Rodrigues, R = c I + s [u]× + (1 − c) u uᵀ, as a 4×4 (the compiler folds the axis's zeros)."""
    x, y, z = (to_exact(v) for v in u)
    k = 1 - c
    return [[c + k * x * x, k * x * y - s * z, k * x * z + s * y, 0],
            [k * x * y + s * z, c + k * y * y, k * y * z - s * x, 0],
            [k * x * z - s * y, k * y * z + s * x, c + k * z * z, 0],
            [0, 0, 0, 1]]


def matrix_chain_pj(leg: Leg, q: Any, ga: Any) -> dict[str, Any]:
    """p and J of the leg's toe in the body frame by the plain 4×4 homogeneous-matrix chain."""
    mount = [[to_exact(v) for v in row] + [to_exact(t)] for row, t in zip(rpy_matrix(leg.rpy), leg.xyz,
                                                                          strict=True)]
    T = [*mount, [0, 0, 0, 1]]
    origins, axes, previous = [], [], (0.0, 0.0, 0.0)
    for centre, u, angle in zip(leg.centres, leg.axes, q, strict=True):
        T = _matmul(T, _translation([to_exact(c - p) for c, p in zip(centre, previous, strict=True)]))
        origins.append([T[i][3] for i in range(3)])
        axes.append([sum(T[i][k] * to_exact(u[k]) for k in range(3)) for i in range(3)])
        T = _matmul(T, _rotation(u, ga.math.cos(angle), ga.math.sin(angle)))
        previous = centre
    T = _matmul(T, _translation([to_exact(t - p) for t, p in zip(leg.toe, previous, strict=True)]))
    p = [T[i][3] for i in range(3)]
    J = [cross(z, [pi - oi for pi, oi in zip(p, o, strict=True)]) for z, o in zip(axes, origins, strict=True)]
    return {"p": p, "J": J}


def fkj_kernels(leg: Leg) -> list[KernelFunction]:
    """p and J of one leg: gagen's PoE formulas in PGA and CGA, and the 4×4 matrix chain."""
    outputs = {"p": gagen.scalars(3, XYZ), "J": gagen.matrix(gagen.scalars(3, XYZ), 3)}
    inputs = {"q": gagen.scalars(3, leg.joint_names), "ga": "algebra"}

    def pj(algebra: str) -> Callable[[Any, Any], dict[str, Any]]:
        def fn(q: Any, ga: Any) -> dict[str, Any]:
            kin = leg_kinematics(GEOMETRIES[algebra], ga, leg, q)
            return {"p": kin["p"], "J": kin["J"]}
        return fn

    def matrix(q: Any, ga: Any) -> dict[str, Any]:
        return matrix_chain_pj(leg, q, ga)

    return [KernelFunction(fn, algebra=algebra, inputs=inputs, outputs=outputs, name=f"{leg.name}_{name}",
                           doc=doc)
            for fn, algebra, name, doc in (
                (pj("pga3d"), "pga3d", "pj_pga", "toe position and point Jacobian, PGA"),
                (pj("cga3d"), "cga3d", "pj_cga", "toe position and point Jacobian, CGA"),
                (matrix, "pga3d", "pj_matrix", "toe position and point Jacobian, 4×4 matrix chain"))]


def output_op_counts(leg: Leg) -> dict[str, dict[str, Any]]:
    """Op counts of each output of ``leg_kinematics`` alone, per algebra (traced, not compiled): where
    the committed kernels' PGA/CGA difference comes from."""
    twist = ("vx", "vy", "vz", "wx", "wy", "wz")
    declared = {"M": "motor", "toe": "point", "p": gagen.scalars(3, XYZ),
                "J": gagen.matrix(gagen.scalars(3, XYZ), 3), "S": gagen.matrix(gagen.scalars(6, twist), 3)}

    def only(algebra: str, output: str) -> Callable[[Any, Any], dict[str, Any]]:
        def fn(q: Any, ga: Any) -> dict[str, Any]:
            kin = leg_kinematics(GEOMETRIES[algebra], ga, leg, q)
            return {output: kin["motor" if output == "M" else output]}
        return fn

    counts: dict[str, dict[str, Any]] = {}
    for output, declaration in declared.items():
        for algebra in ("pga3d", "cga3d"):
            k = KernelFunction(only(algebra, output), algebra=algebra, name=f"only_{output}",
                               inputs={"q": gagen.scalars(3), "ga": "algebra"}, outputs={output: declaration})
            o = k.trace().op_count
            counts.setdefault(output, {})[algebra] = {"mul": o.mul, "add": o.add, "neg": o.neg, "div": o.div,
                                                      "flops": o.flops, "calls": dict(o.calls)}
    return counts


def compile_fkj(leg: Leg) -> tuple[Any, Path]:
    """The three p + J kernels in one module in gagen's cache (built once per content)."""
    kernels = fkj_kernels(leg)
    source = source_of(kernels, "hexapod_fkj")
    folder = cache_root() / f"{source.name}-{source.key[:16]}"
    return compile_kernels(kernels, name="hexapod_fkj", folder=folder), folder


# -- references in Python ----------------------------------------------------------------------------

def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b written out: np.cross costs ~50 µs a call in NumPy 2.x, more than the whole chain."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def numpy_chain(leg: Leg) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """The 4×4 chain on numpy arrays (z, y, y axes as in the spec), p and the 3×3 J."""
    mount = np.eye(4)
    mount[:3, :3], mount[:3, 3] = rpy_matrix(leg.rpy), leg.xyz
    l1, l2, l3 = leg.lengths
    links = [np.eye(4) for _ in range(3)]
    for link, offset in zip(links, (l1, l2, l3), strict=True):
        link[0, 3] = offset
    signs = [np.sign(sum(u)) for u in leg.axes]  # ±z, ±y, ±y (checked in main)

    def rz(a: float) -> np.ndarray:
        c, s = np.cos(a), np.sin(a)
        return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])

    def ry(a: float) -> np.ndarray:
        c, s = np.cos(a), np.sin(a)
        return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])

    def fkj(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t0 = mount @ rz(signs[0] * q[0])
        t1 = t0 @ links[0] @ ry(signs[1] * q[1])
        t2 = t1 @ links[1] @ ry(signs[2] * q[2])
        p = (t2 @ links[2])[:3, 3]
        z = (signs[0] * t0[:3, 2], signs[1] * t1[:3, 1], signs[2] * t2[:3, 1])
        J = np.column_stack([_cross(zj, p - t[:3, 3]) for zj, t in zip(z, (t0, t1, t2), strict=True)])
        return p, J

    return fkj


def leg_urdf(leg: Leg) -> str:
    """One leg as URDF, from the spec's numbers: base → hip (fixed, xyz rpy) → three revolute joints →
    toe (fixed)."""
    links = ["base", f"{leg.name}_hip", f"{leg.name}_coxa", f"{leg.name}_femur", f"{leg.name}_tibia",
             f"{leg.name}_toe"]
    joints = [f'<joint name="{leg.name}_mount" type="fixed"><parent link="base"/>'
              f'<child link="{links[1]}"/><origin xyz="{" ".join(map(str, leg.xyz))}" '
              f'rpy="{" ".join(map(str, leg.rpy))}"/></joint>']
    previous = (0.0, 0.0, 0.0)
    for j, (name, centre, u, (lo, hi)) in enumerate(zip(leg.joint_names, leg.centres, leg.axes, leg.limits,
                                                         strict=True)):
        offset = " ".join(str(c - p) for c, p in zip(centre, previous, strict=True))
        joints.append(f'<joint name="{name}" type="revolute"><parent link="{links[j + 1]}"/>'
                      f'<child link="{links[j + 2]}"/><origin xyz="{offset}"/>'
                      f'<axis xyz="{" ".join(map(str, u))}"/>'
                      f'<limit lower="{lo}" upper="{hi}" effort="10" velocity="10"/></joint>')
        previous = centre
    offset = " ".join(str(t - p) for t, p in zip(leg.toe, previous, strict=True))
    joints.append(f'<joint name="{leg.name}_toe_joint" type="fixed"><parent link="{links[4]}"/>'
                  f'<child link="{links[5]}"/><origin xyz="{offset}"/></joint>')
    body = "".join(f'<link name="{name}"/>' for name in links) + "".join(joints)
    return f'<?xml version="1.0"?><robot name="{leg.name}">{body}</robot>'


def pinocchio_leg(leg: Leg, folder: Path) -> tuple[Any, str] | None:
    """(fkj(q) -> (p, J) through Pinocchio's Python bindings, where its model comes from), or None."""
    try:
        import pinocchio as pin
    except ImportError:
        return None
    model, frame_name, origin = _pinocchio_model(pin, leg, folder)
    data = model.createData()
    frame = model.getFrameId(frame_name)
    joints, update, get = pin.computeJointJacobians, pin.updateFramePlacement, pin.getFrameJacobian
    aligned = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

    def fkj(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        joints(model, data, q)
        update(model, data, frame)
        return data.oMf[frame].translation, get(model, data, frame, aligned)[:3]

    return fkj, f"{origin}; Pinocchio {pin.__version__}"


def _pinocchio_model(pin: Any, leg: Leg, folder: Path) -> tuple[Any, str, str]:
    """The leg as a 3-joint Pinocchio model (see ``_pinocchio_source``), its toe frame and origin."""
    urdf, frame, keep, origin = _pinocchio_source(pin, leg, folder)
    model = pin.buildModelFromUrdf(str(urdf))
    if keep:
        locked = [model.getJointId(n) for n in model.names[1:] if n not in keep]
        model = pin.buildReducedModel(model, locked, pin.neutral(model))
    return model, frame, origin


def _pinocchio_source(pin: Any, leg: Leg, folder: Path) -> tuple[Path, str, list[str], str]:
    """(URDF, toe frame, joints to keep, origin) of the leg for Pinocchio: the committed hexapod URDF
    (helper ``reference``'s gagen/apps/hexapod/robots/hexapod.urdf) reduced to the leg's joints (the others
    locked at 0; their legs are separate branches, so the leg's kinematics do not depend on them), else a
    one-leg URDF written into ``folder`` (all its joints kept)."""
    urdf = SPEC.with_suffix(".urdf")
    if urdf.is_file() and pin.buildModelFromUrdf(str(urdf)).existFrame(f"{leg.name}_foot"):
        rel = urdf.relative_to(ROOT).as_posix()
        return (urdf, f"{leg.name}_foot", list(leg.joint_names),
                f"{rel} (committed), reduced to the leg's 3 joints")
    path = folder / f"{leg.name}.urdf"
    path.write_text(leg_urdf(leg))
    return path, f"{leg.name}_toe", [], "a one-leg URDF written here from the spec's numbers (`leg_urdf`)"


def pinocchio_cpp(leg: Leg, folder: Path, qs: np.ndarray) -> list[str] | None:
    """The command line of benchmarks/pinocchio_fk.cpp (programs.py's cached ``pinocchio`` build) for the
    leg's toe, LOCAL_WORLD_ALIGNED, over the configurations ``qs`` (written into ``folder``), less REPEATS
    (inserted at index 2); None without Pinocchio or its headers."""
    try:
        import pinocchio as pin

        log("compiling Pinocchio's C++ harness (programs.py, cached; the first time ~1-2 min) ...")
        program = programs.build({"pinocchio"})[0]["pinocchio"]
    except (ImportError, SystemExit) as e:  # programs.py reports missing headers and failed builds so
        log(f"no Pinocchio C++ row: {e}")
        return None
    urdf, frame, keep, _ = _pinocchio_source(pin, leg, folder)
    configs = folder / "pinocchio_configs.bin"
    configs.write_bytes(np.ascontiguousarray(qs, dtype=np.float64).tobytes())
    return [str(program), str(urdf), frame, *(["--keep", ",".join(keep)] if keep else []),
            "--configs", str(configs), "--aligned"]


def run_pinocchio_cpp(command: list[str], repeats: int) -> dict[str, Any]:
    out = subprocess.run([*command[:2], str(repeats), *command[2:]], capture_output=True, text=True,
                         check=True)
    return json.loads(out.stdout)


def check_pinocchio_cpp(module: Any, out: dict[str, Any], q0: np.ndarray) -> float:
    """Max |difference| of the C++ harness's p and point Jacobian at its first configuration from
    front_left_fk_pga's."""
    if not np.array_equal(out["q0"], q0):
        raise SystemExit("pinocchio_fk did not read the configurations written for it")
    _, _, p, J, _ = module.c.front_left_fk_pga(q0)
    J_cpp = np.asarray(out["J0"]).reshape(3, 6).T[:3]  # column-major 6×3, rows [v; ω]: v, the toe's
    return max(float(np.max(np.abs(np.asarray(out["p0"]) - p))), float(np.max(np.abs(J_cpp - J))))


# -- inputs ------------------------------------------------------------------------------------------

def inputs(hexapod: Hexapod, module: Any, rng: np.random.Generator) -> dict[str, np.ndarray]:
    leg = hexapod.leg(LEG)
    lo, hi = np.array(leg.limits).T
    qs = rng.uniform(lo, hi, size=(N_BATCH, 3))
    targets = module.c.front_left_fk_pga.batch(rng.uniform(lo, hi, size=(N_BATCH, 3)))[2]  # reachable
    body_ik = next(k for k in hexapod_kernels(hexapod) if k.name == "body_ik")
    bodies = np.array([np.concatenate(body_ik.sample(rng)) for _ in range(N_BODY)])
    near = np.clip(np.array(hexapod.neutral) + rng.uniform(-DLS_SPREAD, DLS_SPREAD, size=(N_DLS, 3)), lo, hi)
    dls = module.c.front_left_fk_pga.batch(near)[2]
    return {"qs": qs, "targets": np.ascontiguousarray(targets), "bodies": bodies,
            "dls": np.ascontiguousarray(dls)}


# -- C -------------------------------------------------------------------------------------------------

def build_c(module_folder: Path, fkj_folder: Path) -> Path:
    """hexapod_bench linked to both modules' C, compiled as gagen compiles them (cached)."""
    programs.BUILD.mkdir(parents=True, exist_ok=True)
    cc, objects = programs.c_compiler(), []
    includes = [f"-I{BENCH}", f"-I{module_folder}", f"-I{fkj_folder}"]
    steps = []
    for folder, stem in ((module_folder, "hexapod"), (fkj_folder, "hexapod_fkj")):
        header = folder / f"{stem}.h"
        for source, flags in ((folder / f"{stem}.c", programs.gagen_cflags()),
                              (folder / f"{stem}_simd.c", programs.gagen_cflags("-O3"))):
            if source.exists():
                obj = programs.BUILD / f"hexapod_bench_{source.stem}.o"
                command = [*cc, *flags, f"-I{folder}", "-c", str(source), "-o", str(obj)]
                steps.append(programs.Step(obj, command, [source, header]))
    driver = BENCH / "hexapod_bench.c"
    obj = programs.BUILD / "hexapod_bench.o"
    command = [*cc, *programs.DRIVER_CFLAGS, *includes, "-c", str(driver), "-o", str(obj)]
    steps.append(programs.Step(obj, command, [driver, BENCH / "harness.h", module_folder / "hexapod.h",
                                fkj_folder / "hexapod_fkj.h"]))
    for step in steps:
        step.run(False)
        objects.append(step.output)
    program = programs.BUILD / "hexapod_bench"
    libs = [*vector_math_libraries(), "-lm"]
    programs.Step(program, [*cc, *map(str, objects), "-o", str(program), *libs], objects).run(False)
    return program


def run_c(program: Path, data: dict[str, np.ndarray], neutral: np.ndarray, repeats: int) -> dict[str, float]:
    header = [N_CALL, N_BATCH, N_BODY, N_DLS, DAMPING, TOLERANCE, MAX_ITERATIONS, *neutral]
    flat = np.concatenate([np.asarray(header, dtype=float), data["qs"].ravel(), data["targets"].ravel(),
                           data["bodies"].ravel(), data["dls"].ravel()])
    with tempfile.NamedTemporaryFile(suffix=".bin", delete=False) as f:
        f.write(flat.tobytes())
    try:
        out = subprocess.run([str(program), f.name, str(repeats)], capture_output=True, text=True, check=True)
    finally:
        os.unlink(f.name)
    return json.loads(out.stdout)


# -- Python ------------------------------------------------------------------------------------------

def python_times(module: Any, fkj: Any, data: dict[str, np.ndarray], neutral: np.ndarray, calls: int,
                 repeats: int, extra: dict[str, Callable[[np.ndarray], Any]]) -> dict[str, float]:
    ik = module.c.front_left_ik
    seq_t = [data["targets"][i % N_CALL].copy() for i in range(calls)]
    seq_q = [data["qs"][i % N_CALL].copy() for i in range(calls)]
    outs, bound = ik.empty(), ik.bind()
    out: dict[str, float] = {}

    def loop(f: Callable[[np.ndarray], Any], seq: list[np.ndarray]) -> Callable[[], None]:
        def run() -> None:
            for x in seq:
                f(x)
        return run

    def into() -> None:
        for t in seq_t:
            ik(t, out=outs)

    out["ik"] = median_ns(loop(ik, seq_t), calls, repeats)
    out["ik_out"] = median_ns(into, calls, repeats)
    out["ik_bound"] = median_ns(loop(bound, seq_t), calls, repeats)
    targets = data["targets"]
    out["ik_batch"] = median_ns(lambda: ik.batch(targets), N_BATCH, repeats)
    out["ik_batch_columns"] = median_ns(lambda: ik.batch_columns(targets.T), N_BATCH, repeats)

    body = module.c.body_ik.bind()
    bodies = [(b[:8].copy(), b[8:].copy()) for b in data["bodies"]]
    body_seq = [bodies[i % len(bodies)] for i in range(calls)]

    def body_loop() -> None:
        for pose, toes in body_seq:
            body(pose, toes)

    out["body_ik"] = median_ns(body_loop, calls, repeats)
    for name, kernel in (("fk_pga", module.c.front_left_fk_pga), ("fk_cga", module.c.front_left_fk_cga),
                         ("pj_pga", fkj.front_left_pj_pga), ("pj_cga", fkj.front_left_pj_cga),
                         ("pj_matrix", fkj.front_left_pj_matrix)):
        out[name] = median_ns(loop(kernel.bind(), seq_q), calls, repeats)
    few = seq_q[:calls // 10]  # the slower references: fewer calls
    for name, f in extra.items():
        out[name] = median_ns(loop(f, few), len(few), repeats)
    out["dls_solve"], out["dls_iterations"] = dls_python(module, data["dls"], neutral, repeats)
    return out


def dls_python(module: Any, targets: np.ndarray, neutral: np.ndarray, repeats: int) -> tuple[float, float]:
    """ns per solve from the neutral pose to |target − p| < TOLERANCE (bound `front_left_dls`), and the
    mean number of steps."""
    step = module.c.front_left_dls.bind()
    damping = np.array([DAMPING])
    seq = [t.copy() for t in targets]
    counts: list[int] = []

    def solves() -> None:
        counts.clear()
        for t in seq:
            q = neutral.copy()
            steps = 0
            while True:
                q_next, error = step(q, t, damping)
                if error[0] < TOLERANCE or steps == MAX_ITERATIONS:
                    break
                q[:] = q_next
                steps += 1
            counts.append(steps)

    return median_ns(solves, len(seq), repeats), statistics.mean(counts)


def check_peers(module: Any, fkj: Any, qs: np.ndarray, extra: dict[str, Callable]) -> float:
    """Max |difference| of p and J of every peer from front_left_fk_pga over the first 100 configurations."""
    worst = 0.0
    for q in qs[:100]:
        _, _, p, J, _ = module.c.front_left_fk_pga(q)
        peers = [module.c.front_left_fk_cga(q)[2:4], fkj.front_left_pj_pga(q), fkj.front_left_pj_cga(q),
                 fkj.front_left_pj_matrix(q), *(f(q) for f in extra.values())]
        for pp, JJ in peers:
            worst = max(worst, float(np.max(np.abs(pp - p))), float(np.max(np.abs(np.asarray(JJ) - J))))
    return worst


# -- report ------------------------------------------------------------------------------------------

def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats")
    args = ap.parse_args()
    rounds, repeats, calls, c_repeats = (1, 3, 2000, 21) if args.quick else (5, 5, 10000, 51)
    start = time.perf_counter()
    from gagen.runtime import load

    hexapod = load_hexapod(SPEC)
    leg = hexapod.leg(LEG)
    if [tuple(abs(a) for a in u) for u in leg.axes] != [(0, 0, 1), (0, 1, 0), (0, 1, 0)]:
        raise SystemExit(f"{LEG}: the numpy chain assumes axes ±z, ±y, ±y")
    with tempfile.TemporaryDirectory() as tmp:
        from gagen.modules import module_folder

        folder = module_folder(SPEC)  # built on first use: generated/hexapod, else the gagen cache
        origin = "generated/hexapod (committed)" if folder == COMMITTED else f"built into {folder}"
        module = load(folder)
        log("compiling the FK + J peers (gagen.compile, cached) ...")
        t0 = time.perf_counter()
        fkj, fkj_folder = compile_fkj(leg)
        fkj_s = time.perf_counter() - t0
        log("compiling the C timing program ...")
        program = build_c(folder, fkj_folder)

        data = inputs(hexapod, module, np.random.default_rng(14))
        neutral = np.array(hexapod.neutral, dtype=float)
        extra: dict[str, Callable[[np.ndarray], Any]] = {"numpy": numpy_chain(leg)}
        pin = pinocchio_leg(leg, Path(tmp))
        if pin is not None:
            extra["pinocchio"] = pin[0]
        error = check_peers(module, fkj, data["qs"], extra)
        pin_cpp = pinocchio_cpp(leg, Path(tmp), data["qs"][:N_CALL]) if pin is not None else None
        if pin_cpp is not None:
            error = max(error, check_pinocchio_cpp(module, run_pinocchio_cpp(pin_cpp, 21), data["qs"][0]))
        if error > 1e-12:
            raise SystemExit(f"the FK + J peers disagree by {error:.1e}")
        # rounds of every measurement in turn, the median of the rounds' medians per row: a burst of other
        # work on the shared machine then spoils one round of every row, not all of one row
        c_runs, py_runs = [], []
        for r in range(rounds):
            log(f"timing, round {r + 1} of {rounds} ...")
            c_runs.append(run_c(program, data, neutral, c_repeats))
            if pin_cpp is not None:
                cpp = run_pinocchio_cpp(pin_cpp, c_repeats)
                c_runs[-1].update(pin_cpp_ns=cpp["fk_jacobian_lean_ns"],
                                  pin_cpp_frame_ns=cpp["fk_jacobian_ns"])
            py_runs.append(python_times(module, fkj, data, neutral, calls, repeats, extra))
        c, py = _median_of(c_runs), _median_of(py_runs)
        manifest = {k["name"]: k["op_count"] for k in module.manifest["kernels"]}
        per_output = output_op_counts(leg)
        report(hexapod, fkj, c, py, manifest, per_output,
               {"origin": origin, "pin_origin": pin[1] if pin else None, "error": error, "fkj_s": fkj_s,
                "calls": calls, "repeats": repeats, "c_repeats": c_repeats, "rounds": rounds,
                "total": time.perf_counter() - start})
    return 0


def _median_of(runs: list[dict[str, float]]) -> dict[str, float]:
    return {k: statistics.median(run[k] for run in runs) for k in runs[0]}


def _ops(o: dict[str, Any]) -> str:
    calls = ", ".join(f"{n} {k}" for k, n in sorted(o.get("calls", {}).items()))
    return f"{o['flops']}" + (f" + {calls}" if calls else "")


def report(hexapod: Hexapod, fkj: Any, c: dict, py: dict, manifest: dict, per_output: dict,
           run: dict) -> None:
    """Print the markdown tables; ``run``: origin, pin_origin, error, fkj_s, calls, repeats, c_repeats,
    total."""
    origin, pin_origin, error, fkj_s = run["origin"], run["pin_origin"], run["error"], run["fkj_s"]
    calls, repeats, c_repeats, total = run["calls"], run["repeats"], run["c_repeats"], run["total"]
    rounds = run["rounds"]
    flags = " ".join(programs.gagen_cflags())
    print("# Hexapod benchmarks\n\n`python benchmarks/hexapod.py`\n\n" + machine())
    print(f"- module: {origin}; leg {LEG}; FK + J peers: gagen.compile of `hexapod_fkj` "
          f"({fkj_s:.1f} s this run)\n- C: kernels compiled with gagen's `{flags}`, timing loops "
          f"`{' '.join(programs.DRIVER_CFLAGS)}`; {N_CALL} samples per loop, median of {c_repeats} loops\n"
          f"- Python: median of {repeats} loops of {calls} calls (the loop's own cost, ~10–20 ns, "
          "included)\n"
          f"- every number: the median over {rounds} rounds, each timing every row in turn\n")

    ik = manifest["front_left_ik"]
    met = "✓" if c["ik_ns"] <= IK_TARGET_NS else "✗"
    big = f"{N_BATCH:,}".replace(",", " ")
    print("## Analytic IK of one leg (`front_left_ik`: target → q_up, q_down, reach, excess)\n")
    rows = [
        ["C: `hexapod_front_left_ik`, one call per target", fmt_ns(c["ik_ns"]), f"≤ {IK_TARGET_NS} ns {met}"],
        ["C floor: the IK's 4 `atan2` and 3 `sqrt` alone (libm)", fmt_ns(c["ik_floor_ns"]), ""],
        [f"C: `hexapod_front_left_ik_batch`, n = {big}, per target (vector atan2, sqrt)",
         fmt_ns(c["ik_batch_ns"]), f"≤ {IK_TARGET_NS} ns {'✓' if c['ik_batch_ns'] <= IK_TARGET_NS else '✗'}"],
        ["Python: `k(t)` (fresh output arrays)", fmt_ns(py["ik"]), ""],
        ["Python: `k(t, out=outs)`", fmt_ns(py["ik_out"]), ""],
        ["Python: `f(t)`, `f = k.bind()`", fmt_ns(py["ik_bound"]), ""],
        [f"Python: `k.batch(targets)`, n = {big}, per target",
         fmt_ns(py["ik_batch"]), ""],
        [f"Python: `k.batch_columns(targets.T)`, n = {big}, per target",
         fmt_ns(py["ik_batch_columns"]), ""]]
    print(table(["call", "ns (median)", "target"], "lrr", rows))
    print(f"\nops: {_ops(ik)} (if_else_zero, lt, not: branch-free selects). From Python, the bound call "
          f"adds {py['ik_bound'] - c['ik_ns']:.0f} ns of binding overhead to the C call.\n")

    print("## Whole-body IK (`body_ik`: PGA body pose + 18 world toe targets → q18, reach6, excess6)\n")
    print(table(["call", "ns (median)", "per leg"], "lrr",
                [["C: `hexapod_body_ik`", fmt_ns(c["body_ik_ns"]), fmt_ns(c["body_ik_ns"] / 6)],
                 ["Python: `f(pose, toes)`, `f = k.bind()`", fmt_ns(py["body_ik"]),
                  fmt_ns(py["body_ik"] / 6)]]))
    print(f"\nops: {_ops(manifest['body_ik'])}\n")

    print(f"## Numerical IK: DLS with `front_left_dls` (λ = {DAMPING:g}) from the neutral pose to "
          f"|target − p| < {TOLERANCE:g} m\n")
    print(table(["", "steps per solve (mean)", "ns per step", "µs per solve"], "lrrr", [
        ["C loop", f"{c['dls_iterations_mean']:.1f} (max {c['dls_iterations_max']:.0f})",
         fmt_ns(c["dls_step_ns"]), f"{c['dls_solve_ns'] / 1000:.2f}"],
        ["Python loop, `f = k.bind()` (the loop's work included)", f"{py['dls_iterations']:.1f}",
         fmt_ns(py["dls_solve"] / max(py["dls_iterations"] + 1, 1)), f"{py['dls_solve'] / 1000:.2f}"]]))
    print(f"\n{N_DLS} targets: toes of the neutral pose {tuple(hexapod.neutral)} moved by up to "
          f"±{DLS_SPREAD} rad per joint (within the limits); unsolved in "
          f"{MAX_ITERATIONS} steps: {c['dls_unsolved']:.0f}; a step's error is the one before it, so a solve "
          f"of k steps makes k + 1 calls. ops per step: {_ops(manifest['front_left_dls'])}\n")

    print("## FK + point Jacobian of one leg (q → p, J 3×3)\n")
    pj = {name: getattr(fkj, f"front_left_{name}").op_count for name in ("pj_pga", "pj_cga", "pj_matrix")}
    ref = c["pj_matrix_ns"]
    rows = [
        ["gagen PGA `front_left_pj_pga` (p, J)", _ops(pj["pj_pga"]), c["pj_pga_ns"], py["pj_pga"]],
        ["gagen CGA `front_left_pj_cga` (p, J)", _ops(pj["pj_cga"]), c["pj_cga_ns"], py["pj_cga"]],
        ["4×4 matrix chain `front_left_pj_matrix` (p, J), same compiler", _ops(pj["pj_matrix"]),
         c["pj_matrix_ns"], py["pj_matrix"]],
        ["gagen PGA `front_left_fk_pga` (M, toe, p, J, S)", _ops(manifest["front_left_fk_pga"]),
         c["fk_pga_ns"], py["fk_pga"]],
        ["gagen CGA `front_left_fk_cga` (M, toe, p, J, S)", _ops(manifest["front_left_fk_cga"]),
         c["fk_cga_ns"], py["fk_cga"]],
        ["numpy 4×4 chain (p, J)", "–", None, py["numpy"]]]
    if "pin_cpp_ns" in c:
        rows.append(["Pinocchio C++ (`pinocchio_fk.cpp`, `-O3 -march=native`): computeJointJacobians + "
                     "updateFramePlacement + getFrameJacobian(LOCAL_WORLD_ALIGNED)", "–", c["pin_cpp_ns"],
                     None])
    if "pinocchio" in py:
        rows.append(["Pinocchio Python: computeJointJacobians + updateFramePlacement + "
                     "getFrameJacobian(LOCAL_WORLD_ALIGNED)", "–", None, py["pinocchio"]])
    print(table(["method", "flops + calls", "C ns", "× matrix chain (C)", "Python ns (bound call)"], "lrrrr",
                [[m, o, fmt_ns(ns), "–" if ns is None else f"{ns / ref:.2f}", fmt_ns(p)]
                 for m, o, ns, p in rows]))
    notes = [f"every peer agrees with `front_left_fk_pga` to {error:.1e} (p and J, 100 configurations)",
             "Python rows include the call overhead (CPython binding for gagen; Pinocchio's boost::python "
             "bindings, three calls)"]
    if pin_origin:
        notes.append(f"Pinocchio model: {pin_origin}")
    if "pin_cpp_ns" in c:
        notes.append("Pinocchio C++: benchmarks/pinocchio_fk.cpp (`--keep` the leg's joints, `--aligned`) "
                     f"instantiated from Pinocchio {programs.pinocchio_paths()['version']}'s headers, on the "
                     "C rows' configurations, its p and J checked at the first; forwardKinematics + "
                     "updateFramePlacement + computeFrameJacobian (a second pass over the chain): "
                     f"{fmt_ns(c['pin_cpp_frame_ns'])} ns")
    print("\n" + "\n".join(f"- {n}" for n in notes) + "\n")

    print("## Op counts, FK + J per leg: PGA vs CGA\n")
    fk_p, fk_c = manifest["front_left_fk_pga"], manifest["front_left_fk_cga"]
    op_rows = [["p, J (front-end `pj_*`)", pj["pj_pga"], pj["pj_cga"]],
               ["M, toe, p, J, S (committed `fk_*`)", fk_p, fk_c]]
    op_rows += [[f"{name} alone", c["pga3d"], c["cga3d"]] for name, c in per_output.items()]
    print(table(["outputs", "PGA mul/add/neg", "PGA flops", "CGA mul/add/neg", "CGA flops", "CGA − PGA"],
                "lrrrrr",
                [[w, f"{a['mul']}/{a['add']}/{a['neg']}", a["flops"], f"{b['mul']}/{b['add']}/{b['neg']}",
                  b["flops"], f"{b['flops'] - a['flops']:+d}"] for w, a, b in op_rows]))
    print(f"\n4×4 matrix chain (p, J): {_ops(pj['pj_matrix'])}; every row also calls sin and cos 3 times.\n")
    print(f"_whole run {total:.0f} s_")


if __name__ == "__main__":
    sys.exit(main())
