"""A missing optional dependency is one line naming the extra that brings it, exit status 2, in every verb
that needs one (and every flag), and on the library's import paths: each case runs in a fresh interpreter
whose import system hides the extra's modules."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from gagen.extras import EXTRAS, MissingExtra, require

ROOT = Path(__file__).resolve().parents[1]
TRACE = ROOT / "gagen" / "apps" / "cooperative" / "traces" / "circle_move_tilt_dilate.csv"

HIDE = '''
import importlib.abc, sys
HIDDEN = set({hidden!r})
class Hide(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in HIDDEN:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
        return None
sys.meta_path.insert(0, Hide())
'''


def _run(hidden: set[str], code: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    script = HIDE.format(hidden=sorted(hidden)) + textwrap.dedent(code)
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=cwd,
                          timeout=120)


def _modules(extra: str) -> set[str]:
    return {module for module, owner in EXTRAS.items() if owner == extra}


VERBS = [
    (["view", "panda_point", "--png", "x.png"], "viewer"),
    (["sweep", "manipulability", "--out", "sweep", "--samples", "10"], "sweep"),
    (["impedance", "--runs", "1", "--duration", "0.01"], "dynamics"),
    (["reach", "circle", "--view"], "viewer"),
    (["nullspace", "--view"], "viewer"),
    (["mpc", "--view"], "viewer"),
    (["teleop", "three_pandas_circle", "--trace", str(TRACE), "--view"], "viewer"),
    (["teleop", "three_pandas_circle", "--spacemouse"], "teleop"),
    (["reach", "circle", "--dynamics"], "ocp"),
    (["walk", "--no-animation", "--out", "walk"], "statics"),
]


@pytest.mark.parametrize(("argv", "extra"), VERBS, ids=[" ".join(a[:2]) for a, _ in VERBS])
def test_a_verb_without_its_extra_is_one_line_and_exit_status_2(argv, extra, tmp_path):
    done = _run(_modules(extra), f"from gagen.cli import main\nsys.exit(main({argv!r}))", tmp_path)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and f"pip install 'gagen[{extra}]'" in lines[0], done.stderr
    assert not list(tmp_path.iterdir())  # refused before anything was written


@pytest.mark.parametrize(("code", "extra"), [
    ("import gagen.sweep.engine", "sweep"),
    ("import gagen.sweep.store", "sweep"),
    ("import gagen.control.torque", "ocp"),
    ("import gagen.dynamics.mujoco_model", "sim"),
    ("from gagen.apps.hexapod.statics import distribute_forces\n"
     "distribute_forces([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [0.3, 0.3, 0.2], 1.0)", "statics"),
    ("from gagen.robots.spec import load_system\nfrom gagen.registry import bundled_specs\n"
     "from gagen.viewer import Scene\nScene(load_system(bundled_specs()['panda_point'])[0], port=0)",
     "viewer"),
])
def test_a_library_import_without_its_extra_names_it(code, extra, tmp_path):
    done = _run(_modules(extra), code, tmp_path)
    assert done.returncode == 1
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("gagen.extras.MissingExtra: gagen.") and f"'gagen[{extra}]'" in last, done.stderr


def test_every_extra_named_exists_and_all_brings_them():
    import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert set(EXTRAS.values()) <= set(extras)
    named = ["sweep", "jax", "dynamics", "viewer", "teleop", "ocp", "sim", "statics"]
    assert extras["all"] == [f"gagen[{','.join(named)}]"]
    assert set(EXTRAS.values()) - {"cuda"} <= set(named)  # cuda: GPU machines only, not in all


def test_require_passes_other_missing_modules_through():
    with pytest.raises(ModuleNotFoundError) as raised:
        require("gagen_no_such_module", "a test")
    assert not isinstance(raised.value, MissingExtra)
    assert require("json", "a test").dumps([1]) == "[1]"
