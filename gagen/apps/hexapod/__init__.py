"""Hexapod legs in PGA and CGA [HEX]: a spec of six 3-DOF legs on a body, their kinematics in both
algebras, analytic and numerical IK, ground contact, and a tripod gait.

Modules: ``spec`` (the YAML schema and its loader), ``legs`` (the formulas, over either algebra),
``kernels`` (the kernel catalogue, as front-end kernels), ``module`` (a spec as a module source for
``gagen build``), ``urdf`` (the URDF written from a spec), ``gait`` (the walking demo).
"""

from gagen.apps.hexapod.bundled import BUNDLED
from gagen.apps.hexapod.commands import VERBS
from gagen.registry import App, SpecKind

APP = App("hexapod", "hexapod legs in PGA and CGA [HEX]",
          spec_kinds=(SpecKind("hexapod", "gagen.apps.hexapod.module:hexapod_source"),),
          verbs=VERBS, bundled=BUNDLED, kernel_modules=("gagen.apps.hexapod.module",))
