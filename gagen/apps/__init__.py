"""Applications built on the compiler, one package each: a spec schema, its kernel catalogue
(front-end kernels, ``gagen.frontend``), library code and scenario scripts.

- ``cooperative``: cooperative multi-chain systems [COOP]: robot specs (YAML + URDF), the kernel
  catalogue (fk, Jacobians, primitive, similarity, task), goals and the control scenarios;
- ``hexapod``: hexapod legs in PGA and CGA [HEX]: kinematics, IK, ground contact, a tripod gait;
- ``linkage``: closed-loop planar linkages in 2D CGA [LINK]: constraint kernels, a Lie-algebra
  Newton solver;
- ``stereo``: stereo symmetry-line pose estimation in CGA [SMC IV]: a calibrated rig (YAML), the
  geometry kernels (image lines to the 3D symmetry axis, reprojection, triangulation).

A spec names its application by its top-level ``app`` key (default ``cooperative``);
:func:`spec_source` hands it to that application's module source.
"""

from __future__ import annotations

import importlib
from pathlib import Path

from gagen.codegen.ir import ModuleSource

# app name -> (module, function making the ModuleSource of a spec path)
SPEC_APPS = {"cooperative": ("gagen.apps.cooperative.module", "cooperative_source"),
             "hexapod": ("gagen.apps.hexapod.module", "hexapod_source"),
             "linkage": ("gagen.apps.linkage.kernels", "linkage_source"),
             "stereo": ("gagen.apps.stereo.kernels", "stereo_source")}


def spec_app(path: str | Path) -> str:
    """The application a spec belongs to: its ``app`` key, or ``cooperative``; a SpecError for an
    unknown one (or a malformed document)."""
    from gagen.yaml_document import Document, show

    spec = Document(Path(path), "a mapping (a spec)")
    app = spec.data.get("app", "cooperative")
    if app not in SPEC_APPS:
        raise spec.error("app", f"got {show(app)}; expected one of {', '.join(SPEC_APPS)}")
    return app


def spec_source(path: str | Path) -> ModuleSource:
    """The module source of a spec file, made by its application."""
    module, function = SPEC_APPS[spec_app(path)]
    return getattr(importlib.import_module(module), function)(path)
