"""Robots: URDF import of kinematic chains and (later) the bundled robot specs."""
