"""Closed-loop planar linkages in 2D CGA [LINK]: a spec of bodies, ground pivots, revolute and
prismatic joints and a crank (``spec``), the constraints over body motors (``constraints``), their
kernels (``kernels``) and the Lie-algebra Newton solver that follows the crank (``solver``)."""

from gagen.apps.linkage.bundled import BUNDLED
from gagen.apps.linkage.commands import VERBS
from gagen.registry import App, SpecKind

APP = App("linkage", "closed-loop planar linkages in 2D CGA [LINK]",
          spec_kinds=(SpecKind("linkage", "gagen.apps.linkage.kernels:linkage_source"),),
          verbs=VERBS, bundled=BUNDLED, kernel_modules=("gagen.apps.linkage.kernels",))
