"""The README stays a front page (at most 200 lines; the rest is the documentation site, docs/), and its
two commands are what CI runs: `.ci/run` runs README command 2 as written, after creating .venv. The
README's code blocks run with the docs' (test_code_blocks.py)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()


def readme_commands() -> list[str]:
    """The README's numbered commands: the line after each `# N. …` comment of its first bash block."""
    block = re.search(r"^```bash\n(.*?)^```", README, flags=re.S | re.M)
    assert block, "the README has no bash block with its commands"
    lines = block[1].split("\n")
    return [lines[i + 1] for i, line in enumerate(lines) if re.match(r"# \d\. ", line)]


def test_the_readme_is_short():
    assert len(README.splitlines()) <= 200


def test_the_readme_has_its_two_commands():
    commands = readme_commands()
    assert len(commands) == 2
    assert commands[0].startswith("python3 -m venv .venv && .venv/bin/pip install")


def test_ci_runs_readme_command_2_as_written():
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert readme_commands()[1] in ci, "the last command of .ci/run must equal README command 2"
    assert ci[-1] == readme_commands()[1]


def test_the_readme_links_into_the_docs():
    for page in re.findall(r"\]\((docs/[^)#]+)", README):
        assert (ROOT / page).exists(), page
    assert "docs/images/" in README


def test_the_getting_started_page_has_the_same_commands():
    """docs/index.md repeats the two commands: the same lines as the README's."""
    page = (ROOT / "docs" / "index.md").read_text().splitlines()
    assert all(command in page for command in readme_commands())
