"""Optional dependencies: which extra of ``pip install 'gagen[...]'`` brings each, and the one-line error
that says so, wherever a missing one is met (a verb, a flag such as ``--view``, a library import)."""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Iterable
from types import ModuleType

EXTRAS = {
    "viser": "viewer",
    "dask": "sweep",
    "distributed": "sweep",
    "pyarrow": "sweep",
    "tqdm": "sweep",
    "pinocchio": "dynamics",
    "crocoddyl": "ocp",
    "mujoco": "sim",
    "pyspacemouse": "teleop",
    "jax": "jax",
    "jaxlib": "jax",
    "cupy": "cuda",
    "proxsuite": "statics",
}
"""Top-level module -> the extra that installs it (``all`` installs every one)."""


class MissingExtra(ModuleNotFoundError):
    """An optional dependency that is not installed: ``<what> needs <module>: pip install 'gagen[<extra>]'``
    (a ModuleNotFoundError, so ``except ImportError`` still catches it)."""

    def __init__(self, module: str, what: str) -> None:
        root = module.split(".")[0]
        extra = EXTRAS.get(root)
        how = f"pip install 'gagen[{extra}]'" if extra else f"pip install {root}"
        super().__init__(f"{what} needs {root}, which is not installed: {how} (or 'gagen[all]')", name=root)


def installed(module: str) -> bool:
    """Whether ``module`` can be imported (found on the path; not imported)."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # a parent package missing, or a finder that refuses it
        return False


def require(module: str, what: str) -> ModuleType:
    """``module`` imported, or MissingExtra naming the extra that brings it (``what``: who needs it)."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as e:
        if e.name is not None and e.name.split(".")[0] in EXTRAS:
            raise MissingExtra(e.name, what) from e
        raise


def check(modules: Iterable[str], what: str) -> None:
    """MissingExtra for the first of ``modules`` that is not installed (nothing is imported)."""
    for module in modules:
        if not installed(module):
            raise MissingExtra(module, what)


def optional_missing(error: BaseException) -> bool:
    """Whether ``error`` is a missing optional dependency (a module of ``EXTRAS``, or a MissingExtra)."""
    if isinstance(error, MissingExtra):
        return True
    return isinstance(error, ModuleNotFoundError) and error.name is not None \
        and error.name.split(".")[0] in EXTRAS
