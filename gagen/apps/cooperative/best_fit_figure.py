"""The figure of docs/best-fit.md: primitives fitted to more end points than they need [COOP Sec. 5.6].

Left, the LEAP Hand's ball grasp (``leap_hand_palm_sphere`` at ``ready``): four fingertips and a palm
point, and the sphere fitted to the five. Right, four Pandas (``four_pandas_circle``) after IK moved
their fitted circle onto a target: the end points stay off it by the fit's residuals.

    python -m gagen.apps.cooperative.best_fit_figure docs/images/best_fit.png
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from gagen.apps.cooperative.bundled import bundled_systems, ready_configuration
from gagen.interp import MultiVector, cga3d
from gagen.model import kinematics as K
from gagen.model.conformal import EUCLID
from gagen.model.fitting import span
from gagen.model.primitives import centre, radius, unit_normal
from gagen.robots.system import System

Array = NDArray[np.float64]
# the circle the IK reaches (centre, radius, normal)
TARGET_CENTRE, TARGET_RADIUS, TARGET_NORMAL = (0.05, 0.0, 0.62), 0.45, (0.0, 0.2, 1.0)
PANELS = (("leap_hand_palm_sphere", "LEAP Hand: 4 fingertips + palm, sphere"),
          ("four_pandas_circle", "4 Pandas after IK: fitted circle = target"))


@dataclass(frozen=True)
class Fitted:
    """The end points of a system at q, the round fitted to them, and the fit's conditioning."""

    points: Array  # (n, 3)
    centre: Array
    radius: float
    normal: Array | None  # circles only
    conditioning: float

    def residuals(self) -> Array:
        """Each point's distance from the round (signed: outside positive; a circle's is the distance
        from the circle itself)."""
        d = self.points - self.centre
        if self.normal is None:
            return np.asarray(np.linalg.norm(d, axis=1) - self.radius)
        h = d @ self.normal
        return np.asarray(np.hypot(np.linalg.norm(d - np.outer(h, self.normal), axis=1) - self.radius, h))


def fitted(system: System, q: Array) -> Fitted:
    """The round fitted to ``system``'s end points at q, on the reference interpreter."""
    zero = MultiVector.zero(cga3d())
    ends = [K.end_point(K.forward_kinematics(zero, c.joints, [float(v) for v in qc]))
            for c, qc in zip(system.chains, system.split(list(q)), strict=True)]
    fit = span(system.kind, ends)
    xyz = np.array([[p[b] for b in EUCLID] for p in ends])
    normal = np.array([unit_normal(fit.primitive)[b] for b in EUCLID]) if system.kind == "circle" else None
    return Fitted(xyz, np.array([centre(fit.primitive)[b] for b in EUCLID]), float(radius(fit.primitive)),
                  normal, float(fit.conditioning))


def reach_target(system: System) -> Array:
    """q after IK (the task kernel on CasADi) moved the fitted circle of ``four_pandas_circle`` from
    ``ready`` onto TARGET."""
    from gagen.apps.cooperative.catalogue import kernel_functions
    from gagen.control import goals, solve_ik

    task = kernel_functions(system)["task"].trace().function

    def kernel(q: Array, vsd: Array) -> tuple[Array, Array]:
        e, j = task(q, vsd)
        return np.array(e).ravel(), np.array(j)

    target = goals.circle(centre=TARGET_CENTRE, radius=TARGET_RADIUS, normal=TARGET_NORMAL)
    result = solve_ik(kernel, ready_configuration(system), target)
    if not result.converged:
        raise RuntimeError(f"IK did not reach the target circle: {result.message}")
    return result.q


def figure(path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from gagen.viewer.geometry import system_pose

    systems = bundled_systems()
    fig = plt.figure(figsize=(11, 5))
    for panel, (name, title) in enumerate(PANELS):
        system = systems[name]
        q = np.array(ready_configuration(system)) if panel == 0 else reach_target(system)
        fit = fitted(system, q)
        ax = fig.add_subplot(1, 2, panel + 1, projection="3d")
        for pose in system_pose(system, q):
            ax.plot(*pose.origins.T, color="0.55", lw=1.2)
        t = np.linspace(0, 2 * np.pi, 60)
        if fit.normal is None:
            u, v = np.meshgrid(t, np.linspace(0, np.pi, 30))
            sphere = fit.centre[:, None, None] + fit.radius * np.array(
                [np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)])
            ax.plot_wireframe(*sphere, color="tab:blue", lw=0.3, alpha=0.4)
        else:
            a = np.cross(fit.normal, [1.0, 0.0, 0.0])
            a /= np.linalg.norm(a)
            b = np.cross(fit.normal, a)
            ax.plot(*(fit.centre[:, None] + fit.radius * (np.outer(a, np.cos(t)) + np.outer(b, np.sin(t)))),
                    color="tab:blue", lw=2)
        ax.scatter(*fit.points.T, color="tab:red", s=25, depthshade=False)
        residual = np.abs(fit.residuals()).max()
        ax.set_title(f"{title}\nr = {fit.radius * 1000:.1f} mm, max residual {residual * 1000:.2f} mm, "
                     f"conditioning {fit.conditioning:.2f}", fontsize=9)
        ax.set_box_aspect(np.ptp(np.vstack([fit.points, fit.centre + fit.radius, fit.centre - fit.radius,
                                            *(p.origins for p in system_pose(system, q))]), axis=0))
        ax.view_init(elev=25 if panel == 0 else 40, azim=-60)
        ax.tick_params(labelsize=6)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


if __name__ == "__main__":
    print(f"wrote {figure(Path(sys.argv[1] if len(sys.argv) > 1 else 'best_fit.png'))}")
