"""Resource limits on every input: how large a robot, formula, linkage or image gagen accepts.

A limit bounds the work an input can ask for (a 1000-joint chain, a formula input of 10⁶ scalars), so
a hostile or mistaken file is refused in one line instead of running for minutes. The defaults are
generous for every real robot (a 60-joint humanoid) and every bundled example; each is raised for one
run with the environment variable ``GAGEN_LIMIT_<NAME>`` (``GAGEN_LIMIT_JOINTS_PER_CHAIN=500``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from gagen.errors import SpecError


@dataclass(frozen=True)
class Limit:
    """One bound: its name (the environment variable's tail), default and the thing it counts."""

    name: str
    default: int
    counts: str  # plural noun phrase: "joints in one chain"

    @property
    def variable(self) -> str:
        return f"GAGEN_LIMIT_{self.name.upper()}"


LIMITS: dict[str, Limit] = {limit.name: limit for limit in (
    Limit("joints_per_chain", 100, "joints in one chain"),
    Limit("joints_per_system", 400, "joints in one system"),
    Limit("chains", 32, "chains in one system"),
    Limit("formula_scalars", 4096, "scalars in one kernel input"),
    Limit("kernel_nodes", 2_000_000, "expression nodes in one kernel"),
    Limit("linkage_bodies", 100, "bodies in one linkage"),
    Limit("linkage_joints", 200, "joints in one linkage"),
    Limit("hexapod_legs", 16, "legs in one walker"),
    Limit("image_pixels", 16384, "pixels along an image side"),
)}


def limit(name: str) -> int:
    """The limit ``name``: its environment override where set (a positive integer), else the default."""
    entry = LIMITS[name]
    text = os.environ.get(entry.variable, "").strip()
    if not text:
        return entry.default
    try:
        value = int(text.replace("_", ""))
    except ValueError:
        value = 0
    if value < 1:
        raise ValueError(f"{entry.variable}={text!r}: expected a positive integer (the limit on "
                         f"{entry.counts}; default {entry.default})")
    return value


def over_limit(name: str, count: int) -> str | None:
    """The one-line complaint when ``count`` passes the limit ``name``, else None."""
    bound = limit(name)
    if count <= bound:
        return None
    entry = LIMITS[name]
    return (f"{count} {entry.counts}, over the limit of {bound} "
            f"(set {entry.variable} to raise it)")


def check_limit(name: str, count: int, file: str | Path, field: str) -> None:
    """Raise a SpecError naming ``file`` and ``field`` when ``count`` passes the limit ``name``."""
    problem = over_limit(name, count)
    if problem:
        raise SpecError(file, field, problem)
