"""The robot as a library concept: a multi-chain system and where it comes from.

- ``system``: ``Chain`` and ``System`` (chains whose end points span a primitive; joint keys, shared
  and mimic joints, splitting q) and the formulas over them written once against the multivector
  protocol (end points, the cooperative primitive and its Jacobian, the similarity, the task error);
- ``spec``: the YAML spec of a system (``load_system``) with strict, located errors;
- ``urdf``: kinematic chains from URDF files;
- ``points``: the chains' end points from a system's generated module.

Every layer above (``check``, ``control``, ``dynamics``, ``viewer``, ``sweep``, the applications) uses
these; nothing here imports an application.
"""
