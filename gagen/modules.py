"""Generated modules built on first use: the one road from a spec or a Python file of kernels to its
loaded module, for every bundled system and for any other file.

Only a representative few modules are committed under the checkout's ``generated/`` (their readable
files: C, headers, the binding, JAX, ``__init__.py``, ``manifest.json``; see ``generated/README.md``).
:func:`module_folder` decides where a module lives and builds it there when it is missing,
incomplete or out of date (``gagen.build``: a no-op when current; builds of one folder wait for each
other on its lock, across threads and processes):

- a file whose module is committed in this checkout (``generated/<name>/manifest.json`` names the
  file and its sha256): that folder. A fresh clone has only its text files, so the first use
  rebuilds it, to the same bytes, adding the CasADi serialisations (``casadi/*.casadi.gz``, never
  committed) and compiling;
- any other file (the other bundled systems, a user's spec, every file of an installed gagen): the
  gagen cache, ``gagen.build.cache_root()/<name>-<key>``, the key over the file's path and bytes
  (the build's own key, kept in the folder, also covers what the file refers to and gagen's code
  generator: an edit of either rebuilds the same folder).

:func:`bundled_module` is the same, loaded (``gagen.runtime.GeneratedModule``), once per process.
"""

from __future__ import annotations

import hashlib
import json
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from gagen.runtime import MANIFEST

if TYPE_CHECKING:
    from gagen.runtime import GeneratedModule

CHECKOUT = Path(__file__).resolve().parents[1]  # the repository root, when gagen runs from a checkout
COMMITTED = CHECKOUT / "generated"  # the committed modules (only in a checkout)


def committed_folder(path: str | Path, name: str) -> Path | None:
    """The checkout's ``generated/<name>`` if the module committed there was generated from ``path``
    as it is (its manifest names the file and its sha256), else None: a changed or another file of
    the same name is built into the cache, and never overwrites a committed module."""
    path, folder = Path(path), COMMITTED / name
    try:
        manifest = json.loads((folder / MANIFEST).read_text())
        if manifest["source"] == path.name and \
                manifest["source_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest():
            return folder
    except (OSError, ValueError, KeyError, TypeError):
        pass
    return None


def cache_folder(path: str | Path, name: str) -> Path:
    """``cache_root()/<name>-<key>``: where the module of ``path`` is built when it is not committed."""
    from gagen.build import cache_root

    path = Path(path).resolve()
    key = hashlib.sha256(str(path).encode() + b"\0" + path.read_bytes()).hexdigest()[:16]
    return cache_root() / f"{name}-{key}"


def _first_use(name: str, folder: Path) -> Callable[[str], None]:
    """A build's progress: one line on stderr when it builds (or waits for another build), else quiet."""
    said = False

    def progress(message: str) -> None:
        nonlocal said
        if not said and "up to date" not in message:
            said = True
            print(f"gagen: building {name} into {folder} (first use, or its source or gagen's code "
                  "generator changed; seconds to a minute)", file=sys.stderr, flush=True)

    return progress


def module_folder(path: str | Path, folder: str | Path | None = None, *,
                  progress: Callable[[str], None] | None = None) -> Path:
    """The folder of the generated module of ``path`` (a spec, or a Python file of kernels named after
    its stem), built there, compiled included, unless it is up to date: ``folder`` if given, else the
    checkout's committed ``generated/<name>`` (:func:`committed_folder`), else the gagen cache
    (:func:`cache_folder`). Raises what ``gagen.build.build`` raises (``SpecError``, ``OutputError``,
    ...)."""
    from gagen.build import build_source, load_source

    source = load_source(path)
    if folder is None:
        folder = committed_folder(path, source.name) or cache_folder(path, source.name)
    folder = Path(folder)
    return build_source(source, folder, progress=progress or _first_use(source.name, folder)).folder


_LOADED: dict[Path, GeneratedModule] = {}
_LOCK = threading.Lock()


def bundled_module(path: str | Path, *, progress: Callable[[str], None] | None = None) -> GeneratedModule:
    """The generated module of ``path`` (a bundled spec, any spec, a Python file of kernels), built on
    first use where :func:`module_folder` says and loaded; the same object for the same file for the
    rest of the process."""
    from gagen.runtime import load

    key = Path(path).resolve()
    with _LOCK:  # (one build per file also when threads ask at once; other processes wait on its lock)
        module = _LOADED.get(key)
        if module is None:
            module = _LOADED[key] = load(module_folder(key, progress=progress))
    return module


__all__ = ["CHECKOUT", "COMMITTED", "bundled_module", "cache_folder", "committed_folder", "module_folder"]
