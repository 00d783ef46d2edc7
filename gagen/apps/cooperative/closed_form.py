"""The closed-form circle similarity Jacobian of a cooperative system as a kernel [COOP Appendix B].

``closed_form_jacobian(zero, system, q)`` evaluates J_A,Sc = ∂V_Sc/∂q without automatic
differentiation: X_c and J_c from each chain's end point and point Jacobian (the joint lines,
[COOP Eq. 14-17]), then ``gagen.model.closed_form_jacobians`` (Eq. 29, 78-91). On interpreter
multivectors it gives numbers; on the compiler's symbolic ones, expressions.

``similarity_closed_form(system)`` declares it as a front-end kernel ``similarity_closed_form``
(q → J_A, 12 × dof, the rows of ``similarity_jacobians``'s J_A): its function is both the
compiler's expressions and the interpreter's reference, so ``.trace().function`` is a CasADi
Function and ``gagen.compile``/``gagen build`` of a formula file holding it give C. It is not in the
default catalogue (``catalogue.kernel_functions``), which keeps the committed modules as they are.

``agreement(system, count)`` measures it against the AD J_A of ``similarity_jacobians`` at random
configurations within the joint limits, and ``agreement_figure`` plots that (docs/closed-form-jacobians.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gagen.algebra.signature import cga3d
from gagen.apps.cooperative.catalogue import kernel_functions
from gagen.check import joint_limits
from gagen.frontend import KernelFunction, matrix, scalars
from gagen.interp import MultiVector
from gagen.model.closed_form_jacobians import CircleSimilarityJacobian, circle_similarity_jacobian
from gagen.model.conformal import SIMILARITY
from gagen.model.primitives import through
from gagen.robots.system import System, points_and_jacobians, primitive_jacobian

KERNEL = "similarity_closed_form"


def _check_circle(system: System) -> None:
    if system.kind != "circle":
        raise ValueError(f"system {system.name!r}: primitive: the closed-form similarity Jacobian is for a "
                         f"circle system, got {system.kind!r}")


def closed_form_jacobian(zero: Any, system: System, q: Sequence[Any]) -> CircleSimilarityJacobian:
    """J_A,Sc of a circle system at q, with its factors (``circle_similarity_jacobian``); ``zero`` is
    the zero multivector of the path (interpreter or compiler) to build on."""
    _check_circle(system)
    points = points_and_jacobians(zero, system, q)
    xc = through(system.kind, [p for p, _ in points])
    return circle_similarity_jacobian(xc, primitive_jacobian(system, points))


def similarity_closed_form(system: System) -> KernelFunction:
    """The kernel ``similarity_closed_form``: q → J_A (rows ``SIMILARITY``, one column per joint)."""
    _check_circle(system)
    labels = [f"{robot}/{joint}" for robot, joint in system.joint_keys]

    def jacobian(ga: Any, q: Sequence[Any]) -> dict[str, Any]:
        return {"J_A": closed_form_jacobian(ga, system, q).J_A}

    return KernelFunction(jacobian, algebra=cga3d(), name=KERNEL,
                          doc="J_A,Sc = dV_Sc/dq in closed form [COOP Appendix B]",
                          inputs={"ga": "algebra", "q": scalars(system.dof, labels)},
                          outputs={"J_A": matrix(SIMILARITY, system.dof)})


TERMS = ("J_T V_R V_D", "V_T J_R V_D", "V_T V_R J_D")  # the terms of Eq. 29


@dataclass(frozen=True)
class Agreement:
    """Per configuration (rows of ``q``): max |J_closed − J_AD| / max |J_AD| for the closed form on the
    interpreter and as its traced CasADi Function, and max |·| of each term of Eq. 29 (``TERMS``) over
    max |J_AD|."""

    system: str
    q: np.ndarray
    interpreter: np.ndarray
    casadi: np.ndarray
    terms: np.ndarray  # (count, 3)


def agreement(system: System, count: int, seed: int = 0) -> Agreement:
    """The closed form against AD at ``count`` configurations drawn uniformly within the joint limits
    (±π where a joint has none)."""
    lower, upper, _ = joint_limits(system)
    lower, upper = np.where(np.isfinite(lower), lower, -np.pi), np.where(np.isfinite(upper), upper, np.pi)
    rng = np.random.default_rng(seed)
    configurations = rng.uniform(lower, upper, (count, system.dof))
    ad = kernel_functions(system)["similarity_jacobians"].trace().function
    closed = similarity_closed_form(system).trace().function
    zero = MultiVector.zero(cga3d())
    interpreter, compiled, terms = [], [], []
    for q in configurations:
        reference = np.array(ad(q)[0])
        scale = np.max(np.abs(reference))
        result = closed_form_jacobian(zero, system, [float(v) for v in q])
        ours = np.array([[c[b] for b in SIMILARITY] for c in result.J_A]).T
        interpreter.append(np.max(np.abs(ours - reference)) / scale)
        compiled.append(np.max(np.abs(np.array(closed(q)) - reference)) / scale)
        t, r, d = (f.value for f in (result.translator, result.rotor, result.dilator))
        parts = ([jt * (r * d) for jt in result.translator.jacobian],
                 [t * jr * d for jr in result.rotor.jacobian], [t * r * jd for jd in result.dilator.jacobian])
        terms.append([max(np.max(np.abs(c.coeffs)) for c in p) / scale for p in parts])
    return Agreement(system.name, configurations, np.array(interpreter), np.array(compiled), np.array(terms))


def agreement_figure(results: Sequence[Agreement], path: str | Path) -> Path:
    """A PNG: per system, the relative error of the closed form (interpreter and CasADi) at each
    configuration (log scale), and box plots of the size of each term of Eq. 29."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 3.8), layout="constrained")
    FigureCanvasAgg(fig)
    left, right = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    floor = np.finfo(float).eps / 4  # an exact agreement (0) drawn at the bottom of the log axis
    for k, result in enumerate(results):
        x = np.arange(result.interpreter.size)
        left.semilogy(x, np.maximum(result.interpreter, floor), ".", ms=3, color=f"C{2 * k}",
                      label=f"{result.system}: interpreter")
        left.semilogy(x, np.maximum(result.casadi, floor), "x", ms=3, color=f"C{2 * k + 1}",
                      label=f"{result.system}: CasADi")
    left.axhline(1e-12, color="k", lw=0.8, ls="--", label="test tolerance 1e-12")
    left.set(xlabel="random configuration", ylabel="max |J_closed − J_AD| / max |J_AD|",
             title="closed form vs AD (Eq. 29, 78-91)", ylim=(floor / 2, 1e-11))
    left.legend(fontsize=7, loc="upper right")
    data = [result.terms[:, j] for result in results for j in range(len(TERMS))]
    labels = [f"{result.system.split('_')[1]}\n{name}" for result in results for name in TERMS]
    right.boxplot(data, tick_labels=labels)
    right.set_yscale("log")
    right.tick_params(axis="x", labelsize=7)
    right.set(ylabel="max |term| / max |J_AD|", title="size of each term of Eq. 29")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    return path
