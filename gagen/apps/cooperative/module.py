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
from gagen.apps.cooperative.catalogue import build_kernels
from gagen.apps.cooperative.spec import load_system
from gagen.apps.cooperative.system import System
from gagen.build import check_identifier
from gagen.codegen.ir import Kernel, ModuleSource
from gagen.errors import read_input

PACKAGE = Path(__file__).resolve().parents[2]  # gagen/
# the parts of gagen that take no part in making a system's kernel graphs: every other module is in
# the key (the code generator, gagen/codegen and build.py, is in the build's own key)
NOT_IN_KEY = {"build.py", "codegen", "runtime.py", "cli.py", "check.py", "report.py", "demo.py",
              "apps/cooperative/scenarios.py", "apps/cooperative/nullspace_demo.py",
              "apps/cooperative/goals.py", "apps/cooperative/impedance_demo.py", "apps/cooperative/teleop.py",
              "apps/cooperative/teleop_input.py", "apps/cooperative/mpc_demo.py", "apps/hexapod", "dynamics",
              "viewer", "sweep",
              "crosscheck.py", "goals.py", "conventions.py", "control", "interp"}


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
    """What decides a system's kernels: the loaded system (every joint constant, so URDF edits that
    change nothing do not rebuild), gagen's version and the source of every module that may make
    them (all but ``NOT_IN_KEY``: a new module is in the key until it is known to take no part)."""
    digest = hashlib.sha256()
    digest.update(repr(system).encode())
    digest.update(__version__.encode())
    for module in sorted(PACKAGE.rglob("*.py")):
        name = module.relative_to(PACKAGE).as_posix()
        if not any(name == part or name.startswith(f"{part}/") for part in NOT_IN_KEY):
            digest.update(name.encode() + b"\0" + module.read_bytes())
    return digest.hexdigest()


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
        kernels=SystemKernels(system),  # type: ignore[arg-type]  (a Mapping, built on first use)
        source_name=spec_path.name,
        source_hash=hashlib.sha256(read_input(spec_path, "spec")).hexdigest(),
        meta=meta,
        key=system_key(system),
        rebuild=f"gagen build {spec_path.name}",
    )
