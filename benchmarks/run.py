"""gagen's benchmarks: one markdown report, every number measured side by side in the same run.

    python benchmarks/run.py [--only fk,circle,ops,build] [--repeats 51] [--calls 10000] [--big-n 100000]
                             [--rebuild] [--save PATH | --no-save]

Sections (default: all, in this order):

- fk      Panda FK and FK + 6×7 Jacobian in C: gagen (generated/panda_point, compiled with gagen's own flags
          and with -O3), Pinocchio C++ and the 4×4 matrix chain (matrix_chain.py); and one call from Python:
          gagen's ``k(q)`` and ``k.fast(q)``, Pinocchio Python and pygafro (python_calls.py);
- circle  the three-Panda circle (generated/three_pandas_circle): every system kernel per evaluation in C,
          ``similarity`` batched over 1000 and --big-n configurations and from Python, and batched Panda
          FK + J throughput (panda_point's ``arm0_fk_jacobian_batch`` over --big-n configurations);
- ops     op counts of gagen's kernels next to the 4×4 matrix chain's;
- build   build time of every bundled example, sequentially and all together (build_times.py; 2–3 min).

C timings (harness.h): BENCH_N = 1000 fixed random configurations within the joint limits, the median over
--repeats loops of the time per evaluation; batches of --big-n: the median of 5. Python timings: the median
of 7 loops of --calls calls. The C programs are built into benchmarks/build/ (programs.py; cached, so only
the first run pays for Pinocchio's templates, ~1 min). The report goes to stdout and, for a run of every
section, to benchmarks/latest.md (--save/--no-save to change that); progress goes to stderr.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import resource
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np

BENCH = Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH))

import programs  # noqa: E402 -- benchmarks/ is not a package

ROOT = programs.ROOT
URDF = ROOT / "robots" / "panda" / "panda.urdf"
PANDA = programs.GENERATED / "panda_point"
CIRCLE = programs.GENERATED / "three_pandas_circle"
SECTIONS = ("fk", "circle", "ops", "build")
LATEST = BENCH / "latest.md"
BIG_REPEATS = 5  # batches of --big-n, in the C programs


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


# -- formatting --------------------------------------------------------------------------------------
def fmt_ns(ns: float | None) -> str:
    return "–" if ns is None else (f"{ns:.0f}" if ns >= 100 else f"{ns:.1f}")


def fmt_count(n: int) -> str:
    return f"{n:,}".replace(",", " ")


def fmt_time(ns: float) -> str:
    return f"{ns / 1000:.2f} µs" if ns >= 1000 else f"{fmt_ns(ns)} ns"


def table(header: list[str], align: str, rows: list[list]) -> str:
    """A markdown table; align: one of l/r per column."""
    lines = ["| " + " | ".join(header) + " |",
             "| " + " | ".join("---:" if a == "r" else "---" for a in align) + " |"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


@dataclass
class Target:
    """A goal from the issue: measured ≤ goal."""

    what: str
    measured: float
    goal: float
    unit: str  # "ns", "×" or "s"

    def show(self, value: float) -> str:
        return {"ns": fmt_time(value), "×": f"{value:.2f}×", "s": f"{value:.1f} s"}[self.unit]

    @property
    def met(self) -> bool:
        return self.measured <= self.goal

    @property
    def goal_text(self) -> str:
        if self.unit == "ns":
            return f"≤ {self.goal / 1000:g} µs" if self.goal >= 1000 else f"≤ {self.goal:g} ns"
        return f"≤ {self.goal:g}{'×' if self.unit == '×' else ' s'}"

    def cell(self) -> str:
        """For a table's target column: the goal and whether it is met."""
        return f"{self.goal_text} {'✓' if self.met else '✗'}"


@dataclass
class Section:
    title: str
    body: list[str] = field(default_factory=list)
    targets: list[Target] = field(default_factory=list)

    def add(self, *parts: str) -> None:
        self.body.extend(parts)

    def target(self, what: str, measured: float, goal: float, unit: str) -> str:
        t = Target(what, measured, goal, unit)
        self.targets.append(t)
        return t.cell()

    def text(self) -> str:
        return f"## {self.title}\n\n" + "\n\n".join(self.body)


# -- shared state ------------------------------------------------------------------------------------
class Context:
    """Options, the built programs and their results (each program runs once, when first needed)."""

    def __init__(self, args: argparse.Namespace, paths: dict[str, Path]) -> None:
        self.args, self.paths = args, paths
        self.repeats = max(21, args.repeats)
        self._results: dict[str, dict] = {}

    def run(self, name: str) -> dict:
        if name not in self._results:
            extra = {"pinocchio": [str(URDF), str(self.repeats)], "matrix_chain": [str(self.repeats)]}
            args = extra.get(name, [str(self.repeats), str(self.args.big_n)])
            log(f"timing {self.paths[name].name} ...")
            out = subprocess.run([str(self.paths[name]), *args], capture_output=True, text=True, check=True)
            self._results[name] = json.loads(out.stdout)
        return self._results[name]


@cache
def mc_functions():
    import matrix_chain

    return matrix_chain.functions()


def manifest(folder: Path) -> dict:
    return json.loads((folder / "manifest.json").read_text())


def kernel_entry(folder: Path, name: str) -> dict:
    return next(k for k in manifest(folder)["kernels"] if k["name"] == name)


def generated_status(folder: Path) -> str:
    """Whether generated/<system> is what the current gagen builds from its spec (regenerated in
    memory and compared byte for byte, as the golden test does)."""
    from gagen.apps.cooperative.module import cooperative_source
    from gagen.build import render

    m = manifest(folder)
    spec_name = m["source"]
    rel = os.path.relpath(folder, ROOT)
    try:
        expected = render(cooperative_source(ROOT / "robots" / spec_name))
    except Exception as e:
        return f"{rel}: could not regenerate it from robots/{spec_name} ({e})"
    stale = [name for name, data in expected.items()
             if not (folder / name).is_file() or (folder / name).read_bytes() != data]
    if not stale:
        return f"{rel}: up to date with robots/{spec_name} and this gagen (regenerated, byte-identical)"
    return (f"{rel}: **stale** ({', '.join(stale[:3])}{', ...' if len(stale) > 3 else ''} differ from what "
            f"this gagen generates): run `gagen build robots/{spec_name}`")


def flag_label(optimisation: str | None = None) -> str:
    level = next(f for f in programs.gagen_cflags(optimisation) if f.startswith("-O"))
    return f"`{level}`" if optimisation else f"`{level}` (gagen's)"


def floor_ns(floor: dict, ops: dict) -> float:
    """A kernel's floor on this machine [issue 19, item 2]: one 8-lane vector sine and cosine per 8 of
    its angles, plus its flops at the scalar add/multiply throughput."""
    angles = ops.get("calls", {}).get("sin", 0)
    return -(-angles // 8) * floor["sincos8_ns"] + ops["flops"] * floor["flop_ns"]


def floor_note(floor: dict) -> str:
    how = (f"glibc's libmvec, {floor['vector']:.0f} lanes a call" if floor["vector"] else
           "libm: no libmvec in this build")
    return (f"- floor of a kernel: {fmt_ns(floor['sincos8_ns'])} ns per 8 angles (sine and cosine of 8 "
            f"angles, {how}) + its flops × {floor['flop_ns']:.3f} ns (a scalar add or multiply at full "
            "throughput); benchmarks/floor_bench.c, gagen's flags")


def ops_cell(ops: dict) -> str:
    calls = ops.get("calls", {})
    paired = calls.get("sin") and calls.get("sin") == calls.get("cos")
    return f"{ops['flops']} + {calls['sin']} sincos" if paired else str(ops["flops"])


# -- sections ----------------------------------------------------------------------------------------
def _twist(column) -> np.ndarray:
    """A motor-generator column [e12, e13, e23, e1∞, e2∞, e3∞] as Pinocchio's [v; ω]."""
    e12, e13, e23, e1i, e2i, e3i = column
    return np.array([e1i, e2i, e3i, e23, -e13, e12])


def check_gagen_fk(pin: dict, gg: dict) -> float:
    """gagen's P (e0, e1, e2, e3, e∞) and J_S against Pinocchio's position and WORLD Jacobian at q0."""
    ports = {p["name"]: p["rows"] for p in kernel_entry(PANDA, "arm0_fk_jacobian")["outputs"]}
    P = dict(zip(ports["P"], gg["P0"], strict=True))
    position = np.array([P["e1"], P["e2"], P["e3"]]) / P["e0"]
    J = np.asarray(gg["J0"]).reshape(7, 6)  # column-major 6×7: row k of this is column k
    order = ("e12", "e13", "e23", "e1inf", "e2inf", "e3inf")
    cols = [_twist([dict(zip(ports["J_S"], c, strict=True))[b] for b in order]) for c in J]
    pin_J = np.asarray(pin["J0"]).reshape(7, 6)
    return max(float(np.max(np.abs(position - pin["p0"]))), float(np.max(np.abs(np.array(cols) - pin_J))))


def section_fk(ctx: Context) -> Section:
    import matrix_chain
    import python_calls

    s = Section("1. Panda FK and FK + 6×7 Jacobian")
    pin, mc = ctx.run("pinocchio"), ctx.run("matrix_chain")
    g1, g3 = ctx.run("gagen_fk"), ctx.run("gagen_fk_O3")
    fns = mc_functions()
    mc_ops = matrix_chain.op_counts(fns)
    mc_err = matrix_chain.check_against_pinocchio(fns)  # raises past 1e-10
    fk_ops = ops_cell(kernel_entry(PANDA, "arm0_fk")["op_count"])
    fkj_ops = ops_cell(kernel_entry(PANDA, "arm0_fk_jacobian")["op_count"])

    def mc_cell(name):
        return f"{mc_ops[name].flops} + {mc_ops[name].calls.get('sin', 0)} sincos"

    ref_fk, ref_fkj = pin["fk_ns"], pin["fk_jacobian_ns"]
    ratio_fkj = g1["fk_jacobian_ns"] / ref_fkj
    fkj_target = s.target("Panda FK + J (gagen's flags) vs Pinocchio C++ (FK + computeFrameJacobian)",
                          ratio_fkj, 0.25, "×")
    floor = ctx.run("floor")
    fkj_floor = floor_ns(floor, kernel_entry(PANDA, "arm0_fk_jacobian")["op_count"])
    floor_target = s.target("Panda FK + J single call vs its floor (8-lane sin + cos + flops)",
                            g1["fk_jacobian_ns"] / fkj_floor, 1.5, "×")
    o1, o3 = flag_label(), flag_label("-O3")
    rows = [  # task, method, flags, ns, reference, flops, target
        ("floor", "7 × (sin, cos) of the joint values alone (libm)", "`-O3`", mc["sincos7_ns"], ref_fk,
         "0 + 7 sincos", ""),
        ("floor", "sin + cos of 8 angles, vector (gagen's `gagen_sincos`)", o1, floor["sincos8_ns"], ref_fk,
         "0 + 8 sincos", ""),
        ("floor", "FK + 6×7 J: 8-lane sin + cos + its flops at the scalar add/mul rate", o1, fkj_floor,
         ref_fkj, fkj_ops, ""),
        ("Panda FK", "Pinocchio C++: forwardKinematics + updateFramePlacement", "`-O3`", pin["fk_ns"], ref_fk,
         "–", ""),
        ("Panda FK", "4×4 matrix chain (CasADi SX → C)", "`-O3`", mc["fk_ns"], ref_fk, mc_cell("mc_fk"), ""),
        ("Panda FK", "gagen `panda_point_arm0_fk`", o1, g1["fk_ns"], ref_fk, fk_ops, ""),
        ("Panda FK", "gagen `panda_point_arm0_fk`", o3, g3["fk_ns"], ref_fk, fk_ops, ""),
        ("Panda FK", "gagen `panda_point_arm0_fk_batch` (n = 1000, per configuration)", o1, g1["fk_batch_ns"],
         ref_fk, fk_ops, ""),
        ("Panda FK", "gagen `panda_point_arm0_fk_batch` (n = 1000, per configuration)", o3, g3["fk_batch_ns"],
         ref_fk, fk_ops, ""),
        ("FK + 6×7 J", "Pinocchio C++: FK + updateFramePlacement + computeFrameJacobian(WORLD)", "`-O3`",
         pin["fk_jacobian_ns"], ref_fkj, "–", ""),
        ("FK + 6×7 J", "Pinocchio C++, one pass: computeJointJacobians + updateFramePlacement + "
         "getFrameJacobian(WORLD)", "`-O3`", pin["fk_jacobian_lean_ns"], ref_fkj, "–", ""),
        ("FK + 6×7 J", "4×4 matrix chain, spatial J [p_i × z_i; z_i] (= WORLD)", "`-O3`",
         mc["fk_jacobian_ns"], ref_fkj, mc_cell("mc_fk_jacobian"), ""),
        ("FK + 6×7 J", "4×4 matrix chain, geometric J [z_i × (p_e − p_i); z_i]", "`-O3`",
         mc["fk_jacobian_geo_ns"], ref_fkj, mc_cell("mc_fk_jacobian_geo"), ""),
        ("FK + 6×7 J", "gagen `panda_point_arm0_fk_jacobian` (J_S = WORLD)", o1, g1["fk_jacobian_ns"],
         ref_fkj, fkj_ops, f"{fkj_target}; {floor_target} floor"),
        ("FK + 6×7 J", "gagen `panda_point_arm0_fk_jacobian` (J_S = WORLD)", o3, g3["fk_jacobian_ns"],
         ref_fkj, fkj_ops, ""),
        ("FK + 6×7 J", "gagen `panda_point_arm0_fk_jacobian_batch` (n = 1000, per configuration)", o1,
         g1["fk_jacobian_batch_ns"], ref_fkj, fkj_ops, ""),
        ("FK + 6×7 J", "gagen `panda_point_arm0_fk_jacobian_batch` (n = 1000, per configuration)", o3,
         g3["fk_jacobian_batch_ns"], ref_fkj, fkj_ops, ""),
    ]
    s.add("### In C, per evaluation",
          table(["task", "method", "flags", "ns (median)", "× Pinocchio C++", "flops", "target"], "lllrrlr",
                [[t, m, f, fmt_ns(ns), f"{ns / ref:.2f}", ops, tg] for t, m, f, ns, ref, ops, tg in rows]))
    s.add("\n".join([
        f"- × Pinocchio C++: against the first Pinocchio C++ row of the same task; gagen's FK + J is "
        f"{g1['fk_jacobian_ns'] / pin['fk_jacobian_lean_ns']:.2f}× the one-pass variant",
        f"- flags: gagen's kernels with gagen's own `{' '.join(programs.gagen_cflags())}` "
        f"(gagen.codegen.compiler.FLAGS, without -shared) and with the same but `-O3`; Pinocchio "
        f"{programs.pinocchio_paths()['version']} (instantiated from the pip wheel's headers) "
        f"`{' '.join(programs.CXXFLAGS[:3])}`; matrix chain and timing loops "
        f"`{' '.join(programs.DRIVER_CFLAGS)}`",
        f"- {pin['n_configs']:.0f} configurations, median of {ctx.repeats} loops",
        floor_note(floor),
        "- max |difference| from Pinocchio C++ at the first configuration (position, WORLD Jacobian): "
        f"gagen {check_gagen_fk(pin, g1):.1e} (`-O3`: {check_gagen_fk(pin, g3):.1e}), matrix chain "
        f"{max(np.max(np.abs(np.subtract(mc[k], pin[k]))) for k in ('p0', 'J0')):.1e}; matrix chain vs "
        f"Pinocchio Python over 50 configurations: {mc_err:.1e}",
        f"- {generated_status(PANDA)}"]))

    # one call from Python
    qs = python_calls.configs()
    if not np.array_equal(qs[0], pin["q0"]):
        raise SystemExit("python_calls.configs() no longer reproduces harness.h's configurations")
    calls, notes = ctx.args.calls, []
    log("timing calls from Python ...")
    py_pin = python_calls.pinocchio_python(qs, calls)
    rows = []
    try:
        gg = python_calls.gagen_calls(PANDA, ["arm0_fk", "arm0_fk_jacobian"], qs, calls)
    except Exception as e:
        gg = None
        notes.append(f"gagen rows skipped: {type(e).__name__}: {e}")
    try:
        py_gafro = python_calls.pygafro_calls(qs, calls)
        gafro = python_calls.check_pygafro()
    except ImportError as e:
        py_gafro = gafro = None
        notes.append(f"pygafro rows skipped: {e}")
    for task, key, kernel, gafro_method in (
            ("Panda FK", "fk_ns", "arm0_fk", "getEEMotor"),
            ("FK + 6×7 J", "fk_jacobian_ns", "arm0_fk_jacobian", "getEEMotor + getEEGeometricJacobian")):
        ref = py_pin[key]
        method = "pin.forwardKinematics + pin.updateFramePlacement" + (
            " + pin.computeFrameJacobian(WORLD)" if kernel.endswith("jacobian") else "")
        rows.append((task, f"Pinocchio Python: {method}", ref, ref, ""))
        if py_gafro:
            rows.append((task, f"pygafro: Manipulator_7.{gafro_method}", py_gafro[key], ref, ""))
        if gg:
            for how, label in (("call_ns", f"`m.c.{kernel}(q)`"), ("fast_ns", f"`m.c.{kernel}.fast(q)`")):
                ns = gg[kernel][how]
                goal = s.target(f"one call from Python: gagen {label}", ns, 500, "ns") \
                    if kernel == "arm0_fk_jacobian" else ""
                rows.append((task, f"gagen {label}", ns, ref, goal))
    s.add("### One call from Python",
          table(["task", "method", "ns per call (median)", "× Pinocchio Python", "target"], "llrrr",
                [[t, m, fmt_ns(ns), f"{ns / ref:.2f}", tg] for t, m, ns, ref, tg in rows]))
    lines = [f"- median of 7 loops of {calls} calls, cycling through the same 1000 configurations; the loop "
             "itself (a Python `for` over a list) is included, ~10–20 ns a call",
             "- gagen: `m = gagen.load('generated/panda_point')`; `k(q)` returns fresh output arrays "
             "(M, P[, J_S]) every call; `k.fast(q)` writes into outputs bound once (`k.bind()`; "
             "`k(q, out=outs)` costs about the same); all of them thread-safe "
             "(benchmarks/python_calls.py --calls-only: every way side by side)"]
    if gg:
        k = load_kernel(PANDA, "arm0_fk_jacobian")
        _, P, J = k(np.ascontiguousarray(qs[0]))
        diff = max(np.max(np.abs(P - g1["P0"])), np.max(np.abs(J.ravel(order="F") - g1["J0"])))
        lines.append("- gagen from Python vs the C program at the first configuration: "
                     f"max |difference| {diff:.1e}")
    if gafro:
        lines.append("- pygafro's Panda (its panda.yaml cut at panda_joint8) vs our URDF: "
                     f"pose {gafro['tip_pose_max_err']:.1e}, WORLD Jacobian (getEEGeometricJacobian) "
                     f"{gafro['world_jacobian_max_err']:.1e}; its default FrankaEmikaRobot end effector is "
                     f"panda_link8 · Rz({gafro['flange_offset_rz_deg']:.0f}°) · "
                     f"Tz({gafro['flange_offset_translation'][2]:g} m)")
    lines += [f"- {n}" for n in notes]
    s.add("\n".join(lines))
    return s


def load_kernel(folder: Path, name: str):
    from gagen.runtime import load

    return getattr(load(folder).c, name)


def section_circle(ctx: Context) -> Section:
    import python_calls

    s = Section("2. Three-Panda circle")
    c = ctx.run("circle")
    g1, g3 = ctx.run("gagen_fk"), ctx.run("gagen_fk_O3")
    big = int(c["big_n"])
    o1 = flag_label()

    def ops(name):
        return str(kernel_entry(CIRCLE, name)["op_count"]["flops"])

    floor = ctx.run("floor")
    similarity_floor = floor_ns(floor, kernel_entry(CIRCLE, "similarity")["op_count"])
    rows = [  # measurement, flags, ns, flops, target
        ("floor of `similarity`: its angles' 8-lane sin + cos + its flops at the scalar add/mul rate", o1,
         similarity_floor, ops("similarity"), ""),
        ("`similarity` (V_Sc, conditioning, J_G,Sc): one call", o1, c["similarity_ns"], ops("similarity"),
         s.target("three-Panda circle V_Sc + J_G,Sc per evaluation (C)", c["similarity_ns"], 1000, "ns")
         + "; " + s.target("three-Panda circle V_Sc + J_G,Sc vs its floor",
                           c["similarity_ns"] / similarity_floor, 2.0, "×") + " floor"),
        ("`similarity_batch`, n = 1000, per configuration", o1, c["similarity_batch_ns"], ops("similarity"),
         ""),
        (f"`similarity_batch`, n = {fmt_count(big)}, per configuration", o1,
         c["similarity_batch_big_ns"], ops("similarity"), ""),
        ("`primitive` (X_c, J_c): one call", o1, c["primitive_ns"], ops("primitive"), ""),
        ("`similarity_jacobians` (J_A,Sc, log V_Sc, J_B): one call", o1, c["similarity_jacobians_ns"],
         ops("similarity_jacobians"), ""),
        ("`task` (e, J_Be): one call", o1, c["task_ns"], ops("task"), ""),
        ("for scale: `arm0_fk_jacobian` + `arm1_…` + `arm2_…` (three calls)", o1, c["arms_fk_jacobian_ns"],
         str(sum(kernel_entry(CIRCLE, f"arm{i}_fk_jacobian")["op_count"]["flops"] for i in range(3))), ""),
    ]
    notes = []
    log("timing the circle from Python ...")
    qs = python_calls.configs(arms=3)
    if not np.array_equal(qs[0], c["q0"]):
        raise SystemExit("python_calls.configs(arms=3) no longer reproduces circle_bench.c's configurations")
    try:
        py = python_calls.gagen_calls(CIRCLE, ["similarity"], qs, ctx.args.calls)["similarity"]
        rows += [("from Python: `m.c.similarity(q)`", o1, py["call_ns"], ops("similarity"), ""),
                 ("from Python: `m.c.similarity.fast(q)`", o1, py["fast_ns"], ops("similarity"), "")]
    except Exception as e:
        notes.append(f"Python rows skipped: {type(e).__name__}: {e}")
    per_core = [(f"Panda FK + J: panda_point `arm0_fk_jacobian_batch`, n = {fmt_count(big)}, per "
                 "configuration (one core)", g["fk_jacobian_batch_big_ns"], flags, False)
                for g, flags in ((g1, o1), (g3, flag_label("-O3")))]
    per_core += [(f"Panda FK + J, column layout: `arm0_fk_jacobian_batch_columns`, n = {n_label}, per "
                  "configuration (one core)", g1[key], o1, target)
                 for n_label, key, target in (("1000", "fk_jacobian_batch_columns_ns", False),
                                              (fmt_count(big), "fk_jacobian_batch_columns_big_ns", True))]
    rows += [(m, f, ns, ops_cell(kernel_entry(PANDA, "arm0_fk_jacobian")["op_count"]),
              s.target(f"batched Panda FK + J per configuration per core, n = {fmt_count(big)} "
                       f"({'column layout' if target else 'sample-major'}, gagen's flags)", ns, 40, "ns")
              if i == 0 or target else "") for i, (m, ns, f, target) in enumerate(per_core)]
    s.add(table(["measurement", "flags", "ns (median)", "flops", "target"], "llrrr",
                [[m, f, fmt_ns(ns), fl, tg] for m, f, ns, fl, tg in rows]))

    sim = load_casadi(CIRCLE, "similarity")
    V, cond, J = (np.asarray(x).ravel(order="F") for x in sim(c["q0"]))
    diff = max(np.max(np.abs(V - c["V0"])), np.max(np.abs(cond - c["cond0"])), np.max(np.abs(J - c["J0"])))
    lines = [f"- C: {c['n_configs']:.0f} configurations (each arm's 7 joints uniform within the Panda "
             f"limits), median of {ctx.repeats} loops; n = {fmt_count(big)} batches: median of "
             f"{BIG_REPEATS}; one thread. Kernels compiled with gagen's "
             f"`{' '.join(programs.gagen_cflags())}`",
             "- task's V_Sd: V_Sc at the last configuration",
             floor_note(floor),
             f"- C `similarity` vs its CasADi Function (`m.casadi.similarity`) at the first configuration: "
             f"max |difference| {diff:.1e}",
             f"- {generated_status(CIRCLE)}"]
    lines += [f"- {n}" for n in notes]
    s.add("\n".join(lines))
    return s


def load_casadi(folder: Path, name: str):
    from gagen.runtime import load

    return getattr(load(folder).casadi, name)


def section_ops(ctx: Context) -> Section:
    import matrix_chain

    s = Section("3. Op counts")
    mc_ops = matrix_chain.op_counts(mc_functions())

    def calls(c: dict) -> str:
        return ", ".join(f"{n} {k}" for n, k in sorted(c.items())) or "–"

    def row(kernel, formulation, outputs, o: dict, ref: int | None) -> list:
        ratio = f"{o['flops'] / ref:.2f}" if ref else "–"
        return [kernel, formulation, outputs, o["mul"], o["add"], o["neg"], o["div"], o["flops"], ratio,
                calls(o["calls"])]

    def mc(name) -> dict:
        o = mc_ops[name]
        return {"mul": o.mul, "add": o.add, "neg": o.neg, "div": o.div, "flops": o.flops, "calls": o.calls}

    def outputs(entry) -> str:
        return ", ".join(f"{p['name']} {len(p['rows'])}" + (f"×{p['cols']}" if p["cols"] > 1 else "")
                         for p in entry["outputs"])

    fk, fkj = kernel_entry(PANDA, "arm0_fk"), kernel_entry(PANDA, "arm0_fk_jacobian")
    ref_fk, ref_fkj = mc("mc_fk")["flops"], mc("mc_fk_jacobian")["flops"]
    header = ["kernel", "formulation", "outputs", "mul", "add", "neg", "div", "flops", "× matrix chain",
              "calls"]
    s.add("### Panda (generated/panda_point) vs the 4×4 matrix chain",
          table(header, "lllrrrrrrl", [
              row("FK", "gagen `arm0_fk` (motor M, point P)", outputs(fk), fk["op_count"], ref_fk),
              row("FK", "4×4 matrix chain `mc_fk`", "R 3×3, p 3", mc("mc_fk"), ref_fk),
              row("FK + J", "gagen `arm0_fk_jacobian`", outputs(fkj), fkj["op_count"], ref_fkj),
              row("FK + J", "4×4 matrix chain `mc_fk_jacobian` (spatial = WORLD)", "R 3×3, p 3, J 6×7",
                  mc("mc_fk_jacobian"), ref_fkj),
              row("FK + J", "4×4 matrix chain `mc_fk_jacobian_geo` (geometric)", "R 3×3, p 3, J 6×7",
                  mc("mc_fk_jacobian_geo"), ref_fkj)]),
          "- gagen: from generated/panda_point/manifest.json (`op_count`); matrix chain: CasADi's "
          "instructions after `casadi.cse` on all outputs (matrix_chain.py); flops = mul + add + neg + div, "
          "calls apart")
    rows = [[f"`{k['name']}`", outputs(k), *(k["op_count"][x] for x in ("mul", "add", "neg", "div", "flops")),
             calls(k["op_count"]["calls"])] for k in manifest(CIRCLE)["kernels"]]
    s.add("### Three-Panda circle (generated/three_pandas_circle/manifest.json)",
          table(["kernel", "outputs", "mul", "add", "neg", "div", "flops", "calls"], "llrrrrrl", rows))
    return s


def section_build(ctx: Context) -> Section:
    import build_times

    s = Section("4. Build time of the bundled examples")
    specs = sorted((ROOT / "robots").glob("*.yaml"))
    tmp = Path(tempfile.mkdtemp(prefix="gagen-bench-build-"))
    try:
        log(f"building {len(specs)} specs one at a time into {tmp}/seq ...")
        seq = build_times.sequential(specs, tmp / "seq", log)
        log(f"building {len(specs)} specs together (build_many) into {tmp}/par ...")
        par = build_times.parallel(specs, tmp / "par")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    def sec(v):
        return "–" if v is None else f"{v:.1f}"

    rows = []
    for r in seq:
        goal = s.target("build: three-Panda circle (`gagen build`, wall)", r["wall"], 15, "s") \
            if r["spec"] == "three_pandas_circle.yaml" else ""
        rows.append([r["spec"] + ("" if r["ok"] else " (**failed**)"), r["kernels"] or "–",
                     "–" if r["c_kb"] is None else f"{r['c_kb']:.0f}", sec(r["model"]), sec(r.get("source")),
                     sec(r["compile"]), sec(r["built"]), sec(r["wall"]), goal])
    total = {k: sum(r[k] or 0.0 for r in seq) for k in ("model", "compile", "built", "wall")}
    total["source"] = sum(r.get("source") or 0.0 for r in seq)
    phases = ("model", "source", "compile", "built", "wall")
    rows.append(["**all, one after another**", sum(r["kernels"] or 0 for r in seq),
                 f"{sum(r['c_kb'] or 0 for r in seq):.0f}", *(sec(total[k]) for k in phases), ""])
    cores = os.cpu_count() or 1
    rows.append([f"**all together**: `build_many` ({cores} cores), one process", "", "", "", "", "", "",
                 sec(par["wall"]) + ("" if par["ok"] else " (**failed**)"),
                 s.target("build: all bundled examples together (wall)", par["wall"], 60, "s")])
    s.add(table(["spec", "kernels", "C source (kB)", "model (s)", "render (s)", "compile (s)",
                 "`built in` (s)", "wall (s)", "target"], "lrrrrrrrr", rows))
    lines = [
        "- one at a time: `gagen build robots/<spec> -o $TMP/<name> --force`, one process each; model: "
        "\"model and N kernel graphs built\"; render: the rest before compiling (loading the spec, "
        "emitting and writing the sources); compile: the C library and the CPython binding "
        "(\"compiled … (X s)\"); `built in`: gagen's own total; wall: the process, interpreter start and "
        "imports included",
        f"- together: `build_many(specs, force=True, outputs=[$TMP/<name>, …])` in one `python -c` process "
        f"(models and sources one after another, C compilations on {cores} workers meanwhile); its compile "
        f"phases add up to {par['compile_sum']:.1f} s (one at a time: {total['compile']:.1f} s): the cores "
        "are shared with the model building",
        f"- C compiler: `{' '.join(programs.c_compiler())} {' '.join(programs.gagen_cflags())} -shared`"]
    lines += [f"- {r['spec']} failed: {r['error']}" for r in seq if r["error"]]
    if par["error"]:
        lines.append(f"- build_many failed: {par['error']}")
    s.add("\n".join(lines))
    return s


# -- report ------------------------------------------------------------------------------------------
class OtherWork:
    """CPU time the rest of the machine used meanwhile: the busy time in /proc/stat less this process's
    and its children's (every child is waited for, so its CPU time is counted when it ends)."""

    def __init__(self) -> None:
        self.start = self._sample()

    @staticmethod
    def _sample() -> tuple[float, float, float] | None:
        try:
            user, nice, system, _idle, _iowait, irq, softirq = map(
                int, Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:8])
        except (OSError, ValueError):
            return None
        busy = (user + nice + system + irq + softirq) / os.sysconf("SC_CLK_TCK")
        ours = sum(getattr(resource.getrusage(who), part) for who in (resource.RUSAGE_SELF,
                                                                       resource.RUSAGE_CHILDREN)
                   for part in ("ru_utime", "ru_stime"))
        return time.perf_counter(), busy, ours

    def stop(self) -> tuple[float, float] | None:
        """(CPU seconds used by other processes, wall seconds)."""
        end = self._sample()
        if self.start is None or end is None:
            return None
        wall = end[0] - self.start[0]
        return max(0.0, (end[1] - self.start[1]) - (end[2] - self.start[2])), wall


def other_work_line(busy: dict[str, tuple[float, float] | None]) -> str:
    parts = [f"{name} {b[0]:.1f} CPU-s in {b[1]:.0f} s" for name, b in busy.items() if b]
    if not parts:
        return ""
    cores = os.cpu_count() or 1
    heavy = [name for name, b in busy.items() if b and b[0] > 0.05 * b[1] * cores]
    warn = (f" (**other work during {', '.join(heavy)}: those timings may be inflated**)" if heavy else "")
    return "\n- other processes' CPU time during each section: " + "; ".join(parts) + warn


def command_line() -> str:
    try:
        argv = Path("/proc/self/cmdline").read_bytes().rstrip(b"\0").split(b"\0")
        return shlex.join(a.decode() for a in argv)
    except OSError:
        return shlex.join([Path(sys.executable).name, *sys.argv])


def machine() -> str:
    try:
        cpuinfo = Path("/proc/cpuinfo").read_text().splitlines()
        cpu = next(line.split(":", 1)[1].strip() for line in cpuinfo if line.startswith("model name"))
    except (OSError, StopIteration):
        cpu = platform.processor() or platform.machine()
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    import casadi

    import gagen

    git = subprocess.run(["git", "-C", str(ROOT), "describe", "--always", "--dirty=+uncommitted changes"],
                         capture_output=True, text=True).stdout.strip() or "?"
    return "\n".join([
        f"- machine: {cpu}, {os.cpu_count()} cores ({usable} usable); "
        f"{platform.system()} {platform.release()} {platform.machine()}",
        f"- compilers: {programs.compiler_version(programs.c_compiler())} "
        f"(`{' '.join(programs.c_compiler())}`), {programs.compiler_version(['g++'])} (`g++`)",
        f"- Python {platform.python_version()}, NumPy {np.__version__}, CasADi {casadi.__version__}; "
        f"gagen {gagen.__version__} (git {git})"])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=",".join(SECTIONS),
                    help=f"comma-separated sections to run, of {','.join(SECTIONS)} (default: all)")
    ap.add_argument("--repeats", type=int, default=51, help="timed loops per C measurement (median; >= 21)")
    ap.add_argument("--calls", type=int, default=10000, help="calls per timed Python loop")
    ap.add_argument("--big-n", type=int, default=100000, help="configurations of the large batches")
    ap.add_argument("--rebuild", action="store_true", help="ignore the C programs' build cache")
    save = ap.add_mutually_exclusive_group()
    save.add_argument("--save", type=Path, help=f"write the report here too (default: {LATEST.name} when "
                                                "every section runs)")
    save.add_argument("--no-save", action="store_true", help="print the report only")
    args = ap.parse_args(argv)
    only = [x.strip() for x in args.only.split(",") if x.strip()]
    unknown = set(only) - set(SECTIONS)
    if unknown or not only:
        ap.error(f"--only takes some of {','.join(SECTIONS)}, got {args.only!r}")
    selected = [x for x in SECTIONS if x in only]
    start = time.perf_counter()
    started = datetime.datetime.now(datetime.UTC)

    wanted = set()
    if "fk" in selected:
        wanted |= {"pinocchio", "matrix_chain", "gagen_fk", "gagen_fk_O3", "floor"}
    if "circle" in selected:
        wanted |= {"circle", "gagen_fk", "gagen_fk_O3", "floor"}
    for folder in (PANDA, CIRCLE) if wanted else ():  # (a fresh clone has no CasADi files: built here)
        if programs.bundled_folder(folder.name) != folder:
            raise SystemExit(f"{os.path.relpath(folder, ROOT)} is not generated from robots/"
                             f"{folder.name}.yaml as it is: run `gagen build robots/{folder.name}.yaml`")
    if wanted:
        log(f"compiling the timing programs ({', '.join(sorted(wanted))}) ...")
    paths, commands, build_s = programs.build(wanted, args.rebuild)
    ctx = Context(args, paths)

    sections, busy = [], {}
    for name in selected:
        meter = OtherWork()
        sections.append({"fk": section_fk, "circle": section_circle, "ops": section_ops,
                         "build": section_build}[name](ctx))
        busy[name] = meter.stop()

    targets = [t for s in sections for t in s.targets]
    head = ["# gagen benchmarks", "", f"`{command_line()}`", "",
            machine() + f"\n- run {started:%Y-%m-%d %H:%M} UTC; sections: {', '.join(selected)}"
            + other_work_line(busy)]
    if targets:
        head += ["", "## Targets", "",
                 table(["target", "goal", "measured", "met"], "lrrl",
                       [[t.what, t.goal_text, t.show(t.measured), "✓" if t.met else "✗ **no**"]
                        for t in targets])]
    total = time.perf_counter() - start
    tail = f"_whole run {total:.0f} s" + (f", of which compiling the timing programs {build_s:.1f} s "
                                         "(cached in benchmarks/build/)" if wanted else "") + "_"
    report = "\n".join(head) + "\n\n" + "\n\n".join(s.text() for s in sections) + "\n\n" + tail + "\n"
    if os.environ.get("BENCH_SHOW_COMMANDS"):
        report += "\n```\n" + "\n".join(commands) + "\n```\n"
    print(report)
    out = None if args.no_save else args.save or (LATEST if selected == list(SECTIONS) else None)
    if out:
        out.write_text(report)
        log(f"wrote {os.path.relpath(out.resolve(), Path.cwd())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
