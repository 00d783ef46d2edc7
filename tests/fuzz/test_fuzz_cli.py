"""The fuzz tier for the command line (issue 29): every verb's arguments drawn from its own options and
a hostile list (non-finite and huge numbers, hostile names and paths), and every verb that reads a file
run on a bad one (missing, a folder, empty, binary, mutated, another application's spec). Each case: one
line on stderr and exit status 2, or a parse whose every number is finite; never a traceback or a hang."""

from __future__ import annotations

import contextlib
import io
import math
import os
import shutil
import tempfile
from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st

from gagen.cli import main, parser

from .harness import CASE_SECONDS, COUNTS, HOSTILE_NAMES, byte_mutation, examples

REPO = Path(__file__).resolve().parents[2]
APPS = REPO / "gagen" / "apps"
NUMBERS = ["nan", "inf", "-inf", "1e400", "-1e400", "-1", "0", "1.5", "3", "abc", "", "1e-320", "0x10",
           "1_000"]
SUBPARSERS = next(a for a in parser()._actions if a.__class__.__name__ == "_SubParsersAction")
VERBS = sorted(SUBPARSERS.choices)


def _subparsers(command) -> dict:
    found = [a for a in command._actions if a.__class__.__name__ == "_SubParsersAction"]
    return found[0].choices if found else {}


SWEEPS = {verb: subs for verb in VERBS if (subs := _subparsers(SUBPARSERS.choices[verb]))}


def _options(verb: str, sub: str | None = None) -> list[str]:
    command = SUBPARSERS.choices[verb] if sub is None else SWEEPS[verb][sub]
    return [s for a in command._actions for s in a.option_strings if s not in ("-h", "--help")]


def _call(argv: list[str]) -> tuple[int, str, str]:
    """(exit status, stdout, stderr) of ``gagen <argv>`` in-process."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = main(argv)
        except SystemExit as e:
            status = e.code if isinstance(e.code, int) else 2
    return status, out.getvalue(), err.getvalue()


def _one_line_refusal(kind: str, argv: list[str], status: int, err: str) -> None:
    lines = [line for line in err.splitlines() if line.strip()]
    assert status == 2 and len(lines) == 1, f"{kind} gagen {argv!r}: status {status}, stderr {err[-1500:]!r}"
    assert "Traceback" not in err


@examples(fast=60, full=300)
@given(st.data())
def test_drawn_arguments_are_parsed_or_refused_in_one_line(data):
    verb = data.draw(st.sampled_from(VERBS), label="verb")
    head = [verb]
    if verb in SWEEPS:  # a sweep's own sub-verb, then its options
        head.append(data.draw(st.sampled_from(sorted(SWEEPS[verb])), label="sweep"))
    options = _options(*head) or ["--x"]
    tokens = st.one_of(st.sampled_from(options), st.sampled_from(NUMBERS),
                       st.sampled_from(HOSTILE_NAMES), st.sampled_from(["-", "--", "-x", "--no-such"]))
    values = st.one_of(st.sampled_from(NUMBERS), st.sampled_from(HOSTILE_NAMES))
    pairs = st.tuples(st.sampled_from(options), values).map(list)  # an option and its value
    pieces = data.draw(st.lists(st.one_of(tokens.map(lambda t: [t]), pairs), max_size=4), label="arguments")
    argv = [*head, *(token for piece in pieces for token in piece)]
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            parsed = parser().parse_args(argv)
        except SystemExit as e:
            COUNTS["CLI arguments"]["refused" if e.code == 2 else "help"] += 1
            if e.code != 0:
                _one_line_refusal("CLI arguments", argv, e.code, err.getvalue())
            return
    command = SUBPARSERS.choices[verb] if len(head) == 1 else SWEEPS[verb][head[1]]
    defaults = {a.dest: a.default for a in command._actions}  # (teleop's --duration is inf until quit)
    given = [v for k, v in vars(parsed).items() if k not in defaults or v != defaults[k]]
    numbers = [v for v in given if isinstance(v, float)]
    numbers += [x for v in given if isinstance(v, list | tuple) for x in v if isinstance(x, float)]
    COUNTS["CLI arguments"]["parsed"] += 1
    if not all(math.isfinite(v) for v in numbers):
        COUNTS["CLI arguments"]["wrongly accepted"] += 1
        raise AssertionError(f"gagen {argv!r} parsed a non-finite number: {vars(parsed)}")


# each verb that reads a file: how its argument list puts the file in
FILE_VERBS = {
    "kernels": lambda f: ["kernels", f],
    "build": lambda f: ["build", f, "-o", "out", "--no-compile"],
    "view": lambda f: ["view", f, "--png", "out.png"],
    "smc": lambda f: ["smc", "--spec", f, "--duration", "0.01"],
    "reach": lambda f: ["reach", f],
    "nullspace": lambda f: ["nullspace", f, "--steps", "2"],
    "impedance": lambda f: ["impedance", f, "--runs", "1"],
    "mpc": lambda f: ["mpc", f, "--duration", "0.01"],
    "teleop": lambda f: ["teleop", f, "--duration", "0.01"],
    "teleop --trace": lambda f: ["teleop", str(APPS / "cooperative" / "robots" / "three_pandas_circle.yaml"),
                                 "--trace", f, "--duration", "0.01"],
    "interpolate": lambda f: ["interpolate", f, "--from", "ready", "--to", "ready", "--steps", "2"],
    "manipulability": lambda f: ["manipulability", f, "--steps", "1"],
    "follow": lambda f: ["follow", f, "--duration", "0.01"],
    "follow --trace": lambda f: ["follow", "--trace", f, "--duration", "0.01"],
    "objectives": lambda f: ["objectives", f, str(REPO / "examples" / "three_pandas_objectives.yaml")],
    "objectives FILE": lambda f: ["objectives", "three_pandas_circle", f],
    "walk": lambda f: ["walk", f],
    "walk-sim": lambda f: ["walk-sim", f, "--no-animation"],
    "track-head": lambda f: ["track-head", f, "--duration", "0.01"],
    "linkage": lambda f: ["linkage", f, "--steps", "2"],
    "singularities": lambda f: ["singularities", f, "--steps", "8"],
    "stereo": lambda f: ["stereo", "--rig", f, "--duration", "0.01"],
}
# a valid file of another kind for each verb (a spec of another application)
FOREIGN = {"walk": APPS / "linkage" / "robots" / "four_bar.yaml",
           "walk-sim": APPS / "stereo" / "robots" / "stereo_rig.yaml",
           "track-head": APPS / "hexapod" / "robots" / "hexapod.yaml",
           "linkage": APPS / "hexapod" / "robots" / "hexapod.yaml",
           "singularities": APPS / "stereo" / "robots" / "stereo_rig.yaml",
           "stereo": APPS / "cooperative" / "robots" / "panda_point.yaml",
           "smc": APPS / "stereo" / "robots" / "stereo_rig.yaml",
           "nullspace": APPS / "linkage" / "robots" / "jansen.yaml",
           "impedance": APPS / "hexapod" / "robots" / "hexapod.yaml",
           "mpc": APPS / "stereo" / "robots" / "stereo_rig.yaml",
           "teleop": APPS / "linkage" / "robots" / "six_bar.yaml",
           "view": APPS / "linkage" / "robots" / "four_bar.yaml",
           "reach": APPS / "hexapod" / "robots" / "hexapod.yaml",
           "teleop --trace": APPS / "linkage" / "robots" / "six_bar.yaml",
           "interpolate": APPS / "hexapod" / "robots" / "hexapod.yaml",
           "manipulability": APPS / "stereo" / "robots" / "stereo_rig.yaml",
           "follow": APPS / "cooperative" / "robots" / "three_pandas_circle.yaml",  # no measured chain
           "follow --trace": APPS / "cooperative" / "traces" / "fig17_dilation.csv",  # a teleop trace
           "objectives": APPS / "linkage" / "robots" / "four_bar.yaml",
           "objectives FILE": APPS / "cooperative" / "robots" / "three_pandas_circle.yaml"}


@st.composite
def _bad_file(draw, verb: str, folder: Path) -> tuple[str, str]:
    """(description, path argument) of a file the verb must refuse."""
    kind = draw(st.sampled_from(["missing", "folder", "empty", "binary", "mutated", "foreign", "name"]))
    if kind == "foreign" and verb in FOREIGN:
        return kind, str(FOREIGN[verb])
    if kind == "missing":
        return kind, str(folder / "absent.yaml")
    if kind == "folder":
        return kind, str(folder)
    if kind == "name":
        return kind, draw(st.sampled_from([n for n in HOSTILE_NAMES if n and "\x00" not in n] + ["a\x00b"]))
    path = folder / "input.yaml"
    if kind == "empty":
        path.write_bytes(b"")
    elif kind == "binary":
        path.write_bytes(bytes(range(256)) * 4)
    else:  # the verb's own kind of file, cut short or with flipped bytes (which may stay valid: then skip)
        source = {"walk": APPS / "hexapod" / "robots" / "hexapod.yaml",
                  "walk-sim": APPS / "hexapod" / "robots" / "hexapod.yaml",
                  "track-head": APPS / "stereo" / "robots" / "stereo_rig.yaml",
                  "linkage": APPS / "linkage" / "robots" / "four_bar.yaml",
                  "singularities": APPS / "linkage" / "robots" / "four_bar.yaml",
                  "stereo": APPS / "stereo" / "robots" / "stereo_rig.yaml"}.get(
            verb, APPS / "cooperative" / "robots" / "three_pandas_circle.yaml")
        cuts = byte_mutation(source.read_text()).filter(lambda m: m[0].startswith(("truncate", "nul")))
        what, raw = draw(cuts)
        path.write_bytes(raw[: max(1, len(raw) // 3)] + b"\n  - [unclosed\x00")  # certainly broken
        kind = f"mutated {source.name} ({what})"
    return kind, str(path)


@examples(fast=30, full=150)
@given(st.data())
def test_every_verb_refuses_a_bad_file_in_one_line(data):
    from conftest import deadline

    verb = data.draw(st.sampled_from(sorted(FILE_VERBS)), label="verb")
    with tempfile.TemporaryDirectory() as folder:
        cwd = os.getcwd()
        os.chdir(folder)
        try:
            kind, path = data.draw(_bad_file(verb, Path(folder) / "inputs"), label="file") \
                if (Path(folder) / "inputs").mkdir() is None else ("", "")
            argv = FILE_VERBS[verb](path)
            with deadline(CASE_SECONDS):
                status, _, err = _call(argv)
        except TimeoutError as e:
            COUNTS["CLI bad files"]["hang"] += 1
            raise AssertionError(f"gagen {argv!r}: a hang ({e})") from e
        finally:
            os.chdir(cwd)
            shutil.rmtree(folder, ignore_errors=True)
    COUNTS["CLI bad files"]["refused" if status == 2 else "wrongly accepted"] += 1
    _one_line_refusal("CLI bad files", [verb, kind], status, err)
