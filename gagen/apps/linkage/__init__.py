"""Closed-loop planar linkages in 2D CGA [LINK]: a spec of bodies, ground pivots, revolute and
prismatic joints and a crank (``spec``), the constraints over body motors (``constraints``), their
kernels (``kernels``) and the Lie-algebra Newton solver that follows the crank (``solver``)."""
