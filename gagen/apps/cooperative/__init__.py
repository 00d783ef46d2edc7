"""Cooperative multi-chain systems [COOP]: the end points of n chains span a primitive whose
similarity to a unit primitive is the task space.

Modules: ``system`` (chains, the System and its formulas), ``spec`` (the YAML schema and its
loader), ``bundled`` (the bundled systems in robots/), ``catalogue`` (the kernels, as front-end
kernels), ``module`` (a spec as a module source for ``gagen build``), ``goals`` (desired
primitives), ``scenarios`` and ``nullspace_demo`` (the paper's scenarios on the generated kernels).
"""
