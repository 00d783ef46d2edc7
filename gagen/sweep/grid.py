"""Regular configuration grids: chosen joints on evenly spaced values within their limits, the others at a
fixed configuration, enumerated by one flat index so that any range of it (a chunk) is made alone.

A grid is written ``JOINT=COUNT`` (COUNT values from the joint's lower to its upper limit, both included)
or ``JOINT=COUNT:LOW:HIGH`` (a sub-range, within the limits), several joined by commas; JOINT is the
joint's label as the module's manifest lists it (``arm0/panda_joint2``) or its 0-based index in q. The
flat index runs over the axes in the order given, the last fastest (C order, as ``numpy.unravel_index``),
so ``1=3,4=2`` visits (q1, q4) = (l, l'), (l, h'), (m, l'), … .
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gagen.sweep.store import SweepError

MAX_POINTS = 10**9
"""The largest grid accepted (≈ 3 h of the manipulability sweep on one core): a typo such as 100 points on
each of 7 joints (1e14) is refused before any work, not discovered as a sweep that never ends."""


@dataclass(frozen=True)
class Axis:
    """One joint of a grid: ``count`` ≥ 2 evenly spaced values from ``lower`` to ``upper`` (both
    included) for entry ``joint`` of q, whose label is ``name``."""

    joint: int
    name: str
    count: int
    lower: float
    upper: float

    def values(self) -> NDArray[np.float64]:
        return np.linspace(self.lower, self.upper, self.count)


def _fail(message: str) -> SweepError:
    return SweepError(f"grid: {message}")


def _joint(text: str, labels: Sequence[str]) -> int:
    if text.isascii() and text.isdigit():
        if int(text) >= len(labels):
            raise _fail(f"joint index {text} is out of range: the system has {len(labels)} joints "
                        f"(0 … {len(labels) - 1})")
        return int(text)
    if text not in labels:
        shown = ", ".join(labels[:4]) + (", …" if len(labels) > 4 else "")
        raise _fail(f"expected a joint label ({shown}) or a 0-based index, got {text!r}")
    return list(labels).index(text)


def _number(text: str, what: str, item: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise _fail(f"expected a finite {what} in {item!r}, got {text!r}")
    return value


def _axis(item: str, labels: Sequence[str], lower: Sequence[float], upper: Sequence[float]) -> Axis:
    joint_text, equals, rest = item.partition("=")
    if not equals or not joint_text.strip() or not rest.strip():
        raise _fail(f"expected JOINT=COUNT or JOINT=COUNT:LOW:HIGH, got {item!r}")
    joint = _joint(joint_text.strip(), labels)
    parts = [p.strip() for p in rest.split(":")]
    if len(parts) not in (1, 3):
        raise _fail(f"expected JOINT=COUNT or JOINT=COUNT:LOW:HIGH, got {item!r}")
    try:
        count = int(parts[0])
    except ValueError:
        raise _fail(f"expected an integer count ≥ 2 in {item!r}, got {parts[0]!r}") from None
    if count < 2:
        raise _fail(f"expected a count ≥ 2 in {item!r} (a joint left out of the grid stays fixed), "
                    f"got {count}")
    low, high = lower[joint], upper[joint]
    if len(parts) == 3:
        low, high = _number(parts[1], "LOW", item), _number(parts[2], "HIGH", item)
        if not low < high:
            raise _fail(f"expected LOW < HIGH in {item!r}")
        if low < lower[joint] or high > upper[joint]:
            raise _fail(f"{item!r} leaves the limits of {labels[joint]} [{lower[joint]:g}, {upper[joint]:g}]")
    return Axis(joint, labels[joint], count, float(low), float(high))


def parse(spec: str | Sequence[object], labels: Sequence[str], lower: Sequence[float], upper: Sequence[float],
          cap: int = MAX_POINTS) -> tuple[Axis, ...]:
    """The axes of ``spec`` (a string of comma-separated items, or a sequence of them) for a system with
    joints ``labels`` and limits ``lower``/``upper``; a SweepError starting ``grid:`` names what is wrong."""
    items = [spec] if isinstance(spec, str) else list(spec)
    texts = [item for item in items if isinstance(item, str)]
    if len(texts) != len(items):
        raise _fail(f"expected strings JOINT=COUNT[:LOW:HIGH], got {spec!r}")
    pieces = [piece.strip() for item in texts for piece in item.split(",")]
    if not any(pieces):
        raise _fail(f"expected at least one JOINT=COUNT, got {spec!r}")
    axes = tuple(_axis(piece, labels, lower, upper) for piece in pieces)
    seen: set[int] = set()
    for axis in axes:
        if axis.joint in seen:
            raise _fail(f"joint {axis.name} appears twice")
        seen.add(axis.joint)
    size = math.prod(axis.count for axis in axes)
    if size > cap:
        counts = " × ".join(str(axis.count) for axis in axes)
        raise _fail(f"{counts} = {size:.3g} configurations exceed the cap of {cap:.0e}; use fewer values "
                    "per joint or fewer joints")
    return axes


def size(axes: Sequence[Axis]) -> int:
    return math.prod(axis.count for axis in axes)


def configurations(axes: Sequence[Axis], fixed: Sequence[float], first: int, count: int
                   ) -> NDArray[np.float64]:
    """Rows ``first`` … ``first + count − 1`` of the grid in flat order: ``fixed`` with the axes' joints
    set to their values."""
    q = np.tile(np.asarray(fixed, dtype=float), (count, 1))
    digits = np.unravel_index(np.arange(first, first + count), tuple(axis.count for axis in axes))
    for axis, digit in zip(axes, digits, strict=True):
        q[:, axis.joint] = axis.values()[digit]
    return q
