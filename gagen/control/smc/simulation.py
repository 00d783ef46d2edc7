"""The step from Python: the compiled step (``gagen.load(module).c.step``), CasADi's, and ``simulate``, the
same loop as the C runner in numpy, tick for tick."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from gagen.control.smc.kernel import KERNEL
from gagen.control.smc.law import check_finite, reference
from gagen.control.smc.log import csv_header

Step = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]
"""What a step callable returns: the pose x, the Jacobian J and the control u."""


# -- the step from Python --------------------------------------------------------------------------
class CompiledStep:
    """The compiled ``smc_step`` of a built module (``gagen.load(module).c.step``, the CPython
    binding): ``step(q, x_ref) -> (x, J (k × n), u)`` (fresh arrays)."""

    def __init__(self, module: str | Path) -> None:
        import gagen

        self.module = gagen.load(module)
        self._f = self.module.c.step
        entry = self.module.entry(KERNEL)
        self.n = len(entry["inputs"][0]["rows"])
        self.k = len(entry["inputs"][1]["rows"])

    def __call__(self, q: ArrayLike, x_ref: ArrayLike) -> Step:
        q = np.asarray(q, dtype=np.float64)
        x_ref = np.asarray(x_ref, dtype=np.float64)
        if q.shape != (self.n,) or x_ref.shape != (self.k,):
            raise ValueError(f"smc_step takes q[{self.n}] and x_ref[{self.k}], got {q.shape}, {x_ref.shape}")
        x, J, u = self._f(q, x_ref)
        return x, J, u


def casadi_step(function: ca.Function) -> Callable[[ArrayLike, ArrayLike], Step]:
    """``smc_step_function``'s Function as a step callable for ``simulate`` (CasADi's VM)."""

    def step(q: ArrayLike, x_ref: ArrayLike) -> Step:
        x, J, u = function(np.asarray(q, dtype=float), np.asarray(x_ref, dtype=float))
        return np.asarray(x).ravel(), np.asarray(J), np.asarray(u).ravel()

    return step


@dataclass
class Simulation:
    """A closed-loop run, one row per tick k (t_k = k dt): the state q_k before the step, the pose x_k,
    the reference, the control u_k and s_k = x_k − x_ref(t_k)."""

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    x: NDArray[np.float64]
    x_ref: NDArray[np.float64]
    u: NDArray[np.float64]

    @property
    def s(self) -> NDArray[np.float64]:
        return self.x - self.x_ref

    def error_after(self, transient: float) -> float:
        """max |s_i| over the ticks with t ≥ ``transient``."""
        return float(np.abs(self.s[self.t >= transient]).max())

    def write_csv(self, path: str | Path) -> Path:
        """The runner's CSV layout (lateness and work 0)."""
        s = self.s
        columns = np.column_stack([self.t, self.q, self.x, self.x_ref, self.u,
                                   np.linalg.norm(s[:, :3], axis=1), np.linalg.norm(s[:, 3:], axis=1),
                                   np.abs(s).max(axis=1), np.zeros((len(self.t), 2))])
        path = Path(path)
        np.savetxt(path, columns, delimiter=",", fmt="%.17g", header=",".join(csv_header(self.q.shape[1])),
                   comments="")
        return path


def simulate(step: Callable[[ArrayLike, ArrayLike], tuple[Any, Any, Any]], q0: ArrayLike, duration: float,
             dt: float, *, reference: Callable[[float], NDArray[np.float64]] = reference,
             disturbance: Callable[[float], ArrayLike] | None = None,
             limits: tuple[ArrayLike, ArrayLike] | None = None) -> Simulation:
    """The C runner's loop in Python: round(duration / dt) ticks of x_ref(t_k), (x, J, u) = step(q, x_ref),
    q += u dt, with t_k = k dt. With the compiled step (``CompiledStep``), dt = 1/rate and the build's
    ``limits`` it gives the runner's log bit for bit. ``disturbance(t)``: an optional joint-velocity
    disturbance d added to u in the integration (q += (u + d) dt), i.e. λ = J d in ẋ = J u + λ [SMC
    Eq. 32]. ``limits``: (lower, upper), the joints' hard stops (``SmcBuild.limits``): q is clamped to
    them after each step, as the runner does."""
    q = np.array(q0, dtype=float)
    if not np.all(np.isfinite(q)):
        raise ValueError(f"q0 must be finite, got {q}")
    check_finite("duration", duration, "s", positive=True)
    check_finite("dt", dt, "s", positive=True)
    ticks = round(duration / dt)
    bounds = None if limits is None else tuple(np.asarray(v, dtype=float) for v in limits)
    if ticks < 1:
        raise ValueError(f"a duration of {duration:g} s is less than one tick of {dt:g} s")
    rows: dict[str, list[Any]] = {"t": [], "q": [], "x": [], "x_ref": [], "u": []}
    for k in range(ticks):
        t = k * dt
        xr = reference(t)
        x, _, u = step(q, xr)
        for name, value in (("t", t), ("q", q.copy()), ("x", x), ("x_ref", xr), ("u", u)):
            rows[name].append(value)
        q = q + (u if disturbance is None else u + np.asarray(disturbance(t), dtype=float)) * dt
        if bounds is not None:  # the runner's hard stops (integrate() in smc_loop.c)
            q = np.minimum(np.maximum(q, bounds[0]), bounds[1])
    return Simulation(*(np.array(rows[name], dtype=float) for name in ("t", "q", "x", "x_ref", "u")))
