"""The paper's reaching scenarios [COOP Section 4.2, Figs. 7-13] as data: which bundled system, and the
similarity that moves its ready primitive to the target (``scenarios`` solves them; kept apart so that the
command line lists them without importing the solvers)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Scenario:
    """A system and the similarity that moves its ready primitive to the target (see ``target_from``):
    ``translation`` (m), ``rotation`` = (world axis, angle in rad) about the primitive's reference
    point, ``dilation`` about it (rounds only)."""

    name: str
    system: str
    title: str
    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[tuple[float, float, float], float] | None = None
    dilation: float = 1.0


SCENARIOS: dict[str, Scenario] = {
    "line": Scenario("line", "g1_arms_line", "Unitree G1 arms (17 DOF) reaching a line [COOP Fig. 7]",
                     translation=(0.05, 0.0, 0.1), rotation=((0.0, 0.0, 1.0), 0.3)),
    "circle": Scenario("circle", "three_pandas_circle",
                       "three Franka Pandas (21 DOF) reaching a larger circle [COOP Fig. 8]",
                       translation=(0.0, 0.0, 0.1), rotation=((1.0, 0.0, 0.0), 0.2), dilation=1.3),
    "torso_circle": Scenario("torso_circle", "g1_torso_circle",
                             "Unitree G1 torso point and hands (17 DOF) reaching a smaller, turned circle "
                             "[COOP Fig. 9]", rotation=((0.0, 0.0, 1.0), 0.1), dilation=0.9),
    "collaboration_circle": Scenario("collaboration_circle", "panda_g1_circle",
                                     "a Franka Panda and a Unitree G1 (24 DOF) lifting, tilting and "
                                     "enlarging a circle together [COOP Fig. 10]",
                                     translation=(0.0, 0.0, 0.05), rotation=((1.0, 0.0, 0.0), 0.2),
                                     dilation=1.1),
    "plane": Scenario("plane", "leap_three_fingers_plane",
                      "LEAP Hand, three fingers (12 DOF), reaching a plane [COOP Fig. 11]",
                      translation=(0.0, 0.0, 0.01), rotation=((1.0, 0.0, 0.0), 0.2)),
    "hand_sphere": Scenario("hand_sphere", "leap_hand_sphere",
                            "LEAP Hand, four fingers (16 DOF), reaching a smaller sphere [COOP Fig. 12]",
                            translation=(0.01, 0.0, 0.0), dilation=0.85),
    "humanoids_sphere": Scenario("humanoids_sphere", "two_g1_sphere",
                                 "two Unitree G1s (34 DOF) reaching a sphere [COOP Fig. 13]",
                                 translation=(0.0, 0.0, 0.1), dilation=1.15),
}
