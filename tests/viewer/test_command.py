"""``gagen view`` / ``python -m gagen.viewer``: malformed arguments name the argument and what was expected;
a missing browser is an error with a way out, not a traceback."""

import pytest

from gagen.cli import main as gagen
from gagen.viewer.command import main

pytest.importorskip("viser")  # the viewer extra


def test_malformed_arguments(capsys):
    assert main(["no_such_system"]) == 2
    assert "system 'no_such_system': not a bundled system (" in capsys.readouterr().err
    assert main(["three_pandas_circle", "--q", "1,2"]) == 2
    err = capsys.readouterr().err
    assert "--q: expected 21 finite comma-separated numbers for three_pandas_circle, got 2" in err
    assert main(["three_pandas_circle", "--q", "1,x"]) == 2
    assert "--q: expected 21 comma-separated numbers, got '1,x'" in capsys.readouterr().err
    assert main(["three_pandas_circle", "--configuration", "home"]) == 2
    assert "--configuration: three_pandas_circle names ready; got 'home'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        main(["three_pandas_circle", "--size", "big"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "--size: expected WIDTHxHEIGHT in pixels (16 to 8192 each), e.g. 1024x768; got 'big'" in err


def test_a_missing_browser_is_reported(monkeypatch, tmp_path, capsys):
    monkeypatch.setenv("GAGEN_CHROMIUM", str(tmp_path / "no-chromium"))
    assert gagen(["view", "panda_point", "--png", str(tmp_path / "f.png")]) == 1
    assert "no Chromium found: install it (Debian: apt-get install chromium) or set GAGEN_CHROMIUM" in (
        capsys.readouterr().err)
    assert not (tmp_path / "f.png").exists()


def test_help_says_the_url_carries_a_token(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--help"])
    assert exit_.value.code == 0
    assert "?token=" in capsys.readouterr().out
