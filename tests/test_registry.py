"""Applications register themselves: a throwaway app package on ``gagen.apps``' path brings its verb and its
spec kind to ``gagen`` without a core file changed; ``gagen --help`` lists every registered verb; a bad
argument of any verb is one line on stderr and exit status 2."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

import gagen.apps
from gagen import registry
from gagen.cli import main, parser

THROWAWAY = '''
"""A throwaway application for the registry's test."""

from pathlib import Path

from gagen.registry import App, SpecKind, Verb


def _arguments(parser):
    parser.add_argument("--times", type=int, default=1)


def _hello(args):
    print("hello " * args.times)
    return 0


def source(path):
    import gagen
    from gagen.frontend import source_of
    from gagen.yaml_document import Document

    spec = Document(Path(path), "a mapping (a spec)")
    scale = float(spec.data["scale"])

    @gagen.kernel(algebra="cga3d", name="scaled")
    def scaled(X: "point"):
        return {"Y": X * scale}

    return source_of([scaled], spec.data["name"], Path(path).name, Path(path).read_bytes())


APP = App("throwaway_app", "a test", spec_kinds=(SpecKind("throwaway", "gagen.apps.throwaway_app:source"),),
          verbs=(Verb("hello", "say hello", _arguments, _hello),), bundled=Path(__file__).parent / "robots")
'''


@pytest.fixture
def throwaway(tmp_path, monkeypatch):
    """A package ``throwaway_app`` on gagen.apps' path, registered as any application is."""
    package = tmp_path / "throwaway_app"
    (package / "robots").mkdir(parents=True)
    (package / "__init__.py").write_text(THROWAWAY)
    (package / "robots" / "tiny.yaml").write_text("app: throwaway\nname: tiny\nscale: 2.0\n")
    monkeypatch.setattr(gagen.apps, "__path__", [*gagen.apps.__path__, str(tmp_path)])
    registry.apps.cache_clear()
    yield package
    registry.apps.cache_clear()
    import sys

    for name in [m for m in sys.modules if m.startswith("gagen.apps.throwaway_app")]:
        del sys.modules[name]


def test_gagen_help_lists_every_registered_verb(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--help"])
    assert exit_.value.code == 0
    listed = capsys.readouterr().out
    names = [v.name for v in registry.verbs()]
    assert set(names) >= {"build", "kernels", "reach", "walk", "linkage", "stereo", "smc", "view", "sweep"}
    for name in names:
        assert f"\n    {name}" in listed, name
    assert {a.name for a in registry.apps()} == {"cooperative", "hexapod", "linkage", "stereo"}


def test_a_throwaway_app_brings_its_verb_and_spec_kind(throwaway, tmp_path, capsys):
    assert "throwaway_app" in [a.name for a in registry.apps()]
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "hello" in capsys.readouterr().out
    assert main(["hello", "--times", "3"]) == 0
    assert capsys.readouterr().out.strip() == "hello hello hello"
    # its spec kind: `gagen kernels` and `gagen build` take a spec of it, from a path or a bundled name
    spec = throwaway / "robots" / "tiny.yaml"
    assert registry.bundled_specs("throwaway_app") == {"tiny": spec}
    assert main(["kernels", str(spec)]) == 0
    assert "scaled" in capsys.readouterr().out
    out = tmp_path / "built"
    assert main(["build", str(spec), "-o", str(out), "--no-compile"]) == 0
    import json

    manifest = json.loads((out / "manifest.json").read_text())
    assert [k["name"] for k in manifest["kernels"]] == ["scaled"]
    # the kernel computes what the app's function says: Y = 2 X (its CasADi Function on numbers)
    from gagen.build import load_source

    kernel = load_source(spec).kernels["scaled"]
    x = np.array([0.3, -1.0, 2.0, 0.5, 4.0])
    assert np.allclose(np.asarray(kernel.function(x)).ravel(), 2.0 * x, rtol=0, atol=1e-15)


def test_an_unknown_spec_kind_names_the_registered_ones(tmp_path, capsys):
    spec = tmp_path / "odd.yaml"
    spec.write_text("app: gripper\nname: x\n")
    assert main(["kernels", str(spec)]) == 2
    err = capsys.readouterr().err
    assert "app" in err and "gripper" in err and "cooperative, hexapod, linkage, stereo" in err


def test_a_verb_registered_twice_is_refused(monkeypatch):
    duplicate = registry.Verb("build", "again", lambda p: None, lambda a: 0)
    app = registry.App("dup", "a duplicate", verbs=(duplicate,))
    monkeypatch.setattr(registry, "apps", lambda: (app,))
    with pytest.raises(RuntimeError, match="'build' is registered twice"):
        registry.verbs()


@pytest.mark.parametrize("argv", [
    ["build", "robots/panda_point.yaml", "-j", "-3"],
    ["build", "robots/panda_point.yaml", "--samples", "0"],
    ["build", "robots/panda_point.yaml", "--tolerance", "nan"],
    ["reach", "circle", "--N", "0"],
    ["reach", "no_such_scenario"],
    ["mpc", "--rate", "-1"],
    ["impedance", "--spread", "inf"],
    ["teleop", "three_pandas_circle", "--trace", "x.csv", "--dt", "0"],
    ["view", "three_pandas_circle", "--port", "70000"],
    ["walk", "--frames", "0"],
    ["walk", "--step-height", "nan"],  # (a plain float before issue 29's fuzzer)
    ["walk", "--straight", "inf"],
    ["sweep", "reach", "--out", "x", "--span", "nan"],
    ["sweep", "reach", "--out", "x", "--normal", "0", "0", "inf"],
    ["build", "a\nb"],  # a newline of the user's own, written as \n
    ["linkage", "--steps", "x"],
    ["stereo", "--clutter", "-2"],
    ["smc", "--rate", "0"],
    ["sweep", "manipulability", "--out", "x", "--workers", "0"],
    ["demo", "--samples", "-5"],
    ["no_such_verb"],
])
def test_every_bad_argument_is_one_line_and_exit_status_2(argv, capsys):
    try:  # argparse's own refusal, or the verb's (a value only the verb can check)
        status = main(argv)
    except SystemExit as exit_:
        status = exit_.code
    assert status == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error:" in err, err


def test_each_verb_parses_its_own_arguments_once():
    """The dispatcher's parser and the verb's own (``Verb.parser``, used by ``python -m``) are one
    definition: the same options with the same defaults."""
    top = parser()
    sub = next(a for a in top._actions if a.dest == "command")
    for verb in registry.verbs():
        mine = {a.dest: a.default for a in verb.parser()._actions if a.dest != "help"}
        theirs = {a.dest: a.default for a in sub.choices[verb.name]._actions
                  if a.dest not in ("help", "verb")}
        assert mine == theirs, verb.name


def test_the_registry_reads_a_spec_name_or_path(tmp_path):
    assert registry.resolve_spec("three_pandas_circle").name == "three_pandas_circle.yaml"
    own = tmp_path / "mine.yaml"
    own.write_text(textwrap.dedent("name: mine\n"))
    assert registry.resolve_spec(str(own)) == own
    with pytest.raises(ValueError, match=r"spec 'nothing_here': not a bundled spec .* nor a spec file"):
        registry.resolve_spec("nothing_here")
