"""User-style kernels through the public front-end only (``gagen.kernel``, ``gagen.compile``).

Each kernel below is written as a user would: a decorated function at module level over one of the
preset algebras (cga3d, cga2d, pga3d, ga3d), using the multivector API and the helpers of
``gagen.model``. On ≥ 20 random inputs each (``kernel.sample`` or the kernel's own ``sample``):

- fast part (no C compiler): the CasADi Function of ``kernel.trace()`` against the reference
  interpreter (``kernel.reference``), and every AD Jacobian against Richardson-extrapolated central
  differences of the reference;
- compiling part (``@pytest.mark.compiling``): ``gagen.compile(kernel)`` called once per sample
  (``k(*inputs)``) and on all samples at once (``k.batch``), against the same reference, and its
  Jacobians against the same differences.

Values agree to 1e-12 relative (|error| / max(1, |reference|), entry by entry); Jacobians to 1e-7
relative to the differences.
"""
# ruff: noqa: F821 (the annotations are gagen kinds, "point", "motor", …: strings, not Python names)

import numpy as np
import pytest

import gagen
from gagen.algebra.kinds import kind_blades
from gagen.algebra.signature import cga2d, cga3d
from gagen.interp import MultiVector
from gagen.interp.multivector import conformal_point
from gagen.model.conformal import einf, location, point
from gagen.model.primitives import centre, radius, through, unit_normal

SAMPLES = 20
RTOL = 1e-12
JAC_RTOL = 1e-7


# -- samplers a user would write for kinds whose random coefficients are not the geometric object --------
def _rounds(algebra, count: int):
    """A sampler: ``count`` conformal points spanning a round (circle: 3, sphere: 4) as its only input."""
    def sample(rng: np.random.Generator) -> list[np.ndarray]:
        n = algebra.dimension - 2
        x = MultiVector.from_blades(algebra, {0: 1.0})
        for _ in range(count):
            x = x ^ conformal_point(algebra, rng.normal(size=n))
        kind = {3: "circle", 4: "sphere"}[count]
        return [np.array([x[b] for b in kind_blades(algebra, kind)])]
    return sample


def _point_and_circle(rng: np.random.Generator) -> list[np.ndarray]:
    x = conformal_point(cga3d(), rng.normal(size=3))
    return [np.array([x[b] for b in kind_blades(cga3d(), "point")]), *_rounds(cga3d(), 3)(rng)]


# -- cga3d ------------------------------------------------------------------------------------------------
@gagen.kernel(algebra="cga3d", jacobians={"J_d": ("d", "X")}, sample=_point_and_circle)
def circle_distance(X: "point", C: "circle"):
    """Euclidean distance of a point from a circle (its nearest point on the circle)."""
    m = X.math
    c, r, n = location(centre(C)), radius(C), unit_normal(C)
    v = location(X) - c
    h = v.sp(n)  # height above the circle's plane
    rho = m.sqrt(v.sp(v) - h * h)  # distance from the axis
    return {"d": m.sqrt((rho - r) * (rho - r) + h * h)}


@gagen.kernel(algebra="cga3d")
def plane_meet(A: "plane", B: "plane"):
    """The line where two planes meet."""
    return {"L": A & B}


@gagen.kernel(algebra="cga3d")
def motor_product(A: "motor", B: "motor"):
    """Composition of two motors."""
    return A * B


@gagen.kernel(algebra="cga3d", outputs={"Y": "point"})
def motor_point(M: "motor", X: "point"):
    """A point moved by a motor."""
    return M.sandwich(X)


@gagen.kernel(algebra="cga3d", jacobians={"J_P": ("P", "x")})
def point_from_vector(x: "vector"):
    """The conformal point of a Euclidean vector."""
    return {"P": point(x)}


@gagen.kernel(algebra="cga3d", sample=_rounds(cga3d(), 4), jacobians={"J_r": ("r", "S")})
def sphere_radius(S: "sphere"):
    """Centre and radius of a sphere given as the outer product of four points."""
    return {"c": location(centre(S)), "r": radius(S)}


@gagen.kernel(algebra="cga3d")
def sphere_through(P1: "point", P2: "point", P3: "point", P4: "point"):
    """The sphere through four points, and its radius squared."""
    s = through("sphere", [P1, P2, P3, P4])
    e = einf(s)
    return {"S": s, "r2": -s.norm_squared() / (e | s).norm_squared()}


# -- cga2d ------------------------------------------------------------------------------------------------
@gagen.kernel(algebra="cga2d", jacobians={"J_theta": ("Y", "theta")})
def se2_point(theta: "scalar", t: gagen.scalars(2, ("x", "y")), X: "point", ga: "algebra"):
    """A point turned by theta about the origin, then moved by t, in the plane."""
    m = ga.math
    rotor = ga.make({"1": m.cos(theta / 2), "e12": -m.sin(theta / 2)})
    translator = ga.make({"1": 1, "e1inf": -t[0] / 2, "e2inf": -t[1] / 2})
    return {"Y": (translator * rotor).sandwich(X)}


@gagen.kernel(algebra="cga2d")
def line_through(A: "point", B: "point"):
    """The line through two points."""
    return A ^ B ^ einf(A)


@gagen.kernel(algebra="cga2d", sample=_rounds(cga2d(), 3), jacobians={"J_c": ("c", "C")})
def circle_centre(C: "circle"):
    """The centre of a circle, as a normalised point."""
    return {"c": centre(C)}


# -- pga3d ------------------------------------------------------------------------------------------------
@gagen.kernel(algebra="pga3d")
def pga_motor_point(M: "motor", X: "point"):
    """A point moved by a motor (PGA)."""
    return M.sandwich(X)


@gagen.kernel(algebra="pga3d")
def pga_join(P: "point", Q: "point"):
    """The line through two points (PGA join)."""
    return {"L": P & Q}


@gagen.kernel(algebra="pga3d")
def pga_plane_line(p: "plane", L: "line"):
    """The point where a line meets a plane (PGA meet)."""
    return {"X": p ^ L}


@gagen.kernel(algebra="pga3d", jacobians={"J_d": ("d", "X")})
def pga_point_plane_distance(X: "point", p: "plane"):
    """Signed distance of a point from a plane."""
    return {"d": (p.normalized() ^ X)["e0123"] / X["e123"]}


# -- ga3d -------------------------------------------------------------------------------------------------
@gagen.kernel(algebra="ga3d", outputs={"R": "rotor"})
def rotor_between(a: "vector", b: "vector"):
    """The rotor turning the direction of a into the direction of b (the shorter way)."""
    m = a.math
    r = 1 + b * a * (1 / m.sqrt(a.sp(a) * b.sp(b)))
    return r.normalized()


@gagen.kernel(algebra="ga3d", jacobians={"J_v": ("w", "R")})
def rotate_vector(R: "rotor", v: "vector"):
    """A vector turned by a rotor."""
    return {"w": R.sandwich(v)}


@gagen.kernel(algebra="ga3d", outputs={"c": "vector"}, jacobians={"J_a": ("c", "a")})
def cross(a: "vector", b: "vector"):
    """The cross product a × b, as the dual of a ∧ b."""
    return (a ^ b).dual()


KERNELS = [circle_distance, plane_meet, motor_product, motor_point, point_from_vector, sphere_radius,
           sphere_through, se2_point, line_through, circle_centre, pga_motor_point, pga_join,
           pga_plane_line, pga_point_plane_distance, rotor_between, rotate_vector, cross]
IDS = [k.name for k in KERNELS]


# -- helpers ----------------------------------------------------------------------------------------------
def _samples(kernel) -> list[list[np.ndarray]]:
    rng = np.random.default_rng(sum(map(ord, kernel.name)))  # fixed per kernel
    return [kernel.sample(rng) for _ in range(SAMPLES)]


def _assert_close(got, ref: np.ndarray, what: str, rtol: float = RTOL) -> None:
    got = np.asarray(got, dtype=float).reshape(ref.shape)
    err = np.abs(got - ref) / np.maximum(1.0, np.abs(ref))
    worst = float(np.max(err)) if err.size else 0.0
    assert worst <= rtol, f"{what}: relative error {worst:.3g} > {rtol:g}\n got {got}\n ref {ref}"


def _differences(kernel, inputs: list[np.ndarray], of: str, wrt: str) -> np.ndarray:
    """∂(of)/∂(wrt) by central differences of the reference, Richardson-extrapolated (O(h⁴))."""
    traced = kernel.trace()
    names_in = [p.name for p in traced.inputs]
    names_out = [p.name for p in traced.outputs]
    i, o = names_in.index(wrt), names_out.index(of)
    x0 = np.asarray(inputs[i], dtype=float).reshape(-1)

    def f(x: np.ndarray) -> np.ndarray:
        args = list(inputs)
        args[i] = x
        return kernel.reference(*args)[o].reshape(-1, order="F")

    def central(h: float) -> np.ndarray:
        cols = []
        for j in range(x0.size):
            step = np.zeros_like(x0)
            step[j] = h * max(1.0, abs(x0[j]))
            cols.append((f(x0 + step) - f(x0 - step)) / (2 * step[j]))
        return np.stack(cols, axis=1)

    h = 1e-4
    return (4 * central(h / 2) - central(h)) / 3


def _casadi(kernel, inputs: list[np.ndarray]) -> list[np.ndarray]:
    return [np.asarray(v) for v in kernel.trace().function.call([np.asarray(a, float) for a in inputs])]


# -- fast: the trace's CasADi Function and the reference --------------------------------------------------
def test_kernel_count_and_algebras() -> None:
    assert len(KERNELS) >= 12
    assert {k.algebra.name for k in KERNELS} == {"cga3d", "cga2d", "pga3d", "ga3d"}
    assert len(set(IDS)) == len(IDS)


@pytest.mark.parametrize("kernel", KERNELS, ids=IDS)
def test_casadi_matches_reference(kernel) -> None:
    traced = kernel.trace()
    for n, inputs in enumerate(_samples(kernel)):
        ref = kernel.reference(*inputs)
        got = _casadi(kernel, inputs)
        assert len(ref) == len(got) == len(traced.outputs)
        for port, r, g in zip(traced.outputs, ref, got, strict=True):
            assert g.shape == port.shape
            if r is not None:
                _assert_close(g, r, f"{kernel.name} sample {n}: CasADi {port.name}")


JACOBIAN_KERNELS = [k for k in KERNELS if k.jacobians]


@pytest.mark.parametrize("kernel", JACOBIAN_KERNELS, ids=[k.name for k in JACOBIAN_KERNELS])
def test_casadi_jacobians_match_differences(kernel) -> None:
    traced = kernel.trace()
    names = [p.name for p in traced.outputs]
    for n, inputs in enumerate(_samples(kernel)):
        ref = kernel.reference(*inputs)
        got = _casadi(kernel, inputs)
        for name, (of, wrt, *_) in kernel.jacobians.items():
            assert ref[names.index(name)] is None  # AD Jacobians have no reference of their own
            fd = _differences(kernel, inputs, of, wrt)
            _assert_close(got[names.index(name)], fd, f"{kernel.name} sample {n}: {name} = d{of}/d{wrt}",
                          JAC_RTOL)


# -- compiling: gagen.compile, one call at a time and batched ----------------------------------------------
@pytest.fixture(scope="module")
def compiled(tmp_path_factory):
    """Every kernel compiled through ``gagen.compile`` into a fresh cache folder (built once per module)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("GAGEN_CACHE", str(tmp_path_factory.mktemp("gagen-cache")))
        yield {k.name: gagen.compile(k) for k in KERNELS}


def _as_list(result, count: int) -> list[np.ndarray]:
    return [result] if count == 1 else list(result)


@pytest.mark.compiling
@pytest.mark.parametrize("kernel", KERNELS, ids=IDS)
def test_compiled_matches_reference(kernel, compiled) -> None:
    k = compiled[kernel.name]
    traced = kernel.trace()
    names = [p.name for p in traced.outputs]
    samples = _samples(kernel)
    batch = _as_list(k.batch(*[np.stack([np.asarray(a, float).reshape(-1) for a in column])
                               for column in zip(*samples, strict=True)]), len(names))
    for n, inputs in enumerate(samples):
        ref = kernel.reference(*inputs)
        casadi = _casadi(kernel, inputs)
        single = _as_list(k(*inputs), len(names))
        for j, port in enumerate(traced.outputs):
            expected = ref[j]
            if expected is None:  # an AD Jacobian: differences of the reference, and CasADi's own value
                of, wrt, *_ = kernel.jacobians[port.name]
                expected = _differences(kernel, inputs, of, wrt)
                _assert_close(single[j], casadi[j], f"{kernel.name} sample {n}: C {port.name} vs CasADi")
                _assert_close(batch[j][n], casadi[j],
                              f"{kernel.name} sample {n}: C batch {port.name} vs CasADi")
                rtol = JAC_RTOL
            else:
                rtol = RTOL
            _assert_close(single[j], expected, f"{kernel.name} sample {n}: C {port.name}", rtol)
            _assert_close(batch[j][n], expected, f"{kernel.name} sample {n}: C batch {port.name}", rtol)


@pytest.mark.compiling
def test_compile_uses_the_cache(tmp_path, monkeypatch) -> None:
    """A second compile of the same content (a new KernelFunction) loads the built module."""
    monkeypatch.setenv("GAGEN_CACHE", str(tmp_path))
    first = gagen.compile(gagen.kernel(algebra="ga3d")(cross_plain))
    folders = [p for p in tmp_path.iterdir() if p.is_dir()]
    assert len(folders) == 1, folders
    stamp = {p: p.stat().st_mtime_ns for p in folders[0].rglob("*")}
    again = gagen.compile(gagen.kernel(algebra="ga3d")(cross_plain))
    assert [p for p in tmp_path.iterdir() if p.is_dir()] == folders
    assert {p: p.stat().st_mtime_ns for p in folders[0].rglob("*")} == stamp
    a, b = np.array([1.0, 2.0, 3.0]), np.array([-1.0, 0.5, 2.0])
    np.testing.assert_allclose(first(a, b), np.cross(a, b), rtol=1e-15)
    np.testing.assert_allclose(again(a, b), np.cross(a, b), rtol=1e-15)


def cross_plain(a: "vector", b: "vector"):
    return (a ^ b).dual()


# -- --check holds a Jacobian the function gives itself against differences ----------------------------

def _sweep(q: gagen.scalars(2), ga: "algebra", wrong: bool):
    m = ga.math
    p = [m.cos(q[0]) + q[1] * q[1], m.sin(q[0]) * q[1]]
    columns = [[-m.sin(q[0]), m.cos(q[0]) * q[1]], [2 * q[1], m.sin(q[0])]]
    if wrong:  # an author's slip: one entry's sign
        columns[1][0] = -columns[1][0]
    return {"p": p, "J": columns}


@pytest.mark.compiling
@pytest.mark.parametrize("wrong", [False, True])
def test_check_holds_an_authored_jacobian_against_differences(tmp_path, wrong) -> None:
    """A Jacobian the function returns itself (declared as ∂p/∂q) used to be compared only with the
    function's own values, so a wrong formula passed --check; now it is also held against central
    differences at the first FD_SAMPLES points and fails there."""
    from gagen.build import build_source
    from gagen.check import DIFFERENCES, check_kernels, failures
    from gagen.frontend import KernelFunction, source_of
    from gagen.runtime import load

    fn = KernelFunction(lambda q, ga: _sweep(q, ga, wrong), algebra="ga3d", name="sweep",
                        inputs={"q": gagen.scalars(2), "ga": "algebra"},
                        outputs={"p": gagen.scalars(2), "J": gagen.matrix(gagen.scalars(2), 2)},
                        jacobians={"J": ("p", "q")})
    build_source(source_of([fn], "sweep"), tmp_path / "sweep", progress=lambda _: None)
    report = check_kernels(load(tmp_path / "sweep"), {"sweep": fn}, count=4)
    by_differences = [d for d in report if d.output == "J" and d.reference == DIFFERENCES]
    assert len(by_differences) == 1
    assert [d.output for d in failures(report)] == (["J"] if wrong else [])
    assert (by_differences[0].worst > 0.1) if wrong else (by_differences[0].worst < 1e-8)


@pytest.mark.compiling
def test_simd_batch_takes_absolute_values_of_negative_numbers(tmp_path) -> None:
    """The SIMD batch's fabs masked the sign bit with a splat of −0.0, which the splat (0 + c) turned
    into +0.0: |x| of a negative x stayed negative in the batch while single calls were right (found
    through a linkage's max |F|). Batch = single on inputs of both signs."""
    from gagen.build import build_source
    from gagen.frontend import KernelFunction, source_of
    from gagen.runtime import load

    def magnitude(x: gagen.scalars(3), ga: "algebra"):
        m = ga.math
        return {"y": [m.fabs(x[0]), m.fabs(x[1] - x[2]), m.fabs(x[0] * x[1]) + m.fabs(x[2])]}

    fn = KernelFunction(magnitude, algebra="ga3d", name="magnitude", outputs={"y": gagen.scalars(3)})
    build_source(source_of([fn], "magnitude"), tmp_path / "magnitude", progress=lambda _: None)
    kernel = load(tmp_path / "magnitude").c.magnitude
    x = np.random.default_rng(3).uniform(-1.0, 1.0, (37, 3))
    expected = np.c_[np.abs(x[:, 0]), np.abs(x[:, 1] - x[:, 2]), np.abs(x[:, 0] * x[:, 1]) + np.abs(x[:, 2])]
    np.testing.assert_array_equal(np.asarray(kernel.batch(x)).reshape(37, 3), expected)
    np.testing.assert_array_equal(np.array([kernel(v) for v in x]).reshape(37, 3), expected)
