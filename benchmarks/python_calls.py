"""Per-call timings from Python: gagen's runtime, Pinocchio's bindings and pygafro, on the Panda
(robots/panda/panda.urdf).

Each timing is the median over REPEATS loops of CALLS calls (time.perf_counter_ns around the whole loop,
divided by CALLS), cycling through the same configurations as the C harness (``configs`` reproduces
harness.h's bench_configs). The loop itself (a Python ``for`` over a list) is included: ~10–20 ns a call.

pygafro (pip ``pygafro``, the Python bindings of the C++ gafro library) ships a Panda model
(``pygafro.FrankaEmikaRobot()``, from its panda.yaml); its end effector is a flange frame beyond
panda_link8. ``pygafro.createManipulator(<that yaml>, 7, "panda_joint8")`` builds the same robot with
panda_link8 as the tip, which is what our URDF and the other rows use; ``check_pygafro`` compares both
with Pinocchio.

    python benchmarks/python_calls.py     # the one-call table, then timings and the pygafro check (JSON)
    python benchmarks/python_calls.py --calls-only   # only gagen's ways to call Panda FK + J, side by side
"""

from __future__ import annotations

import json
import os
import statistics
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
URDF = ROOT / "robots" / "panda" / "panda.urdf"
TIP = "panda_link8"
CALLS = 10000
REPEATS = 7

# harness.h
BENCH_N = 1000
BENCH_SEED = 20240611
LOWER = (-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973)
UPPER = (2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973)
_MASK = (1 << 64) - 1


def configs(n: int = BENCH_N, seed: int = BENCH_SEED, arms: int = 1) -> np.ndarray:
    """harness.h's bench_configs: n×(7·arms), each arm's 7 values within the Panda limits, the same
    doubles as the C programs draw."""
    s = (seed * 0x9E3779B97F4A7C15 + 1) & _MASK
    out = np.empty((n, 7 * arms))
    for i in range(n):
        for j in range(7 * arms):
            s ^= (s << 13) & _MASK
            s ^= s >> 7
            s ^= (s << 17) & _MASK
            u = (s >> 11) * (1.0 / 9007199254740992.0)
            out[i, j] = LOWER[j % 7] + u * (UPPER[j % 7] - LOWER[j % 7])
    return out


def median_ns(loop, calls: int, repeats: int) -> float:
    loop()  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        loop()
        times.append((time.perf_counter_ns() - t0) / calls)
    return statistics.median(times)


def _cycle(items, calls):
    return [items[i % len(items)] for i in range(calls)]


def gagen_calls(folder: str | Path, kernels: list[str], qs: np.ndarray, calls: int = CALLS,
                repeats: int = REPEATS) -> dict[str, dict[str, float]]:
    """Per kernel of the generated module in ``folder``, ns per call (median):

    - ``call_ns``: ``k(q)``, fresh output arrays every call (the default);
    - ``out_ns``: ``k(q, out=outs)``, into caller-owned arrays (zero allocation);
    - ``fast_ns``: ``f(q)`` with ``f = k.bind()`` (``k.fast``): outputs bound once, the fastest call;
    - ``ctypes_ns``: ``k(q)`` through the ctypes fallback (the same kernel without the binding);
    - ``casadi_ns``: the generated CasADi Function called on the numpy q (``casadi.<kernel>(q)``)."""
    from gagen.codegen.backends.c.loader import CKernel
    from gagen.runtime import load

    module = load(folder)
    seq = _cycle([np.ascontiguousarray(q, dtype=float) for q in qs], calls)
    out = {}
    for name in kernels:
        kernel = getattr(module.c, name)
        if kernel.fast is None:
            raise RuntimeError(f"{folder}: no CPython binding, calls go through ctypes")
        entry = next(k for k in module.manifest["kernels"] if k["name"] == name)
        via_ctypes = CKernel(module.library, entry, binding=None)
        casadi_function = getattr(module.casadi, name)
        outs = kernel.empty()

        def loop(f):
            def run():
                for q in seq:
                    f(q)
            return run

        def into(kernel=kernel, outs=outs):
            for q in seq:
                kernel(q, out=outs)

        out[name] = {"call_ns": median_ns(loop(kernel), calls, repeats),
                     "out_ns": median_ns(into, calls, repeats),
                     "fast_ns": median_ns(loop(kernel.bind()), calls, repeats),
                     "ctypes_ns": median_ns(loop(via_ctypes), calls, repeats),
                     "casadi_ns": median_ns(loop(casadi_function), calls, repeats)}
    return out


def pinocchio_python(qs: np.ndarray, calls: int = CALLS, repeats: int = REPEATS) -> dict[str, float]:
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    frame = model.getFrameId(TIP)
    seq = _cycle([np.ascontiguousarray(q) for q in qs], calls)
    fk, update, jac, world = pin.forwardKinematics, pin.updateFramePlacement, pin.computeFrameJacobian, \
        pin.ReferenceFrame.WORLD

    def fk_loop():
        for q in seq:
            fk(model, data, q)
            update(model, data, frame)

    def fkj_loop():
        for q in seq:
            fk(model, data, q)
            update(model, data, frame)
            jac(model, data, q, frame, world)

    return {"fk_ns": median_ns(fk_loop, calls, repeats),
            "fk_jacobian_ns": median_ns(fkj_loop, calls, repeats)}


def pygafro_panda(tip_joint: str | None = "panda_joint8"):
    """pygafro's Panda: with tip_joint, the yaml's robot cut at that joint's child link; None: its default
    end effector (FrankaEmikaRobot)."""
    import pygafro

    if tip_joint is None:
        return pygafro.FrankaEmikaRobot()
    yaml = os.path.join(os.path.dirname(pygafro.__file__), "assets", "robots", "panda", "panda.yaml")
    return pygafro.createManipulator(yaml, 7, tip_joint)


def pygafro_calls(qs: np.ndarray, calls: int = CALLS, repeats: int = REPEATS) -> dict[str, float]:
    robot = pygafro_panda()
    seq = _cycle([[float(x) for x in q] for q in qs], calls)  # its bindings take list[float]
    motor, jacobian = robot.getEEMotor, robot.getEEGeometricJacobian

    def fk_loop():
        for q in seq:
            motor(q)

    def fkj_loop():
        for q in seq:
            motor(q)
            jacobian(q)

    return {"fk_ns": median_ns(fk_loop, calls, repeats),
            "fk_jacobian_ns": median_ns(fkj_loop, calls, repeats)}


def _twist(column) -> np.ndarray:
    """A motor-generator column [e12, e13, e23, e1∞, e2∞, e3∞] as Pinocchio's [v; ω]."""
    e12, e13, e23, e1i, e2i, e3i = column
    return np.array([e1i, e2i, e3i, e23, -e13, e12])


def check_pygafro(n: int = 20, seed: int = 3) -> dict:
    """pygafro's Panda against Pinocchio on our URDF: pose to panda_link8 and the WORLD Jacobian (as
    getEEGeometricJacobian), and the constant offset of FrankaEmikaRobot's end effector from panda_link8."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    frame = model.getFrameId(TIP)
    robot, flange = pygafro_panda(), pygafro_panda(None)
    rng = np.random.default_rng(seed)
    pose_err = jac_err = 0.0
    offsets = []
    for _ in range(n):
        q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacement(model, data, frame)
        T = data.oMf[frame].homogeneous
        J = pin.computeFrameJacobian(model, data, q, frame, pin.ReferenceFrame.WORLD)
        ql = [float(x) for x in q]
        ours = np.asarray(robot.getEEMotor(ql).toTransformationMatrix())
        pose_err = max(pose_err, float(np.max(np.abs(ours - T))))
        cols = [_twist(np.asarray(c.vector())) for c in robot.getEEGeometricJacobian(ql)]
        jac_err = max(jac_err, float(np.max(np.abs(np.array(cols).T - J))))
        offsets.append(np.linalg.inv(T) @ np.asarray(flange.getEEMotor(ql).toTransformationMatrix()))
    offset = np.mean(offsets, axis=0)
    spread = float(np.max(np.abs(np.array(offsets) - offset)))
    return {"tip_pose_max_err": pose_err, "world_jacobian_max_err": jac_err,
            "flange_offset_translation": offset[:3, 3].round(12).tolist(),
            "flange_offset_rz_deg": float(np.degrees(np.arctan2(offset[1, 0], offset[0, 0]))),
            "flange_offset_spread": spread}


def one_call_table(folder: str | Path = ROOT / "generated" / "panda_point", calls: int = CALLS) -> str:
    """Panda FK + J, one call from Python, every way side by side (medians, one run)."""
    timings = gagen_calls(folder, ["arm0_fk_jacobian"], configs(), calls)["arm0_fk_jacobian"]
    rows = [("`k(q)`: fresh arrays (default)", "call_ns", 400), ("`k(q, out=outs)`", "out_ns", 150),
            ("`f(q)`, `f = k.bind()` (= `k.fast`)", "fast_ns", None),
            ("`k(q)` through the ctypes fallback", "ctypes_ns", None),
            ("`casadi.arm0_fk_jacobian(q)` (CasADi Function)", "casadi_ns", None)]
    lines = ["| Panda FK + J from Python | ns per call (median) | target |", "|---|---:|---:|"]
    for label, key, target in rows:
        lines.append(f"| {label} | {timings[key]:.0f} | {f'≤ {target}' if target else ''} |")
    return "\n".join(lines)


def main() -> None:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--module", default=str(ROOT / "generated" / "panda_point"),
                        help="the generated panda_point module (compiled on first use)")
    parser.add_argument("--calls-only", action="store_true",
                        help="only the one-call table of gagen's paths (no Pinocchio, pygafro)")
    args = parser.parse_args()
    print(one_call_table(args.module))
    if args.calls_only:
        return
    qs = configs()
    gagen = gagen_calls(args.module, ["arm0_fk", "arm0_fk_jacobian"], qs)
    print(json.dumps({"gagen": gagen,
                      "pinocchio_python": pinocchio_python(qs), "pygafro": pygafro_calls(qs),
                      "pygafro_check": check_pygafro()}, indent=1))


if __name__ == "__main__":
    main()
