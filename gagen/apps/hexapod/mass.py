"""The hexapod's mass model: a uniform box for the body and a uniform solid rod (cylinder) per leg link,
with the masses, sizes and centre of mass the physics code (statics, the MuJoCo walk) shares.

The default (:func:`default_mass_model`), plausible for a small servo-driven hexapod of ~2.5 kg:

- body: 1.0 kg, a box as long and wide as the hips' span (the bundled hexapod: 0.2078 × 0.24 m) and
  ``BODY_HEIGHT`` = 0.05 m tall, centred on the body frame's origin;
- each leg: coxa (l1) 0.10 kg, femur (l2) 0.10 kg, tibia (l3) 0.05 kg, uniform rods of radius
  ``LINK_RADIUS`` = 0.012 m from one joint centre to the next (the tibia to the toe); the coxa is the
  heaviest per metre because it carries the hip servos.

Total 2.5 kg. A link's centre is the midpoint of its segment, carried by the leg's chain at q
(:func:`gagen.apps.hexapod.gait.joint_points`, a matrix chain that matches the generated FK).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gagen.apps.hexapod.spec import Hexapod

Array = NDArray[np.float64]
Vec = tuple[float, float, float]

BODY_MASS = 1.0  # kg
BODY_HEIGHT = 0.05  # m
LINK_MASSES: Vec = (0.10, 0.10, 0.05)  # kg: coxa, femur, tibia
LINK_RADIUS = 0.012  # m


@dataclass(frozen=True)
class MassModel:
    """Body box (mass kg, full size x, y, z m, centre in the body frame) and per leg (spec order) the
    masses of its coxa, femur and tibia (uniform rods of ``link_radius`` m along the leg's segments)."""

    body_mass: float
    body_size: Vec
    link_masses: tuple[Vec, ...]
    body_centre: Vec = (0.0, 0.0, 0.0)
    link_radius: float = LINK_RADIUS

    def __post_init__(self) -> None:
        values = [("body_mass", self.body_mass), ("link_radius", self.link_radius),
                  *((f"body_size[{i}]", v) for i, v in enumerate(self.body_size)),
                  *((f"link_masses[{i}][{j}]", m) for i, leg in enumerate(self.link_masses)
                    for j, m in enumerate(leg))]
        for name, value in values:
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"mass model {name}: expected a finite number > 0, got {value!r}")
        if len(self.body_size) != 3 or any(len(leg) != 3 for leg in self.link_masses):
            raise ValueError("mass model: body_size needs 3 numbers and each leg 3 link masses")
        if not all(math.isfinite(c) for c in self.body_centre):
            raise ValueError(f"mass model body_centre: expected finite numbers, got {self.body_centre!r}")


def default_mass_model(hexapod: Hexapod) -> MassModel:
    """The documented default (module docstring): the body box spans the hips in x and y."""
    span = [2 * max(abs(leg.xyz[k]) for leg in hexapod.legs) for k in (0, 1)]
    size = (span[0] or 0.1, span[1] or 0.1, BODY_HEIGHT)
    return MassModel(BODY_MASS, size, (LINK_MASSES,) * len(hexapod.legs))


def total_mass(model: MassModel) -> float:
    return model.body_mass + sum(sum(leg) for leg in model.link_masses)


def box_inertia(mass: float, size: Vec) -> Vec:
    """Principal moments of a uniform box about its centre (along its edges)."""
    a, b, c = size
    return mass * (b * b + c * c) / 12, mass * (a * a + c * c) / 12, mass * (a * a + b * b) / 12


def rod_inertia(mass: float, length: float, radius: float) -> Vec:
    """Principal moments of a uniform solid cylinder along x about its centre."""
    across = mass * (3 * radius * radius + length * length) / 12
    return mass * radius * radius / 2, across, across


def link_centres(hexapod: Hexapod, q: Array) -> Array:
    """The centres of every leg's three links (6×3×3, body frame) at joint angles ``q`` (18,)."""
    from gagen.apps.hexapod.gait import joint_points

    q = np.asarray(q, dtype=float).reshape(-1)
    if q.shape != (hexapod.dof,):
        raise ValueError(f"q: expected {hexapod.dof} joint angles, got shape {q.shape}")
    points = joint_points(hexapod, q)[0]  # legs × (hip, thigh joint, knee, toe) × 3
    centres: Array = (points[:, :-1] + points[:, 1:]) / 2
    return centres


def centre_of_mass(hexapod: Hexapod, model: MassModel, pose_matrix: Array, q: Array) -> Array:
    """The whole robot's centre of mass (3,) in the world, for the body pose ``pose_matrix`` (4×4,
    body → world) and joint angles ``q`` (18,)."""
    pose = np.asarray(pose_matrix, dtype=float)
    if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
        raise ValueError(f"pose_matrix: expected a finite 4x4 body->world transform, got shape {pose.shape}")
    if len(model.link_masses) != len(hexapod.legs):
        raise ValueError(f"mass model has {len(model.link_masses)} legs, the hexapod {len(hexapod.legs)}")
    masses = np.array(model.link_masses)  # legs × 3
    weighted = (masses[:, :, None] * link_centres(hexapod, q)).sum(axis=(0, 1))
    local = (weighted + model.body_mass * np.array(model.body_centre)) / total_mass(model)
    com: Array = pose[:3, :3] @ local + pose[:3, 3]
    return com


__all__ = ["MassModel", "box_inertia", "centre_of_mass", "default_mass_model", "link_centres",
           "rod_inertia", "total_mass"]
