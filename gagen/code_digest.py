"""The part of a cache key that covers gagen's own code: the sources of the modules that make a module's
kernels and of every gagen module they import, found by reading their import statements.

A module's import runs its top-level imports and its packages' ``__init__`` files, so those are followed;
an import inside a function runs only when that function does, so it is followed only where the importing
module is itself one of the named ones (the application's kernel-making module: its functions are the
ones the build calls). Editing any other module (a demo, a plot, another application) leaves the key, and
so the cached build, as it is; editing anything the kernels are made from changes it.
"""

from __future__ import annotations

import ast
import hashlib
from collections.abc import Iterable
from functools import cache
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent  # gagen/
ROOT = "gagen"


def module_file(name: str) -> Path | None:
    """The source file of gagen module ``name`` (a package's ``__init__.py``), or None if there is none."""
    if name != ROOT and not name.startswith(ROOT + "."):
        return None
    relative = PACKAGE.joinpath(*name.split(".")[1:])
    if (relative / "__init__.py").is_file():
        return relative / "__init__.py"
    path = relative.with_suffix(".py")
    return path if path.is_file() else None


def _imported(node: ast.AST) -> list[str]:
    """The gagen modules an import statement names (``from a import b``: ``a.b`` where b is a module)."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
        names = [node.module]
        names += [f"{node.module}.{alias.name}" for alias in node.names
                  if module_file(f"{node.module}.{alias.name}") is not None]
        return names
    return []


def _type_checking(node: ast.If) -> bool:
    return isinstance(node.test, ast.Name | ast.Attribute) and "TYPE_CHECKING" in ast.unparse(node.test)


@cache
def _imports(name: str, inside_functions: bool) -> tuple[str, ...]:
    """The gagen modules ``name`` imports when it is imported (and, with ``inside_functions``, when any of
    its functions run)."""
    path = module_file(name)
    if path is None:
        return ()
    found: list[str] = []

    def visit(nodes: Iterable[ast.stmt]) -> None:
        for node in nodes:
            if isinstance(node, ast.If) and _type_checking(node):
                continue  # annotations only
            if isinstance(node, ast.Import | ast.ImportFrom):
                found.extend(m for m in _imported(node) if module_file(m) is not None)
            elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                if inside_functions:
                    visit(node.body)
            elif isinstance(node, ast.ClassDef | ast.If | ast.Try | ast.With | ast.For | ast.While):
                for field in ("body", "orelse", "finalbody", "handlers"):
                    for child in getattr(node, field, []):
                        visit(child.body if isinstance(child, ast.ExceptHandler) else [child])

    visit(ast.parse(path.read_bytes(), str(path)).body)
    return tuple(dict.fromkeys(found))


def _parents(name: str) -> list[str]:
    parts = name.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts))]


def import_closure(modules: Iterable[str]) -> list[Path]:
    """The source files of ``modules`` and of every gagen module importing them runs (see the module
    docstring), sorted."""
    named = list(modules)
    seen: set[str] = set()
    todo = [(name, True) for name in named]
    while todo:
        name, functions = todo.pop()
        if name in seen or module_file(name) is None:
            continue
        seen.add(name)
        todo += [(parent, False) for parent in _parents(name)]
        todo += [(child, False) for child in _imports(name, functions)]
    return sorted(path for path in (module_file(name) for name in seen) if path is not None)


def code_digest(modules: Iterable[str]) -> str:
    """A sha256 over the import closure of ``modules``: each file's path within gagen and its bytes."""
    digest = hashlib.sha256()
    for path in import_closure(modules):
        digest.update(path.relative_to(PACKAGE).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()
