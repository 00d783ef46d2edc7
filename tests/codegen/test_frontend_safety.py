"""A Python file of kernels is a new way in: its kernels' docstrings reach every generated file only
escaped, and its file, kernel and output names only as checked identifiers."""

from __future__ import annotations

import ast
import re

import pytest

from gagen.build import build
from gagen.frontend import KernelError

HOSTILE = '*/ __attribute__((constructor)) static void pwn(void) { } /* """ \\n#error boom ??/'
KERNELS = f'''
import gagen
from gagen.kinds import vector


@gagen.kernel(algebra="ga3d", doc={HOSTILE!r})
def wedge(a: vector, b: vector):
    return {{"B": a ^ b}}
'''


def _code_only(c_text: str) -> str:
    """C text without its comments and string literals (what the compiler reads as code)."""
    text = re.sub(r"/\*.*?\*/", " ", c_text, flags=re.S)
    text = re.sub(r"//[^\n]*", " ", text)
    return re.sub(r'"(?:\\.|[^"\\\n])*"', '""', text)


def test_a_hostile_kernel_doc_stays_inside_comments_docstrings_and_strings(tmp_path):
    source = tmp_path / "evil.py"
    source.write_text(KERNELS)
    out = tmp_path / "out"
    build(source, out, compile_c=False, progress=lambda _: None)
    generated = [p for p in out.iterdir() if p.suffix in (".c", ".h")]
    assert len(generated) == 4
    assert any("pwn" in p.read_text() for p in generated)  # the doc is written (escaped)
    for path in generated:
        code = _code_only(path.read_text())
        for planted in ("constructor", "pwn", "#error", "boom"):
            assert planted not in code, f"{path.name}: {planted!r} outside a comment or string"
    init = ast.parse((out / "__init__.py").read_text())
    assert isinstance(init.body[0], ast.Expr)  # the docstring, then imports and assignments only
    assert all(isinstance(s, (ast.Import, ast.ImportFrom, ast.Assign)) for s in init.body[1:])


@pytest.mark.parametrize("file_name", ["evil name.py", "1st.py", "class.py", "__init__x.py"])
def test_a_file_name_that_is_no_identifier_is_refused_before_anything_is_written(tmp_path, file_name):
    source = tmp_path / file_name
    source.write_text(KERNELS)
    out = tmp_path / "out"
    with pytest.raises(KernelError, match="module name"):
        build(source, out, compile_c=False, progress=lambda _: None)
    assert not out.exists()


# names a user may well choose that are also the generated code's own identifiers: its locals (w<i>),
# the templates' loop variables (s, n, k, ld, s0, stream), libm's functions and macros, a port and
# another port with the templates' old "_s" suffix
CLASHING = '''
import gagen


@gagen.kernel(algebra="ga3d", inputs={**{name: "scalar" for name in ("s", "n", "k", "ld", "w0", "sin", "NAN",
                                                                     "x", "x_s")}, "ga": "algebra"},
              outputs={"stream": "scalar", "s0": "scalar", "w1": "scalar"})
def clash(s, n, k, ld, w0, sin, NAN, x, x_s, ga):
    return {"stream": s * n + k * ld, "s0": w0 * sin - NAN, "w1": x * x_s + ga.math.sin(x)}
'''


@pytest.mark.compiling
def test_port_names_that_are_identifiers_of_the_generated_code_compile_and_agree(tmp_path):
    import numpy as np

    from gagen.runtime import load

    source = tmp_path / "clashing.py"
    source.write_text(CLASHING)
    build(source, tmp_path / "clashing", progress=lambda _: None)
    c = load(tmp_path / "clashing").c
    values = [np.array([v]) for v in (0.5, 2.0, -1.5, 3.0, 0.25, 1.5, -2.0, 0.7, 1.1)]
    stream, s0, w1 = c.clash(*values)
    np.testing.assert_allclose([stream[0], s0[0], w1[0]],
                               [0.5 * 2.0 - 1.5 * 3.0, 0.25 * 1.5 + 2.0, 0.7 * 1.1 + np.sin(0.7)], rtol=1e-15)
    batch = [np.tile(v, (37, 1)) for v in values]  # the batched forms' loops too
    outs = c.clash.batch(*batch)
    np.testing.assert_allclose(outs[2][:, 0], 0.7 * 1.1 + np.sin(0.7), rtol=1e-15)


def test_ports_whose_c_size_macros_would_collide_are_refused(tmp_path):
    source = tmp_path / "macros.py"
    source.write_text('''
import gagen


@gagen.kernel(algebra="ga3d", inputs={"r": 1, "R": 2}, outputs={"y": "scalar"})
def twin(r, R):
    return {"y": r[0] + R[1]}
''')
    with pytest.raises(ValueError, match="TWIN_R_SIZE"):
        build(source, tmp_path / "out", compile_c=False, progress=lambda _: None)
    assert not (tmp_path / "out").exists()
