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
    LIMIT_GAIN,
    LIMIT_RATE,
    LIMIT_ZONE,
    POSE,
    REFINEMENTS,
    _checked,
    _gains,
    joint_bounds,
    limited_law,
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
    [Eq. 35, 40], J⁺ = Jᵀ(J Jᵀ + λ_d² I)⁻¹ (λ_d = ``damping``, refined), plus the joint-limit
    avoidance in the nullspace and the velocity bound toward each limit (``law.limited_law``; the
    limits are the joints' URDF limits). ``K``: a scalar or 6 task-space gains. Its function
    (``step_law``) is also its reference on the interpreter. ``joints``: default the bundled Panda
    (``panda_point``'s arm)."""
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
    Jacobian as SX, then the same law (``limited_law``) in SX operations. Kept as a cross-check and as
    the op-count baseline the kernel must not exceed."""
    joints = tuple(joints) if joints is not None else _panda_joints()
    gains = _checked(K, epsilon, damping)
    q = ca.SX.sym("q", len(kin.chain_variables(joints)))
    x_ref = ca.SX.sym("x_ref", len(POSE))
    x, J = pose_and_jacobian(joints, q)
    n, k = J.shape[1], len(POSE)
    u = limited_law([x[i] for i in range(k)], [[J[i, m] for i in range(k)] for m in range(n)],
                    [q[m] for m in range(n)], [x_ref[i] for i in range(k)], gains, epsilon, damping,
                    joint_bounds(joints), ca.tanh, lambda a, b: a < b, ca.if_else)
    return ca.Function("smc_step_sx", [q, x_ref], ca.cse([x, J, ca.vertcat(*u)]), ["q", "x_ref"],
                       ["x", "J", "u"])


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
    lower, upper = joint_bounds(joints)  # the limits are out of the joints' repr: the key needs them
    params = {"joints": [j.name for j in joints], "K": _gains(K, len(POSE)), "epsilon": float(epsilon),
              "damping": float(damping), "refinements": REFINEMENTS, "lower": list(lower),
              "upper": list(upper), "limit_zone": LIMIT_ZONE, "limit_gain": LIMIT_GAIN,
              "limit_rate": LIMIT_RATE}
    source = source_of([kernel], MODULE, "gagen.control.smc",
                       json.dumps([repr(joints), params]).encode(), "gagen smc")
    source.title = "sliding-mode pose tracking step [SMC Eq. 17-20, 35, 40]"
    source.meta["smc"] = params
    return source
