"""Many mechanisms of one topology in one batched call [LINK 5: "vmap across mechanisms"].

The parametric kernels (``linkage_kernels(linkage, parametric=True)``) take each mechanism's initial
points ``X0`` as an input, so one compiled module serves a whole family: :func:`sweep` follows the
crank of N mechanisms at once, each Newton iteration one SIMD-batched ``newton_step`` call over all
of them (continuation per mechanism, as in ``solver.simulate``); a mechanism whose Newton fails at an
angle has reached a configuration it cannot assemble (its crank cannot turn further) and is frozen
at its last solved configuration. :func:`classify` uses it to sort four-bars into Grashof's classes by
simulation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from gagen.apps.linkage.kernels import identity_motors, linkage_kernels
from gagen.apps.linkage.solver import MAX_ITERATIONS, TOLERANCE
from gagen.apps.linkage.spec import Linkage


@dataclass
class Sweep:
    angles: np.ndarray  # the crank's rotation from each mechanism's initial configuration (rad)
    motors: np.ndarray  # (steps, N, 4 × moving bodies)
    reached: np.ndarray  # (N,) how many angles each mechanism solved (len(angles): all)
    residuals: np.ndarray  # (steps, N) max |F| at the solution (NaN where not reached)
    iterations: np.ndarray  # (steps,) batched Newton iterations per angle


def family(linkage: Linkage) -> Any:
    """The compiled parametric kernels of the linkage's topology (the gagen.compile cache)."""
    from gagen.build import compile_kernels

    return compile_kernels(linkage_kernels(linkage, parametric=True), name=f"{linkage.name}_family")


def sweep(module: Any, linkage: Linkage, initial: np.ndarray, angles: np.ndarray,
          tolerance: float = TOLERANCE, max_iterations: int = MAX_ITERATIONS) -> Sweep:
    """Follow the crank of N mechanisms (``initial``: N × len(initial_labels), assembled initial
    points) through ``angles`` (k drivers: steps × k values), all mechanisms in each batched call."""
    X0 = np.atleast_2d(np.asarray(initial, dtype=float))
    count = len(X0)
    R = np.tile(identity_motors(linkage), (count, 1))
    alive = np.ones(count, dtype=bool)
    reached = np.zeros(count, dtype=int)
    motors, residuals, iterations = [], [], []
    for step, angle in enumerate(np.asarray(angles, dtype=float)):
        theta = np.tile(np.atleast_1d(angle), (count, 1))  # (N, k): k drivers' values per mechanism
        pending = alive.copy()
        final = np.full(count, np.nan)
        solved = R.copy()  # the configurations at the previous value: where an unsolved one stays
        for iteration in range(max_iterations + 1):
            R_next, residual = module.newton_step.batch(R, theta, X0)
            residual = np.asarray(residual).reshape(-1)
            done = pending & (residual < tolerance)
            final[done] = residual[done]
            pending &= ~done
            if not pending.any() or iteration == max_iterations:
                break
            R[pending] = np.asarray(R_next)[pending]
        R[pending] = solved[pending]  # not the diverged iterate: the last configuration it reached
        alive &= ~pending  # those still pending could not be solved at this angle: frozen
        reached[alive] = step + 1
        motors.append(R.copy())
        residuals.append(final)
        iterations.append(iteration)
    return Sweep(np.asarray(angles), np.array(motors), reached, np.array(residuals), np.array(iterations))


# -- the four-bar family and Grashof's classes ----------------------------------------------------------

def four_bar_points(ground: float, crank: float, coupler: float, rocker: float) -> np.ndarray | None:
    """Assembled initial points of a four-bar (pivots A = (0, 0), D = (ground, 0); the crank's B at
    the first angle where the loop closes, C on the upper branch), in the bundled four_bar's
    ``initial_labels`` order (A, D, then crank A B, coupler B C P, rocker C D); None if it never closes."""
    for theta in np.linspace(0.0, np.pi, 721):
        B = crank * np.array([np.cos(theta), np.sin(theta)])
        D = np.array([ground, 0.0])
        d = np.linalg.norm(D - B)
        if not abs(coupler - rocker) < d < coupler + rocker:
            continue
        a = (coupler ** 2 - rocker ** 2 + d ** 2) / (2 * d)
        C = B + a * (D - B) / d + np.sqrt(coupler ** 2 - a ** 2) * np.array([B[1] - D[1], D[0] - B[0]]) / d
        P = (B + C) / 2 + 0.5 * np.array([B[1] - C[1], C[0] - B[0]])
        return np.concatenate([[0, 0], D, [0, 0], B, B, C, P, C, D])
    return None


def grashof_class(ground: float, crank: float, coupler: float, rocker: float) -> str:
    """Grashof's prediction: s + l ≤ p + q and the shortest link's place decide the class."""
    lengths = {"ground": ground, "crank": crank, "coupler": coupler, "rocker": rocker}
    shortest_length, longest = min(lengths.values()), max(lengths.values())
    if shortest_length + longest > sum(lengths.values()) - shortest_length - longest:
        return "triple-rocker"
    shortest = min(lengths, key=lambda link: lengths[link])
    return {"crank": "crank-rocker", "ground": "double-crank"}.get(shortest, "double-rocker")


def _turn(motors: np.ndarray) -> np.ndarray:
    """A body's rotation angle along a trajectory of its motors (1, e12, …): R = cos(φ/2) − sin(φ/2) e12."""
    return np.unwrap(2 * np.arctan2(-motors[..., 1], motors[..., 0]), axis=0)


def classify(linkage: Linkage, result: Sweep, rocker: str = "rocker") -> list[str]:
    """Per mechanism, by simulation: the crank does not turn fully → "rocker" (double or triple);
    it does and the rocker turns fully too → "double-crank"; else → "crank-rocker"."""
    index = linkage.unknown.index(rocker)
    turn = _turn(result.motors[:, :, 4 * index:4 * index + 4])
    full = len(result.angles)
    out = []
    for k in range(result.motors.shape[1]):
        if result.reached[k] < full:
            out.append("rocker")
        elif np.ptp(turn[:, k]) > 2 * np.pi - 1e-6:
            out.append("double-crank")
        else:
            out.append("crank-rocker")
    return out
