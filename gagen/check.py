"""``gagen build --check``: every generated kernel (C single, C batched, CasADi) against the interpreter.

References come from the reference interpreter running the model's formulas on floats: values
directly, the closed-form Jacobians (joint lines, Eq. 15-17) directly, and the Jacobians that the
kernels take by AD (J_A,Sc, J_G,Sc, J_B, J_Be) by central differences of the interpreter.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gagen.algebra.signature import cga3d
from gagen.interp import MultiVector
from gagen.kernels import TOOL_LINE
from gagen.model import kinematics as K
from gagen.model.conformal import SIMILARITY, SIMILARITY_GENERATOR
from gagen.model.cooperative import System, end_points, primitive_jacobian
from gagen.model.primitives import through
from gagen.model.similarity import cooperative_similarity
from gagen.model.versors import exp_similarity, log_similarity
from gagen.runtime import GeneratedModule

FD_STEP = 1e-6
BY_DIFFERENCES = ("J_A", "J_G", "J_B", "J_Be")  # system outputs the kernels differentiate by AD


@dataclass
class Discrepancy:
    """Largest absolute difference of one output over the samples, per evaluation path."""

    kernel: str
    output: str
    reference: str  # "interpreter" or "central differences"
    c_single: float
    c_batch: float
    casadi: float

    @property
    def worst(self) -> float:
        return max(self.c_single, self.c_batch, self.casadi)


def _gap(value, reference: np.ndarray) -> float:
    return float(np.max(np.abs(np.reshape(np.asarray(value, dtype=float), reference.shape) - reference)))


def _dense(x: MultiVector, rows) -> np.ndarray:
    return np.array([x[b] for b in rows])


def _matrix(columns, rows) -> np.ndarray:
    return np.array([[c[b] for b in rows] for c in columns]).T


class _Reference:
    """The interpreter's values of every kernel output at one (q, V_Sd)."""

    def __init__(self, system: System, q: np.ndarray, desired: MultiVector) -> None:
        self.system, self.q, self.desired = system, q, desired
        self.zero = MultiVector.zero(cga3d())
        self._memo: dict[tuple, object] = {}

    def _once(self, key: tuple, compute: Callable[[], object]) -> object:
        if key not in self._memo:
            self._memo[key] = compute()
        return self._memo[key]

    def chain(self, index: int, port: str, rows) -> np.ndarray:
        chain = self.system.chains[index]
        qc = self.system.split(list(self.q))[index]
        motor, lines = self._once(("chain", index), lambda: K.chain_kinematics(self.zero, chain.joints, qc))
        tool = self.zero.make({TOOL_LINE: 1})
        values = {"M": lambda: _dense(motor, rows), "P": lambda: _dense(K.end_point(motor), rows),
                  "J_S": lambda: _matrix(K.spatial_jacobian(lines), rows),
                  "J_b": lambda: _matrix(K.body_jacobian(motor, lines), rows),
                  "J_A": lambda: _matrix(K.analytic_jacobian(motor, lines), rows),
                  "J_P": lambda: _matrix(K.point_jacobian(motor, lines), rows),
                  "L": lambda: _dense(motor.sandwich(tool), rows),
                  "J_L": lambda: _matrix(K.line_jacobian(motor, lines, tool), rows)}
        return values[port]()

    def task(self, q: np.ndarray) -> dict[str, MultiVector]:
        return self._once(("task", q.tobytes()), lambda: self._task(q))

    def _task(self, q: np.ndarray) -> dict[str, MultiVector]:
        points = end_points(self.zero, self.system, list(q))
        xc = through(self.system.kind, [p for p, _ in points])
        v, conditioning = cooperative_similarity(self.system.kind, xc)
        return {"X_c": xc, "V_Sc": v, "conditioning": conditioning, "log_V": log_similarity(v),
                "e": log_similarity(~v * self.desired), "points": points}

    def system_output(self, port: str, rows) -> np.ndarray:
        at = self.task(self.q)
        if port == "J_c":
            return _matrix(primitive_jacobian(self.system, at["points"]), rows)
        if port == "conditioning":
            return np.array([at["conditioning"]])
        if port in BY_DIFFERENCES:
            return self._differences(port, at["V_Sc"], rows)
        return _dense(at[port], rows)

    def _differences(self, port: str, v: MultiVector, rows) -> np.ndarray:
        of = {"J_A": "V_Sc", "J_G": "V_Sc", "J_B": "log_V", "J_Be": "e"}[port]
        columns = []
        for i in range(self.q.size):
            step = np.zeros(self.q.size)
            step[i] = FD_STEP
            d = (self.task(self.q + step)[of] - self.task(self.q - step)[of]) * (0.5 / FD_STEP)
            columns.append(~v * d * -2 if port == "J_G" else d)
        return _matrix(columns, rows)


def samples(system: System, ready: list[float] | None, count: int, seed: int) -> list[tuple[np.ndarray,
                                                                                             MultiVector]]:
    """(q, V_Sd) pairs: q near the ready configuration (or uniform in ±1 rad), V_Sd a random similarity."""
    rng = np.random.default_rng(seed)
    centre = np.array(ready if ready is not None else np.zeros(system.dof))
    spread = 0.4 if ready is not None else 1.0
    zero = MultiVector.zero(cga3d())
    out = []
    for _ in range(count):
        generator = zero.make(dict(zip(SIMILARITY_GENERATOR, rng.uniform(-0.5, 0.5, 7), strict=True)))
        out.append((centre + rng.uniform(-spread, spread, system.dof), exp_similarity(generator)))
    return out


def check_module(module: GeneratedModule, system: System, ready: list[float] | None = None, count: int = 5,
                 seed: int = 0, progress: Callable[[str], None] = lambda _: None) -> list[Discrepancy]:
    """Evaluate every kernel of ``module`` on ``count`` samples; one Discrepancy per output."""
    chain_index = {c.name: i for i, c in enumerate(system.chains)}
    pairs = samples(system, ready, count, seed)
    result = []
    for entry in module.manifest["kernels"]:
        name = entry["name"]
        progress(f"  checking {name}")
        c_kernel, ca_function = getattr(module.c, name), getattr(module.casadi, name)
        scope = next((c for c in chain_index if name.startswith(c + "_")
                      and name[len(c) + 1:] in ("fk", "fk_jacobian", "jacobians")), None)
        worst: dict[str, list[float]] = {p["name"]: [0.0, 0.0, 0.0] for p in entry["outputs"]}
        batch_inputs = []
        references = []
        for q, desired in pairs:
            reference = _Reference(system, q, desired)
            inputs = [q if p["name"] == "q" else np.array([desired[b] for b in SIMILARITY])
                      for p in entry["inputs"]]
            if scope is not None:
                inputs = [np.array(system.split(list(q))[chain_index[scope]])]
            batch_inputs.append(inputs)
            c_out = c_kernel(*inputs)
            c_out = c_out if isinstance(c_out, tuple) else (c_out,)
            ca_out = ca_function(*inputs)
            ca_out = ca_out if isinstance(ca_out, (list, tuple)) else [ca_out]
            refs = []
            for k, port in enumerate(entry["outputs"]):
                rows, shape = port["rows"], (len(port["rows"]), port["cols"])
                ref = (reference.chain(chain_index[scope], port["name"], rows) if scope is not None
                       else reference.system_output(port["name"], rows)).reshape(shape)
                refs.append(ref)
                w = worst[port["name"]]
                w[0] = max(w[0], _gap(c_out[k], ref))
                w[2] = max(w[2], _gap(ca_out[k], ref))
            references.append(refs)
        stacked_inputs = [np.array([b[i] for b in batch_inputs]) for i in range(len(entry["inputs"]))]
        batched = c_kernel.batch(*stacked_inputs)
        batched = batched if isinstance(batched, tuple) else (batched,)
        for k, port in enumerate(entry["outputs"]):
            shape = (len(pairs), len(port["rows"]), port["cols"])
            stacked = np.array([refs[k] for refs in references]).reshape(shape)
            worst[port["name"]][1] = _gap(batched[k], stacked)
        for port in entry["outputs"]:
            by_differences = scope is None and port["name"] in BY_DIFFERENCES
            result.append(Discrepancy(name, port["name"], "central differences" if by_differences
                                      else "interpreter", *worst[port["name"]]))
    return result


def format_report(discrepancies: list[Discrepancy]) -> str:
    lines = ["| kernel | output | reference | C single | C batched | CasADi |", "|---|---|---|--:|--:|--:|"]
    lines += [f"| {d.kernel} | {d.output} | {d.reference} | {d.c_single:.1e} | {d.c_batch:.1e} "
              f"| {d.casadi:.1e} |" for d in discrepancies]
    return "\n".join(lines)
