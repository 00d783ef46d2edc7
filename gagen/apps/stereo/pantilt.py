"""A pan-tilt head carrying the stereo rig [SMC IV, Fig. 1; Eq. 16-20, 29, 33-40], written once over the
multivector protocol: the interpreter runs it as the reference, the front-end compiles it (``head_kernel``).

**The head** (:func:`head_joints`): the frame H is the left camera's frame at q = 0 (OpenCV axes: x right,
y down, z forward). Pan turns about the axis along −y (image up) through the rig's middle, the rig
file's ``head.pan_behind`` behind the cameras; tilt turns about the pan link's x axis, ``head.tilt_offset``
from the pan axis (``calibration.Head``: 8 cm and (0, 4, 3) cm unless the file says otherwise); the left
camera is fixed on the tilt link so that it sits at H's origin for q = 0. Neither axis passes through
the camera centre, so the centre c_l(q) moves when the head turns.

**The line pose**: the optical axis L'_p = V_M e12 V_M~ (the tool line of ``gagen.model.kinematics``: the
camera's z axis through its centre), a bivector on ``LINE_ROWS``; its Jacobian is the paper's line
Jacobian α_j = ½(L'_p L'_j − L'_j L'_p) (Eq. 19-20), L'_j the joint lines carried by the chain.

**The reference** (Eq. 29): L*_Vref = x_Mref ∧ c_l ∧ e∞, the line through the object's point and the
left camera centre; as a bivector L_Vref = (x ∧ c ∧ e∞)* / |x − c|, oriented like the optical axis
(from the camera to the object: Eq. 29's x ∧ c ∧ e∞ runs from x to c, and A* = −(the bivector of the
same direction), so the dual of the paper's order is already the camera-to-object orientation).

**The law** (Eq. 33, 35, 40): s = L'_p − L_Vref (six coefficients). Both lines pass through c_l, so
they differ only in direction, and s has two degrees of freedom, as the head has joints. Deviation from
the paper's u = −K J⁺ tanh(ε s): the switching acts on σ = J⁺ s, the least-squares joint-space image
of s (J⁺ = (JᵀJ)⁻¹Jᵀ, J the 6 × 2 line Jacobian), u = −K tanh(ε σ). Inside the boundary layer
(|ε σ| ≲ 1) the two laws are the same linear law −Kε J⁺ s; outside it, tanh(ε s) saturates each of the
six coefficients to ±k separately (direction and moment coefficients of different units alike), and
J⁺ of that is not the direction that reduces s, whereas σ̇ = u + d per joint (d: the object's motion
and the camera centre's, see ``pantilt_loop.reaching_bound``) gives the reaching condition of Eq. 38
joint by joint. ``u_paper`` is the literal law, for comparison. The conditioning det(J_dᵀJ_d) of J's
direction
rows J_d (cos² tilt here) is 0 when the optical axis looks along the pan axis, the pan-tilt's singularity
(the line still moves there, by the axes' offsets, so σ stays finite but the pan turns fast)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gagen.apps.stereo.calibration import Pose, Rig
from gagen.model import kinematics as kin
from gagen.model.conformal import EUCLID, einf, point, vector
from gagen.model.guarded import safe_reciprocal

LINE_ROWS = ("e12", "e13", "e23", "e1inf", "e2inf", "e3inf")  # a line bivector: n3, −n2, n1, then moment
MOTOR_ROWS = ("1", "e12", "e13", "e23", "e1inf", "e2inf", "e3inf", "e123inf")
GAIN = 2.0  # k, rad/s: the largest joint speed the law commands (K = diag(k, k), Eq. 36)
EPSILON = 100.0  # tanh slope (Eq. 40): boundary layer |σ| ≲ 1/ε = 10 mrad, k ε = 200/s inside it


def head_joints(rig: Rig) -> tuple[kin.Joint, ...]:
    """The head's chain in H (the left camera's frame at q = 0): pan, tilt, and the fixed camera mount."""
    b, head = rig.right_in_left.t, rig.head
    pan = (float(b[0]) / 2, float(b[1]) / 2, float(b[2]) / 2 - head.pan_behind)  # behind the rig's middle
    mount = tuple(-(p + t) for p, t in zip(pan, head.tilt_offset, strict=True))
    # (the limits are information: the law has no limit term)
    return (kin.Joint("pan", "revolute", pan, axis=(0.0, -1.0, 0.0),
                      limits=(-head.pan_limit, head.pan_limit)),
            kin.Joint("tilt", "revolute", head.tilt_offset, axis=(1.0, 0.0, 0.0),
                      limits=(-head.tilt_limit, head.tilt_limit)),
            kin.Joint("camera", "fixed", (mount[0], mount[1], mount[2])))


def reference_line(target: Any, centre: Any) -> Any:
    """L_Vref = (x ∧ c ∧ e∞)* / |x − c| (Eq. 29) for conformal points x (the object) and c (the camera
    centre): the unit line bivector through both, directed from c to x. x = c gives a zero line."""
    line = (target ^ centre ^ einf(target)).dual()
    m = target.math
    n = [line["e23"], -line["e13"], line["e12"]]
    return line * safe_reciprocal(m, m.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]))


def line_coefficients(line: Any) -> list[Any]:
    return [line[b] for b in LINE_ROWS]


@dataclass
class Pursuit:
    """One evaluation of the head's law: everything on plain scalars (``LINE_ROWS`` for lines)."""

    motor: list[Any]  # V_M on MOTOR_ROWS: the left camera's pose in H
    centre: list[Any]  # c_l (x, y, z) in H
    line: list[Any]  # L'_p, the optical axis
    reference: list[Any]  # L_Vref (Eq. 29)
    s: list[Any]  # L'_p − L_Vref (Eq. 33)
    J: list[list[Any]]  # two columns α_pan, α_tilt (Eq. 19-20)
    sigma: list[Any]  # J⁺ s
    u: list[Any]  # −K tanh(ε σ)
    u_paper: list[Any]  # −K J⁺ tanh(ε s), the paper's order (Eq. 35, 40)
    conditioning: Any  # det(J_dᵀJ_d) of J's direction rows: 0 looking along the pan axis


def pursue(ga: Any, joints: Sequence[kin.Joint], q: Sequence[Any], target: Sequence[Any],
           gains: Sequence[Any]) -> Pursuit:
    """The law at joint angles q for the object's point ``target`` (H) with gains = (k, ε)."""
    m = ga.math
    motor, lines, position = kin.chain_pose(ga, joints, q)
    tool = ga.make({kin.TOOL_LINE: 1})
    alphas = kin.line_jacobian(motor, lines, tool)  # ½(L'_p L'_j − L'_j L'_p)
    line = motor.sandwich(tool)
    ref = reference_line(point(vector(ga, list(target))), point(position))
    s = [m.shared(a - b) for a, b in zip(line_coefficients(line), line_coefficients(ref), strict=True)]
    J = [[m.shared(v) for v in line_coefficients(a)] for a in alphas]
    k, eps = gains

    def dot(a: Sequence[Any], b: Sequence[Any]) -> Any:
        return sum(x * y for x, y in zip(a, b, strict=True))

    def pseudo_inverse_times(v: Sequence[Any]) -> list[Any]:  # (JᵀJ)⁻¹ Jᵀ v, a 2 × 2 solve
        g00, g01, g11 = dot(J[0], J[0]), dot(J[0], J[1]), dot(J[1], J[1])
        b0, b1 = dot(J[0], v), dot(J[1], v)
        inv = safe_reciprocal(m, g00 * g11 - g01 * g01)
        return [(g11 * b0 - g01 * b1) * inv, (g00 * b1 - g01 * b0) * inv]

    sigma = [m.shared(v) for v in pseudo_inverse_times(s)]
    u = [-k * m.tanh(eps * v) for v in sigma]
    w = pseudo_inverse_times([m.tanh(eps * v) for v in s])
    # the pointing singularity: the direction rows' Gram determinant, |ω_pan × d × ω_tilt × d|² (unit
    # axes: ≤ 1; cos² tilt for perpendicular axes), 0 when the optical axis runs along the pan axis
    a, b = J[0][:3], J[1][:3]
    conditioning = dot(a, a) * dot(b, b) - dot(a, b) * dot(a, b)
    return Pursuit([motor[b] for b in MOTOR_ROWS], [position[b] for b in EUCLID], line_coefficients(line),
                   line_coefficients(ref), s, J, sigma, u, [-k * v for v in w], conditioning)


OUTPUTS = ("motor", "centre", "line", "reference", "s", "J", "sigma", "u", "u_paper", "conditioning")


def head_kernel(rig: Rig) -> Any:
    """The front-end kernel ``head_step`` (q, target, gains → ``OUTPUTS``) of a rig's head."""
    from gagen.frontend import KernelFunction, blades, matrix, scalars

    joints = head_joints(rig)

    def head_step(q: Any, target: Any, gains: Any, ga: Any) -> dict[str, Any]:
        p = pursue(ga, joints, q, target, gains)
        return {name: getattr(p, name) for name in OUTPUTS}

    def sample(rng: np.random.Generator) -> list[np.ndarray]:
        return [rng.uniform(-0.6, 0.6, 2), np.array([0.1, 0.0, 1.0]) + rng.uniform(-0.4, 0.4, 3),
                np.array([GAIN, EPSILON])]

    line = blades(*LINE_ROWS)
    return KernelFunction(
        head_step, algebra="cga3d",
        inputs={"q": scalars(2, ("pan", "tilt")), "target": scalars(3, ("x", "y", "z")),
                "gains": scalars(2, ("k", "epsilon")), "ga": "algebra"},
        outputs={"motor": blades(*MOTOR_ROWS), "centre": scalars(3, ("x", "y", "z")), "line": line,
                 "reference": line, "s": scalars(6, LINE_ROWS), "J": matrix(scalars(6, LINE_ROWS), 2),
                 "sigma": scalars(2, ("pan", "tilt")), "u": scalars(2, ("pan", "tilt")),
                 "u_paper": scalars(2, ("pan", "tilt")), "conditioning": "scalar"},
        name="head_step", doc="pan-tilt head: optical axis, L_Vref (Eq. 29), s, line Jacobian, sliding-mode "
                              "u",
        sample=sample)


@dataclass(frozen=True)
class Step:
    """``head_step``'s outputs as numpy arrays."""

    motor: np.ndarray
    centre: np.ndarray
    line: np.ndarray
    reference: np.ndarray
    s: np.ndarray
    J: np.ndarray  # (6, 2)
    sigma: np.ndarray
    u: np.ndarray
    u_paper: np.ndarray
    conditioning: float

    @property
    def camera(self) -> Pose:
        """The left camera's pose in H: X_H = R X_cam + t."""
        from gagen.conventions import motor_to_homogeneous

        h = motor_to_homogeneous(self.motor)
        return Pose(h[:3, :3], h[:3, 3])


class Head:
    """A rig's head with its ``head_step`` compiled (``gagen.build.compile_kernels``: built once per
    content into the cache) or, with ``interpreted=True``, on the reference interpreter."""

    def __init__(self, rig: Rig, gain: float = GAIN, epsilon: float = EPSILON, *, interpreted: bool = False,
                 progress: Any = None) -> None:
        for name, v in (("gain", gain), ("epsilon", epsilon)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"head {name} must be a finite number > 0, got {v!r}")
        self.rig, self.joints, self.gains = rig, head_joints(rig), np.array([gain, epsilon], dtype=float)
        self.kernel = head_kernel(rig)
        if interpreted:
            self._call = self.kernel.reference
        else:
            from gagen.build import compile_kernels

            self._call = compile_kernels([self.kernel], name=f"{rig.name}_head", progress=progress)

    def __call__(self, q: np.ndarray, target: np.ndarray) -> Step:
        out = [np.asarray(v, dtype=float) for v in self._call(np.asarray(q, dtype=float),
                                                              np.asarray(target, dtype=float), self.gains)]
        flat = [v.reshape(-1) for v in out]
        motor, centre, line, reference, s, _, sigma, u, u_paper, conditioning = flat
        return Step(motor, centre, line, reference, s, out[5].reshape(6, 2), sigma, u, u_paper,
                    float(conditioning[0]))
