"""Directional Jacobian declarations (``gagen.along``): one column (∂out/∂in)·v by forward AD, nested
ones (the derivative of such a column along v again, as J̇ q̇ is), against closed forms; the check's
differences along the direction, which catch a wrong rule; and the refused declarations."""

import numpy as np
import pytest

import gagen
from gagen.frontend import KernelError, KernelFunction


def _f(ga, x, v):
    """f(x) = x0² x1 + sin x1 (v is only the direction of the declared derivatives)."""
    return {"f": x[0] * x[0] * x[1] + ga.math.sin(x[1])}


def _closed_forms(x: np.ndarray, v: np.ndarray) -> tuple[float, float, float]:
    gradient = np.array([2 * x[0] * x[1], x[0] ** 2 + np.cos(x[1])])
    hessian = np.array([[2 * x[1], 2 * x[0]], [2 * x[0], -np.sin(x[1])]])
    return x[0] ** 2 * x[1] + np.sin(x[1]), gradient @ v, v @ hessian @ v


def _kernel(rule=None) -> KernelFunction:
    return KernelFunction(_f, algebra="ga3d", name="quadratic",
                          inputs={"ga": "algebra", "x": gagen.scalars(2), "v": gagen.scalars(2)},
                          outputs={"f": "scalar"},
                          jacobians={"Jv": ("f", "x", gagen.along("v")),
                                     "Hvv": ("Jv", "x", gagen.along("v"))}, rule=rule)


@pytest.mark.parametrize("seed", range(5))
def test_forward_ad_gives_the_directional_and_nested_derivatives(seed):
    rng = np.random.default_rng(seed)
    x, v = rng.uniform(-2, 2, 2), rng.uniform(-2, 2, 2)
    traced = _kernel().trace()
    assert [(p.name, p.shape) for p in traced.outputs] == [("f", (1, 1)), ("Jv", (1, 1)), ("Hvv", (1, 1))]
    got = [float(np.asarray(o).item()) for o in traced.function(x, v)]
    assert got == pytest.approx(_closed_forms(x, v), rel=1e-13, abs=1e-13)


@pytest.mark.compiling
@pytest.mark.parametrize("wrong", [False, True])
def test_check_holds_directional_rules_against_differences(tmp_path, wrong):
    """A rule giving Hvv is held against nested differences of f along v (a wrong one, missing the
    cross term, fails), and Jv against differences along v."""
    import casadi as ca

    from gagen.build import build_source
    from gagen.check import DIFFERENCES, check_kernels, failures
    from gagen.frontend import source_of
    from gagen.runtime import load

    def rule(inputs):
        x, v = inputs["x"], inputs["v"]
        jv = 2 * x[0] * x[1] * v[0] + (x[0] ** 2 + ca.cos(x[1])) * v[1]
        cross = 0 if wrong else 4 * x[0] * v[0] * v[1]
        return {"f": x[0] ** 2 * x[1] + ca.sin(x[1]), "Jv": jv,
                "Hvv": 2 * x[1] * v[0] ** 2 + cross - ca.sin(x[1]) * v[1] ** 2}

    fn = _kernel(rule)
    build_source(source_of([fn], "quadratic"), tmp_path / "quadratic", progress=lambda _: None)
    report = check_kernels(load(tmp_path / "quadratic"), {"quadratic": fn}, count=6)
    by_differences = {d.output: d for d in report if d.reference == DIFFERENCES}
    assert set(by_differences) == {"Jv", "Hvv"}
    assert [d.output for d in failures(report)] == (["Hvv"] if wrong else [])
    assert by_differences["Jv"].worst < 1e-9
    assert (by_differences["Hvv"].worst > 0.01) if wrong else (by_differences["Hvv"].worst < 1e-7)


@pytest.mark.parametrize(("jacobians", "expected"), [
    ({"Jv": ("f", "x", gagen.along("w"))}, "along 'w': expected an input of 2 entries"),
    ({"Jv": ("f", "x", gagen.along("s"))}, "along 's': expected an input of 2 entries"),
    ({"Jv": ("f", "x", gagen.along("v"), gagen.along("v"))}, "optionally ending in along"),
    ({"Jv": ("f", "x", "v")}, "optionally ending in along"),
])
def test_malformed_directional_declarations_are_refused(jacobians, expected):
    with pytest.raises(KernelError, match=expected):
        KernelFunction(lambda ga, x, v, s: _f(ga, x, v), algebra="ga3d", name="bad",
                       inputs={"ga": "algebra", "x": gagen.scalars(2), "v": gagen.scalars(2), "s": "scalar"},
                       outputs={"f": "scalar"}, jacobians=jacobians)
