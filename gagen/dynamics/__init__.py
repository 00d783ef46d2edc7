"""Rigid-body and task-space dynamics of cooperative systems [COOP Sections 3.5, 3.8; Eq. 33-38].

``rigid_body``: the joint-space M(q), C(q, q̇)q̇, g(q) and forward dynamics (ABA) of a whole system
from Pinocchio, built from the spec's URDFs and their inertial parameters. ``task_space``: the
similarity task-space inertia M_Sc, Coriolis C_Sc and gravity g_Sc from those and the generated
kernels (J_G,Sc of ``similarity``, J̇_G,Sc q̇ of ``similarity_rate``).

Pinocchio is the ``dynamics`` extra (``pip install 'gagen[dynamics]'``); importing this package does
not import it.
"""
