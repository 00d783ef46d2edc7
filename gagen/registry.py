"""What the core and the applications register: command-line verbs, spec kinds and bundled specs.

An application is a package under ``gagen/apps/`` whose ``__init__`` defines ``APP = App(...)``: its
spec kinds (a spec's top-level ``app`` key; the function that turns such a spec into a module source,
named as ``"module:function"`` and imported only when a spec of that kind is built), its verbs (each
defines and parses its own arguments), the folder of its bundled specs, and the modules whose source
makes its kernels (the build's cache key covers them and everything they import, see
``gagen.code_digest``). The core's verbs are listed in ``CORE_VERBS``.

Nothing here imports an application by name: the packages are found under ``gagen.apps``' path (a
plug-in package appended to that path registers itself the same way), so the library never depends on
an application, and adding one touches no core file (``docs/extending.md``).
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any, NoReturn

# modules whose VERBS the core registers, in the order `gagen --help` lists them
CORE_VERBS = ("gagen.commands", "gagen.viewer.command", "gagen.sweep.command", "gagen.control.smc.command")
DEFAULT_SPEC_KIND = "cooperative"  # a spec without an ``app`` key


@dataclass(frozen=True)
class Verb:
    """A ``gagen <name>`` subcommand: ``add_arguments`` defines its arguments, ``run`` runs it on the parsed
    ones and returns the exit status (0 done, 1 failed, 2 bad input). Both live in a light module: heavy
    imports go inside ``run``, so ``gagen --help`` stays fast."""

    name: str
    help: str
    add_arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]
    needs: tuple[str, ...] = ()  # optional modules it cannot run without (gagen.extras: one line if missing)

    def parser(self, prog: str | None = None) -> argparse.ArgumentParser:
        """A parser of this verb's arguments alone."""
        parser = OneLineParser(prog=prog or f"gagen {self.name}", description=self.help)
        self.add_arguments(parser)
        return parser


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line on stderr (``gagen build: error: argument -j/--jobs:
    expected an integer >= 1, got '-3' (gagen build --help)``) and exit status 2, subparsers included."""

    def error(self, message: str) -> NoReturn:
        message = message.replace("\r", "\\r").replace("\n", "\\n")  # an argument's own newline, escaped
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


@dataclass(frozen=True)
class SpecKind:
    """Specs whose ``app`` key is ``name``: ``source`` (``"module:function"``) makes the module source of
    such a spec path; ``check``, where the kernels are not front-end kernels that check themselves, is the
    ``gagen build --check`` of such a module: ``check(spec, folder, samples, tolerance) -> exit status``."""

    name: str
    source: str
    check: str = ""


@dataclass(frozen=True)
class App:
    """An application's registration (``gagen/apps/<name>/__init__.py``: ``APP = App(...)``)."""

    name: str
    summary: str
    spec_kinds: tuple[SpecKind, ...] = ()
    verbs: tuple[Verb, ...] = ()
    bundled: Path | None = None  # the folder of its bundled specs (``*.yaml``), shipped in the package
    kernel_modules: tuple[str, ...] = field(default=())  # the modules that make its kernels: the sources of
    # these and of every gagen module they import are in its builds' cache key (ModuleSource.code)


@cache
def apps() -> tuple[App, ...]:
    """Every registered application, by package name: each package under ``gagen.apps``' path with an
    ``APP``."""
    package = importlib.import_module("gagen.apps")  # by name: the core never imports an application itself
    found = []
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda i: i.name):
        if not info.ispkg:
            continue
        app = getattr(importlib.import_module(f"gagen.apps.{info.name}"), "APP", None)
        if isinstance(app, App):
            found.append(app)
    return tuple(found)


def verbs() -> list[Verb]:
    """The core's verbs, then every application's; a name registered twice is an error."""
    found: list[Verb] = [verb for module in CORE_VERBS for verb in importlib.import_module(module).VERBS]
    found += [verb for app in apps() for verb in app.verbs]
    seen: set[str] = set()
    for verb in found:
        if verb.name in seen:
            raise RuntimeError(f"the verb {verb.name!r} is registered twice")
        seen.add(verb.name)
    return found


def spec_kinds() -> dict[str, tuple[App, SpecKind]]:
    """Spec kind name -> (its application, the kind)."""
    return {kind.name: (app, kind) for app in apps() for kind in app.spec_kinds}


def function(reference: str) -> Callable[..., Any]:
    """The function named by ``"module:function"`` (imported now)."""
    module, _, name = reference.partition(":")
    found: Callable[..., Any] = getattr(importlib.import_module(module), name)
    return found


def bundled_specs(app: str | None = None) -> dict[str, Path]:
    """Name -> spec file of every bundled spec (``*.yaml`` in the applications' ``bundled`` folders), or
    of one application's."""
    found: dict[str, Path] = {}
    for each in apps():
        if each.bundled is not None and app in (None, each.name):
            found.update({path.stem: path for path in sorted(each.bundled.glob("*.yaml"))})
    return found


def resolve_spec(name_or_path: str | Path, app: str | None = None, what: str = "spec") -> Path:
    """A spec file from a bundled name (``three_pandas_circle``) or a path; a ValueError naming the bundled
    ones when it is neither (``what``: the word for a spec in the message, e.g. ``system``)."""
    specs = bundled_specs(app)
    if isinstance(name_or_path, str) and name_or_path in specs:
        return specs[name_or_path]
    path = Path(name_or_path)
    if path.is_file():
        return path
    raise ValueError(f"{what} {str(name_or_path)!r}: not a bundled {what} ({', '.join(specs)}) nor a spec "
                     "file")
