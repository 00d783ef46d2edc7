"""gagen: a symbolic code-generation compiler for conformal geometric algebra in robotics.

Subpackages: ``algebra`` (algebra descriptions, exact blade rules, sparse symbolic multivectors),
``symbolic`` (exact scalar layer over CasADi SX / sympy, flattening, op counts), ``interp`` (the
independent dense reference interpreter). ``gagen.load(folder)`` opens a generated module.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from gagen.runtime import GeneratedModule

__version__ = "0.1.0"


def load(folder: str | Path) -> GeneratedModule:
    """The generated module in ``folder`` (any working directory; see ``gagen.runtime``). Imports the
    runtime (numpy, ctypes) on first use, so ``import gagen`` stays cheap."""
    from gagen.runtime import load as _load

    return _load(folder)
