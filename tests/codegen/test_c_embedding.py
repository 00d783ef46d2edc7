"""Generated C embeds cleanly [issue 28, item 7]: every generated C file (``<name>.c``, ``<name>.h``,
``<name>_simd.c``, ``<name>_binding.c``) of every committed module, and of a user-kernel module built
from ``examples/formulas.py``, compiles with ``-std=c99 -Wall -Wextra -pedantic -Werror`` (GCC, and
Clang where it is on PATH; the binding with Python's and numpy's headers as ``-isystem``, so that only
warnings of our own code count). The single-call ``<name>.c`` links on its own, without
``<name>_simd.c``: a small ``main.c`` calls a kernel through it and prints what the module's own
``m.c.<kernel>`` returns (which test_build.py holds against the interpreter). The C program of
``docs/generated-code.md`` is compiled with the page's own command and run, and checked the same way.
"""

from __future__ import annotations

import json
import platform
import re
import shlex
import shutil
import subprocess
import sysconfig
from pathlib import Path

import numpy as np
import pytest
from conftest import committed_modules

from gagen.build import build
from gagen.runtime import load

pytestmark = pytest.mark.compiling

REPO = Path(__file__).resolve().parents[2]
GENERATED = REPO / "generated"
DOC = REPO / "docs" / "generated-code.md"
WARNINGS = ("-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror")
NATIVE = ("-march=native",) if platform.machine() in ("x86_64", "AMD64") else ()
COMPILERS = ("gcc", "clang")
USER = "user_formulas"  # the module built from examples/formulas.py into a temporary folder
MODULES = (*committed_modules(), USER)
KINDS = ("c", "h", "simd", "binding")
# per kind, the compiles checked: gagen's own build (optimised: some warnings need the optimiser's
# analyses), then the other configurations the file's preprocessor switches select (syntax only)
VARIANTS: dict[str, tuple[tuple[str, ...], ...]] = {
    "c": (("-c", "-O1", *NATIVE, "-DGAGEN_HAVE_LIBMVEC"), ("-fsyntax-only",),
          ("-fsyntax-only", "-DGAGEN_SCALAR_TRIG")),
    "h": (("-fsyntax-only",), ("-fsyntax-only", "-x", "c++", "-std=c++11")),
    "simd": (("-c", "-O3", *NATIVE, "-DGAGEN_HAVE_LIBMVEC", "-DGAGEN_HAVE_LIBMVEC_ATAN2"),
             ("-fsyntax-only",), ("-fsyntax-only", "-DGAGEN_NO_SIMD")),
    "binding": (("-c", "-O2", "-DGAGEN_MODULE=_gagen_embedding_test"),),
}


def _compiler(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        pytest.skip(f"{name} is not on PATH")
    return path


@pytest.fixture(scope="module")
def user_folder(tmp_path_factory) -> Path:
    """A user's module of kernels: examples/formulas.py built (and compiled) into a temporary folder."""
    folder = tmp_path_factory.mktemp("embedding") / USER
    build(REPO / "examples" / "formulas.py", folder, name=USER, progress=lambda _: None)
    return folder


def _folder(name: str, request) -> Path:
    return request.getfixturevalue("user_folder") if name == USER else GENERATED / name


def _run(command: list[str], cwd: Path | None = None) -> str:
    result = subprocess.run(command, capture_output=True, text=True, cwd=cwd)
    assert result.returncode == 0 and not result.stderr.strip(), \
        f"{shlex.join(command)} (exit {result.returncode}):\n{result.stderr.strip()[:4000]}"
    return result.stdout


def _source(folder: Path, kind: str, tmp_path: Path) -> Path:
    """The file of ``kind`` (the header: a file including it)."""
    name = folder.name
    if kind == "h":
        unit = tmp_path / f"include_{name}.c"
        unit.write_text(f'#include "{name}.h"\n')
        return unit
    return folder / {"c": f"{name}.c", "simd": f"{name}_simd.c", "binding": f"{name}_binding.c"}[kind]


@pytest.mark.parametrize("compiler", COMPILERS)
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", MODULES)
def test_every_generated_c_file_compiles_without_warnings(name, kind, compiler, request, tmp_path):
    cc = _compiler(compiler)
    folder = _folder(name, request)
    source = _source(folder, kind, tmp_path)
    headers: tuple[str, ...] = ()
    if kind == "binding":
        import numpy

        headers = ("-isystem", sysconfig.get_paths()["include"], "-isystem", numpy.get_include())
    for variant in VARIANTS[kind]:
        output = ("-o", str(tmp_path / "unit.o")) if "-c" in variant else ()
        own_standard = any(flag.startswith("-std=") for flag in variant)  # the header as C++
        flags = [f for f in WARNINGS if not (own_standard and f.startswith("-std="))]
        _run([cc, *flags, *variant, *headers, f"-I{folder}", *output, str(source)])


def _kernel(module, manifest: dict, rng: np.random.Generator):
    """The first kernel of the module giving finite outputs on random inputs in [-1, 1], with those
    inputs (flat, column-major) and its outputs (flat, column-major, concatenated)."""
    for entry in manifest["kernels"]:
        inputs = [rng.uniform(-1.0, 1.0, len(p["rows"]) * p["cols"]) for p in entry["inputs"]]
        outputs = getattr(module.c, entry["name"])(*inputs)
        outputs = outputs if isinstance(outputs, tuple) else (outputs,)
        flat = np.concatenate([np.asarray(o).reshape(-1, order="F") for o in outputs])
        if np.all(np.isfinite(flat)):
            return entry, inputs, flat
    raise AssertionError(f"{manifest['module']}: no kernel gives finite outputs on random inputs")


def _main(name: str, entry: dict) -> str:
    """A C program calling the kernel ``entry`` through its _argv form: inputs from the command line,
    outputs printed one per line."""
    sizes_in = [len(p["rows"]) * p["cols"] for p in entry["inputs"]]
    sizes_out = [len(p["rows"]) * p["cols"] for p in entry["outputs"]]
    offsets_in = np.concatenate([[0], np.cumsum(sizes_in)[:-1]]).astype(int)
    offsets_out = np.concatenate([[0], np.cumsum(sizes_out)[:-1]]).astype(int)
    n_in, n_out = sum(sizes_in), sum(sizes_out)
    return f"""#include <stdio.h>
#include <stdlib.h>
#include "{name}.h"

int main(int argc, char **argv) {{
  static double in[{n_in}], out[{n_out}];
  const double *arg[] = {{{", ".join(f"in + {o}" for o in offsets_in)}}};
  double *res[] = {{{", ".join(f"out + {o}" for o in offsets_out)}}};
  for (int i = 1; i < argc && i <= {n_in}; ++i) in[i - 1] = strtod(argv[i], NULL);
  {entry["c_name"]}_argv(arg, res);
  for (int i = 0; i < {n_out}; ++i) printf("%.17g\\n", out[i]);
  return 0;
}}
"""


def _close(got: np.ndarray, expected: np.ndarray, what: str) -> None:
    """Equal to the vector-trig tolerance (the module's library may take libmvec's sines and cosines,
    the programs here libm's: test_vector_trig.py states 1e-14 of the largest output)."""
    assert got.shape == expected.shape, f"{what}: {got.shape} values, expected {expected.shape}"
    scale = max(1.0, float(np.max(np.abs(expected), initial=0.0)))
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * scale, err_msg=what)


@pytest.mark.parametrize("compiler", COMPILERS)
@pytest.mark.parametrize("name", MODULES)
def test_the_single_call_c_links_on_its_own(name, compiler, request, tmp_path):
    """main.c + <name>.c + libm, nothing else (no _simd.c, no libmvec): it links, and a kernel called
    through it gives the module's own results."""
    cc = _compiler(compiler)
    folder = _folder(name, request)
    manifest = json.loads((folder / "manifest.json").read_text())
    entry, inputs, expected = _kernel(load(folder), manifest, np.random.default_rng(28))
    main = tmp_path / "main.c"
    main.write_text(_main(folder.name, entry))
    program = tmp_path / "main"
    _run([cc, *WARNINGS, "-O0", "-ffp-contract=off", f"-I{folder}", "-o", str(program), str(main),
          str(folder / f"{folder.name}.c"), "-lm"])
    printed = _run([str(program), *(repr(float(x)) for x in np.concatenate(inputs))])
    _close(np.array([float(v) for v in printed.split()]), expected, f"{name}: {entry['name']} from main.c")


def _doc_blocks(language: str) -> list[str]:
    text = DOC.read_text()
    return re.findall(rf"^```{language}\n(.*?)^```$", text, flags=re.M | re.S)


@pytest.mark.parametrize("compiler", COMPILERS)
def test_the_program_of_the_docs_compiles_with_the_docs_command_and_runs(compiler, tmp_path):
    """The page's ```c block, built with the page's compile command (the compiler swapped, the warnings
    added, -Werror) and run with the page's arguments, prints module.c.arm0_fk_jacobian's M and J_S."""
    cc = _compiler(compiler)
    (program,) = _doc_blocks("c")
    assert len(program.strip().splitlines()) <= 20, "the docs' C program is longer than 20 lines"
    commands = [block for block in _doc_blocks("text") if block.startswith("cc ")]
    assert len(commands) == 1, "docs/generated-code.md: expected one ```text block of the cc command"
    compile_line, run_line = commands[0].replace("\\\n", " ").strip().splitlines()
    (tmp_path / "main.c").write_text(program)
    words = shlex.split(compile_line)
    assert words[0] == "cc" and "main.c" in words and words[words.index("-o") + 1] == "fk", words
    words[words.index("main.c")] = str(tmp_path / "main.c")
    words[words.index("-o") + 1] = str(tmp_path / "fk")
    _run([cc, *words[1:], *WARNINGS], cwd=REPO)
    arguments = shlex.split(run_line)
    assert arguments[0] == "./fk", run_line
    printed = _run([str(tmp_path / "fk"), *arguments[1:]]).strip().splitlines()
    assert len(printed) == 2, printed

    q = np.array([float(a) for a in arguments[1:]])
    M, _, J = load(GENERATED / "panda_point").c.arm0_fk_jacobian(q)
    _close(np.array([float(v) for v in printed[0].split()]), np.asarray(M).reshape(-1, order="F"), "M")
    _close(np.array([float(v) for v in printed[1].split()]), np.asarray(J).reshape(-1, order="F"), "J_S")
