"""Applications built on the compiler, one package each; each registers itself in its ``__init__``
(``APP = gagen.registry.App(...)``: spec kinds, verbs, bundled specs, the modules that make its kernels).

- ``cooperative``: cooperative multi-chain systems [COOP]: the kernel catalogue (fk, Jacobians,
  primitive, similarity, task) of a robot spec (``gagen.robots``), goals and the control scenarios;
- ``hexapod``: hexapod legs in PGA and CGA [HEX]: kinematics, IK, ground contact, a tripod gait;
- ``linkage``: closed-loop planar linkages in 2D CGA [LINK]: constraint kernels, a Lie-algebra
  Newton solver;
- ``stereo``: stereo symmetry-line pose estimation in CGA [SMC IV]: a calibrated rig (YAML), the
  geometry kernels (image lines to the 3D symmetry axis, reprojection, triangulation).

A spec names its application by its top-level ``app`` key (default ``cooperative``); ``gagen.build``
hands it to the registered kind. Nothing outside ``gagen/apps`` and ``gagen/cli.py`` imports an
application (a layering contract in pyproject.toml, checked by the tests).
"""
