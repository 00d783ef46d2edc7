"""Systems with more chains than their primitive needs: X_c is the best fit through the end points.

The two bundled ones, ``leap_hand_palm_sphere`` (four fingertips and a palm point, a sphere) and
``four_pandas_circle`` (four Pandas, a circle): IK reaching a circle, checked by a plain numpy circle
fit of the end points. (Their kernels' values and every Jacobian against the interpreter and its
central differences: tests/cooperative/test_cooperative.py, which takes every bundled system.) The
spec loader and ``System`` take more chains, except for a point pair.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from gagen.apps.cooperative.bundled import bundled_specs
from gagen.apps.cooperative.catalogue import kernel_functions
from gagen.control import goals, solve_ik
from gagen.errors import SpecError
from gagen.interp import MultiVector, cga3d
from gagen.model import kinematics as K
from gagen.model.fitting import span
from gagen.model.primitives import points_needed
from gagen.robots.spec import load_system
from gagen.robots.system import System, cooperative_jacobian

ALG = cga3d()
ZERO = MultiVector.zero(ALG)
FITTED = ("four_pandas_circle", "leap_hand_palm_sphere")


@cache
def _system(name: str) -> tuple[System, dict[str, list[float]]]:
    return load_system(bundled_specs()[name])


@cache
def _kernel(name: str, kernel: str):
    return kernel_functions(_system(name)[0])[kernel].trace()


def _ends(system: System, q) -> list[MultiVector]:
    return [K.end_point(K.forward_kinematics(ZERO, c.joints, [float(v) for v in qc]))
            for c, qc in zip(system.chains, system.split(list(q)), strict=True)]


@pytest.mark.parametrize("name", FITTED)
def test_the_specs_have_more_chains_than_the_primitive_needs_and_a_well_conditioned_ready(name):
    system, configurations = _system(name)
    assert len(system.chains) == points_needed(system.kind) + 1
    fit = span(system.kind, _ends(system, configurations["ready"]))
    assert fit.fitted and fit.conditioning > 0.2
    with pytest.raises(ValueError, match="closed-form J_c spans"):
        cooperative_jacobian(ZERO, system, configurations["ready"])
    if name == "leap_hand_palm_sphere":  # the palm point sits on joint 12's axis: it never moves
        palm = system.chains[-1]
        q = configurations["ready"]
        columns = K.point_jacobian(*K.chain_kinematics(ZERO, palm.joints, system.split(list(q))[-1]))
        assert max(abs(c[b]) for c in columns for b in ("e1", "e2", "e3")) < 1e-15


def _numpy_circle(xs: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """(centre, radius, unit normal) of the algebraic circle fit in plain numpy: the SVD plane, then
    lstsq on |x|² − 2c·x − k with c in that plane."""
    mean = xs.mean(axis=0)
    _, _, vt = np.linalg.svd(xs - mean)
    u, v, n = vt
    rows = np.c_[2 * xs @ u, 2 * xs @ v, np.ones(len(xs))]
    (s, t, k), *_ = np.linalg.lstsq(rows, np.sum(xs**2, axis=1) - 2 * xs @ mean, rcond=None)
    c = mean + s * u + t * v
    return c, float(np.sqrt(k + c @ c)), n


def test_ik_moves_the_four_pandas_fitted_circle_onto_a_target():
    """solve_ik on the task kernel (CasADi) reaches e = 0: the numpy circle fit of the end points is then
    the target circle; the points themselves stay off it by the fit's residuals."""
    name = "four_pandas_circle"
    system, configurations = _system(name)
    centre, radius, normal = np.array([0.05, 0.0, 0.62]), 0.45, np.array([0.0, 0.2, 1.0]) / np.sqrt(1.04)
    target = goals.circle(centre=centre, radius=radius, normal=normal)
    task = _kernel(name, "task").function

    def kernel(q, vsd):
        e, j = task(q, vsd)
        return np.array(e).ravel(), np.array(j)

    result = solve_ik(kernel, configurations["ready"], target)
    assert result.status == "converged" and result.error_norm < 1e-12
    xs = np.array([[p[b] for b in ("e1", "e2", "e3")] for p in _ends(system, result.q)])
    c, r, n = _numpy_circle(xs)
    np.testing.assert_allclose(c, centre, rtol=0, atol=1e-9)
    assert r == pytest.approx(radius, abs=1e-9)
    assert abs(n @ normal) == pytest.approx(1, abs=1e-12)
    d = xs - c
    off_plane = d @ n
    radial = np.linalg.norm(d - np.outer(off_plane, n), axis=1) - r
    print(f"\n{name}: IK in {result.iterations} iterations; off-plane {off_plane} m, radial {radial} m")
    assert np.max(np.abs(off_plane)) < 0.05 and np.max(np.abs(radial)) < 0.05


def test_more_chains_than_a_point_pair_or_fewer_than_needed_are_refused(tmp_path):
    panda = bundled_specs()["four_pandas_circle"].parent / "panda/panda.urdf"
    spec = (bundled_specs()["four_pandas_circle"].read_text()
            .replace("primitive: circle", "primitive: point_pair")
            .replace("urdf: panda/panda.urdf", f"urdf: {panda}"))
    path = tmp_path / "pair.yaml"
    path.write_text(spec.split("configurations:")[0])
    with pytest.raises(SpecError, match="a point_pair is spanned by 2 chains \\(one per point\\), got 4"):
        load_system(path)
    chains = _system("four_pandas_circle")[0].chains
    with pytest.raises(ValueError, match="a sphere is spanned by 4 chains \\(more are fitted\\), got 3"):
        System("three", "sphere", chains[:3])
    System("five_points", "point", chains)  # the centroid of four end points
