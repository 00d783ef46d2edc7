"""``pip install .`` (not editable) ships everything gagen reads at run time (the backends' templates,
the module template, the SMC loop's C source, the bundled robots): a copy of the source tree is
installed into a folder of its own, and from an unrelated working directory that install builds a
Python file of kernels (``gagen build FILE.py``); the module is loaded and called there. Without the
templates in the wheel, the build fails and so does this test."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]

KERNELS = '''
import gagen
from gagen.kinds import vector


@gagen.kernel(algebra="ga3d")
def wedge(a: vector, b: vector):
    """The outer product of two vectors."""
    return {"B": a ^ b}
'''

CALL = """
import json, sys
import numpy as np
import gagen
module = gagen.load(sys.argv[2])
B = module.c.wedge(np.array([1.0, 2.0, 3.0]), np.array([4.0, 5.0, 6.0]))
print(json.dumps({"gagen": gagen.__file__, "B": B.tolist(), "binding": module.binding is not None,
                  "casadi": [float(x) for x in module.casadi.wedge([1, 2, 3], [4, 5, 6]).full().ravel()]}))
"""


def _build_isolation() -> list[str]:
    """Build with this environment's setuptools when it is recent enough for pyproject.toml (no index
    needed); otherwise pip fetches one into an isolated build environment."""
    try:
        major = int(version("setuptools").split(".")[0])
    except (PackageNotFoundError, ValueError):
        major = 0
    return ["--no-build-isolation"] if major >= 68 else []


def _run(command: list[str], cwd: Path, env: dict[str, str]) -> str:
    result = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, f"{' '.join(command)}:\n{result.stdout}\n{result.stderr}"
    return result.stdout


@pytest.mark.slow
@pytest.mark.compiling
def test_a_non_editable_install_builds_a_python_file_of_kernels_and_loads_it(tmp_path):
    source, site, work, out = (tmp_path / name for name in ("src", "site", "work", "out"))
    source.mkdir()
    work.mkdir()
    shutil.copytree(REPO / "gagen", source / "gagen",
                    ignore=shutil.ignore_patterns("__pycache__", "*.so", "*.pyc"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, source / name)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    _run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-compile",
          *_build_isolation(), "--target", str(site), str(source)], tmp_path, env)
    installed = site / "gagen"
    shipped = sorted(p.relative_to(installed).as_posix() for p in installed.rglob("*.j2"))
    ours = sorted(p.relative_to(REPO / "gagen").as_posix() for p in (REPO / "gagen").rglob("*.j2"))
    assert shipped == ours and "codegen/backends/cpython/templates/binding.c.j2" in ours
    assert (installed / "control" / "smc" / "smc_loop.c").is_file()
    assert (installed / "py.typed").is_file()  # the annotations are part of the package (PEP 561)
    bundled = sorted(p.name for p in (installed / "apps" / "cooperative" / "robots").glob("*.yaml"))
    assert bundled == sorted(p.name for p in (REPO / "robots").glob("*.yaml")) and len(bundled) == 15
    leader = installed / "apps" / "cooperative"
    assert (leader / "robots" / "leader" / "two_pandas_hand_circle.yaml").is_file()
    assert (leader / "traces" / "leader" / "hand_circle.csv").is_file()
    traces = sorted(p.name for p in (installed / "apps" / "cooperative" / "traces").glob("*.csv"))
    ours = sorted(p.name for p in (REPO / "gagen" / "apps" / "cooperative" / "traces").glob("*.csv"))
    assert traces == ours
    assert traces  # gagen teleop --trace replays the bundled traces after a non-editable install
    assert len(list((installed / "apps" / "cooperative" / "robots").glob("*/*.urdf"))) == 4
    hexapod = installed / "apps" / "hexapod" / "robots"
    assert sorted(p.name for p in hexapod.iterdir() if p.suffix in (".yaml", ".urdf")) == \
        ["hexapod.urdf", "hexapod.yaml"]
    for app in ("linkage", "stereo"):  # every app's bundled specs ship (gagen linkage runs them by default)
        shipped_specs = sorted(p.name for p in (installed / "apps" / app / "robots").glob("*.yaml"))
        ours = sorted(p.name for p in (REPO / "gagen" / "apps" / app / "robots").glob("*.yaml"))
        assert shipped_specs == ours and ours

    (work / "tiny.py").write_text(KERNELS)
    env["PYTHONPATH"] = str(site)  # the install, before the editable one of the environment
    _run([sys.executable, "-m", "gagen.cli", "build", "tiny.py", "-o", str(out)], work, env)
    assert sorted(p.name for p in out.iterdir() if not p.name.endswith(".so")) == [
        ".build-key", "__init__.py", "casadi", "manifest.json", "tiny.c", "tiny.cu", "tiny.h",
        "tiny_binding.c", "tiny_jax.py", "tiny_simd.c"]
    result = json.loads(_run([sys.executable, "-c", CALL, str(site), str(out)], work, env))
    assert Path(result["gagen"]).resolve().is_relative_to(site.resolve()), result["gagen"]
    a, b = np.array([1.0, 2.0, 3.0]), np.array([4.0, 5.0, 6.0])
    # a ^ b on e12, e13, e23
    expected = [a[0] * b[1] - a[1] * b[0], a[0] * b[2] - a[2] * b[0], a[1] * b[2] - a[2] * b[1]]
    assert result["B"] == expected and result["casadi"] == expected
    assert result["binding"]  # the CPython binding compiled from the installed template
