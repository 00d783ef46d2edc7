"""Interpolating primitives through similarity versors [COOP Fig. 4]: the group exponential against its
power series, the path's ends, its constant speed, the kind it keeps, closed forms for pure
translations, dilations and turns, the kernels' dX/dt against differences, and ``gagen interpolate``."""

from __future__ import annotations

import csv
import importlib.util
import shutil
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from gagen.algebra.signature import cga3d
from gagen.cli import main as gagen
from gagen.interp import MultiVector
from gagen.model import versors as V
from gagen.model.conformal import SIMILARITY_GENERATOR
from gagen.model.interpolation import interpolate, versor_path
from gagen.model.primitives import KINDS, centre, contains_cost, radius_squared, through, unit_normal
from gagen.model.primitives import direction as line_direction

ALG = cga3d()
GRADE = {"point": 1, "point_pair": 2, "line": 3, "circle": 3, "plane": 4, "sphere": 4}
FLAT = {"line", "plane"}


def P(x) -> MultiVector:
    x = np.asarray(x, dtype=float)
    return MultiVector.from_blades(ALG, {"e0": 1.0, "e1": x[0], "e2": x[1], "e3": x[2], "einf": 0.5 * x @ x})


def frame(n):
    """Unit u, v with u × v = n̂ (numpy)."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    helper = np.eye(3)[int(np.argmin(np.abs(n)))]
    u = np.cross(helper, n)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u), n


def spanning(kind, c, r, n):
    """Points spanning a primitive of ``kind`` about c with size r and axis n (numpy), oriented like the
    unit primitives (pair and line along n, circle counter-clockwise about n, plane normal n, sphere
    positively)."""
    u, v, n = frame(n)
    c = np.asarray(c, float)
    return {"point": [c], "point_pair": [c - r * n, c + r * n], "line": [c, c + n],
            "circle": [c + r * u, c + r * v, c - r * u], "plane": [c, c + u, c + v],
            "sphere": [c + r * np.eye(3)[0], c + r * np.eye(3)[1], c - r * np.eye(3)[0],
                       c + r * np.eye(3)[2]]}[kind]


def primitive(kind, c, r=1.0, n=(0, 0, 1)) -> MultiVector:
    return through(kind, [P(p) for p in spanning(kind, c, r, n)])


def assert_proportional(a: MultiVector, b: MultiVector, tol: float) -> float:
    """a = s b with s > 0, to tol relative; returns s."""
    s = float(a.coeffs @ b.coeffs) / float(b.coeffs @ b.coeffs)
    assert s > 0
    assert np.linalg.norm(a.coeffs - s * b.coeffs) <= tol * np.linalg.norm(a.coeffs)
    return s


def affine(v: MultiVector):
    """(u, A) of x ↦ u + A x for the versor v, from the images of 0, e1, e2, e3 (numpy from the sandwich)."""
    def image(x):
        p = v.sandwich(P(x))
        return np.array([p["e1"], p["e2"], p["e3"]]) / -p.sp(MultiVector.from_blades(ALG, {"einf": 1.0}))

    u = image(np.zeros(3))
    return u, np.array([image(e) - u for e in np.eye(3)]).T


def generator_norm(b: MultiVector) -> float:
    return float(np.linalg.norm([b[k] for k in SIMILARITY_GENERATOR]))


coordinate = st.floats(-1, 1, allow_nan=False, allow_subnormal=False)
centres = st.tuples(coordinate, coordinate, coordinate)
radii = st.floats(0.2, 1.5)
directions = st.tuples(coordinate, coordinate, coordinate).filter(lambda n: np.linalg.norm(n) > 0.3)
ends = st.tuples(centres, radii, directions)


def pair(kind, a, b):
    x1, x2 = primitive(kind, *a), primitive(kind, *b)
    path = versor_path(kind, x1, x2)
    # well away from the guarded half turns (V_S of a flat nearly opposite to X_u loses eps/K0)
    assume(float(path.conditioning) > 1e-4)
    return x1, x2, path


# -- the group exponential -----------------------------------------------------------------------------
def series_exp(b: MultiVector) -> MultiVector:
    """e^{−B/2} = Σ (−B/2)^k / k! with the interpreter's geometric product."""
    x, term = b * -0.5, MultiVector.from_blades(ALG, {"1": 1.0})
    total = term
    for k in range(1, 80):
        term = term * x * (1.0 / k)
        total = total + term
    return total


generators = st.tuples(*[st.floats(-1.5, 1.5, allow_subnormal=False)] * 7,
                       st.sampled_from([1e-9, 1e-3, 0.3, 1.0]))


@settings(max_examples=40)
@given(generators)
def test_group_exponential_is_the_series_and_log_inverts_it(values):
    *coefficients, scale = values
    values = np.array(coefficients) * scale
    b = MultiVector.from_blades(ALG, dict(zip(SIMILARITY_GENERATOR, values, strict=True)))
    assume(np.linalg.norm([b["e12"], b["e13"], b["e23"]]) < 3.0)  # log's domain: turns below π
    v = V.exp_similarity_lie(b)
    assert np.max(np.abs(v.coeffs - series_exp(b).coeffs)) <= 5e-15 * max(1.0, np.max(np.abs(v.coeffs)))
    back = V.log_similarity_lie(v)
    assert max(abs(back[k] - b[k]) for k in SIMILARITY_GENERATOR) <= 1e-13 * max(1.0, generator_norm(b))
    # a one-parameter subgroup: exp(sB) exp((1 − s)B) = exp(B)
    product = V.exp_similarity_lie(b * 0.3) * V.exp_similarity_lie(b * 0.7)
    assert np.max(np.abs(product.coeffs - v.coeffs)) <= 5e-15 * max(1.0, np.max(np.abs(v.coeffs)))


def test_group_exponential_near_the_series_switch():
    """Both sides of |z|² = σ² + θ² = LIE_SERIES_BELOW (σ the e0∞ part, θ the turn) agree with the series
    to 1e-15: no seam between the branches."""
    for root in np.sqrt(V.LIE_SERIES_BELOW) * np.array([1 - 1e-9, 1.0, 1 + 1e-9]):
        for turn_share in (0.0, 0.6, 1.0):  # how |z| splits between the turn and the dilation
            z = {"e12": 0.6 * turn_share * root, "e23": 0.8 * turn_share * root,
                 "e0inf": np.sqrt(1 - turn_share ** 2) * root}
            b = MultiVector.from_blades(ALG, {**z, "e1inf": 0.7, "e2inf": -0.4, "e3inf": 0.9})
            assert np.max(np.abs(V.exp_similarity_lie(b).coeffs - series_exp(b).coeffs)) < 1e-15


# -- the path ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", KINDS)
@settings(max_examples=25)
@given(a=ends, b=ends)
def test_ends_speed_and_kind(kind, a, b):
    x1, x2, path = pair(kind, a, b)
    unit_points = spanning(kind, np.zeros(3), 1.0, (1, 0, 0) if kind in ("point_pair", "line") else (0, 0, 1))
    # the ends, up to a positive scale
    assert_proportional(interpolate(kind, x1, x2, 0.0).primitive, x1, 1e-12)
    assert_proportional(interpolate(kind, x1, x2, 1.0).primitive, x2, 1e-12)
    # constant speed in the similarity metric: ‖log(V(t)~ V(t+h))‖ = h ‖log(V1~ V2)‖
    h, speed = 0.05, generator_norm(path.generator)
    for t in (0.0, 0.3, 0.6, 0.95):
        step = V.log_similarity_lie(~path.at(t) * path.at(t + h))
        assert abs(generator_norm(step) - h * speed) <= 1e-10
    for t in (0.25, 0.5, 0.75):
        x, v, _ = interpolate(kind, x1, x2, t)
        # one grade, flat or round as the kind is
        assert np.linalg.norm((x - x.grade(GRADE[kind])).coeffs) <= 1e-13 * np.linalg.norm(x.coeffs)
        einf = MultiVector.from_blades(ALG, {"einf": 1.0})
        wedge = np.linalg.norm((x ^ einf).coeffs) / np.linalg.norm(x.coeffs)
        if kind in FLAT:
            assert wedge <= 1e-13
        else:  # rounds and points: X ∧ e∞ is their carrier flat (a flat point for a point)
            assert wedge > 1e-3
        # the image of the unit primitive under the similarity x ↦ u + A x (numpy): A = s·rotation
        u, m = affine(v)
        s = np.cbrt(np.linalg.det(m))
        assert s > 0 and np.allclose(m.T @ m, s * s * np.eye(3), rtol=0, atol=1e-12 * s * s)
        image = [u + m @ p for p in unit_points]
        assert_proportional(x, through(kind, [P(p) for p in image]), 1e-11)
        if kind in ("point_pair", "circle", "sphere"):  # a real round of radius s about u
            assert radius_squared(x) > 0
            assert abs(np.sqrt(radius_squared(x)) - s) <= 1e-11 * s
            c = centre(x)
            assert np.allclose([c["e1"], c["e2"], c["e3"]], u, rtol=0, atol=1e-11)
        if kind == "circle":  # on-circle points from numpy's centre, normal and radius
            e1, e2, normal = m[:, 0] / s, m[:, 1] / s, m[:, 2] / s
            n = unit_normal(x)
            assert np.allclose([n["e1"], n["e2"], n["e3"]], normal, rtol=0, atol=1e-11)
            for phi in np.linspace(0, 2 * np.pi, 7):
                on = P(u + s * (np.cos(phi) * e1 + np.sin(phi) * e2))
                assert contains_cost(x, on) <= 1e-22 * np.linalg.norm(x.coeffs) ** 2
        if kind == "line":
            d = line_direction(x)
            assert np.allclose([d["e1"], d["e2"], d["e3"]], m[:, 0], rtol=0, atol=1e-11)


def test_point_moves_linearly():
    x = interpolate("point", P([0, 0, 0]), P([1, 2, 3]), 0.5).primitive
    assert_proportional(x, P([0.5, 1.0, 1.5]), 1e-15)


# -- closed forms ---------------------------------------------------------------------------------------
def _xyz(x):
    return np.array([x["e1"], x["e2"], x["e3"]])


@pytest.mark.parametrize("kind", ["point_pair", "circle", "sphere"])
@settings(max_examples=20)
@given(c=centres, d=centres, r=radii, n=directions, t=st.floats(0, 1))
def test_translation_moves_the_centre_linearly(kind, c, d, r, n, t):
    x1 = primitive(kind, c, r, n)
    x2 = primitive(kind, np.add(c, d), r, n)
    x = interpolate(kind, x1, x2, t).primitive
    assert np.allclose(_xyz(centre(x)), np.asarray(c) + t * np.asarray(d), rtol=0, atol=1e-12)
    assert abs(np.sqrt(radius_squared(x)) - r) <= 1e-12 * r


@pytest.mark.parametrize("kind", ["point_pair", "circle", "sphere"])
@settings(max_examples=20)
@given(c=centres, r1=radii, r2=radii, n=directions, t=st.floats(0, 1))
def test_dilation_scales_the_radius_geometrically(kind, c, r1, r2, n, t):
    x = interpolate(kind, primitive(kind, c, r1, n), primitive(kind, c, r2, n), t).primitive
    assert abs(np.sqrt(radius_squared(x)) - r1 ** (1 - t) * r2 ** t) <= 1e-12 * r2
    assert np.allclose(_xyz(centre(x)), c, rtol=0, atol=1e-12)


@settings(max_examples=20)
@given(c=centres, r=radii, beta=st.floats(0, 2 * np.pi), alpha=st.floats(0.01, 3.0), t=st.floats(0, 1))
def test_turn_about_the_centre_turns_the_normal_linearly(c, r, beta, alpha, t):
    axis = np.array([np.cos(beta), np.sin(beta), 0.0])  # ⟂ e3, so V_S's minimal rotor turns about it

    def turned(angle):  # Rodrigues (numpy): e3 turned by angle about axis
        e3 = np.array([0.0, 0.0, 1.0])
        return e3 * np.cos(angle) + np.cross(axis, e3) * np.sin(angle)

    x1, x2 = primitive("circle", c, r, (0, 0, 1)), primitive("circle", c, r, turned(alpha))
    x = interpolate("circle", x1, x2, t).primitive
    assert np.allclose(_xyz(unit_normal(x)), turned(t * alpha), rtol=0, atol=1e-12)
    assert np.allclose(_xyz(centre(x)), c, rtol=0, atol=1e-12)
    assert abs(np.sqrt(radius_squared(x)) - r) <= 1e-12 * r


def test_degenerate_and_opposite_are_reported():
    """Collinear spanning points, and a line against its own reverse (a half turn): conditioning 0, finite."""
    good = primitive("circle", (0, 0, 0), 1.0, (0, 0, 1))
    flat = through("circle", [P([0, 0, 0]), P([1, 0, 0]), P([2, 0, 0])])
    path = versor_path("circle", good, flat)
    assert path.conditioning == 0
    assert np.all(np.isfinite(interpolate("circle", good, flat, 0.5).primitive.coeffs))
    line = primitive("line", (0.3, 0.2, 0.1), 1.0, (0, 1, 0))
    path = versor_path("line", line, -line)
    assert abs(path.conditioning) < 1e-20 and np.all(np.isfinite(path.at(0.5).coeffs))
    # the same line twice: the similarity's K0/4 = (1 + cos 90°)/2 from X_u along e1, no relative turn
    assert abs(versor_path("line", line, line).conditioning - 0.5) <= 1e-15


# -- the kernels ---------------------------------------------------------------------------------------
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "interpolation.py"


@cache
def _kernels():
    """The example file's kernels, imported as gagen build imports it."""
    spec = importlib.util.spec_from_file_location("interpolation_example", EXAMPLE)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    return {kind: getattr(example, f"interpolate_{kind}") for kind in KINDS}


@pytest.mark.parametrize("kind", KINDS)
def test_kernel_derivative_against_central_differences(kind):
    k = _kernels()[kind]
    traced = k.trace()
    rng = np.random.default_rng(7)
    for _ in range(3):
        x1, x2, t = k.sample(rng)
        x, conditioning, dx = (np.asarray(o, dtype=float).ravel() for o in traced.function(x1, x2, t))
        reference, reference_conditioning, _ = k.reference(x1, x2, t)
        assert np.allclose(x, reference.ravel(), rtol=0, atol=1e-13 * np.abs(reference).max())
        assert abs(conditioning[0] - reference_conditioning[0, 0]) <= 1e-12 * abs(conditioning[0])
        h = 1e-5
        central = (k.reference(x1, x2, t + h)[0] - k.reference(x1, x2, t - h)[0]).ravel() / (2 * h)
        assert np.allclose(dx, central, rtol=0, atol=1e-8 * np.abs(central).max())


@pytest.mark.slow  # writes every backend's files (C, CUDA, JAX sources): ~2-4 s
def test_example_file_builds_and_its_casadi_functions_run(tmp_path):
    assert gagen(["build", str(EXAMPLE), "--no-compile", "-o", str(tmp_path / "m")]) == 0
    module = gagen_load(tmp_path / "m")
    k = _kernels()["circle"]
    x1, x2, t = k.sample(np.random.default_rng(3))
    x, conditioning, dx = module.casadi.interpolate_circle(x1, x2, t)
    reference = k.reference(x1, x2, t)
    assert np.allclose(np.asarray(x).ravel(), reference[0].ravel(), rtol=0, atol=1e-13)
    assert abs(float(conditioning) - reference[1][0, 0]) <= 1e-12 * abs(float(conditioning))
    h = 1e-5
    central = (k.reference(x1, x2, t + h)[0] - k.reference(x1, x2, t - h)[0]).ravel() / (2 * h)
    assert np.allclose(np.asarray(dx).ravel(), central, rtol=0, atol=1e-8 * np.abs(central).max())


def gagen_load(folder):
    from gagen.runtime import load

    return load(folder)


# -- the command ----------------------------------------------------------------------------------------
def _rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def test_command_on_a_users_spec(tmp_path, capsys):
    """Copy of a bundled spec under another name, from ready to its goal (ready moved by 0.1 m up, 0.2 rad
    about x and ×1.3): the CSV's ends hold the primitive's centre, radius and normal of that closed form."""
    from gagen.registry import bundled_specs

    spec = tmp_path / "my_ring.yaml"
    source = bundled_specs("cooperative")["three_pandas_circle"]
    shutil.copytree(source.parent / "panda", tmp_path / "panda")
    shutil.copy(source, spec)
    out = tmp_path / "out"
    assert gagen(["interpolate", str(spec), "--from", "ready", "--to", "circle", "--steps", "3",
                  "--out", str(out)]) == 0
    rows = _rows(out / "interpolation_my_ring_ready_circle.csv")
    assert [float(r["t"]) for r in rows] == [0.0, 0.5, 1.0]
    assert (out / "interpolation_my_ring_ready_circle.png").stat().st_size > 10_000
    columns = ("x", "y", "z", "scale", "ax", "ay", "az")
    start, end = ([float(r[k]) for k in columns] for r in (rows[0], rows[-1]))
    # the ready circle, from the same model through its own queries
    from gagen.robots.spec import load_system
    from gagen.robots.system import cooperative_primitive

    system, configurations = load_system(spec)
    x0 = cooperative_primitive(MultiVector.zero(ALG), system, configurations["ready"])
    c0, r0, n0 = _xyz(centre(x0)), np.sqrt(radius_squared(x0)), _xyz(unit_normal(x0))
    assert np.allclose(start, [*c0, r0, *n0], rtol=0, atol=1e-12)
    rx = np.array([[1, 0, 0], [0, np.cos(0.2), -np.sin(0.2)], [0, np.sin(0.2), np.cos(0.2)]])
    assert np.allclose(end, [*(c0 + np.array([0, 0, 0.1])), 1.3 * r0, *(rx @ n0)], rtol=0, atol=1e-12)
    assert "circle: conditioning" in capsys.readouterr().out


def test_command_on_stated_primitives_and_bad_arguments(tmp_path, capsys):
    out = tmp_path / "out"
    assert gagen(["interpolate", "sphere", "--from", "centre=0,0,0", "radius=0.5", "--to", "centre=1,0,0",
                  "radius=2", "--steps", "3", "--out", str(out)]) == 0
    rows = _rows(out / "interpolation_sphere.csv")
    assert np.allclose([float(r["scale"]) for r in rows], [0.5, 1.0, 2.0], rtol=1e-12)  # 0.5^(1-t) 2^t
    capsys.readouterr()
    assert gagen(["interpolate", "circle", "--from", "centre=0,0", "radius=1", "normal=0,0,1", "--to",
                  "centre=0,0,1", "radius=1", "normal=0,0,1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--from centre: expected three comma-separated finite numbers" in err
    assert gagen(["interpolate", "my_missing.yaml", "--from", "ready", "--to", "x", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a bundled system" in err
    with pytest.raises(SystemExit) as exit_:
        gagen(["interpolate", "circle", "--steps", "0"])
    assert exit_.value.code == 2
    assert capsys.readouterr().err.count("\n") == 1
