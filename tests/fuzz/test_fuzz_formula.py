"""The fuzz tier for formula files, Python files of ``@gagen.kernel`` functions (issue 29): files drawn
from the front end's schema (kernel names, algebras, input declarations, bodies of products, wedges,
regressive products and sums, outputs, constants, module names taken from a hostile list), plus byte
mutations of examples/formulas.py. Each case goes through ``gagen build`` (every check, the templates,
no compiler); it passes with a one-line error naming the file or the kernel and the field, or a module
whose every kernel equals the interpreter at sampled inputs with finite values. A compiling variant
builds the C library of drawn files: gcc must never see an error."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gagen.build import build
from gagen.frontend import module_from_file
from gagen.runtime import load

from .harness import HOSTILE_NAMES, all_finite, byte_mutation, examples, run_case

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "formulas.py"
KINDS = {"cga3d": ["point", "circle", "sphere", "motor", "line", "vector", "rotor", "plane"],
         "pga3d": ["point", "motor", "line", "plane", "rotor", "translator"],
         "ga3d": ["vector", "rotor", "bivector", "multivector"],
         "cga2d": ["point", "vector", "rotor", "circle"]}
SAFE_NAMES = ["k", "meet", "circle_of", "f", "pose2", "HAVE_LIBMVEC", "W", "v", "f_batch", "body", "main"]
FILE_NAMES = ["drawn", "gagen", "GAGEN", "M", "make", "in", "Py", "kernels", "a b", "1x", "for", "x" * 80]
CONSTANTS = ["2.0", "0.5", "-1.0", "1e300", "float('inf')", "float('nan')", "1e308 * 10", "-float('inf')"]
QUIET = {"progress": lambda _: None}


@st.composite
def formula_file(draw, hostile: bool = True) -> tuple[str, bool]:
    """(source text, certainly refused) of a drawn formula file; ``hostile=False`` draws only valid
    declarations, names and constants (the compiling variant)."""
    lines = ["import gagen", ""]
    refuse = False
    for i in range(draw(st.integers(1, 3))):
        algebra = draw(st.sampled_from([*KINDS, "nope"] if hostile else list(KINDS)))
        refuse |= algebra == "nope"
        kinds = KINDS.get(algebra, ["point"])
        names = st.one_of(st.sampled_from(SAFE_NAMES), st.sampled_from(HOSTILE_NAMES)) if hostile \
            else st.sampled_from(SAFE_NAMES)
        name = draw(names) if i == 0 else f"k{i}"
        arguments, multivectors, scalars = [], [], []
        for j in range(draw(st.integers(1, 3))):
            others = ["1", "3", "gagen.scalars(4)", "0", "-2", "10 ** 6", "'pointy'",
                      "gagen.blades('e1', 'e1')"]
            declared = st.one_of(st.sampled_from(kinds).map(repr), st.sampled_from(others)) if hostile \
                else st.sampled_from(kinds).map(repr)  # (multivectors only: ^ and & need no care)
            declaration = draw(declared)
            refuse |= declaration in ("0", "-2", "10 ** 6", "'pointy'", "gagen.blades('e1', 'e1')")
            arguments.append(f"a{j}: {declaration}")
            (scalars if declaration in ("1", "3", "gagen.scalars(4)") else multivectors).append(f"a{j}")
        terms = [f"{s}[0]" for s in scalars] + multivectors
        expression = draw(st.sampled_from(terms))
        for _ in range(draw(st.integers(0, 4))):
            op = draw(st.sampled_from(["*", "^", "+", "-", "&", "const"]))
            if op == "const":
                constant = draw(st.sampled_from(CONSTANTS if hostile else CONSTANTS[:4]))
                refuse |= constant not in ("2.0", "0.5", "-1.0", "1e300")
                expression = f"({expression}) * {constant}"
            else:
                expression = f"({expression}) {op} {draw(st.sampled_from(terms))}"
        output = draw(st.sampled_from(["dict", "dict", "dict", "empty", "tuple", "hostile"] if hostile
                                      else ["dict", "tuple"]))
        refuse |= output == "empty"
        body = {"dict": f"{{'out_{i}': {expression}}}", "empty": "{}",
                "tuple": f"({expression}, {expression})",
                "hostile": f"{{{draw(st.sampled_from(HOSTILE_NAMES))!r}: {expression}}}"}[output]
        lines += [f"@gagen.kernel(algebra={algebra!r}, name={name!r})",
                  f"def kernel_{i}({', '.join(arguments)}):", f"    return {body}", ""]
    return "\n".join(lines), refuse


def _build_and_compare(path: Path, out: Path, compile_c: bool):
    """Build the file, then every kernel: the built module's CasADi Function (and C with ``compile_c``)
    against the interpreter at three sampled inputs."""
    build(path, out, compile_c=compile_c, **QUIET)
    module = load(out)
    functions = module_from_file(path).functions
    rng = np.random.default_rng(0)
    compared = []
    for name, fn in functions.items():
        for _ in range(3):
            inputs = fn.sample(rng)
            reference = fn.reference(*inputs)
            got = [np.asarray(v) for v in fn.trace().function.call([np.asarray(a, float) for a in inputs])]
            if compile_c:
                result = getattr(module.c, name)(*inputs)
                got_c = [result] if len(got) == 1 else list(result)
                for c, casadi in zip(got_c, got, strict=True):
                    np.testing.assert_allclose(np.asarray(c).reshape(casadi.shape, order="F"), casadi,
                                               rtol=1e-12, atol=1e-12 * (1 + np.abs(casadi).max()))
            compared.append((reference, got))
    return compared


def _check(compared) -> None:
    for reference, got in compared:
        assert all_finite(got), f"non-finite kernel outputs {got}"
        for r, g in zip(reference, got, strict=True):
            if r is not None:
                scale = 1 + float(np.abs(r).max(initial=0))
                np.testing.assert_allclose(g, np.asarray(r).reshape(g.shape), rtol=1e-9, atol=1e-9 * scale)


def _case(data, text: str | bytes, file_name: str, refuse: bool, compile_c: bool, what: str,
          kind: str = "formula file") -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"{file_name}.py"
        if isinstance(text, bytes):
            path.write_bytes(text)
        else:
            path.write_text(text, encoding="utf-8")
        run_case(kind, (path,), lambda: _build_and_compare(path, Path(folder) / "out", compile_c),
                 _check, must_refuse=refuse, what=what)


@examples(fast=40, full=250)
@given(st.data())
def test_formula_files_drawn_from_the_schema(data):
    text, refuse = data.draw(st.booleans().flatmap(formula_file), label="file")  # hostile or not
    file_name = data.draw(st.sampled_from(FILE_NAMES[:1] * 10 + FILE_NAMES), label="file name")
    _case(data, text, file_name, refuse, False, f"{file_name}.py:\n{text}")


@pytest.mark.filterwarnings("ignore::DeprecationWarning", "ignore::SyntaxWarning")  # a mutated "\\w"
@examples(fast=20, full=150)
@given(st.data())
def test_mutated_example_formulas(data):
    what, mutated = data.draw(byte_mutation(EXAMPLE.read_text()), label="mutation")
    _case(data, mutated, "formulas", False, False, f"formulas.py {what}")


@pytest.mark.compiling
@examples(fast=16, full=16)
@given(st.data())
def test_drawn_formula_files_compile_without_a_gcc_error(data):
    text, refuse = data.draw(formula_file(hostile=False), label="file")
    file_name = data.draw(st.sampled_from(["drawn", "kernels", "drawn", "gagen"]), label="file name")
    _case(data, text, file_name, refuse, True, f"{file_name}.py:\n{text}", kind="formula file, compiled")


def test_the_drawn_files_are_not_vacuous():
    """The generator makes files gagen accepts and files it refuses (a sanity check of the fuzzer)."""
    from hypothesis import find

    accepted = find(formula_file(), lambda f: not f[1] and "'out_0'" in f[0] and "float" not in f[0])
    assert "@gagen.kernel" in accepted[0]
    assert math.isfinite(2.0)
