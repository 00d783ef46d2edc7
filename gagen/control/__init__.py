"""Control and optimisation on top of the generated kernels [COOP Section 3.7, 3.10, 3.11].

- ``ik``: inverse kinematics on the task error e(q) = log(V_Sc(q)~ V_Sd) by damped Gauss-Newton /
  Levenberg-Marquardt with a backtracking line search [COOP Eq. 43-47];
- ``differential``: differential kinematics q̇ = J_G⁺ B [Eq. 48], the nullspace projector
  N = I − J⁺J [Eq. 58] and the similarity manipulability M_S = J_G J_Gᵀ [Eq. 59];
- ``ocp``: cooperative reaching as an optimal control problem solved by IPOPT [Eq. 53-57] (the
  paper's scenarios with plots, ``gagen reach``, and the nullspace demo, ``gagen nullspace``, are
  in ``gagen.apps.cooperative``);
- ``smc``: sliding-mode pose tracking [SMC] as a generated C step kernel in a real-time loop
  (``gagen smc``).

Everything here works on plain numpy arrays, so the compiled C kernels (``module.c.task``) and the
CasADi Functions evaluated on numbers can both be passed in.
"""

from gagen.control.differential import (
    CONTROLLABLE_DIMENSION,
    damped_pseudo_inverse,
    joint_velocity,
    manipulability,
    manipulability_index,
    nullspace_projector,
)
from gagen.control.ik import IKResult, solve_ik

__all__ = [
    "CONTROLLABLE_DIMENSION",
    "IKResult",
    "damped_pseudo_inverse",
    "joint_velocity",
    "manipulability",
    "manipulability_index",
    "nullspace_projector",
    "solve_ik",
]
