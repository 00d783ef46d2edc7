"""What a backend is: :class:`Backend` (render, compile, open, load), what it renders (:class:`Output`)
and what it renders from (:class:`Context`), what it loads into (:class:`LoadedModule`), plus the
module tag that names compiled files."""

from __future__ import annotations

import functools
import hashlib
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    import jinja2

    from gagen.codegen.ir import ModuleSource

Progress = Callable[[str], None]


@dataclass(frozen=True)
class ReservedNames:
    """Names a backend's generated files take for themselves: exact names and whole prefixes."""

    exact: frozenset[str] = frozenset()
    prefixes: tuple[str, ...] = ()


_TEMPLATE_TAG = re.compile(r"\{\{.*?\}\}|\{%.*?%\}|\{#.*?#\}", re.DOTALL)
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


@functools.cache
def template_names(folder: Path | None) -> ReservedNames:
    """The identifiers with an underscore that the templates in ``folder`` write (C keywords and plain
    words have none, and no kernel symbol, ``<module>_<kernel>``, lacks one), and the identifier
    fragments that end right before a template expression (``gagen_`` in ``gagen_{{ p.name }}``: the
    expression may make any name of that prefix)."""
    exact: set[str] = set()
    prefixes: set[str] = set()
    for path in sorted(folder.glob("*.j2")) if folder is not None else ():
        text = path.read_text(encoding="utf-8")
        for piece in _TEMPLATE_TAG.split(text):
            exact.update(name for name in _IDENTIFIER.findall(piece) if "_" in name.strip("_"))
        for match in re.finditer(r"([A-Za-z_][A-Za-z0-9_]*_)\{\{", text):
            prefixes.add(match[1])
    return ReservedNames(frozenset(exact), tuple(sorted(prefixes)))


class LoadedModule(Protocol):
    """What a backend sees of a loaded module (``gagen.runtime.LoadedModule``, which sits above the
    backends and hands itself to them)."""

    folder: Path
    manifest: dict[str, Any]

    def entry(self, name: str) -> dict[str, Any]:
        """The manifest's entry of kernel ``name``."""
        ...

    def path(self, relative: str) -> Path:
        """``folder / relative``, refused unless it stays inside the folder."""
        ...

    def handle(self, backend: str) -> Any:
        """What backend ``backend`` opened for this module, once; None for one it does not have."""
        ...

    def compile_missing(self) -> None:
        """Compile what the backends compile if the folder has only their sources."""
        ...

    def __getattr__(self, namespace: str) -> Any:
        """A backend's namespace of kernels (``casadi``, ``c``, ``jax``)."""
        ...


class TemplateNotFound(RuntimeError):
    """A backend's template is missing: gagen was installed without its package data."""


@dataclass
class Output:
    """What one backend renders: its files (relative path -> bytes), its entries of the manifest
    (``manifest``: module-wide, e.g. ``{"c_source": "x.c"}``; ``kernels``: per kernel name, e.g.
    ``{"arm0_fk": {"c_name": "x_arm0_fk"}}``)."""

    files: dict[str, bytes]
    manifest: dict[str, Any] = field(default_factory=dict)
    kernels: dict[str, dict[str, Any]] = field(default_factory=dict)


@dataclass
class Context:
    """What every backend renders with besides the ModuleSource: the variables every template gets
    (``name``, ``title``, ``version``, ``source_name``, ``source_hash`` (16 hex digits), ``rebuild``),
    the progress callback, and the renders of the backends before it (``earlier``: by name)."""

    variables: dict[str, Any]
    progress: Progress
    earlier: dict[str, Output] = field(default_factory=dict)


class Backend:
    """One backend: a package ``gagen/codegen/backends/<name>/`` with its templates in ``templates/``,
    registered in ``gagen.codegen.backends``. Subclasses set the attributes and override:

    - ``render(source, context) -> Output`` (required): the files, from the templates through the
      escaping filters (``self.template(name)``); deterministic (same source, same bytes);
    - ``artefacts(folder, manifest)`` and ``compile(folder, manifest)``: what it compiles from its
      files (none by default) and how (raising ``CompileError`` / ``CompilerNotFound``). Compiled
      files are not listed in the manifest; their names carry the module tag;
    - ``open(module)``: a handle the module keeps (a loaded library), after compiling what is missing;
    - ``load(module, kernel)``: the object ``module.<namespace>.<kernel>`` hands out;
    - ``symbols(module, kernel)``: the global names it defines for a kernel (C functions), which the
      build holds unique across the module's kernels before anything is written.
    """

    name: str = ""
    namespace: str | None = None  # the LoadedModule attribute of its kernels, or None
    requires: tuple[str, ...] = ()  # backends it needs in the same module (rendered before it)
    optional: str = ""  # non-empty: a failed compile is a warning, and this says what happens instead
    templates: Path | None = None  # its templates folder

    def render(self, source: ModuleSource, context: Context) -> Output:
        raise NotImplementedError

    def artefacts(self, folder: Path, manifest: Mapping[str, Any]) -> list[Path]:
        return []

    def symbols(self, module: str, kernel: str) -> tuple[str, ...]:
        return ()

    def reserved(self) -> ReservedNames:
        """The names its files use for themselves, which no kernel symbol may meet: every identifier
        written in its templates (``gagen_v``, ``GAGEN_W``), each fragment before a template
        expression as a whole prefix (``gagen_`` of ``gagen_{{ p.name }}``)."""
        return template_names(self.templates)

    def compile(self, folder: Path, manifest: Mapping[str, Any]) -> None:
        return None

    def open(self, module: LoadedModule) -> Any:
        return None

    def load(self, module: LoadedModule, kernel: str) -> Any:
        raise AttributeError(f"the {self.name} backend has no kernels of its own")

    def template(self, name: str) -> jinja2.Template:
        """One of this backend's templates."""
        if self.templates is None:
            raise TemplateNotFound(f"the {self.name} backend has no templates folder")
        return template(self.templates, name)

    def __repr__(self) -> str:
        return f"<gagen backend {self.name}>"


def template(folder: Path, name: str) -> jinja2.Template:
    """The template ``name`` of ``folder``, with the escaping filters (``gagen.codegen.escape``) and
    strict about undefined names."""
    if not (folder / name).is_file():
        raise TemplateNotFound(f"gagen template {name} not found in {folder}: gagen was installed without "
                                "its package data (see [tool.setuptools.package-data] in pyproject.toml)")
    return environment(folder).get_template(name)


@functools.cache
def environment(folder: Path) -> jinja2.Environment:
    """One environment per templates folder: it compiles each template once (and again if edited)."""
    import jinja2

    from gagen.codegen.escape import FILTERS

    env = jinja2.Environment(loader=jinja2.FileSystemLoader(folder), keep_trailing_newline=True,
                             undefined=jinja2.StrictUndefined, autoescape=False)
    env.filters.update(FILTERS)
    return env


def module_name(manifest: Mapping[str, Any]) -> str:
    """The module's name."""
    return str(manifest["module"])


def module_tag(manifest: Mapping[str, Any]) -> str:
    """12 hex digits of a sha256 over the manifest's files and their sha256: what names the compiled
    files of this content (``lib<name>_<tag>.so``, the binding ``_gagen_<name>_<tag>``), so that two
    contents never share a name in one process (dlopen and sys.modules key by it)."""
    digest = hashlib.sha256()
    for path, sha in sorted(manifest["files"].items()):
        digest.update(f"{path}\0{sha}\n".encode())
    return digest.hexdigest()[:12]
