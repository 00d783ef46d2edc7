"""The step as a front-end kernel ``step`` (q, x_ref -> x, J, u) and as CasADi Functions; ``step_source``:
the one-kernel module ``smc`` for ``gagen.build.build_source`` (default: the bundled Panda's arm)."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence

import casadi as ca
import numpy as np

from gagen.algebra.signature import cga3d
from gagen.codegen.ir import ModuleSource
from gagen.control.smc.law import (
    DAMPING,
    EPSILON,
    GAIN,
    POSE,
    _checked,
    _gains,
    damped_solve,
    pose_and_jacobian,
    reference,
    step_law,
)
from gagen.frontend import KernelFunction, matrix, scalars, source_of
from gagen.model import kinematics as kin
from gagen.model.kinematics import Joint

MODULE = "smc"  # the generated module: smc.h / smc.c
KERNEL = "step"  # its one kernel: the C function smc_step


def step_kernel(joints: Sequence[Joint] | None = None, *, K: float | Sequence[float] = GAIN,
                epsilon: float = EPSILON, damping: float = DAMPING) -> KernelFunction:
    """The sliding-mode step as a front-end kernel ``step`` over cga3d: (q[n], x_ref[6]) -> (x[6],
    J[6×n], u[n]) with x the pose, J its Jacobian [SMC Eq. 17-20] and u = −J⁺ K tanh(ε (x − x_ref))
    [Eq. 35, 40], J⁺ = Jᵀ(J Jᵀ + λ_d² I)⁻¹ (λ_d = ``damping``). ``K``: a scalar or 6 task-space gains.
    Its function (``step_law``) is also its reference on the interpreter. ``joints``: default the
    bundled Panda (``panda_point``'s arm)."""
    joints = tuple(joints) if joints is not None else _panda_joints()
    gains = _checked(K, epsilon, damping)
    variables = tuple(kin.chain_variables(joints))  # mimic joints follow their leader: no entry of their own
    n = len(variables)

    def sample(rng: np.random.Generator) -> list[np.ndarray]:
        return [rng.uniform(-2.5, 2.5, n), reference(rng.uniform(0.0, math.pi))]

    return KernelFunction(
        step_law(joints, gains, float(epsilon), float(damping)), algebra=cga3d(), name=KERNEL,
        doc="sliding-mode pose tracking step [SMC Eq. 17-20, 35, 40]: pose x, its Jacobian J and "
            "u = -J+ K tanh(eps (x - x_ref))",
        inputs={"ga": "algebra", "q": scalars(n, variables), "x_ref": scalars(len(POSE), POSE)},
        outputs={"x": scalars(len(POSE), POSE), "J": matrix(scalars(len(POSE), POSE), n),
                 "u": scalars(n, variables)},
        sample=sample)


def smc_step_function(joints: Sequence[Joint] | None = None, *, K: float | Sequence[float] = GAIN,
                      epsilon: float = EPSILON, damping: float = DAMPING) -> ca.Function:
    """The compiled step's CasADi SX Function (``step_kernel(...).trace().function``):
    (q[n], x_ref[6]) -> (x[6], J[6×n], u[n])."""
    return step_kernel(joints, K=K, epsilon=epsilon, damping=damping).trace().function


def sx_step_function(joints: Sequence[Joint] | None = None, *, K: float | Sequence[float] = GAIN,
                     epsilon: float = EPSILON, damping: float = DAMPING) -> ca.Function:
    """The step built directly in CasADi SX, as gagen did before the front-end kernel: the pose and
    Jacobian as SX, then the law in SX operations. Kept as a cross-check and as the op-count baseline
    the kernel must not exceed."""
    joints = tuple(joints) if joints is not None else _panda_joints()
    gains = _checked(K, epsilon, damping)
    q = ca.SX.sym("q", len(kin.chain_variables(joints)))
    x_ref = ca.SX.sym("x_ref", len(POSE))
    x, J = pose_and_jacobian(joints, q)
    r = ca.vertcat(*[gains[i] * ca.tanh(epsilon * (x[i] - x_ref[i])) for i in range(len(POSE))])
    rows = [[J[i, m] for m in range(J.shape[1])] for i in range(len(POSE))]
    w = damped_solve(rows, [r[i] for i in range(len(POSE))], damping)
    u = -ca.mtimes(J.T, ca.vertcat(*w))
    return ca.Function("smc_step_sx", [q, x_ref], ca.cse([x, J, u]), ["q", "x_ref"], ["x", "J", "u"])


def _panda_joints() -> tuple[Joint, ...]:
    from gagen.registry import bundled_specs
    from gagen.robots.spec import load_system

    system, _ = load_system(bundled_specs()["panda_point"])  # the bundled Panda, by its shortcut
    return tuple(system.chains[0].joints)


def step_source(joints: Sequence[Joint] | None = None, *, K: float | Sequence[float] = GAIN,
                epsilon: float = EPSILON, damping: float = DAMPING) -> ModuleSource:
    """The module ``smc`` of the one kernel ``step`` (C function ``smc_step``), for
    ``gagen.build.build_source``; its manifest records the parameters under ``"smc"``."""
    joints = tuple(joints) if joints is not None else _panda_joints()
    kernel = step_kernel(joints, K=K, epsilon=epsilon, damping=damping)
    params = {"joints": [j.name for j in joints], "K": _gains(K, len(POSE)), "epsilon": float(epsilon),
              "damping": float(damping)}
    source = source_of([kernel], MODULE, "gagen.control.smc",
                       json.dumps([repr(joints), params]).encode(), "gagen smc")
    source.title = "sliding-mode pose tracking step [SMC Eq. 17-20, 35, 40]"
    source.meta["smc"] = params
    return source
