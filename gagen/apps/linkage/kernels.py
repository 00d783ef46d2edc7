"""The kernel catalogue of a linkage, as front-end kernels over cga2d (``gagen.kernel``):

- ``constraints``: R (the moving bodies' motors, 4 each, ``linkage.unknown`` order) and the driver's
  value (the crank angle ``theta`` or the slider's displacement ``s``) → F (the residual rows) and J
  (∂F/∂ε, three columns per moving body);
- ``positions``: R, θ (or s) → every named point of every body (x, y);
- ``retract``: R and a Lie-algebra step ΔB (3 per body) → T(Δt) C(Δθ) R per body (C: the Cayley rotor);
- ``newton_step`` (when the constraints are as many as the unknowns, as in every mechanism of mobility
  1 without redundant joints): R, θ → the next Newton iterate and max |F| at R, the linear solve
  flattened into the kernel (``elimination``: a revolute tree's 2 × 2 blocks and a dense solve of the
  bodies' turns; CasADi's symbolic QR of J where no revolute tree reaches every body).
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from gagen.apps.linkage.constraints import MOTOR, constraints, positions, retract
from gagen.apps.linkage.elimination import structured_solve
from gagen.apps.linkage.spec import GROUND, Linkage, Prismatic, Revolute, Slider, load_linkage
from gagen.build import check_identifier
from gagen.codegen.ir import ModuleSource
from gagen.errors import read_input
from gagen.frontend import KernelFunction, matrix, scalars, source_of


def motor_labels(linkage: Linkage) -> tuple[str, ...]:
    return tuple(f"{body}_{blade}" for body in linkage.unknown for blade in MOTOR)


def step_labels(linkage: Linkage) -> tuple[str, ...]:
    return tuple(f"{body}_{g}" for body in linkage.unknown for g in ("w", "x", "y"))


def row_labels(linkage: Linkage) -> tuple[str, ...]:
    labels: list[str] = []
    for i, joint in enumerate(linkage.joints):
        if joint not in linkage.active_joints:
            continue
        if isinstance(joint, Revolute):
            labels += [f"j{i}_x", f"j{i}_y"]
        elif isinstance(joint, Prismatic):
            labels += [f"j{i}_d", f"j{i}_turn"] if isinstance(joint, Slider) else [f"j{i}_d"]
    return tuple(labels)


def point_labels(linkage: Linkage) -> tuple[str, ...]:
    return tuple(f"{body}_{name}_{c}" for body, points in linkage.bodies.items() for name in points
                 for c in "xy")


def driver_labels(linkage: Linkage) -> tuple[str, ...]:
    """The drivers' values of a mechanism of mobility k > 1 (the kernels' input ``drivers``)."""
    return tuple(f"{d.body}_{d.input}" for d in linkage.drivers)


def driver_input(linkage: Linkage) -> tuple[str, Any]:
    """The kernels' driver input: ``theta`` or ``s`` (a scalar) for one driver; ``drivers`` (k scalars,
    ``driver_labels``) for k."""
    if len(linkage.drivers) == 1:
        return linkage.driver.input, "scalar"
    return "drivers", scalars(len(linkage.drivers), driver_labels(linkage))


def _motors(ga: Any, linkage: Linkage, R: Any) -> dict[str, Any]:
    return {body: ga.make(dict(zip(MOTOR, R[4 * i:4 * i + 4], strict=True)))
            for i, body in enumerate(linkage.unknown)}


def identity_motors(linkage: Linkage) -> np.ndarray:
    """Every moving body at its initial configuration (the identity motor)."""
    return np.tile([1.0, 0.0, 0.0, 0.0], len(linkage.unknown))


def _near(linkage: Linkage, rng: np.random.Generator) -> list[np.ndarray]:
    """Motors a little off the initial configuration, and a driver value (for --check): a crank angle,
    or a slider displacement of up to a tenth of the mechanism's size."""
    motors = []
    for _ in linkage.unknown:
        a, t = rng.uniform(-0.2, 0.2), rng.uniform(-0.1, 0.1, 2)
        c, s = np.cos(a / 2), np.sin(a / 2)
        # T(t) R(a): (1 − ½ t∧e∞)(c − s e12) on 1, e12, e1∞, e2∞
        motors += [c, -s, -0.5 * (t[0] * c - t[1] * s), -0.5 * (t[1] * c + t[0] * s)]
    size = float(np.ptp(initial_points(linkage)))
    values = [rng.uniform(-np.pi, np.pi) if driver.slide is None else rng.uniform(-0.1, 0.1) * size
              for driver in linkage.drivers]
    return [np.array(motors), np.array(values)]


def initial_labels(linkage: Linkage) -> tuple[str, ...]:
    """The points a parametric kernel takes (``X0``): the ground's, then every body's, x and y."""
    points = [(GROUND, name) for name in linkage.ground]
    points += [(body, name) for body, named in linkage.bodies.items() for name in named]
    return tuple(f"{body}_{name}_{c}" for body, name in points for c in "xy")


def initial_points(linkage: Linkage) -> np.ndarray:
    """The spec's initial points in ``initial_labels`` order."""
    return np.array([v for xy in (*linkage.ground.values(), *(p for named in linkage.bodies.values()
                                                                for p in named.values())) for v in xy])


def _coordinates(linkage: Linkage, X0: Any) -> dict[tuple[str, str], list[Any]] | None:
    if X0 is None:
        return None
    refs = [(GROUND, name) for name in linkage.ground]
    refs += [(body, name) for body, named in linkage.bodies.items() for name in named]
    return {ref: [X0[2 * i], X0[2 * i + 1]] for i, ref in enumerate(refs)}


def _with_arguments(fn: Callable[..., Any], names: list[str]) -> Callable[..., Any]:
    """``fn`` called with the values in order, under the plain signature ``names``: the front end reads
    the inputs' names from it (the driver's is ``theta`` or ``s``)."""
    def call(*values: Any) -> Any:
        return fn(*values)

    kind = inspect.Parameter.POSITIONAL_OR_KEYWORD
    call.__signature__ = inspect.Signature([inspect.Parameter(n, kind) for n in names])  # type: ignore[attr-defined]
    return call


def linkage_kernels(linkage: Linkage, parametric: bool = False) -> list[KernelFunction]:
    """The kernels of one linkage, or with ``parametric`` of the family of linkages of its topology:
    every kernel but ``retract`` then also takes the initial points ``X0`` (``initial_labels``), so one
    compiled module solves many mechanisms of different dimensions, batched."""
    n, m = len(linkage.unknown), linkage.constraint_rows
    R = scalars(4 * n, motor_labels(linkage))
    driver_name, driver_type = driver_input(linkage)
    inputs: dict[str, Any] = {"R": R, driver_name: driver_type}
    if parametric:
        inputs["X0"] = scalars(2 * (len(linkage.ground) + sum(map(len, linkage.bodies.values()))),
                               initial_labels(linkage))
    inputs["ga"] = "algebra"

    def constraint_values(R: Any, theta: Any, X0: Any, ga: Any) -> dict[str, Any]:
        F, J = constraints(ga, linkage, _motors(ga, linkage, R), theta, _coordinates(linkage, X0))
        return {"F": F, "J": J}

    def position_values(R: Any, theta: Any, X0: Any, ga: Any) -> dict[str, Any]:
        return {"P": positions(ga, linkage, _motors(ga, linkage, R), theta, _coordinates(linkage, X0))}

    def retract_values(R: Any, dB: Any, ga: Any) -> dict[str, Any]:
        motors = _motors(ga, linkage, R)
        moved = [retract(ga, motors[body], dB[3 * i:3 * i + 3]) for i, body in enumerate(linkage.unknown)]
        return {"R_next": [c for motor in moved for c in (motor[b] for b in MOTOR)]}

    def with_points(fn: Any) -> Any:  # the function with the signature the declared inputs name
        if parametric:
            return _with_arguments(fn, list(inputs))
        return _with_arguments(lambda R, value, ga: fn(R, value, None, ga), list(inputs))

    def sample(rng: np.random.Generator) -> list[np.ndarray]:
        return [*_near(linkage, rng), *([initial_points(linkage)] if parametric else [])]

    def sample_step(rng: np.random.Generator) -> list[np.ndarray]:
        return [_near(linkage, rng)[0], rng.uniform(-0.1, 0.1, 3 * n)]

    rows = row_labels(linkage)
    constraint = KernelFunction(with_points(constraint_values), algebra="cga2d", name="constraints",
                                doc=f"{linkage.name}: constraint residuals and their Jacobian in se(2)",
                                inputs=inputs, sample=sample,
                                outputs={"F": scalars(m, rows), "J": matrix(scalars(m, rows), 3 * n)})
    retraction = KernelFunction(retract_values, algebra="cga2d", name="retract",
                                doc=f"{linkage.name}: the Newton update R ← T(Δt) C(Δθ) R of every "
                                    f"moving body",
                                inputs={"R": R, "dB": scalars(3 * n, step_labels(linkage)), "ga": "algebra"},
                                outputs={"R_next": R}, sample=sample_step)

    def newton_values(R: Any, theta: Any, X0: Any, ga: Any) -> dict[str, Any]:
        # the reference, on the interpreter: the same step with numpy's least squares
        extra = [np.array(X0, dtype=float)] if parametric else []
        values = np.array(theta, dtype=float).reshape(-1)  # [θ], or the k drivers' values
        F, J = constraint.reference(np.array(R, dtype=float), values, *extra)
        assert F is not None and J is not None  # (None only for a Jacobian left to AD: these are outputs)
        step = -np.linalg.lstsq(J, F.reshape(-1), rcond=None)[0]
        (R_next,) = retraction.reference(np.array(R, dtype=float), step)
        assert R_next is not None
        return {"R_next": [float(v) for v in R_next.reshape(-1)], "residual": float(np.max(np.abs(F)))}

    def newton_rule(symbols: dict[str, Any]) -> dict[str, Any]:
        # the compiler's: F and J from the constraints kernel's graph, ΔB = −J⁻¹F (the system is
        # square for a mechanism of mobility 1) by the revolute tree's elimination and a dense solve
        # of the turns (``elimination``), else CasADi's symbolic QR of J; then the retraction
        F, J = constraint.trace().function(*(symbols[name] for name in inputs if name != "ga"))
        step = structured_solve(linkage, F, J)
        if step is None:
            step = -ca.solve(J, F)
        return {"R_next": retraction.trace().function(symbols["R"], step),
                "residual": ca.mmax(ca.fabs(F))}

    position = KernelFunction(with_points(position_values), algebra="cga2d", name="positions",
                              doc=f"{linkage.name}: every body point in the world", inputs=inputs,
                              outputs={"P": scalars(len(point_labels(linkage)), point_labels(linkage))},
                              sample=sample)
    kernels = [constraint, position, retraction]
    if m == 3 * n:
        kernels.append(KernelFunction(
            with_points(newton_values), algebra="cga2d", name="newton_step",
            doc=f"{linkage.name}: one Newton step at the driver's {driver_name}, and max |F| before it"
            if len(linkage.drivers) == 1 else
            f"{linkage.name}: one Newton step at the {len(linkage.drivers)} drivers' values, and max |F| "
            f"before it",
            inputs=inputs, outputs={"R_next": R, "residual": "scalar"}, sample=sample, rule=newton_rule))
    return kernels


def linkage_source(spec: str | Path) -> ModuleSource:
    """The module of a linkage spec, named after the linkage."""
    path = Path(spec)
    linkage = load_linkage(path)
    check_identifier(linkage.name, "linkage name", path)
    source = source_of(linkage_kernels(linkage), linkage.name, path.name, read_input(path, "spec"),
                       f"gagen build {path.name}")
    meta = {**source.meta, "app": "linkage", "bodies": linkage.unknown, "crank": linkage.crank}
    if linkage.driver.slide is not None:
        meta["driver"] = "slider"
    if len(linkage.drivers) > 1:
        meta["drivers"] = [f"{d.body} ({d.kind})" for d in linkage.drivers]
    title = (f"kernels of {linkage.name}, a planar linkage ({len(linkage.bodies)} moving links, "
             f"{len(linkage.joints)} joints)")
    return dataclasses.replace(source, title=title, meta=meta)
