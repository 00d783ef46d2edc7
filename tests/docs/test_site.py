"""The documentation site builds with `mkdocs build --strict` (mkdocs.yml, docs/): a broken link, a
page missing from the nav, an unresolved API reference or a docstring mkdocstrings cannot read fails
it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_the_site_builds_strictly(tmp_path):  # ≈ 1.5 s: fast tier
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
                          cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env={"NO_MKDOCS_2_WARNING": "1", "PATH": "/usr/bin:/bin"})
    assert done.returncode == 0, done.stdout + done.stderr
    assert (tmp_path / "site" / "index.html").exists()
    api = (tmp_path / "site" / "api" / "index.html").read_text()
    for module in ("gagen.frontend", "gagen.build", "gagen.runtime", "gagen.registry", "gagen.modules",
                   "gagen.robots.system", "gagen.robots.spec", "gagen.control.ik", "gagen.control.goals",
                   "gagen.control.ilqr", "gagen.control.ocp"):
        assert f'id="{module}"' in api, f"the API reference lacks {module}"
