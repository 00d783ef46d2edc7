"""Bad kernel declarations give a ``gagen.KernelError`` that names the kernel, the argument (or output,
Jacobian, name) at fault and what was expected, before anything is compiled.

This file deliberately has no ``from __future__ import annotations``: annotations are evaluated as
written, so ``X: "pointy"`` is the string a user writes, and ``X: pointy`` would be a NameError of
Python's own.
"""
# ruff: noqa: F821, F722 (the annotations are gagen kinds, "point", …, and deliberately bad ones)

import numpy as np
import pytest

import gagen
from gagen import KernelError


def _error(make, *, trace: bool = True) -> KernelError:
    """The KernelError of declaring (and, with ``trace``, tracing) a kernel."""
    with pytest.raises(KernelError) as info:
        k = make()
        if trace:
            k.trace()
    return info.value


def _assert_parts(e: KernelError, kernel: str, where: str, *expected: str) -> None:
    message = str(e)
    assert e.kernel == kernel, message
    assert e.where == where, message
    plain = kernel.isprintable() and not any(c.isspace() for c in kernel)  # else shown quoted
    assert message.startswith(f"kernel {kernel if plain else repr(kernel)}, {where}: "), message
    for part in expected:
        assert part in e.expected, f"{part!r} not in {message!r}"


# -- kinds and blades --------------------------------------------------------------------------------------
def test_unknown_kind_in_annotation() -> None:
    def near(X: "pointy"):
        return X

    e = _error(lambda: gagen.kernel(algebra="cga3d")(near), trace=False)
    _assert_parts(e, "near", "argument X", "unknown kind 'pointy'", "cga3d", "point", "circle", "motor")


def test_kind_of_another_algebra() -> None:
    def centre(C: "circle"):
        return C

    e = _error(lambda: gagen.kernel(algebra="ga3d")(centre), trace=False)
    _assert_parts(e, "centre", "argument C", "unknown kind 'circle'", "ga3d", "rotor", "vector")


def test_unknown_kind_in_inputs() -> None:
    def f(X):
        return X

    e = _error(lambda: gagen.kernel(algebra="pga3d", inputs={"X": "sphere"})(f), trace=False)
    _assert_parts(e, "f", "argument X", "unknown kind 'sphere'", "pga3d", "plane", "line", "point")


def test_unknown_kind_of_an_output() -> None:
    def f(X: "point"):
        return {"d": X.sp(X)}

    e = _error(lambda: gagen.kernel(algebra="cga3d", outputs={"d": "blob"})(f), trace=False)
    _assert_parts(e, "f", "output d", "unknown kind 'blob'")


@pytest.mark.parametrize(("algebra", "blades", "bad"), [
    ("ga3d", gagen.blades("e1", "e9"), "e9"),
    ("pga3d", ("e0", "einf"), "einf"),
    ("cga3d", ["e1", "e4"], "e4"),
])
def test_blade_not_in_the_algebra(algebra, blades, bad) -> None:
    def f(X):
        return X

    e = _error(lambda: gagen.kernel(algebra=algebra, inputs={"X": blades})(f), trace=False)
    _assert_parts(e, "f", "argument X", f"blade {bad!r} is not in {algebra}", "its blades:")


def test_blade_listed_twice() -> None:
    def f(X: ("e1", "e2", "e1")):
        return X

    _assert_parts(_error(lambda: gagen.kernel(algebra="ga3d")(f), trace=False), "f", "argument X",
                  "listed twice")


def test_output_outside_its_declared_kind() -> None:
    def f(X: "point"):
        return X

    e = _error(lambda: gagen.kernel(algebra="cga3d", outputs={"Y": "plane"})(f))
    _assert_parts(e, "f", "output Y", "has blade e0 outside its declared rows")


@pytest.mark.parametrize(("declaration", "expected"), [
    (0, "a positive number of scalars, got 0"),
    (True, "got True"),
    (2.5, "got 2.5"),
    (gagen.scalars(2, ("x",)), "1 labels for 2 scalars"),
])
def test_bad_declaration(declaration, expected) -> None:
    def f(q):
        return q

    e = _error(lambda: gagen.kernel(algebra="cga3d", inputs={"q": declaration})(f), trace=False)
    _assert_parts(e, "f", "argument q", expected)


def test_unknown_algebra() -> None:
    def f(X: "point"):
        return X

    e = _error(lambda: gagen.kernel(algebra="cga4d")(f), trace=False)
    _assert_parts(e, "f", "algebra", "cga4d", "cga3d", "pga3d")


# -- the function itself -----------------------------------------------------------------------------------
def test_function_that_raises() -> None:
    def broken(X: "point"):
        raise ValueError("no such luck")

    e = _error(lambda: gagen.kernel(algebra="cga3d")(broken))
    _assert_parts(e, "broken", "on the compiler", "raised ValueError: no such luck")
    assert isinstance(e.__cause__, ValueError)



def test_a_misspelt_name_in_the_users_function_names_its_line_and_the_nearest_name() -> None:
    """The user's file and line (not gagen's) and the nearest name: a method of the multivector, a name of
    the function's module or a builtin."""
    import inspect

    def moved(M: "motor", X: "point"):
        return {"Y": M.sandwhich(X)}

    line = inspect.getsourcelines(moved)[1] + 1
    e = _error(lambda: gagen.kernel(algebra="cga3d")(moved))
    _assert_parts(e, "moved", "on the compiler", f"{__file__}:{line}: ", "AttributeError",
                  "'sandwhich'; did you mean 'sandwich'?")

    def scaled(X: "point"):
        return {"Y": X * flaot(2)}

    e = _error(lambda: gagen.kernel(algebra="cga3d")(scaled))
    _assert_parts(e, "scaled", "on the compiler", "NameError", "did you mean 'float'?")
    assert f"{__file__}:{inspect.getsourcelines(scaled)[1] + 1}: " in e.expected

def test_function_that_reads_a_missing_blade() -> None:
    def f(X: "point"):
        return X["e7"]

    e = _error(lambda: gagen.kernel(algebra="cga3d")(f))
    _assert_parts(e, "f", "on the compiler", "KeyError", "e7")


def test_function_that_raises_on_the_interpreter_only() -> None:
    def f(X: "point"):
        if isinstance(X["e1"], float):
            raise ZeroDivisionError("float division by zero")
        return X

    k = gagen.kernel(algebra="cga3d")(f)
    k.trace()
    e = _error(lambda: k.reference(*k.sample(np.random.default_rng(0))), trace=False)
    _assert_parts(e, "f", "on the interpreter", "ZeroDivisionError")


@pytest.mark.parametrize(("value", "name", "got"), [
    ("abc", "out", "got str"),
    ({"d": np.array([1, 2], dtype=object)}, "d", "got ndarray"),
    ({"d": np.array([1.0, 2.0])}, "d", "got ndarray"),
    ({"d": None}, "d", "got NoneType"),
    ({"d": True}, "d", "got bool"),
])
def test_return_value_not_a_multivector_or_scalar(value, name, got) -> None:
    def f(X: "point"):
        return value

    e = _error(lambda: gagen.kernel(algebra="cga3d")(f))
    _assert_parts(e, "f", f"output {name}", "expected a multivector, a scalar", got)


def test_dict_of_multivectors_in_an_object_array() -> None:
    def f(X: "point"):
        return {"pair": np.array([X, X], dtype=object)}

    e = _error(lambda: gagen.kernel(algebra="cga3d")(f))
    _assert_parts(e, "f", "output pair", "expected a multivector, a scalar", "got ndarray")


@pytest.mark.parametrize("value", [[], "mixed"])
def test_bad_list_output(value) -> None:
    def f(X: "point"):
        return {"d": [X, 1.0] if value == "mixed" else []}

    e = _error(lambda: gagen.kernel(algebra="cga3d")(f))
    _assert_parts(e, "f", "output d", "expected a list of scalars")


def test_string_only_on_the_interpreter() -> None:
    def f(X: "point"):
        v = X.sp(X)
        return {"d": "x" if isinstance(v, float) else v}

    k = gagen.kernel(algebra="cga3d")(f)
    k.trace()
    e = _error(lambda: k.reference(*k.sample(np.random.default_rng(0))), trace=False)
    _assert_parts(e, "f", "output d", "got str")


def test_output_count_differs_from_the_declaration() -> None:
    def f(X: "point"):
        return X, X

    e = _error(lambda: gagen.kernel(algebra="cga3d", outputs=("a",))(f))
    _assert_parts(e, "f", "outputs", "declared 1 (a)", "returned 2")


def test_returned_names_differ_from_the_declaration() -> None:
    def f(X: "point"):
        return {"b": X}

    e = _error(lambda: gagen.kernel(algebra="cga3d", outputs=("a",))(f))
    _assert_parts(e, "f", "outputs", "declared ('a',)", "returned ('b',)")


# -- names ---------------------------------------------------------------------------------------------------
VALID = "expected a letter, then letters, digits or underscores"


@pytest.mark.parametrize("name", ["2x", "for", "class", "a b", "x" * 65, "_hidden"])
def test_kernel_name_not_an_identifier(name) -> None:
    def f(X: "point"):
        return X

    e = _error(lambda: gagen.kernel(algebra="cga3d", name=name)(f), trace=False)
    _assert_parts(e, name, "name", f"{name!r} is not a valid name", VALID)


def test_lambda_needs_a_name() -> None:
    e = _error(lambda: gagen.kernel(algebra="cga3d", inputs={"X": "point"})(lambda X: X), trace=False)
    _assert_parts(e, "<lambda>", "name", "'<lambda>' is not a valid name")


@pytest.mark.parametrize("name", ["a b", "my-out", "int", "while"])
def test_output_name_not_an_identifier(name) -> None:
    def f(X: "point"):
        return X

    e = _error(lambda: gagen.kernel(algebra="cga3d", outputs=(name,))(f), trace=False)
    _assert_parts(e, "f", f"output {name!r}", f"{name!r} is not a valid name", VALID)


def test_returned_output_name_not_an_identifier() -> None:
    def f(X: "point"):
        return {"my-out": X}

    e = _error(lambda: gagen.kernel(algebra="cga3d")(f))
    _assert_parts(e, "f", "output 'my-out'", "'my-out' is not a valid name", VALID)


@pytest.mark.parametrize("name", ["J x", "J-d", "return"])
def test_jacobian_name_not_an_identifier(name) -> None:
    def f(X: "point"):
        return {"d": X.sp(X)}

    e = _error(lambda: gagen.kernel(algebra="cga3d", jacobians={name: ("d", "X")})(f), trace=False)
    _assert_parts(e, "f", f"Jacobian {name!r}", f"{name!r} is not a valid name", VALID)


def test_argument_name_not_an_identifier() -> None:
    def f(_X: "point"):
        return _X

    e = _error(lambda: gagen.kernel(algebra="cga3d")(f), trace=False)
    _assert_parts(e, "f", "argument _X", "'_X' is not a valid name")


@pytest.mark.parametrize("returned", ["tuple", "dict", "declared"])
def test_output_with_the_name_of_an_input(returned) -> None:
    def f(X: "point"):
        return {"X": X} if returned == "dict" else X

    outputs = ("X",) if returned != "dict" else None
    e = _error(lambda: gagen.kernel(algebra="cga3d", outputs=outputs)(f))
    _assert_parts(e, "f", "output X", "has the name of an input")


def test_jacobian_with_the_name_of_an_input() -> None:
    def f(X: "point"):
        return {"d": X.sp(X)}

    e = _error(lambda: gagen.kernel(algebra="cga3d", jacobians={"X": ("d", "X")})(f), trace=False)
    _assert_parts(e, "f", "Jacobian X", "has the name of an input")


# -- arguments -----------------------------------------------------------------------------------------------
def test_undeclared_argument() -> None:
    def f(X, Y: "point"):
        return Y

    e = _error(lambda: gagen.kernel(algebra="cga3d")(f), trace=False)
    _assert_parts(e, "f", "argument X", "undeclared", "annotate it", "inputs=")


def test_inputs_for_a_missing_argument() -> None:
    def f(X: "point"):
        return X

    e = _error(lambda: gagen.kernel(algebra="cga3d", inputs={"Z": "point"})(f), trace=False)
    _assert_parts(e, "f", "argument Z", "declared in inputs= but not an argument")


def test_variadic_arguments() -> None:
    def f(*X):
        return X

    e = _error(lambda: gagen.kernel(algebra="cga3d")(f), trace=False)
    _assert_parts(e, "f", "argument X", "no *args or **kwargs")


def test_no_inputs() -> None:
    def f(ga: "algebra"):
        return ga.make({"e1": 1})

    _assert_parts(_error(lambda: gagen.kernel(algebra="cga3d")(f), trace=False), "f", "arguments",
                  "at least one input")


def test_unreadable_annotation() -> None:
    def f(X: "point(("):
        return X

    e = _error(lambda: gagen.kernel(algebra="cga3d")(f), trace=False)
    _assert_parts(e, "f", "argument X", "cannot read its annotation 'point(('")


# -- Jacobians -----------------------------------------------------------------------------------------------
def test_jacobian_with_respect_to_a_non_input() -> None:
    def f(X: "point"):
        return {"d": X.sp(X)}

    e = _error(lambda: gagen.kernel(algebra="cga3d", jacobians={"J": ("d", "Z")})(f), trace=False)
    _assert_parts(e, "f", "Jacobian J", "'Z' is not an input", "inputs: X")


def test_jacobian_with_respect_to_the_algebra() -> None:
    def f(X: "point", ga: "algebra"):
        return {"d": X.sp(X)}

    e = _error(lambda: gagen.kernel(algebra="cga3d", jacobians={"J": ("d", "ga")})(f), trace=False)
    _assert_parts(e, "f", "Jacobian J", "'ga' is not an input", "inputs: X")


def test_jacobian_of_a_non_output() -> None:
    def f(X: "point"):
        return {"d": X.sp(X)}

    e = _error(lambda: gagen.kernel(algebra="cga3d", jacobians={"J": ("e", "X")})(f))
    _assert_parts(e, "f", "Jacobian J", "'e' is not an output", "outputs: d")


@pytest.mark.parametrize("pair", ["X", ["d", "X"], ("d",), ("d", "X", "not callable")])
def test_malformed_jacobian(pair) -> None:
    def f(X: "point"):
        return {"d": X.sp(X)}

    e = _error(lambda: gagen.kernel(algebra="cga3d", jacobians={"J": pair})(f), trace=False)
    _assert_parts(e, "f", "Jacobian J", "expected (output, input)")


def test_supplied_jacobian_of_the_wrong_shape() -> None:
    def f(X: "point"):
        return {"d": X.sp(X), "J": 1.0}

    e = _error(lambda: gagen.kernel(algebra="cga3d", jacobians={"J": ("d", "X")})(f))
    _assert_parts(e, "f", "output J", "1 x 5", "got 1 x 1")


def test_a_good_declaration_traces() -> None:
    """The errors above are about the declarations, not the machinery: the same shapes, declared well,
    trace."""
    def distance(X: "point", ga: "algebra"):
        return {"d": X.sp(X)}

    k = gagen.kernel(algebra="cga3d", jacobians={"J": ("d", "X")})(distance)
    assert [p.name for p in k.trace().outputs] == ["d", "J"]


# -- issue 29: outputs, constants and sizes ------------------------------------------------------------
@pytest.mark.parametrize("returned", [{}, (), []])
def test_a_kernel_returning_nothing_is_one_line(returned) -> None:
    def nothing(X: "point"):
        return returned

    e = _error(lambda: gagen.kernel(algebra="cga3d")(nothing))
    _assert_parts(e, "nothing", "outputs", "returned no output")


@pytest.mark.parametrize("constant", [float("inf"), -float("inf"), float("nan"), 1e308 * 10])
def test_a_non_finite_constant_output_is_refused_like_nan(constant) -> None:
    def infinite(X: "point"):
        return {"c": constant, "Y": X}

    e = _error(lambda: gagen.kernel(algebra="cga3d")(infinite))
    assert e.kernel == "infinite" and "non-finite" in str(e) and "\n" not in str(e), str(e)


def test_a_non_finite_constant_inside_a_multivector_is_refused() -> None:
    def scaled(X: "point"):
        return {"Y": X * float("inf")}

    e = _error(lambda: gagen.kernel(algebra="cga3d")(scaled))
    assert "non-finite" in str(e), str(e)


@pytest.mark.parametrize("declaration", [10 ** 6, gagen.scalars(10 ** 6),
                                         gagen.matrix(gagen.scalars(100), 100)])
def test_an_input_of_a_million_scalars_is_refused_at_the_limit(declaration) -> None:
    def huge(x: declaration):
        return {"y": x[0]}

    e = _error(lambda: gagen.kernel(algebra="cga3d")(huge), trace=False)
    assert e.kernel == "huge" and e.where == "argument x", str(e)
    assert "over the limit of 4096" in str(e) and "GAGEN_LIMIT_FORMULA_SCALARS" in str(e)


def test_the_scalar_limit_is_raised_by_its_variable(monkeypatch) -> None:
    monkeypatch.setenv("GAGEN_LIMIT_FORMULA_SCALARS", "5000")

    def wide(x: 4500):
        return {"y": x[0] + x[4499]}

    k = gagen.kernel(algebra="cga3d")(wide)
    assert k.trace().inputs[0].size == 4500
