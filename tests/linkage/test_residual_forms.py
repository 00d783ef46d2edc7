"""Why gagen's revolute residual is a − b, and what the paper's wedge does under Newton (issue 32).

[LINK 3.2] writes a revolute joint as X_a ∧ X_b = 0. Read as its six bivector coefficients, that
residual vanishes linearly at a solution (its e01/e02 part is b − a itself), so Gauss-Newton on it
converges quadratically, in as many iterations per 1° crank step as gagen's a − b (which has 3×
fewer rows). Only a scalar norm of it, ‖X_a ∧ X_b‖² = (X_a·X_b)² = ¼|a − b|⁴ per joint, has a root
of multiplicity four and a Jacobian that vanishes there: Newton on it shrinks the error by ¾ per
iteration and stalls. On the bundled four-bar, on the interpreter, with gagen's own frames, retraction
and least-squares step; positions against the circle intersection.
"""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gagen.algebra.signature import cga2d
from gagen.apps.linkage.constraints import GENERATORS, MOTOR, Frames, constraints, retract
from gagen.apps.linkage.spec import Revolute, load_linkage
from gagen.interp import MultiVector

FOUR_BAR = load_linkage(Path(__file__).resolve().parents[2] / "gagen" / "apps" / "linkage" / "robots"
                        / "four_bar.yaml")
LIKE = MultiVector.zero(cga2d())
BIVECTOR = ("e01", "e02", "e0inf", "e12", "e1inf", "e2inf")
GENS = [LIKE.make({g: 1}) for g in GENERATORS]
N = 3 * len(FOUR_BAR.unknown)


def _motors(R: np.ndarray) -> dict[str, MultiVector]:
    return {b: LIKE.make(dict(zip(MOTOR, R[4 * i:4 * i + 4], strict=True)))
            for i, b in enumerate(FOUR_BAR.unknown)}


def _columns(body: str) -> list[int]:
    return [3 * FOUR_BAR.unknown.index(body) + k for k in range(3)] if body in FOUR_BAR.unknown else []


def _residual(kind: str, R: np.ndarray, theta: float) -> tuple[np.ndarray, np.ndarray]:
    """F and ∂F/∂ε (left perturbations, as gagen's): ``difference`` gagen's a − b (2 rows per joint),
    ``wedge`` the coefficients of X_a ∧ X_b (6 rows), ``scalar`` (X_a·X_b)² = ‖X_a ∧ X_b‖² (1 row)."""
    if kind == "difference":
        F, columns = constraints(LIKE, FOUR_BAR, _motors(R), theta)
        return np.array(F, dtype=float), np.array(columns, dtype=float).T
    frames = Frames(LIKE, FOUR_BAR, _motors(R), theta)
    rows: list[float] = []
    jacobian: list[np.ndarray] = []
    for joint in FOUR_BAR.active_joints:
        assert isinstance(joint, Revolute)
        xa, xb = frames.point(joint.a), frames.point(joint.b)
        # d(X_a ∧ X_b) = (X_a × B) ∧ X_b + X_a ∧ (X_b × B): the wedge is bilinear
        moved: dict[int, list[Any]] = {}
        for c, g in zip(_columns(joint.a[0]), GENS, strict=False):
            moved.setdefault(c, []).append(xa.commutator(g) ^ xb)
        for c, g in zip(_columns(joint.b[0]), GENS, strict=False):
            moved.setdefault(c, []).append(xa ^ xb.commutator(g))
        if kind == "wedge":
            wedge = xa ^ xb
            for blade in BIVECTOR:
                rows.append(wedge[blade])
                row = np.zeros(N)
                for c, parts in moved.items():
                    row[c] = sum(part[blade] for part in parts)
                jacobian.append(row)
        else:
            dot = xa.sp(xb)  # = −½|a − b|², so dot² = ‖X_a ∧ X_b‖² for two null vectors
            rows.append(dot * dot)
            row = np.zeros(N)
            for c, g in zip(_columns(joint.a[0]), GENS, strict=False):
                row[c] += 2 * dot * xa.commutator(g).sp(xb)
            for c, g in zip(_columns(joint.b[0]), GENS, strict=False):
                row[c] += 2 * dot * xa.sp(xb.commutator(g))
            jacobian.append(row)
    return np.array(rows), np.array(jacobian)


def _retract(R: np.ndarray, step: np.ndarray) -> np.ndarray:
    motors = _motors(R)
    return np.array([retract(LIKE, motors[b], list(step[3 * i:3 * i + 3]))[m]
                     for i, b in enumerate(FOUR_BAR.unknown) for m in MOTOR])


def _gap(R: np.ndarray, theta: float) -> float:
    """The position error max |a − b| over the joints, whichever residual drives Newton."""
    return float(np.max(np.abs(_residual("difference", R, theta)[0])))


def _newton(kind: str, R: np.ndarray, theta: float, iterations: int = 30) -> tuple[np.ndarray, list[float]]:
    """Gauss-Newton (least squares, as gagen's solver) until max |a − b| < 1e-12; the errors seen."""
    gaps = [_gap(R, theta)]
    while gaps[-1] >= 1e-12 and len(gaps) <= iterations:
        F, J = _residual(kind, R, theta)
        R = _retract(R, -np.linalg.lstsq(J, F, rcond=None)[0])
        gaps.append(_gap(R, theta))
    return R, gaps


def _coupler_c(R: np.ndarray, theta: float) -> np.ndarray:
    point = Frames(LIKE, FOUR_BAR, _motors(R), theta).point(("coupler", "C"))
    return np.array([point["e1"], point["e2"]])


def _circle_intersection(theta: float, near: np.ndarray) -> np.ndarray:
    """C at |C − B| = 3√2, |C − D| = 3, B = (cos θ, sin θ), D = (4, 0): the root nearer ``near``."""
    b, d = np.array([np.cos(theta), np.sin(theta)]), np.array([4.0, 0.0])
    r0, r1, dist = np.sqrt(18.0), 3.0, np.linalg.norm(d - b)
    along = (r0 ** 2 - r1 ** 2 + dist ** 2) / (2 * dist)
    u = (d - b) / dist
    h = np.sqrt(r0 ** 2 - along ** 2)
    roots = [b + along * u + s * h * np.array([-u[1], u[0]]) for s in (1, -1)]
    return min(roots, key=lambda c: float(np.linalg.norm(c - near)))


@pytest.mark.parametrize("kind", ["wedge", "scalar"])
def test_wedge_jacobians_match_differences(kind: str) -> None:
    """∂F/∂ε of both wedge forms against central differences along gagen's retraction."""
    rng = np.random.default_rng(3)
    for _ in range(2):
        R = np.concatenate([[np.cos(a / 2), -np.sin(a / 2), *rng.uniform(-0.1, 0.1, 2)]
                            for a in rng.uniform(-0.5, 0.5, len(FOUR_BAR.unknown))])
        theta = float(rng.uniform(-np.pi, np.pi))
        _, J = _residual(kind, R, theta)
        for c in range(N):
            step = np.zeros(N)
            step[c] = 1e-6
            plus, minus = (_residual(kind, _retract(R, s), theta)[0] for s in (step, -step))
            np.testing.assert_allclose(J[:, c], (plus - minus) / 2e-6, atol=2e-8)


def test_newton_on_the_wedge_as_a_vector_is_quadratic_like_the_difference() -> None:
    """1° crank steps over 60°, each from the previous solution: the wedge's six coefficients per joint
    take 3 iterations a step, as gagen's a − b does, each error ≤ 2 × the previous one squared; the
    coupler's C on the circle intersection to 1e-12."""
    R = {kind: np.tile([1.0, 0.0, 0.0, 0.0], len(FOUR_BAR.unknown)) for kind in ("wedge", "difference")}
    c = np.array([4.0, 3.0])
    for degree in range(61):
        theta = np.radians(degree)
        counts = {}
        for kind in R:
            R[kind], gaps = _newton(kind, R[kind], theta)
            counts[kind] = len(gaps) - 1
            assert gaps[-1] < 1e-12, (kind, degree, gaps)
            for before, after in pairwise(gaps):
                if before > 1e-7:
                    assert after <= 2.0 * before ** 2, (kind, degree, gaps)
        c = _circle_intersection(theta, c)
        np.testing.assert_allclose(_coupler_c(R["wedge"], theta), c, atol=1e-12)
        if degree:
            assert counts["wedge"] == counts["difference"] <= 3, (degree, counts)


def test_newton_on_the_scalar_norm_of_the_wedge_stalls() -> None:
    """The same 1° step with ‖X_a ∧ X_b‖² per joint: the first iterations shrink the error by exactly
    ¾ (Newton on a fourfold root), and 30 iterations leave it above 1e-4, where the vector forms
    reach 1e-15 in 3."""
    R, _ = _newton("difference", np.tile([1.0, 0.0, 0.0, 0.0], len(FOUR_BAR.unknown)), 0.0)
    theta = np.radians(1.0)
    _, vector = _newton("wedge", R, theta)
    _, scalar = _newton("scalar", R, theta, iterations=30)
    assert len(vector) - 1 == 3
    assert len(scalar) - 1 == 30 and min(scalar) > 1e-4, scalar
    np.testing.assert_allclose([scalar[1] / scalar[0], scalar[2] / scalar[1]], 0.75, atol=2e-3)
