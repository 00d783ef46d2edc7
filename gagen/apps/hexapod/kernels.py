"""The kernel catalogue of a hexapod, as front-end kernels (``gagen.kernel``) over PGA and CGA.

Per leg ``<leg>``:

- ``<leg>_fk_pga``, ``<leg>_fk_cga``: q (3) → M (the FK motor), toe (the toe point), p (its position),
  J (3×3 point Jacobian, columns u_j × (p − c_j)), S (6×3 spatial Jacobian, rows vx vy vz wx wy wz);
- ``<leg>_ik``: target (3, body frame) → q_up, q_down (knee up and down), reach (1 or 0), excess (m);
- ``<leg>_dls``: one damped least-squares step q, target, damping → q_next, error.

Per body (legs in spec order, 18 joints):

- ``body_fk_pga``, ``body_fk_cga``: q (18) → p (18 stacked toe positions), J (18×18, block diagonal);
- ``body_ik``: the body's pose (a PGA motor, body → world) and the six toe targets in the world →
  q (18, on the spec's knee branch), reach (6), excess (6);
- ``body_contact_pga``, ``body_contact_cga``: pose, q and the ground plane → each toe's signed
  distance (6) and its foot on the plane (18);
- ``ground_pga``, ``ground_cga``: a plane and a point → signed distance, the foot point, Π ∧ P.

Everything is in the body frame unless it says world. Legs without the planar structure get no
analytic IK kernels (and then there is no ``body_ik``); their numerical IK is ``<leg>_dls``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from gagen.algebra.kinds import kind_blades
from gagen.algebra.protocol import Multivector
from gagen.apps.hexapod.legs import AnalyticIKError, analytic_ik, dls_step, leg_kinematics, planar_signs
from gagen.apps.hexapod.spec import Hexapod, Leg
from gagen.frontend import KernelFunction, matrix, scalars
from gagen.interp import MultiVector, preset
from gagen.model.euclidean import GEOMETRIES

XYZ = ("x", "y", "z")
TWIST = ("vx", "vy", "vz", "wx", "wy", "wz")
ALGEBRAS = {"pga": "pga3d", "cga": "cga3d"}


def analytic(leg: Leg) -> bool:
    try:
        planar_signs(leg)
    except AnalyticIKError:
        return False
    return True


# -- samplers for checks: configurations within the limits, reachable (and some unreachable) targets --

def random_q(hexapod_or_leg: Hexapod | Leg, rng: np.random.Generator) -> np.ndarray:
    legs = hexapod_or_leg.legs if isinstance(hexapod_or_leg, Hexapod) else (hexapod_or_leg,)
    return np.array([rng.uniform(lo, hi) for leg in legs for lo, hi in leg.limits])


def toe_position(leg: Leg, q: Any) -> np.ndarray:
    """The toe in the body frame, on the reference interpreter (PGA)."""
    zero = MultiVector.zero(preset("pga3d"))
    return np.array(leg_kinematics(GEOMETRIES["pga3d"], zero, leg, [float(v) for v in q])["p"])


def _target(leg: Leg, rng: np.random.Generator) -> np.ndarray:
    """Mostly a reachable toe position; one in five pushed out of reach."""
    p = toe_position(leg, random_q(leg, rng))
    if rng.random() < 0.2:
        hip = np.array(leg.xyz)
        p = hip + (p - hip) * rng.uniform(1.5, 3.0)
    return p


def random_pose(rng: np.random.Generator, algebra: str = "pga3d") -> np.ndarray:
    """A body pose near standing (a motor's coefficients, in the algebra's motor order): a few cm up
    or aside of 0.15 m height, turned by up to 0.2 rad."""
    zero = MultiVector.zero(preset(algebra))
    geo = GEOMETRIES[algebra]
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    turn = geo.screw(geo.rotation_generator(zero, list(axis)), rng.uniform(-0.2, 0.2))
    pose = geo.translator(zero, list(rng.uniform(-0.05, 0.05, 3) + np.array([0, 0, 0.15]))) * turn
    return _coefficients(pose, "motor")


def _coefficients(x: Multivector, kind: str) -> np.ndarray:
    return np.array([x[b] for b in kind_blades(x.algebra, kind)])


def _motor(algebra: str, coefficients: np.ndarray) -> MultiVector:
    blades = kind_blades(preset(algebra), "motor")
    return MultiVector.from_blades(preset(algebra), dict(zip(blades, coefficients, strict=True)))


def _plane_sample(algebra: str, rng: np.random.Generator) -> np.ndarray:
    """A random plane (unit normal, offset within 0.3 m), scaled by a random weight."""
    geo = GEOMETRIES[algebra]
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    plane = geo.plane(MultiVector.zero(preset(algebra)), list(n), rng.uniform(-0.3, 0.3))
    return _coefficients(plane * rng.uniform(0.5, 2.0), "plane")


def _point_sample(algebra: str, rng: np.random.Generator) -> np.ndarray:
    geo = GEOMETRIES[algebra]
    point = geo.point(MultiVector.zero(preset(algebra)), list(rng.normal(size=3) * 0.3))
    return _coefficients(point * rng.uniform(0.5, 2.0), "point")


# -- the kernels ---------------------------------------------------------------------------------------

def _kernel(fn: Callable[..., Any], name: str, algebra: str, inputs: dict[str, Any], outputs: dict[str, Any],
            doc: str, sample: Callable[[np.random.Generator], list[np.ndarray]]) -> KernelFunction:
    # J = ∂p/∂q where a kernel returns both: its own formula, held against differences by --check
    jacobians = {"J": ("p", "q")} if {"J", "p"} <= set(outputs) and "q" in inputs else None
    return KernelFunction(fn, algebra=algebra, inputs=inputs, outputs=outputs, name=name, doc=doc,
                          sample=sample, jacobians=jacobians)


def _fk_kernel(leg: Leg, suffix: str) -> KernelFunction:
    algebra = ALGEBRAS[suffix]
    geo = GEOMETRIES[algebra]

    def fk(q: Any, ga: Any) -> dict[str, Any]:
        kin = leg_kinematics(geo, ga, leg, q)
        return {"M": kin["motor"], "toe": kin["toe"], "p": kin["p"], "J": kin["J"], "S": kin["S"]}

    return _kernel(fk, f"{leg.name}_fk_{suffix}", algebra,
                   {"q": scalars(3, leg.joint_names), "ga": "algebra"},
                   {"M": "motor", "toe": "point", "p": scalars(3, XYZ), "J": matrix(scalars(3, XYZ), 3),
                    "S": matrix(scalars(6, TWIST), 3)},
                   f"leg {leg.name} in {algebra.upper()}: FK motor, toe point and position, point and "
                   f"spatial Jacobians",
                   lambda rng: [random_q(leg, rng)])


def _ik_kernel(leg: Leg) -> KernelFunction:
    geo = GEOMETRIES["pga3d"]

    def ik(target: Any, ga: Any) -> dict[str, Any]:
        return analytic_ik(geo, ga, leg, target)

    joints = scalars(3, leg.joint_names)
    return _kernel(ik, f"{leg.name}_ik", "pga3d", {"target": scalars(3, XYZ), "ga": "algebra"},
                   {"q_up": joints, "q_down": joints, "reach": "scalar", "excess": "scalar"},
                   f"leg {leg.name}: analytic IK of a body-frame toe target, knee up and down, with "
                   f"reachability",
                   lambda rng: [_target(leg, rng)])


def _dls_kernel(leg: Leg) -> KernelFunction:
    geo = GEOMETRIES["pga3d"]

    def dls(q: Any, target: Any, damping: Any, ga: Any) -> dict[str, Any]:
        return dls_step(geo, ga, leg, q, target, damping)

    return _kernel(dls, f"{leg.name}_dls", "pga3d",
                   {"q": scalars(3, leg.joint_names), "target": scalars(3, XYZ), "damping": "scalar",
                    "ga": "algebra"},
                   {"q_next": scalars(3, leg.joint_names), "error": "scalar"},
                   f"leg {leg.name}: one damped least-squares IK step towards a body-frame toe target",
                   lambda rng: [random_q(leg, rng), toe_position(leg, random_q(leg, rng)),
                                np.array([rng.uniform(0.01, 0.1)])])


def _stacked_labels(hexapod: Hexapod) -> tuple[str, ...]:
    return tuple(f"{leg.name}_{c}" for leg in hexapod.legs for c in XYZ)


def _body_fk_kernel(hexapod: Hexapod, suffix: str) -> KernelFunction:
    algebra = ALGEBRAS[suffix]
    geo = GEOMETRIES[algebra]
    n = hexapod.dof

    def body_fk(q: Any, ga: Any) -> dict[str, Any]:
        p: list[Any] = []
        columns: list[list[Any]] = []
        for i, leg in enumerate(hexapod.legs):
            kin = leg_kinematics(geo, ga, leg, q[3 * i:3 * i + 3])
            p += kin["p"]
            columns += [[0.0] * (3 * i) + col + [0.0] * (n - 3 * i - 3) for col in kin["J"]]
        return {"p": p, "J": columns}

    return _kernel(body_fk, f"body_fk_{suffix}", algebra,
                   {"q": scalars(n, hexapod.joint_names), "ga": "algebra"},
                   {"p": scalars(n, _stacked_labels(hexapod)),
                    "J": matrix(scalars(n, _stacked_labels(hexapod)), n)},
                   f"all {len(hexapod.legs)} toes in {algebra.upper()}: stacked positions and their "
                   f"{n}×{n} Jacobian",
                   lambda rng: [random_q(hexapod, rng)])


def _world_targets(hexapod: Hexapod, rng: np.random.Generator) -> list[np.ndarray]:
    geo = GEOMETRIES["pga3d"]
    pose = random_pose(rng)
    motor: Multivector = _motor("pga3d", pose)
    toes = [geo.location(motor.sandwich(geo.point(motor, list(_target(leg, rng))))) for leg in hexapod.legs]
    return [pose, np.concatenate(toes)]


def _body_ik_kernel(hexapod: Hexapod) -> KernelFunction:
    geo = GEOMETRIES["pga3d"]
    branch = "q_up" if hexapod.knee == "up" else "q_down"

    def body_ik(pose: Any, toes: Any, ga: Any) -> dict[str, Any]:
        q, reach, excess = [], [], []
        to_body = ~pose
        for i, leg in enumerate(hexapod.legs):
            target = geo.location(to_body.sandwich(geo.point(ga, toes[3 * i:3 * i + 3])))
            solved = analytic_ik(geo, ga, leg, target)
            q += solved[branch]
            reach.append(solved["reach"])
            excess.append(solved["excess"])
        return {"q": q, "reach": reach, "excess": excess}

    legs = tuple(leg.name for leg in hexapod.legs)
    return _kernel(body_ik, "body_ik", "pga3d",
                   {"pose": "motor", "toes": scalars(hexapod.dof, _stacked_labels(hexapod)), "ga": "algebra"},
                   {"q": scalars(hexapod.dof, hexapod.joint_names), "reach": scalars(len(legs), legs),
                    "excess": scalars(len(legs), legs)},
                   f"all legs' analytic IK (knee {hexapod.knee}) for a body pose (PGA motor, body → world) "
                   f"and world toe targets",
                   lambda rng: _world_targets(hexapod, rng))


def _body_contact_kernel(hexapod: Hexapod, suffix: str) -> KernelFunction:
    algebra = ALGEBRAS[suffix]
    geo = GEOMETRIES[algebra]

    def body_contact(pose: Any, q: Any, ground: Any, ga: Any) -> dict[str, Any]:
        distance, feet = [], []
        for i, leg in enumerate(hexapod.legs):
            toe = pose.sandwich(leg_kinematics(geo, ga, leg, q[3 * i:3 * i + 3])["toe"])
            distance.append(geo.signed_distance(ground, toe))
            feet += geo.location(geo.project(ground, toe))
        return {"distance": distance, "feet": feet}

    legs = tuple(leg.name for leg in hexapod.legs)

    def sample(rng: np.random.Generator) -> list[np.ndarray]:
        return [random_pose(rng, algebra), random_q(hexapod, rng), _plane_sample(algebra, rng)]

    return _kernel(body_contact, f"body_contact_{suffix}", algebra,
                   {"pose": "motor", "q": scalars(hexapod.dof, hexapod.joint_names), "ground": "plane",
                    "ga": "algebra"},
                   {"distance": scalars(len(legs), legs),
                    "feet": scalars(hexapod.dof, _stacked_labels(hexapod))},
                   f"each toe's signed distance from the ground plane and its foot on it ({algebra.upper()})",
                   sample)


def _ground_kernel(suffix: str) -> KernelFunction:
    algebra = ALGEBRAS[suffix]
    geo = GEOMETRIES[algebra]

    def ground(plane: Any, toe: Any) -> dict[str, Any]:
        return {"distance": geo.signed_distance(plane, toe), "foot": geo.project(plane, toe),
                "incidence": geo.incidence(plane, toe)}

    def sample(rng: np.random.Generator) -> list[np.ndarray]:
        return [_plane_sample(algebra, rng), _point_sample(algebra, rng)]

    return _kernel(ground, f"ground_{suffix}", algebra, {"plane": "plane", "toe": "point"},
                   {"distance": "scalar", "foot": "point", "incidence": "scalar"},
                   f"a point against a plane in {algebra.upper()}: signed distance, foot of the "
                   f"perpendicular and the incidence Π ∧ P",
                   sample)


def hexapod_kernels(hexapod: Hexapod) -> list[KernelFunction]:
    """Every kernel of the hexapod's module, in a stable order."""
    kernels: list[KernelFunction] = []
    for leg in hexapod.legs:
        kernels += [_fk_kernel(leg, "pga"), _fk_kernel(leg, "cga")]
        if analytic(leg):
            kernels.append(_ik_kernel(leg))
        kernels.append(_dls_kernel(leg))
    kernels += [_body_fk_kernel(hexapod, "pga"), _body_fk_kernel(hexapod, "cga")]
    if all(analytic(leg) for leg in hexapod.legs):
        kernels.append(_body_ik_kernel(hexapod))
    kernels += [_body_contact_kernel(hexapod, "pga"), _body_contact_kernel(hexapod, "cga"),
                _ground_kernel("pga"), _ground_kernel("cga")]
    return kernels
