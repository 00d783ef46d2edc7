"""A robot spec as a module source: ``gagen build robots/<system>.yaml`` builds the kernel catalogue of
the cooperative system it describes (``gagen.apps.cooperative.catalogue.build_kernels``).

The manifest keeps what the control code reads about the system (``system``, ``primitive``, ``dof``,
``joints``) in the source's ``meta``. The kernel graphs are built on first use of ``kernels``: an
up-to-date build (its key is known from the loaded system) never pays for them.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator, Mapping
from pathlib import Path

from gagen import __version__
from gagen.apps.cooperative import APP
from gagen.apps.cooperative.catalogue import build_kernels
from gagen.build import check_identifier
from gagen.codegen.ir import Kernel, ModuleSource
from gagen.errors import read_input
from gagen.robots.spec import load_system
from gagen.robots.system import System


class SystemKernels(Mapping[str, Kernel]):
    """The kernel catalogue of a system, built on first access."""

    def __init__(self, system: System) -> None:
        self.system = system
        self._kernels: dict[str, Kernel] | None = None

    def _all(self) -> dict[str, Kernel]:
        if self._kernels is None:
            self._kernels = build_kernels(self.system)
        return self._kernels

    def __getitem__(self, name: str) -> Kernel:
        return self._all()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._all())

    def __len__(self) -> int:
        return len(self._all())


def system_key(system: System) -> str:
    """What a system's kernels are made from besides gagen's code: the loaded system (every joint constant,
    so URDF edits that change nothing do not rebuild) and gagen's version. The build adds the code: the
    import closure of the modules the application registers as making its kernels (``gagen.code_digest``)."""
    return hashlib.sha256(f"{system!r}\0{__version__}".encode()).hexdigest()


def cooperative_source(spec: str | Path) -> ModuleSource:
    """The module of a robot spec: its system's kernels, named after the system. A malformed spec, or a
    system name that cannot be an identifier, raises ``SpecError``."""
    spec_path = Path(spec)
    system, _ = load_system(spec_path)
    check_identifier(system.name, "system name", spec_path)  # before it names any folder or file
    chains = f"{len(system.chains)} chain{'s' if len(system.chains) != 1 else ''}"
    meta = {"system": system.name, "primitive": system.kind, "dof": system.dof,
            "joints": [f"{r}/{j}" for r, j in system.joint_keys]}
    return ModuleSource(
        name=system.name,
        title=f"kernels of the cooperative system {system.name} ({system.kind}, {chains}, "
              f"{system.dof} joints)",
        kernels=SystemKernels(system),  # built on first use
        source_name=spec_path.name,
        source_hash=hashlib.sha256(read_input(spec_path, "spec")).hexdigest(),
        meta=meta,
        key=system_key(system),
        code=APP.kernel_modules,
        rebuild=f"gagen build {spec_path.name}",
    )
