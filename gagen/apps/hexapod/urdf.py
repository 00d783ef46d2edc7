"""A hexapod as URDF, written from the same numbers as its spec, so outside tools (Pinocchio, viewers)
load the robot the kernels describe.

The tree: ``base_link``, and per leg ``<leg>``

- revolute ``<leg>_yaw``: base_link → ``<leg>_coxa``, origin the mount (xyz, rpy), axis axes[0];
- revolute ``<leg>_thigh``: → ``<leg>_femur``, origin (l1, 0, 0), axis axes[1];
- revolute ``<leg>_knee``: → ``<leg>_tibia``, origin (l2, 0, 0), axis axes[2];
- fixed ``<leg>_toe``: → ``<leg>_foot``, origin (l3, 0, 0): the toe frame.

This is the chain of :mod:`gagen.apps.hexapod.legs` (joint j turns about axes[j] through the centre
c_j of the hip frame; the axes of the spec are relative to the hip frame, and the joint frames here
are only translated from it, so they are the same directions). Joint limits are the spec's; the
inertials are the mass model's (:mod:`gagen.apps.hexapod.mass`: a uniform box for the body, uniform
rods for the links, the foot frames massless), so a dynamics library or a simulator loading the file
has the robot the statics and the MuJoCo walk use; effort and velocity are placeholders, the visuals
the same box and rods. The output is deterministic (the same hexapod gives the same bytes) and every
number is printed with ``repr`` precision, so a parser reads back exactly the spec's doubles.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from xml.sax.saxutils import quoteattr

from gagen.apps.hexapod.mass import MassModel, box_inertia, default_mass_model, rod_inertia
from gagen.apps.hexapod.spec import Hexapod, Leg

EFFORT = 10.0  # N m: placeholder
VELOCITY = 5.0  # rad/s: placeholder
FOOT_RADIUS = 0.01  # m: visual radius of a (massless) foot
HALF_PI = math.pi / 2


def _num(value: float) -> str:
    return repr(float(value))


def _vec(values: Iterable[float]) -> str:
    return " ".join(_num(v) for v in values)


def _attrs(**values: str) -> str:
    return "".join(f" {key}={quoteattr(value)}" for key, value in values.items())


def _inertial(mass: float, centre: Sequence[float], inertia: Sequence[float]) -> list[str]:
    ixx, iyy, izz = inertia
    moments = _attrs(ixx=_num(ixx), ixy="0.0", ixz="0.0", iyy=_num(iyy), iyz="0.0", izz=_num(izz))
    return ["    <inertial>",
            f"      <origin{_attrs(xyz=_vec(centre), rpy='0.0 0.0 0.0')}/>",
            f"      <mass{_attrs(value=_num(mass))}/>",
            f"      <inertia{moments}/>",
            "    </inertial>"]


def _rod_link(name: str, length: float, mass: float, radius: float) -> list[str]:
    """A link along +x of its frame from 0 to ``length``: a uniform rod's inertia, a cylinder to show."""
    centre = (length / 2, 0.0, 0.0)
    return [f"  <link{_attrs(name=name)}>",
            *_inertial(mass, centre, rod_inertia(mass, length, radius)),
            "    <visual>",
            # a URDF cylinder runs along z: turned onto x
            f"      <origin{_attrs(xyz=_vec(centre), rpy=_vec((0.0, HALF_PI, 0.0)))}/>",
            f"      <geometry><cylinder{_attrs(radius=_num(radius), length=_num(length))}/></geometry>",
            "    </visual>",
            "  </link>"]


def _foot_link(name: str) -> list[str]:
    """The toe frame: no inertial (massless; dynamics libraries merge it into the tibia)."""
    return [f"  <link{_attrs(name=name)}>",
            "    <visual>",
            f"      <geometry><sphere{_attrs(radius=_num(FOOT_RADIUS))}/></geometry>",
            "    </visual>",
            "  </link>"]


def _body_link(mass: MassModel) -> list[str]:
    return ["  <link name=\"base_link\">",
            *_inertial(mass.body_mass, mass.body_centre, box_inertia(mass.body_mass, mass.body_size)),
            "    <visual>",
            f"      <origin{_attrs(xyz=_vec(mass.body_centre), rpy='0.0 0.0 0.0')}/>",
            f"      <geometry><box{_attrs(size=_vec(mass.body_size))}/></geometry>",
            "    </visual>",
            "  </link>"]


def _joint(name: str, kind: str, parent: str, child: str, xyz: Sequence[float], rpy: Sequence[float],
           axis: Sequence[float] | None = None, limits: Sequence[float] | None = None) -> list[str]:
    lines = [f"  <joint{_attrs(name=name, type=kind)}>",
             f"    <origin{_attrs(xyz=_vec(xyz), rpy=_vec(rpy))}/>",
             f"    <parent{_attrs(link=parent)}/>",
             f"    <child{_attrs(link=child)}/>"]
    if axis is not None:
        lines.append(f"    <axis{_attrs(xyz=_vec(axis))}/>")
    if limits is not None:
        lower, upper = limits
        bounds = _attrs(lower=_num(lower), upper=_num(upper), effort=_num(EFFORT), velocity=_num(VELOCITY))
        lines.append(f"    <limit{bounds}/>")
    lines.append("  </joint>")
    return lines


def _leg(leg: Leg, masses: Sequence[float], radius: float) -> list[str]:
    l1, l2, l3 = leg.lengths
    yaw, thigh, knee = leg.joint_names
    coxa, femur, tibia, foot = (f"{leg.name}_{part}" for part in ("coxa", "femur", "tibia", "foot"))
    zero = (0.0, 0.0, 0.0)
    return [*_rod_link(coxa, l1, masses[0], radius), *_rod_link(femur, l2, masses[1], radius),
            *_rod_link(tibia, l3, masses[2], radius), *_foot_link(foot),
            *_joint(yaw, "revolute", "base_link", coxa, leg.xyz, leg.rpy, leg.axes[0], leg.limits[0]),
            *_joint(thigh, "revolute", coxa, femur, (l1, 0.0, 0.0), zero, leg.axes[1], leg.limits[1]),
            *_joint(knee, "revolute", femur, tibia, (l2, 0.0, 0.0), zero, leg.axes[2], leg.limits[2]),
            *_joint(f"{leg.name}_toe", "fixed", tibia, foot, (l3, 0.0, 0.0), zero)]


def write_urdf(hexapod: Hexapod, mass: MassModel | None = None) -> str:
    """The hexapod's URDF text (ends with a newline), with the inertials of ``mass`` (default: the
    documented :func:`~gagen.apps.hexapod.mass.default_mass_model`)."""
    mass = mass or default_mass_model(hexapod)
    if len(mass.link_masses) != len(hexapod.legs):
        raise ValueError(f"mass model has {len(mass.link_masses)} legs, the hexapod {len(hexapod.legs)}")
    lines = ["<?xml version=\"1.0\"?>",
             "<!-- Written by gagen.apps.hexapod.urdf from the hexapod spec (write_urdf): the kinematics are",
             "     the spec's numbers, the inertials gagen.apps.hexapod.mass's model; effort and velocity",
             "     limits are placeholders. -->",
             f"<robot{_attrs(name=hexapod.name)}>",
             *_body_link(mass)]
    for leg, masses in zip(hexapod.legs, mass.link_masses, strict=True):
        # a spec's leg names are identifiers, which cannot break a comment; other names go unnamed
        lines += ["", f"  <!-- leg {leg.name if leg.name.isidentifier() else ''} -->",
                  *_leg(leg, masses, mass.link_radius)]
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


__all__ = ["write_urdf"]
