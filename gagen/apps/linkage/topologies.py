"""Batches across topologies [LINK 6]: mechanisms of different linkages in one call.

:func:`topology_module` builds ONE module holding the parametric kernels (``linkage_kernels(linkage,
parametric=True)``) of several linkages, each kernel's name prefixed with its linkage's
(``four_bar_newton_step``, ``jansen_newton_step``, …), once per content in gagen's cache.
A batch is a list of :class:`Group` (a linkage and the initial points ``X0`` of its N mechanisms):

- :func:`sweep_topologies` (C SIMD): at each driver value and Newton iteration, one SIMD-batched
  ``<linkage>_newton_step`` call per group over all its mechanisms, every group advanced together;
  convergence and freezing per mechanism exactly as ``batch.sweep`` (the same numbers, bitwise);
- :func:`jax_sweep` (JAX): the whole multi-topology batch as ONE jitted XLA function, a ``lax.scan``
  over the driver values; in it, per group, a ``lax.while_loop`` of Newton iterations of ``jax.vmap``
  of the module's JAX ``newton_step`` (per group, not one loop for all: a four-bar that cannot
  assemble costs the maximum iterations to its own group only).

Each group's driver width (1 for a mechanism of mobility 1, k for k drivers) is read from the built
module's manifest (the ``newton_step``'s second input), not assumed.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gagen.apps.linkage.batch import Sweep
from gagen.apps.linkage.kernels import identity_motors, linkage_kernels
from gagen.apps.linkage.solver import MAX_ITERATIONS, TOLERANCE
from gagen.apps.linkage.spec import Linkage
from gagen.frontend import KernelFunction, check_name


@dataclass
class Group:
    """N mechanisms of one topology: ``initial`` (N × len(initial_labels)) their assembled initial
    points; ``drivers`` (steps × driver width) their own driver values, else the call's shared ones."""
    linkage: Linkage
    initial: np.ndarray
    drivers: np.ndarray | None = None


GroupLike = Group | tuple[Linkage, np.ndarray] | tuple[Linkage, np.ndarray, np.ndarray]


def kernel_name(linkage: Linkage, kernel: str) -> str:
    """A kernel's name in a multi-topology module: ``<linkage>_<kernel>``."""
    return f"{linkage.name}_{kernel}"


def _renamed(kernel: KernelFunction, name: str) -> KernelFunction:
    """The kernel under another name (a shallow copy, untraced: its trace takes the new name)."""
    clone = copy.copy(kernel)
    clone.name = clone.__name__ = check_name(name, name, "name")
    return clone


def topology_kernels(linkages: Sequence[Linkage]) -> list[KernelFunction]:
    """The parametric kernels of every linkage, named ``<linkage>_<kernel>``; each linkage's own
    kernels unchanged (the same graph as in its single-topology family module)."""
    names = [linkage.name for linkage in linkages]
    if not names:
        raise ValueError("topology_kernels: expected at least one linkage")
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ValueError(f"topology_kernels: linkage name(s) {', '.join(repeated)} given twice; each "
                         f"topology's kernels are named after its linkage")
    return [_renamed(k, kernel_name(linkage, k.name)) for linkage in linkages
            for k in linkage_kernels(linkage, parametric=True)]  # (fresh, untraced kernels)


def topology_module(linkages: Sequence[Linkage], name: str = "topologies",
                    progress: Callable[[str], None] | None = None) -> Any:
    """The module of several topologies' parametric kernels (every backend: ``.c``, ``.jax``),
    built once per content into the gagen cache and loaded (``gagen.build.compile_kernels``'s path,
    returning the whole module rather than its C namespace)."""
    from gagen.build import build_source, cache_root
    from gagen.frontend import source_of
    from gagen.runtime import load

    source = source_of(topology_kernels(linkages), name)
    target = cache_root() / f"{source.name}-{source.key[:16]}"
    build_source(source, target, progress=progress or (lambda _: None))
    return load(target)


# -- the groups and their drivers ------------------------------------------------------------------------

@dataclass
class _Plan:
    """A checked group: its kernel, its initial points, its driver values per step (steps × width)."""
    linkage: Linkage
    kernel: str
    initial: np.ndarray
    drivers: np.ndarray
    angles: np.ndarray  # the driver values as given (Sweep.angles)


def _ports(module: Any, linkage: Linkage, label: str) -> tuple[str, int, int]:
    """The group's newton_step kernel name, driver width and X0 width, from the module's manifest."""
    kernel = kernel_name(linkage, "newton_step")
    if kernel not in module.kernel_names:
        has = [k for k in module.kernel_names if k.endswith("_newton_step")]
        reason = ("its constraints are not square (redundant joints): no Newton-step kernel"
                  if kernel_name(linkage, "constraints") in module.kernel_names else
                  f"the module has none (its topologies: {', '.join(k[:-12] for k in has) or 'none'})")
        raise ValueError(f"{label}: no kernel {kernel}: {reason}")
    inputs = module.entry(kernel)["inputs"]
    if len(inputs) != 3:
        raise ValueError(f"{label}: {kernel} takes {len(inputs)} inputs, expected R, the driver and X0 "
                         f"(a parametric kernel)")
    return kernel, len(inputs[1]["rows"]), len(inputs[2]["rows"])


def _plans(module: Any, groups: Sequence[GroupLike], angles: Any) -> list[_Plan]:
    if not groups:
        raise ValueError("expected at least one group (a linkage and its mechanisms' initial points)")
    shared = None if angles is None else np.asarray(angles, dtype=float)
    plans = []
    for number, given in enumerate(groups):
        group = given if isinstance(given, Group) else Group(*given)
        label = f"group {number} ({group.linkage.name})"
        kernel, width, points = _ports(module, group.linkage, label)
        initial = np.asarray(group.initial, dtype=float)
        initial = initial.reshape(1, -1) if initial.ndim == 1 else initial
        if initial.ndim != 2 or initial.shape[1] != points or len(initial) == 0:
            raise ValueError(f"{label}: initial points of shape {np.shape(group.initial)}, expected "
                             f"(N, {points}) (N ≥ 1 mechanisms × the {points} initial_labels of "
                             f"{group.linkage.name})")
        values = shared if group.drivers is None else np.asarray(group.drivers, dtype=float)
        if values is None:
            raise ValueError(f"{label}: no driver values (give angles, or the group's drivers)")
        if values.ndim == 1 and width == 1:
            drivers = values.reshape(-1, 1)
        elif values.ndim == 2 and values.shape[1] == width:
            drivers = values
        else:
            raise ValueError(f"{label}: driver values of shape {values.shape}, expected (steps, {width})"
                             f"{' or (steps,)' if width == 1 else ''}: {width} driver(s)")
        plans.append(_Plan(group.linkage, kernel, initial, drivers, values))
    steps = {len(plan.drivers) for plan in plans}
    if len(steps) > 1:
        raise ValueError(f"the groups' driver values have {sorted(steps)} steps: all groups advance "
                         f"together, so they need as many")
    return plans


# -- C SIMD --------------------------------------------------------------------------------------------------

def sweep_topologies(module: Any, groups: Sequence[GroupLike], angles: Any = None,
                     tolerance: float = TOLERANCE, max_iterations: int = MAX_ITERATIONS) -> list[Sweep]:
    """Follow the drivers of every group's mechanisms through the driver values (``angles``, shared,
    (steps,) or (steps, width); or each group's own ``drivers``), all groups advanced together: per
    value and Newton iteration, one SIMD-batched call per group still iterating. One ``Sweep`` per
    group, as ``batch.sweep`` of that group alone gives it (``iterations``: the group's own)."""
    plans = _plans(module, groups, angles)
    kernels = [getattr(module.c, plan.kernel).batch for plan in plans]
    R = [np.tile(identity_motors(plan.linkage), (len(plan.initial), 1)) for plan in plans]
    alive = [np.ones(len(plan.initial), dtype=bool) for plan in plans]
    reached = [np.zeros(len(plan.initial), dtype=int) for plan in plans]
    rows: list[dict[str, list[Any]]] = [{"motors": [], "residuals": [], "iterations": []} for _ in plans]
    for step in range(len(plans[0].drivers)):
        theta = [np.tile(plan.drivers[step], (len(plan.initial), 1)) for plan in plans]
        pending = [a.copy() for a in alive]
        solved = [r.copy() for r in R]  # the configurations at the previous value
        final = [np.full(len(plan.initial), np.nan) for plan in plans]
        running = list(range(len(plans)))
        iterations = [max_iterations] * len(plans)
        for iteration in range(max_iterations + 1):
            for g in list(running):
                R_next, residual = kernels[g](R[g], theta[g], plans[g].initial)
                residual = np.asarray(residual).reshape(-1)
                done = pending[g] & (residual < tolerance)
                final[g][done] = residual[done]
                pending[g] &= ~done
                if not pending[g].any() or iteration == max_iterations:
                    running.remove(g)
                    iterations[g] = iteration
                    continue
                R[g][pending[g]] = np.asarray(R_next)[pending[g]]
            if not running:
                break
        for g in range(len(plans)):
            R[g][pending[g]] = solved[g][pending[g]]  # the last configuration reached, as in batch.sweep
            alive[g] &= ~pending[g]  # not solved at this value: frozen there
            reached[g][alive[g]] = step + 1
            rows[g]["motors"].append(R[g].copy())
            rows[g]["residuals"].append(final[g])
            rows[g]["iterations"].append(iterations[g])
    return [Sweep(plan.angles, np.array(row["motors"]), reached[g], np.array(row["residuals"]),
                  np.array(row["iterations"])) for g, (plan, row) in enumerate(zip(plans, rows, strict=True))]


# -- JAX: one jitted function for the whole batch -----------------------------------------------------------

def jax_sweep_function(module: Any, linkages: Sequence[Linkage], tolerance: float = TOLERANCE,
                       max_iterations: int = MAX_ITERATIONS) -> Callable[..., Any]:
    """``f(initials, drivers)``, jitted: ``initials`` and ``drivers`` tuples with one (N_g × points)
    and one (steps × width) array per linkage → per group (motors (steps, N, 4n), reached (N,),
    residuals (steps, N), iterations (steps,)), the algorithm of :func:`sweep_topologies` in one XLA
    call."""
    from gagen.extras import require

    require("jax", "the JAX batch across topologies")
    import jax
    import jax.numpy as jnp

    steps = [jax.vmap(getattr(module.jax, kernel_name(linkage, "newton_step")), in_axes=(0, None, 0))
             for linkage in linkages]
    starts = [identity_motors(linkage) for linkage in linkages]

    def newton(g: int, R: Any, alive: Any, theta: Any, X0: Any) -> tuple[Any, Any, Any, Any]:
        """Group g's Newton at one driver value (its own loop: one group's failures cost it alone)."""
        def body(state: Any) -> Any:
            i, R, pending, final, _ = state
            R_next, residual = steps[g](R, theta, X0)
            residual = residual.reshape(-1)
            done = pending & (residual < tolerance)
            pending = pending & ~done
            stop = ~jnp.any(pending) | (i == max_iterations)
            R = jnp.where((pending & ~stop)[:, None], R_next, R)
            return jnp.where(stop, i, i + 1), R, pending, jnp.where(done, residual, final), stop

        state = (jnp.asarray(0), R, alive, jnp.full(alive.shape, jnp.nan), jnp.asarray(False))
        iterations, R_new, pending, final, _ = jax.lax.while_loop(lambda state: ~state[4], body, state)
        R_new = jnp.where(pending[:, None], R, R_new)  # an unsolved one stays where it was
        return R_new, alive & ~pending, final, iterations

    def solve(carry: Any, theta: Any, initials: Any) -> tuple[Any, Any]:
        solved = [newton(g, R, alive, value, X0)
                  for g, (R, alive, value, X0) in enumerate(zip(*carry, theta, initials, strict=True))]
        R, alive, final, iterations = (tuple(column) for column in zip(*solved, strict=True))
        return (R, alive), (R, alive, final, jnp.stack(iterations))

    def run(initials: tuple[Any, ...], drivers: tuple[Any, ...]) -> list[tuple[Any, Any, Any, Any]]:
        R = tuple(jnp.tile(jnp.asarray(start), (len(x), 1))
                  for start, x in zip(starts, initials, strict=True))
        alive = tuple(jnp.ones(len(x), dtype=bool) for x in initials)
        _, (motors, alives, residuals, iterations) = jax.lax.scan(
            lambda carry, theta: solve(carry, theta, initials), (R, alive), drivers)
        out = []
        for g in range(len(linkages)):  # reached: the steps after which the mechanism was still alive
            reached = jnp.sum(jnp.cumprod(alives[g].astype(jnp.int32), axis=0), axis=0)
            out.append((motors[g], reached, residuals[g], iterations[:, g]))
        return out

    return jax.jit(run)


def jax_sweep(module: Any, groups: Sequence[GroupLike], angles: Any = None, tolerance: float = TOLERANCE,
              max_iterations: int = MAX_ITERATIONS,
              function: Callable[..., Any] | None = None) -> list[Sweep]:
    """:func:`sweep_topologies` on the module's JAX kernels, the whole batch one jitted call
    (``function``: a ``jax_sweep_function`` to reuse, so its compilation is paid once)."""
    plans = _plans(module, groups, angles)
    run = function or jax_sweep_function(module, [plan.linkage for plan in plans], tolerance, max_iterations)
    results = run(tuple(plan.initial for plan in plans), tuple(plan.drivers for plan in plans))
    return [Sweep(plan.angles, np.asarray(motors), np.asarray(reached).astype(int), np.asarray(residuals),
                  np.asarray(iterations).astype(int))
            for plan, (motors, reached, residuals, iterations) in zip(plans, results, strict=True)]
