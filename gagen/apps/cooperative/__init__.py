"""Cooperative multi-chain systems [COOP]: the end points of n chains span a primitive whose
similarity to a unit primitive is the task space.

The multi-chain robot itself (chains, the System, its YAML spec) is a library concept, in
``gagen.robots``. Here: ``catalogue`` (the kernels, as front-end kernels), ``module`` (a spec as a
module source for ``gagen build``), ``check`` (``gagen build --check`` of such a module), ``bundled``
(the bundled systems in robots/), ``dual_task`` (the two-chain dual task space), ``scenarios``,
``nullspace_demo``, ``impedance_demo``, ``mpc_demo`` and ``teleop`` (the paper's scenarios on the
generated kernels), ``commands`` (their verbs).
"""

from pathlib import Path

from gagen.apps.cooperative.commands import VERBS
from gagen.registry import App, SpecKind

APP = App("cooperative", "cooperative multi-chain systems [COOP]",
          spec_kinds=(SpecKind("cooperative", "gagen.apps.cooperative.module:cooperative_source",
                               check="gagen.apps.cooperative.check:check_spec"),),
          verbs=VERBS, bundled=Path(__file__).resolve().parent / "robots",  # = bundled.ROBOTS
          kernel_modules=("gagen.apps.cooperative.module",))
