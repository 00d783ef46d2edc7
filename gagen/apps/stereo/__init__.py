"""Stereo symmetry-line pose estimation in CGA [SMC IV]: a calibrated camera pair, generated geometry
kernels (image lines to the object's 3D symmetry axis), an OpenCV front end, a synthetic scene with
ground truth, and the estimate as the sliding-mode controller's reference."""

from gagen.apps.stereo.bundled import BUNDLED
from gagen.apps.stereo.commands import VERBS
from gagen.registry import App, SpecKind

APP = App("stereo", "stereo symmetry-line pose estimation in CGA [SMC IV]",
          spec_kinds=(SpecKind("stereo", "gagen.apps.stereo.kernels:stereo_source"),),
          verbs=VERBS, bundled=BUNDLED, kernel_modules=("gagen.apps.stereo.kernels",))
