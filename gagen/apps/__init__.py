"""Applications built on the compiler, one package each: a spec schema, its kernel catalogue
(front-end kernels, ``gagen.frontend``), library code and scenario scripts.

- ``cooperative``: cooperative multi-chain systems [COOP]: robot specs (YAML + URDF), the kernel
  catalogue (fk, Jacobians, primitive, similarity, task), goals and the control scenarios.

Mechanisms (hexapod legs, planar linkages) and vision (the stereo symmetry line) come beside it.
"""
