"""Every code block of the README and of the documentation site (docs/, in the order of mkdocs.yml's
nav) runs as written, from the repository root, in page order, each in a fresh namespace (a block may
not lean on names defined in an earlier one). The blocks assert what they claim where they can
(shapes, errors), so a block that runs but shows the wrong thing fails.

- ```python blocks are executed;
- ```bash blocks are commands: each `gagen …` line goes through `gagen.cli.main(shlex.split(…))` with
  the files and folders it writes (`--out`, `-o`, `--png`, a build's output) moved into a temporary
  folder; a line running another program
  of the virtual environment (`.venv/bin/lint-imports`) runs as a subprocess;
- ```yaml blocks must parse; ```text blocks (sample output) and ```c fragments are shown, not run.

HTML comments on the lines right above a block steer it: `<!-- skip: REASON -->` leaves it out (the
reason is required; the block's test reports it as skipped with that reason), `<!-- full: REASON -->`
runs it in the full tier only (marked slow: a long run), and `<!-- test-args: ARGS -->` appends ARGS
to each `gagen` command of the block (cheaper runs: later options override the written ones)."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml
from conftest import bundled_module

ROOT = Path(__file__).resolve().parents[2]
RUN = ("python", "bash", "yaml")  # the languages a block is run (or parsed) in
SHOWN = ("text", "c")  # the languages shown only
# generated modules whose first use builds nothing in the fast tier (the tiers: tests/conftest.py)
CHEAP_MODULES = {"panda_point", "three_pandas_circle"}


@dataclass(frozen=True)
class Block:
    page: str  # the file, relative to the repository root
    line: int  # the line of the opening fence, 1-based
    language: str
    code: str
    skip: str | None  # the reason given by <!-- skip: … -->
    full: str | None  # <!-- full: why --> : the full tier only (a long run)
    test_args: str  # <!-- test-args: … -->

    @property
    def name(self) -> str:
        return f"{self.page}:{self.line}"


def pages() -> list[Path]:
    """The README, then the site's pages in the order of mkdocs.yml's nav."""
    nav = yaml.safe_load((ROOT / "mkdocs.yml").read_text())["nav"]

    def walk(entries):
        for entry in entries:
            value = next(iter(entry.values())) if isinstance(entry, dict) else entry
            yield from walk(value) if isinstance(value, list) else [value]
    return [ROOT / "README.md", *(ROOT / "docs" / page for page in walk(nav))]


def blocks_of(path: Path) -> list[Block]:
    lines = path.read_text().split("\n")
    found, i = [], 0
    while i < len(lines):
        opening = re.match(r"^```(\S*)\s*$", lines[i])
        if not opening:
            i += 1
            continue
        end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
        notes, k = {}, i - 1  # the HTML comments right above the fence: <!-- key: value -->
        while k >= 0 and (note := re.fullmatch(r"<!--\s*([a-z-]+):\s*(.*?)\s*-->", lines[k].strip())):
            notes[note[1]] = note[2]
            k -= 1
        unknown = set(notes) - {"skip", "full", "test-args"}
        assert not unknown, f"{path.name}:{i + 1}: unknown directives {unknown}"
        found.append(Block(str(path.relative_to(ROOT)), i + 1, opening[1], "\n".join(lines[i + 1:end]) + "\n",
                           notes.get("skip"), notes.get("full"), notes.get("test-args", "")))
        i = end + 1
    return found


BLOCKS = [block for page in pages() for block in blocks_of(page)]
RUNNABLE = [block for block in BLOCKS if block.language in RUN]


def test_every_block_names_its_language():
    """A block without a language would be neither run nor highlighted: each says what it is."""
    unknown = [f"{b.name} ({b.language or 'none'})" for b in BLOCKS if b.language not in RUN + SHOWN]
    assert not unknown, f"code blocks of no known language: {unknown}"


def test_every_skip_gives_a_reason():
    assert all(block.skip for block in BLOCKS if block.skip is not None)
    assert all(block.full for block in BLOCKS if block.full is not None)
    assert sum(block.skip is not None for block in RUNNABLE) <= 12, "skips are for what cannot run here"


def test_the_pages_have_python_blocks():
    assert sum(b.language == "python" for b in RUNNABLE if b.page == "README.md") >= 3
    assert sum(b.language == "python" for b in RUNNABLE if b.page != "README.md") >= 8


def marks(block: Block) -> list[pytest.MarkDecorator]:
    """The tier of a block: compiling C (gagen.compile, a gagen command, a module beyond the two the
    fast tier builds anyway) or running long puts it in the full tier."""
    if block.skip:
        return [pytest.mark.skip(reason=block.skip)]
    if block.language == "bash":
        return [pytest.mark.compiling, pytest.mark.slow]
    tier = [pytest.mark.slow] if block.full else []
    modules = set(re.findall(r"generated[./]([A-Za-z_][A-Za-z0-9_]*)", block.code))
    if any(call in block.code for call in ("gagen.compile(", "bundled_module(")) or modules - CHEAP_MODULES:
        tier.append(pytest.mark.compiling)
    return tier


def run_python(block: Block, monkeypatch) -> None:
    # the committed modules a block opens (generated/<name>) built first, as README command 1 does: a
    # fresh clone has only their text files, not the CasADi serialisations (gagen.modules)
    for name in sorted(set(re.findall(r"generated[./]([A-Za-z_][A-Za-z0-9_]*)", block.code))):
        bundled_module(name)
    monkeypatch.syspath_prepend(str(ROOT))  # `from generated.<system> import …` as from the root
    code = compile(block.code, f"{block.name} python block", "exec")
    exec(code, {"__name__": f"docs_block_{block.line}"})


def commands(code: str) -> list[list[str]]:
    """The block's commands, continuation lines joined, comments dropped."""
    return [words for line in code.replace("\\\n", " ").split("\n")
            if (words := shlex.split(line, comments=True))]


def gagen_arguments(words: list[str], extra: str, tmp: Path) -> list[str]:
    """A `gagen` command's arguments, its output folders inside ``tmp``, with the block's test-args."""
    argv = words[1:] + shlex.split(extra)
    for i, word in enumerate(argv[:-1]):
        if word in ("--out", "-o", "--png"):
            argv[i + 1] = str(tmp / argv[i + 1].strip("/"))
    if argv[0] == "build" and "-o" not in argv:
        spec = next(w for w in argv[1:] if not w.startswith("-"))
        argv += ["-o", str(tmp / "generated" / Path(spec).stem)]
    return argv


def run_bash(block: Block, tmp: Path, capsys) -> None:
    from gagen.cli import main

    for words in commands(block.code):
        program = Path(words[0])
        if program.name == "gagen":
            argv = gagen_arguments(words, block.test_args, tmp)
            try:
                code = main(argv)
            except SystemExit as stop:
                code = stop.code
            output = capsys.readouterr()
            assert code in (0, None), f"{block.name}: gagen {shlex.join(argv)} exited {code}\n{output.err}"
        elif str(program.parent) == ".venv/bin" and (Path(sys.executable).parent / program.name).exists():
            done = subprocess.run([str(Path(sys.executable).parent / program.name), *words[1:]], cwd=ROOT,
                                  capture_output=True, text=True, timeout=600)
            assert done.returncode == 0, f"{block.name}: {shlex.join(words)}\n{done.stdout}{done.stderr}"
        else:
            pytest.fail(f"{block.name}: `{shlex.join(words)}` is neither a gagen command nor a program of "
                        f"the virtual environment: run it another way or mark the block <!-- skip: why -->")


@pytest.mark.parametrize("block", [pytest.param(b, marks=marks(b), id=b.name) for b in RUNNABLE])
def test_code_block_runs(block: Block, monkeypatch, tmp_path, capsys):
    monkeypatch.chdir(ROOT)
    if block.language == "python":
        run_python(block, monkeypatch)
    elif block.language == "bash":
        monkeypatch.setenv("MPLBACKEND", "Agg")
        run_bash(block, tmp_path, capsys)
    else:
        assert yaml.safe_load(block.code) is not None

