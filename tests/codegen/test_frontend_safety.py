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
