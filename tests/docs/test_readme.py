"""Every Python block in the README runs as written, from the repository root, in order, each in a
fresh namespace (a block may not lean on names defined in an earlier one). The blocks assert what
they claim where they can (shapes, errors), so a block that runs but shows the wrong thing fails."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from conftest import bundled_module

ROOT = Path(__file__).resolve().parents[2]
BLOCKS = re.findall(r"^```python\n(.*?)^```", (ROOT / "README.md").read_text(), flags=re.S | re.M)


def test_the_readme_has_python_blocks():
    assert len(BLOCKS) >= 3


@pytest.mark.parametrize("index", [  # a block that compiles (gagen.compile) is in the full tier only
    pytest.param(i, marks=[pytest.mark.compiling] if "gagen.compile(" in block else [])
    for i, block in enumerate(BLOCKS)])
def test_readme_python_block_runs(index, monkeypatch):
    # the committed modules a block opens (generated/<name>) built first, as README command 1 does: a
    # fresh clone has only their text files, not the CasADi serialisations (gagen.modules)
    for name in sorted(set(re.findall(r"generated[./]([A-Za-z_][A-Za-z0-9_]*)", BLOCKS[index]))):
        bundled_module(name)
    monkeypatch.chdir(ROOT)
    monkeypatch.syspath_prepend(str(ROOT))  # `from generated.<system> import …` as from the root
    code = compile(BLOCKS[index], f"README.md python block {index + 1}", "exec")
    exec(code, {"__name__": f"readme_block_{index + 1}"})
