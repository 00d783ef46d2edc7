"""Sliding-mode pose tracking of a serial arm [SMC Sections V-VI], as a generated C step and a 1 kHz loop.

Pose [SMC V.A, Eq. 16-20, 43]: x = [x_p; d] ∈ R⁶, the end point's position x_p (the e1, e2, e3
coefficients of P = V_M e0 V_M~) and the direction d of the tool line L'_p = V_M L_p V_M~, with L_p the
tool's z axis through its origin (the bivector e12, gagen's ``TOOL_LINE``). A line bivector
n3 e12 − n2 e13 + n1 e23 + (moment) has direction n, so d = (L'_p[e23], −L'_p[e13], L'_p[e12]).
The reference of the paper's simulation is exactly such a pair, x_ref = [x_Mref, L_Mref]
(Eq. 33, 43): x_ref(t) = [−0.3 + 0.1 cos 2t, 0.15, 0.25, 0, 1, 0].

Jacobian [SMC Eq. 17-20]: with the joint lines L'_j (the generators carried by the motors before
joint j, from ``kinematics.chain_pose``), the point rows are the Euclidean part of the commutators
P × L'_j (Eq. 18, [COOP Eq. 17]) and the direction rows the direction of α_j = ½(L'_p L'_j − L'_j L'_p)
(Eq. 19-20). d is a unit vector, so ḋ ⊥ d and J (6 × n) has rank at most 5: J Jᵀ is singular, and the
pseudo-inverse must be damped.

Controller [SMC Eq. 32-40]: ẋ = J u + λ, s = x − x_ref, u = −J⁺ K tanh(ε s) with the sign function
replaced by tanh (Eq. 39-40) and J⁺ = Jᵀ(J Jᵀ + λ_d² I)⁻¹ the damped pseudo-inverse, solved in the
step kernel by an explicit LDLᵀ factorisation of the 6 × 6 J Jᵀ + λ_d² I (positive definite for
λ_d > 0), unrolled on plain scalars. K = diag(k_1 … k_6) is in task space as in Eq. 36 (the paper's
K = diag{7.5, …} multiplies tanh(ε s); with equal gains K J⁺ = J⁺ K). Inside the boundary layer
(tanh(ε s) ≈ ε s) the error obeys ṡ ≈ −K ε s − ẋ_ref + λ, so it settles at |s_i| ≲ (|ẋ_ref| + |λ|)/(k ε)
(0.2 / (7.5 · 50) = 5.3e-4 for the paper's reference at the default ε = 50), after a transient in which
tanh saturates and each coordinate closes at up to k per second (Eq. 38: k > |ẋ_ref| + |λ|).
At the loop's rate the Euler-discretised boundary layer is stable for k ε dt < 2 (0.375 at 1 kHz).
The damped solve is refined once on its factors (iterated Tikhonov, ``damped_solve``), so the damping
biases J J⁺ by (λ_d²/(σ² + λ_d²))² instead of λ_d²/(σ² + λ_d²) and the error stays at the bound above.

Joint limits (the joints' URDF limits): u = −J⁺ K tanh(ε s) + (I − J⁺ J) u0 with u0 = −k_n ∇H, H = ½ Σ
(depth of q_m in the zone within ρ of a limit)² [Liégeois 1977] (zero away from the limits: no
self-motion, nothing taken from the tracking), computed as u0 − Jᵀ(J Jᵀ + λ_d² I)⁻¹(r + J u0) with the
same solve; then each u_m is bounded to [γ (lower_m − q_m), γ (upper_m − q_m)] (a velocity damper: an
Euler step of dt ≤ 1/γ cannot cross a limit), and the loops clamp q to the limits as hard stops. The
paper's reference passes close to the Panda's base, reachable within the limits only on some branches:
``PANDA_Q0`` starts the arm where the loop settles on one of them.

Modules, one concern each (their names are re-exported here: ``from gagen.control import smc``):

- ``law``: the reference (Eq. 43), the pose and Jacobian on either path, ``damped_solve`` and
  ``step_law``, the step as one function over the multivector protocol;
- ``kernel``: ``step_kernel``, the front-end kernel ``step`` (q, x_ref -> x, J, u), traced for the
  compiler, whose reference is the same function on the interpreter; ``smc_step_function`` (its CasADi
  Function), ``sx_step_function`` (the step built directly in CasADi SX, the op-count baseline) and
  ``step_source`` (the module ``smc``);
- ``runner``: ``build`` (the module through ``gagen.build.build_source``, as every module is built, and
  the loop runner ``smc_loop.c`` compiled with its C), ``run_loop`` / ``bench_step`` (the C loop at a
  fixed rate, or the step in a tight loop);
- ``simulation``: ``CompiledStep`` (the compiled step from Python), ``casadi_step`` and ``simulate``
  (the same loop in numpy, tick for tick identical to the C runner);
- ``log``: ``read_log`` / ``plot_run``, the per-tick CSV and plots like the paper's Figs. 6-8;
- ``command``: the verb ``gagen smc``.
"""

from typing import Any

_MODULES = {
    "kernel": ("KERNEL", "MODULE", "smc_step_function", "step_kernel", "step_source", "sx_step_function"),
    "law": ("DAMPING", "EPSILON", "GAIN", "LIMIT_GAIN", "LIMIT_RATE", "LIMIT_ZONE", "POSE", "REFINEMENTS",
            "damped_solve", "joint_bounds", "limit_avoidance", "limited_law", "pose_and_jacobian",
            "pose_and_jacobian_of", "reference", "reference_rate", "step_law"),
    "log": ("plot_run", "read_log"),
    "runner": ("PANDA_Q0", "LoopSummary", "SmcBuild", "bench_step", "build", "loop_ticks", "op_count",
               "run_loop"),
    "simulation": ("CompiledStep", "Simulation", "casadi_step", "simulate"),
}
_EXPORTS = {name: module for module, names in _MODULES.items() for name in names}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    """The modules load on first use (they import CasADi), so that ``gagen smc``'s arguments load cheaply."""
    if name in _EXPORTS:
        from importlib import import_module

        return getattr(import_module(f"gagen.control.smc.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module 'gagen.control.smc' has no attribute {name!r}")
