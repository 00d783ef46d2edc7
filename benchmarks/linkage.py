"""Linkage benchmarks: time per crank step (Newton to max |F| < 1e-12) of every bundled planar linkage
(gagen/apps/linkage/robots/*.yaml) in C, from Python, and in the JAX peer [LINK 3.3], side by side in
one run; markdown tables on stdout.

    python benchmarks/linkage.py            # < 2 min: 1-1.5 min on 2 shared cores, ~35 s of it JAX's
                                            # jit compilation (gagen's kernels cached; the first time
                                            # each mechanism's compile into gagen's cache, ~5-30 s more)
    python benchmarks/linkage.py --quick    # one round, 21 C revolutions
    python benchmarks/linkage.py --no-jax   # gagen only (also what it does when jax is not installed)

A driver step: a crank turns 1° (360 steps, a full revolution from the initial configuration,
assembled first), a slider moves one 1° step of its stroke's phase (s = a sin φ), and Newton on se(2)
starts from the previous configuration until max |F| < 1e-12.

- C: benchmarks/linkage_bench.c (harness.h), a plain C loop calling the generated
  ``<name>_newton_step`` kernel (one whole Newton iteration per call: constraints, the structured solve
  of ``elimination.py``, retraction; its ``residual`` is max |F| before the step) until the residual is
  below the tolerance. The kernels come from
  ``gagen.frontend.compile_kernels(linkage_kernels(L), name=L.name)`` in gagen's cache
  (``cache_root()/<name>-<key>``: the solver's own module); the harness is linked to
  their C compiled with gagen's flags (``programs.gagen_cflags``), built into benchmarks/build/. Its
  configurations after every step are checked against the Python solver's (``simulate``) to 1e-12.
- Python: ``simulate(kernels(L), L, angles)`` (the solver: ``newton_step`` through the CPython binding,
  one SVD of J per step for the conditioning, the positions and the branch-jump check), and a bare
  Python loop over the bound ``newton_step`` (no SVD).
- JAX (the peer, the paper's approach): the same Lie-algebra Newton in JAX, float64, written with SE(2)
  poses (angle, translation) per moving body instead of 2D CGA motors (the same rigid motions; the
  cheapest form for JAX): the same residuals (revolute: the difference of the two world points;
  prismatic: the signed distance of the point from its line; a slider block's turn: the sine of the
  relative angle), J = ∂F/∂ε for left perturbations exp(ε) · pose by ``jax.jacfwd`` (forward mode,
  jvp), ΔB = −J⁻¹F (``jnp.linalg.solve``; least squares when the constraints are redundant),
  pose ← T(Δt) C(Δθ) pose (the same retraction as gagen's, C the Cayley turn by 2 atan(Δθ/2)). Three
  ways to call it: ``jax.jit`` of one Newton step in a Python loop; ``jax.jit`` of a whole crank step
  (``lax.while_loop``) called per angle; ``jax.jit`` of the whole revolution (``lax.scan`` of crank
  steps, no Python per step). Its body points are checked against the Python solver's to 1e-10.

Every number is the median over the rounds, each timing every row in turn (the machine is shared). Not
part of the test suite.
"""

from __future__ import annotations

import argparse
import json
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
from run import fmt_ns, machine, table  # noqa: E402

from gagen.apps.linkage.demo import driver_path  # noqa: E402
from gagen.apps.linkage.kernels import identity_motors, linkage_kernels  # noqa: E402
from gagen.apps.linkage.solver import MAX_ITERATIONS, TOLERANCE, Trajectory, kernels, newton, simulate  # noqa: E402
from gagen.apps.linkage.spec import GROUND, Linkage, Prismatic, Revolute, Slider, load_linkage  # noqa: E402
from gagen.build import cache_root, compile_kernels  # noqa: E402
from gagen.codegen.compiler import vector_math_libraries  # noqa: E402
from gagen.frontend import source_of  # noqa: E402

ROBOTS = programs.ROOT / "gagen" / "apps" / "linkage" / "robots"
STEPS = 360  # driver steps per cycle: a crank's 1° steps, a slider's stroke in 1° of its phase
C_TARGET_NS = 2000  # four-bar step in C
RATIO_TARGET = 50  # JAX / gagen C per step
C_AGREEMENT = 1e-12  # C loop vs the Python solver: motors
JAX_AGREEMENT = 1e-10  # JAX vs the Python solver: body points


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def mechanisms() -> list[Linkage]:
    """Every bundled linkage, smallest first."""
    found = [load_linkage(p) for p in sorted(ROBOTS.glob("*.yaml"))]
    return sorted(found, key=lambda L: (len(L.bodies), L.constraint_rows, L.name))


# -- gagen: kernels, C ---------------------------------------------------------------------------------

def compile_module(linkage: Linkage) -> tuple[Any, Path]:
    """The linkage's kernels compiled into gagen's cache (the module ``solver.kernels`` uses) and its
    folder."""
    ks = linkage_kernels(linkage)
    source = source_of(ks, linkage.name)
    folder = cache_root() / f"{source.name}-{source.key[:16]}"
    return compile_kernels(ks, name=linkage.name, folder=folder), folder


def build_c(linkage: Linkage, folder: Path) -> Path:
    """linkage_bench linked to the module's C (gagen's flags; its _simd.c companion at -O3, as gagen
    compiles it), one program per mechanism, cached by content in benchmarks/build/."""
    programs.BUILD.mkdir(parents=True, exist_ok=True)
    cc, name = programs.c_compiler(), linkage.name
    header = folder / f"{name}.h"
    steps = []
    for source, flags in ((folder / f"{name}.c", programs.gagen_cflags()),
                          (folder / f"{name}_simd.c", programs.gagen_cflags("-O3"))):
        if source.exists():
            obj = programs.BUILD / f"linkage_{source.stem}.o"
            steps.append(programs.Step(obj, [*cc, *flags, f"-I{folder}", "-c", str(source), "-o", str(obj)],
                                       [source, header]))
    driver, obj = BENCH / "linkage_bench.c", programs.BUILD / f"linkage_bench_{name}.o"
    defines = [f'-DLINKAGE_HEADER="{name}.h"', f"-DLINKAGE_STEP={name}_newton_step"]
    command = [*cc, *programs.DRIVER_CFLAGS, *defines, f"-I{BENCH}", f"-I{folder}", "-c", str(driver), "-o",
               str(obj)]
    steps.append(programs.Step(obj, command, [driver, BENCH / "harness.h", header]))
    for step in steps:
        step.run(False)
    objects = [s.output for s in steps]
    program = programs.BUILD / f"linkage_bench_{name}"
    libs = [*vector_math_libraries(), "-lm"]
    programs.Step(program, [*cc, *map(str, objects), "-o", str(program), *libs], objects).run(False)
    return program


def driver_values(linkage: Linkage) -> np.ndarray:
    """The driver's values at the STEPS steps of a cycle after the initial configuration."""
    return driver_path(linkage, STEPS)[0][1:]


def run_c(program: Path, R0: np.ndarray, values: np.ndarray,
          repeats: int) -> tuple[dict[str, float], np.ndarray]:
    """The C loop's timings and its configurations after every step of a cycle."""
    header = [R0.size, values.size, TOLERANCE, MAX_ITERATIONS]
    with tempfile.TemporaryDirectory() as tmp:
        inputs, output = Path(tmp) / "inputs.bin", Path(tmp) / "motors.bin"
        inputs.write_bytes(np.concatenate([np.asarray(header, dtype=float), R0, values]).tobytes())
        out = subprocess.run([str(program), str(inputs), str(output), str(repeats)], capture_output=True,
                             text=True, check=True)
        motors = np.frombuffer(output.read_bytes(), dtype=np.float64).reshape(values.size, R0.size)
    return json.loads(out.stdout), motors


# -- gagen from Python ---------------------------------------------------------------------------------

def python_loop(step: Callable, R0: np.ndarray, values: np.ndarray) -> tuple[Callable[[], None], list[int]]:
    """A bare Python loop over the bound ``newton_step`` for one cycle, and its calls per run."""
    thetas = [np.array([a]) for a in values]
    calls = [0]

    def revolution() -> None:
        R, n = R0.copy(), 0
        for theta in thetas:
            for _ in range(MAX_ITERATIONS + 1):
                R_next, residual = step(R, theta)
                n += 1
                if residual[0] < TOLERANCE:
                    break
                R[:] = R_next  # the bound outputs are reused by the next call: copy
        calls[0] = n

    return revolution, calls


def seconds(run: Callable[[], Any], repeats: int) -> float:
    """Median wall time of ``run`` (after one warm-up run)."""
    run()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


# -- the JAX peer ----------------------------------------------------------------------------------------

class JaxPeer:
    """The Lie-algebra Newton of one linkage in JAX (float64), on SE(2) poses q = (φ, tx, ty) per moving
    body (``linkage.unknown`` order); x ↦ R(φ) x + t maps a body's points (given at the initial
    configuration, its frame) into the world. The residual is vectorised the JAX way: every joint's
    points are gathered from one pose table (ground, crank, moving bodies), not traced one by one."""

    def __init__(self, linkage: Linkage) -> None:
        import jax
        import jax.numpy as jnp

        jax.config.update("jax_enable_x64", True)
        self.jax, self.jnp, self.linkage = jax, jnp, linkage
        self.moving = linkage.unknown
        self.square = linkage.constraint_rows == 3 * len(self.moving)
        table = [GROUND, linkage.crank, *self.moving]  # rows of the pose table
        revolute = [j for j in linkage.active_joints if isinstance(j, Revolute)]
        prismatic = [j for j in linkage.active_joints if isinstance(j, Prismatic)]
        self.rev_a = np.array([table.index(j.a[0]) for j in revolute], dtype=int)
        self.rev_b = np.array([table.index(j.b[0]) for j in revolute], dtype=int)
        self.rev_xa = np.array([linkage.point(j.a) for j in revolute], dtype=float).reshape(-1, 2)
        self.rev_xb = np.array([linkage.point(j.b) for j in revolute], dtype=float).reshape(-1, 2)
        self.pri_p = np.array([table.index(j.point[0]) for j in prismatic], dtype=int)
        self.pri_on = np.array([table.index(j.on) for j in prismatic], dtype=int)
        self.pri_x = np.array([linkage.point(j.point) for j in prismatic], dtype=float).reshape(-1, 2)
        self.pri_c = np.array([j.through for j in prismatic], dtype=float).reshape(-1, 2)
        self.pri_d = np.array([j.direction for j in prismatic], dtype=float).reshape(-1, 2)
        self.all_body = np.array([table.index(b) for b, pts in linkage.bodies.items() for _ in pts],
                                 dtype=int)
        self.all_x = np.array([xy for pts in linkage.bodies.values() for xy in pts.values()], dtype=float)
        slider = [j for j in linkage.active_joints if isinstance(j, Slider)]
        self.sli_p = np.array([table.index(j.point[0]) for j in slider], dtype=int)
        self.sli_on = np.array([table.index(j.on) for j in slider], dtype=int)
        slide = linkage.driver.slide
        if slide is None:
            self.pivot = np.array(linkage.ground[linkage.pivot], dtype=float)
        else:  # the driven block translates by s along its slot (by −s when the block carries it)
            self.slide = (1.0 if slide.on == GROUND else -1.0) * np.array(slide.direction, dtype=float)
        self.values = driver_values(linkage)
        self.newton_step = jax.jit(self._newton)
        self.crank_step = jax.jit(self._crank_step)
        self.revolution = jax.jit(lambda q, angles: jax.lax.scan(self._scan_step, q, angles))
        self.positions = jax.jit(jax.vmap(self._positions))

    def _table(self, q: Any, theta: Any) -> tuple[Any, Any, Any]:
        """cos φ, sin φ and t of every body: the ground, the driven body (a crank turned by θ about its
        pivot, or a slider moved by s), the moving bodies."""
        jnp = self.jnp
        if self.linkage.driver.slide is None:
            c, s = jnp.cos(theta), jnp.sin(theta)
            px, py = self.pivot
            crank_t = jnp.stack([px - (c * px - s * py), py - (s * px + c * py)])
            driven = theta
        else:
            crank_t, driven = theta * self.slide, jnp.zeros_like(theta)
        phi = jnp.concatenate([jnp.zeros(1), driven[None], q[:, 0]])
        t = jnp.concatenate([jnp.zeros((1, 2)), crank_t[None], q[:, 1:]])
        return jnp.cos(phi), jnp.sin(phi), t

    @staticmethod
    def _rotate(c: Any, s: Any, x: Any) -> Any:
        return (c * x[:, 0] - s * x[:, 1], s * x[:, 0] + c * x[:, 1])

    def _world(self, table: tuple[Any, Any, Any], body: np.ndarray, x: np.ndarray,
               vector: bool = False) -> Any:
        c, s, t = table
        rx, ry = self._rotate(c[body], s[body], x)
        return self.jnp.stack([rx, ry], axis=1) + (0 if vector else t[body])

    def residual(self, q: Any, theta: Any) -> Any:
        """F: revolute rows a − b (x, y); prismatic rows the signed distance of the point from the line
        (its normal (−d_y, d_x)); slider blocks' turn rows sin(φ_on − φ_point); as gagen's constraints
        (rows grouped by joint kind: the same Newton step)."""
        table = self._table(q, theta)
        rev = self._world(table, self.rev_a, self.rev_xa) - self._world(table, self.rev_b, self.rev_xb)
        x = self._world(table, self.pri_p, self.pri_x) - self._world(table, self.pri_on, self.pri_c)
        d = self._world(table, self.pri_on, self.pri_d, vector=True)
        c, s, _ = table
        turn = s[self.sli_on] * c[self.sli_p] - c[self.sli_on] * s[self.sli_p]
        return self.jnp.concatenate([rev.reshape(-1), d[:, 0] * x[:, 1] - d[:, 1] * x[:, 0], turn])

    def _retract(self, q: Any, eps: Any) -> Any:
        """T(Δt) C(Δθ) · pose per body (eps: (Δθ, Δtx, Δty) per body), C the Cayley turn by
        α = 2 atan(Δθ/2) as gagen's retraction: φ + α, R(α) t + Δt."""
        jnp = self.jnp
        e = eps.reshape(-1, 3)
        h = e[:, 0] / 2
        c, s = (1 - h * h) / (1 + h * h), 2 * h / (1 + h * h)  # cos α, sin α
        tx, ty = q[:, 1], q[:, 2]
        return jnp.stack([q[:, 0] + 2 * jnp.arctan(h), c * tx - s * ty + e[:, 1], s * tx + c * ty + e[:, 2]],
                         axis=1)

    def _newton(self, q: Any, theta: Any) -> tuple[Any, Any]:
        """One Newton iteration: the next q and max |F| at q."""
        jnp = self.jnp
        F = self.residual(q, theta)
        zero = jnp.zeros(3 * len(self.moving))
        J = self.jax.jacfwd(lambda e: self.residual(self._retract(q, e), theta))(zero)
        step = jnp.linalg.solve(J, -F) if self.square else jnp.linalg.lstsq(J, -F)[0]
        return self._retract(q, step), jnp.max(jnp.abs(F))

    def _crank_step(self, q: Any, theta: Any) -> tuple[Any, Any]:
        """Newton at θ from q until max |F| < tolerance (as the C loop: the residual before a step
        decides); the solution and (its residual, the Newton calls)."""
        lax = self.jax.lax
        q_next, r = self._newton(q, theta)

        def more(state: tuple[Any, Any, Any, Any]) -> Any:
            return (state[2] >= TOLERANCE) & (state[3] <= MAX_ITERATIONS)

        def iterate(state: tuple[Any, Any, Any, Any]) -> tuple[Any, Any, Any, Any]:
            _, q_next, _, k = state
            return (q_next, *self._newton(q_next, theta), k + 1)

        q, _, r, k = lax.while_loop(more, iterate, (q, q_next, r, 1))
        return q, (r, k)

    def _scan_step(self, q: Any, theta: Any) -> tuple[Any, tuple[Any, Any, Any]]:
        q, (r, k) = self._crank_step(q, theta)
        return q, (q, r, k)

    def _positions(self, q: Any, theta: Any) -> Any:
        """Every body point (``point_labels`` order), as gagen's positions."""
        return self._world(self._table(q, theta), self.all_body, self.all_x).reshape(-1)

    def start(self) -> Any:
        """The assembled configuration at crank 0 (the initial one: identity poses, solved)."""
        q = self.jnp.zeros((len(self.moving), 3))
        return self.crank_step(q, 0.0)[0]

    def loops(self) -> dict[str, Callable[[], Any]]:
        """One revolution each way: jit(newton step) in a Python loop, jit(crank step) per angle,
        jit(scan) of the whole revolution."""
        q0 = self.start()
        angles = self.jnp.asarray(self.values)
        thetas = [self.jnp.asarray(a) for a in self.values]

        def newton_loop() -> Any:
            q = q0
            for theta in thetas:
                for _ in range(MAX_ITERATIONS + 1):
                    q_next, r = self.newton_step(q, theta)
                    if float(r) < TOLERANCE:  # a host sync per iteration, as any Python Newton loop
                        break
                    q = q_next
            return q

        def crank_loop() -> Any:
            q = q0
            for theta in thetas:
                q = self.crank_step(q, theta)[0]
            return q.block_until_ready()

        def scan() -> Any:
            return self.revolution(q0, angles)[0].block_until_ready()

        return {"jax_newton": newton_loop, "jax_crank": crank_loop, "jax_scan": scan}

    def trajectory(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Body points after every step of the revolution (scan), each step's Newton calls and final
        residual, and how far the crank-step loop's last configuration is from the scan's (the same
        path)."""
        q0 = self.start()
        last, (qs, r, k) = self.revolution(q0, self.jnp.asarray(self.values))
        points = self.positions(qs, self.jnp.asarray(self.values))
        q = q0
        for a in self.values:
            q = self.crank_step(q, self.jnp.asarray(a))[0]
        return np.asarray(points), np.asarray(k), np.asarray(r), float(np.max(np.abs(q - last)))


def jax_version() -> str | None:
    try:
        import jax
        import jaxlib
    except ImportError:
        return None
    return f"JAX {jax.__version__} (jaxlib {jaxlib.__version__}, {jax.default_backend()})"


# -- one mechanism ---------------------------------------------------------------------------------------

class Mechanism:
    """Everything timed for one linkage, set up and checked once."""

    def __init__(self, linkage: Linkage, with_jax: bool) -> None:
        self.linkage, self.name = linkage, linkage.name
        t0 = time.perf_counter()
        self.module, folder = compile_module(linkage)
        self.kernels = kernels(linkage, self.module)
        self.compile_s = time.perf_counter() - t0
        self.R0 = newton(self.kernels, identity_motors(linkage), 0.0).motors
        self.values = driver_values(linkage)
        self.reference: Trajectory = simulate(self.kernels, linkage, self.values)
        if self.reference.failures:
            raise SystemExit(f"{self.name}: the solver failed: {self.reference.failures[:3]}")
        self.has_step = self.kernels.newton_step is not None
        self.program = build_c(linkage, folder) if self.has_step else None
        self.checks: dict[str, Any] = {"halvings": int(np.sum(self.reference.halvings)),
                                       "iterations": float(np.mean(self.reference.iterations))}
        if self.program is not None:
            c, motors = run_c(self.program, self.R0, self.values, 21)
            self.checks["c_error"] = float(np.max(np.abs(motors - self.reference.motors)))
            if self.checks["c_error"] > C_AGREEMENT or c["unconverged"]:
                raise SystemExit(f"{self.name}: the C loop's configurations differ from the solver's by "
                                 f"{self.checks['c_error']:.1e} ({c['unconverged']:.0f} unconverged steps)")
            self.loop, self.loop_calls = python_loop(self.kernels.newton_step.bind(), self.R0, self.values)
        self.jax: JaxPeer | None = None
        if with_jax:
            t0 = time.perf_counter()
            self.jax = JaxPeer(linkage)
            points, k, r, apart = self.jax.trajectory()
            self.jax_loops = self.jax.loops()
            for run in self.jax_loops.values():
                run()  # compiled here, not in the timings
            self.checks["jax_compile_s"] = time.perf_counter() - t0
            self.checks["jax_error"] = max(float(np.max(np.abs(points - self.reference.points))), apart)
            self.checks["jax_calls"] = float(np.mean(k))
            if self.checks["jax_error"] > JAX_AGREEMENT or np.max(r) >= TOLERANCE:
                raise SystemExit(f"{self.name}: the JAX peer's points differ from the solver's by "
                                 f"{self.checks['jax_error']:.1e} (max |F| {np.max(r):.1e})")

    def time(self, repeats: int, c_repeats: int) -> dict[str, float]:
        """ns per crank step of every row (one round)."""
        steps = self.values.size
        out: dict[str, float] = {}
        if self.program is not None:
            c, _ = run_c(self.program, self.R0, self.values, c_repeats)
            out.update(c_step=c["step_ns"], c_call=c["call_ns"], c_calls=c["calls_per_step"])
            out["py_loop"] = seconds(self.loop, repeats) / steps * 1e9
            out["py_calls"] = self.loop_calls[0] / steps
        solve = lambda: simulate(self.kernels, self.linkage, self.values)  # noqa: E731
        out["simulate"] = seconds(solve, repeats) / steps * 1e9
        if self.jax is not None:
            for key, run in self.jax_loops.items():
                out[key] = seconds(run, repeats) / steps * 1e9
        return out


# -- report ------------------------------------------------------------------------------------------------

def _us(ns: float | None) -> str:
    return "–" if ns is None else f"{ns / 1000:.2f}"


def _ratio(a: float | None, b: float | None) -> str:
    return "–" if a is None or b is None else f"{a / b:.0f}×" if a / b >= 10 else f"{a / b:.1f}×"


def report(mechs: list[Mechanism], times: dict[str, dict[str, float]], run: dict[str, Any]) -> None:
    print("# Linkage benchmarks\n\n`python benchmarks/linkage.py`\n\n" + machine())
    jax = run["jax"] or f"JAX not installed ({run['jax_why']}): no JAX rows"
    print(f"- {jax}\n- driver steps: a crank's 1° over a full revolution ({STEPS} steps), a slider's "
          f"stroke s = a sin φ in 1° steps of φ, from the assembled initial configuration, Newton from "
          f"the previous configuration to max |F| < {TOLERANCE:g}\n"
          f"- C: kernels compiled with gagen's `{' '.join(programs.gagen_cflags())}`, the loop "
          f"`{' '.join(programs.DRIVER_CFLAGS)}`; median of {run['c_repeats']} revolutions\n"
          f"- Python and JAX: median of {run['repeats']} revolutions\n"
          f"- every number: the median over {run['rounds']} rounds, each timing every row in turn\n")

    print("## gagen: time per crank step (µs, median)\n")
    rows = []
    for m in mechs:
        t, L = times[m.name], m.linkage
        c = t.get("c_step")
        met = "" if c is None or m.name != "four_bar" else f"≤ {C_TARGET_NS / 1000:g} µs " + (
            "✓" if c <= C_TARGET_NS else "✗")
        rows.append([m.name, f"{len(L.unknown)} × 3 / {L.constraint_rows}",
                     "–" if c is None else f"{t['c_calls']:.2f}", fmt_ns(t.get("c_call")), _us(c), met,
                     _us(t.get("py_loop")), _us(t["simulate"]), _ratio(t["simulate"], c)])
    print(table(["mechanism", "unknowns / rows", "Newton calls per step", "C ns per `newton_step` call",
                 "C µs per step", "target", "Python loop µs per step", "`simulate` µs per step",
                 "`simulate` / C"], "lrrrrrrrr", rows))
    print("\n- C: the C loop over `<name>_newton_step`; calls per step count the last call, which only "
          "confirms convergence (its residual is max |F| before its step)\n"
          "- Python loop: the same loop in Python over the bound kernel (`f = k.newton_step.bind()`), no "
          "SVD\n- `simulate`: the solver (`gagen.apps.linkage.solver.simulate`): the same kernel calls plus "
          "one SVD of J per step (conditioning), the positions and the branch-jump check per step\n")

    if run["jax"]:
        print("## The JAX peer [LINK 3.3]: time per crank step (µs, median) and JAX / gagen C\n")
        rows = []
        for m in mechs:
            t, c = times[m.name], times[m.name].get("c_step")
            best = min(t["jax_newton"], t["jax_crank"], t["jax_scan"])
            met = "–" if c is None else (f"≥ {RATIO_TARGET}× " + ("✓" if best / c >= RATIO_TARGET else "✗"))
            jax = [t["jax_newton"], t["jax_crank"], t["jax_scan"]]
            rows.append([m.name, _us(c), *map(_us, jax), *(_ratio(j, c) for j in jax), met])
        print(table(["mechanism", "gagen C", "JAX jit(newton step), Python loop", "JAX jit(crank step) per "
                     "angle", "JAX jit(scan of the revolution)", "÷ C", "÷ C", "÷ C",
                     "target (fastest JAX ÷ C)"], "lrrrrrrrr", rows))
        print("\n- JAX: SE(2) poses (φ, tx, ty) per moving body, the same residuals as gagen's constraints, "
              "J by `jax.jacfwd` (forward mode) of F at left perturbations, `jnp.linalg.solve`, the same "
              "retraction T(Δt) C(Δθ) (C the Cayley turn by 2 atan(Δθ/2)); float64 (`jax_enable_x64`); "
              "compiled before timing\n"
              "- jit(newton step): one iteration per call, `float(max |F|)` read back each time (a "
              "Python Newton loop); jit(crank step): Newton in `lax.while_loop`; jit(scan): the whole "
              "revolution in one call, `lax.scan` of crank steps\n")

    print("## Checks\n")
    rows = []
    for m in mechs:
        ch = m.checks
        rows.append([m.name, f"{ch['iterations']:.2f}", ch["halvings"],
                     f"{ch['c_error']:.1e}" if "c_error" in ch else "no `newton_step` kernel (redundant "
                     "constraints)", f"{ch['jax_error']:.1e}" if "jax_error" in ch else "–",
                     f"{ch['jax_calls']:.2f}" if "jax_calls" in ch else "–", f"{m.compile_s:.1f}",
                     f"{ch['jax_compile_s']:.1f}" if "jax_compile_s" in ch else "–"])
    print(table(["mechanism", "solver iterations per step", "step halvings", "C motors − solver's (max)",
                 "JAX points − solver's (max)", "JAX Newton calls per step", "gagen kernels s (cached)",
                 "JAX jit s"], "lrrrrrrr", rows))
    print(f"\nC loop: every step's motors against `simulate`'s to {C_AGREEMENT:g}; JAX: every body point "
          f"after every step (scan; the crank-step loop's last poses against the scan's) against "
          f"`simulate`'s to {JAX_AGREEMENT:g}. gagen kernels s: `compile_kernels` into gagen's cache (a "
          "build the first time, a load after); JAX jit s: tracing and XLA compilation of the JAX "
          "functions.\n")
    print(f"_whole run {run['total']:.0f} s_")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one round, fewer repeats")
    ap.add_argument("--no-jax", action="store_true", help="time gagen only")
    args = ap.parse_args()
    rounds, repeats, c_repeats = (1, 3, 21) if args.quick else (3, 3, 51)
    start = time.perf_counter()
    version = None if args.no_jax else jax_version()
    why = "--no-jax" if args.no_jax else "`import jax` fails: pip install -e '.[bench]'"
    mechs = []
    for linkage in mechanisms():
        log(f"{linkage.name}: kernels, C harness, reference trajectory{', JAX' if version else ''} ...")
        mechs.append(Mechanism(linkage, version is not None))
    runs: dict[str, list[dict[str, float]]] = {m.name: [] for m in mechs}
    for r in range(rounds):
        log(f"timing, round {r + 1} of {rounds} ...")
        for m in mechs:
            runs[m.name].append(m.time(repeats, c_repeats))
    times = {name: {k: statistics.median(run[k] for run in rs) for k in rs[0]} for name, rs in runs.items()}
    report(mechs, times, {"jax": version, "jax_why": why, "rounds": rounds, "repeats": repeats,
                          "c_repeats": c_repeats, "total": time.perf_counter() - start})
    return 0


if __name__ == "__main__":
    sys.exit(main())
