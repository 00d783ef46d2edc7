"""``gagen demo``: the compiler core on a handful of CGA formulas, each checked against the interpreter.

Every formula is written once against the multivector protocol; the demo flattens it to a CasADi
kernel, reports the op count, and evaluates kernel and interpreter side by side on random inputs.
"""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO

import numpy as np
import sympy

from gagen.algebra.signature import cga3d
from gagen.crosscheck import Formula, flatten_formula, relative_error
from gagen.interp import MultiVector
from gagen.model.conformal import EUCLID, MOTOR, SIMILARITY_GENERATOR, point
from gagen.model.primitives import through
from gagen.model.similarity import cooperative_similarity
from gagen.model.versors import exp_similarity

VECTOR3 = EUCLID
PLANE = ("e012inf", "e013inf", "e023inf", "e123inf")  # grade 4 blades containing e∞


def quarter_turn(x: Any) -> Any:
    """A 90° rotation about e3 with exact constants: the zeros and ±1 fold away."""
    c = sympy.cos(sympy.pi / 4)
    return x.make({"1": c, "e12": -c}).sandwich(x)


def _formulas() -> list[Formula]:
    a = cga3d()
    return [
        Formula("motor * motor", a, (("a", MOTOR), ("b", MOTOR)), lambda m, n: m * n),
        Formula("conformal point P(x)", a, (("x", VECTOR3),), point),
        Formula("motor moves point M P M~", a, (("m", MOTOR), ("x", VECTOR3)),
                lambda m, x: m.sandwich(point(x))),
        Formula("squared distance -2 P(x).P(y)", a, (("x", VECTOR3), ("y", VECTOR3)),
                lambda x, y: -2 * point(x).sp(point(y))),
        Formula("meet of two planes", a, (("p", PLANE), ("q", PLANE)), lambda p, q: p & q),
        Formula("quarter turn (exact constants)", a, (("x", VECTOR3),), quarter_turn),
        Formula("exp similarity (7 generators)", a, (("b", SIMILARITY_GENERATOR),), exp_similarity),
        Formula("V_Sc of circle through 3 points", a, (("x", VECTOR3), ("y", VECTOR3), ("z", VECTOR3)),
                lambda x, y, z: cooperative_similarity("circle", through("circle", [point(x), point(y),
                                                                                    point(z)]))),
    ]


def _random_motor(rng: np.random.Generator) -> np.ndarray:
    """Coefficients of a unit motor T R on MOTOR's blades."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angle = rng.uniform(-np.pi, np.pi)
    t = rng.normal(size=3)
    s, c = np.sin(angle / 2), np.cos(angle / 2)
    # R = c − s (n dual), with the bivector components on e12, e13, e23 = (n3, −n2, n1)
    r = np.array([c, -s * axis[2], s * axis[1], -s * axis[0]])
    alg = cga3d()
    rotor = MultiVector.from_blades(alg, dict(zip(("1", "e12", "e13", "e23"), r, strict=True)))
    trans = MultiVector.from_blades(alg, {"1": 1.0, "e1inf": -t[0] / 2, "e2inf": -t[1] / 2,
                                          "e3inf": -t[2] / 2})
    motor = trans * rotor
    return np.array([motor[b] for b in MOTOR])


def _inputs(formula: Formula, rng: np.random.Generator) -> list[np.ndarray]:
    return [_random_motor(rng) if blades == MOTOR
            else rng.uniform(-1, 1, blades if isinstance(blades, int) else len(blades))
            for _, blades in formula.inputs]


def run(samples: int = 1000, seed: int = 0, out: TextIO = sys.stdout) -> float:
    """Print the demo table; return the worst relative error seen."""
    rng = np.random.default_rng(seed)
    algebra = cga3d()
    p, q, r = algebra.signature
    print(f"gagen compiler core on {algebra.name}: G({p},{q},{r}), null basis "
          f"{', '.join('e' + v for v in algebra.vector_labels)}", file=out)
    print(f"each kernel vs the reference interpreter on {samples} random inputs (seed {seed})\n", file=out)
    header = (f"{'formula':34} {'outputs':>7} {'mul':>5} {'add':>5} {'neg':>4} {'build ms':>9} "
              f"{'max rel err':>12}")
    print(header, file=out)
    print("-" * len(header), file=out)
    worst = 0.0
    for formula in _formulas():
        t0 = time.perf_counter()
        kernel = flatten_formula(formula)
        build_ms = 1e3 * (time.perf_counter() - t0)
        err = max(relative_error(kernel, formula, _inputs(formula, rng)) for _ in range(samples))
        worst = max(worst, err)
        ops = kernel.op_count
        print(f"{formula.name:34} {kernel.outputs[0].size:>7} {ops.mul:>5} {ops.add:>5} {ops.neg:>4} "
              f"{build_ms:>9.1f} {err:>12.1e}", file=out)
    print(f"\nworst relative error {worst:.1e}", file=out)
    return worst
