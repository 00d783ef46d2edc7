"""A hexapod spec as a module source: ``gagen build hexapod.yaml`` builds its kernel catalogue
(``gagen.apps.hexapod.kernels``) into ``generated/<name>/``, with what the walking code reads about
the robot (legs, joints, limits, knee branch) in the manifest."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from gagen.apps.hexapod.kernels import hexapod_kernels
from gagen.apps.hexapod.spec import load_hexapod
from gagen.build import check_identifier
from gagen.codegen.ir import ModuleSource
from gagen.errors import read_input
from gagen.frontend import source_of


def hexapod_source(spec: str | Path) -> ModuleSource:
    """The module of a hexapod spec, named after the hexapod. A malformed spec raises ``SpecError``."""
    path = Path(spec)
    hexapod = load_hexapod(path)
    check_identifier(hexapod.name, "hexapod name", path)
    source = source_of(hexapod_kernels(hexapod), hexapod.name, path.name, read_input(path, "spec"),
                       f"gagen build {path.name}")
    meta = {**source.meta, "app": "hexapod", "knee": hexapod.knee, "joints": hexapod.joint_names,
            "legs": [leg.name for leg in hexapod.legs],
            "limits": [list(limit) for leg in hexapod.legs for limit in leg.limits]}
    title = (f"kernels of {hexapod.name}, a hexapod ({len(hexapod.legs)} legs, {hexapod.dof} joints; "
             f"PGA and CGA)")
    return dataclasses.replace(source, title=title, meta=meta)
