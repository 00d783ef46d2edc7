"""Bundled cooperative systems built from the bundled URDFs (until the YAML specs of issue 4 land).

Arms stand on a circle of radius ``ring`` around the origin, each turned to face its centre.
"""

from __future__ import annotations

import math
from functools import cache
from pathlib import Path

from gagen.model.cooperative import Chain, System
from gagen.model.kinematics import Joint
from gagen.robots.urdf import load_chain

ROBOTS = Path(__file__).resolve().parents[2] / "robots"
PANDA_READY = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
IIWA_READY = (0.0, -0.7854, 0.0, 1.3962, 0.0, 0.6109, 0.0)  # [COOP] q0 for the iiwa 14


@cache
def panda_chain() -> tuple[Joint, ...]:
    return tuple(load_chain(ROBOTS / "panda" / "panda.urdf", "panda_link0", "panda_link8"))


@cache
def iiwa_chain() -> tuple[Joint, ...]:
    return tuple(load_chain(ROBOTS / "iiwa14" / "iiwa14.urdf", "iiwa_link_0", "iiwa_link_ee"))


def ring_of_arms(name: str, kind: str, arm: tuple[Joint, ...], count: int, ring: float = 0.8) -> System:
    chains = []
    for i in range(count):
        angle = 2 * math.pi * i / count
        base = Joint(f"base{i}", "fixed", (ring * math.cos(angle), ring * math.sin(angle), 0.0),
                     (0.0, 0.0, angle + math.pi))
        chains.append(Chain(f"arm{i}", (base, *arm)))
    return System(name, kind, tuple(chains))


def bundled_systems() -> dict[str, System]:
    panda, iiwa = panda_chain(), iiwa_chain()
    return {
        "panda_point": ring_of_arms("panda_point", "point", panda, 1),
        "two_pandas_point_pair": ring_of_arms("two_pandas_point_pair", "point_pair", panda, 2),
        "two_iiwas_line": ring_of_arms("two_iiwas_line", "line", iiwa, 2),
        "three_pandas_circle": ring_of_arms("three_pandas_circle", "circle", panda, 3),
        "three_iiwas_plane": ring_of_arms("three_iiwas_plane", "plane", iiwa, 3),
        "four_pandas_sphere": ring_of_arms("four_pandas_sphere", "sphere", panda, 4),
    }


def ready_configuration(system: System) -> list[float]:
    """Each arm at its ready pose (Panda's, or [COOP]'s q0 for the iiwa)."""
    q: list[float] = []
    for chain in system.chains:
        q += list(PANDA_READY if chain.joints[1:] == panda_chain() else IIWA_READY)
    return q
