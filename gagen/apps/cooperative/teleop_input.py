"""Six-axis command sources for teleoperation [COOP Section 4.4]: recorded traces, the keyboard, a SpaceMouse.

Every source yields the six device axes ``AXES`` = (tx, ty, tz, rx, ry, rz) as *rates*: translations in
m/s (primitive units/s in the body frame), rotations in rad/s, and rz the dilation rate δ = d(ln r)/dt
in 1/s (positive opens). ``gagen.apps.cooperative.teleop`` maps them onto a similarity bivector.

Trace files (what the tests and ``gagen teleop --trace`` use) are small CSV files::

    # comments and blank lines are ignored
    t,tx,ty,tz,rx,ry,rz
    0.00,0,0,0,0,0,-4
    0.25,0,0,0,0,0,4
    0.50,0,0,0,0,0,0

The header is exactly those seven names. Row k holds its axes from its time t_k until the next row's
time (zero-order hold). Times start at 0 and increase strictly; the last row ends the trace (its time is
the duration) and must have all six axes 0, the device released. Anything else is a ``SpecError`` naming
the file, the line and field, and what was expected.

Live devices give normalised deflections in [−1, 1], scaled to rates by ``Scales``. The keyboard mapping
(``KEYMAP``, ``axes_from_keys``) is separate from the terminal I/O (``KeyboardReader``) so it can be tested.
The SpaceMouse goes through pyspacemouse (optional: ``pip install gagen[teleop]``; it needs the hidapi C
library), imported only when asked for.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gagen.errors import SpecError, read_input

AXES = ("tx", "ty", "tz", "rx", "ry", "rz")
HEADER = ("t", *AXES)
TIME_TOLERANCE = 1e-9
"""Step start times within this of a row's time count as at that row (k · dt is not exact in floats)."""


# -- traces ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Trace:
    """A recorded command: ``times`` (rows,) strictly increasing from 0, ``axes`` (rows, 6) rates held
    from each row's time to the next; the last row (all zero) ends the trace at ``duration``."""

    times: NDArray[np.float64]
    axes: NDArray[np.float64]
    source: str = "<memory>"

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def at(self, t: float) -> NDArray[np.float64]:
        """The six axes held at time t (zero-order hold; zeros from the end on)."""
        row = int(np.searchsorted(self.times, t + TIME_TOLERANCE, side="right")) - 1
        if row < 0 or row >= len(self.times) - 1:
            return np.zeros(len(AXES))
        held: NDArray[np.float64] = self.axes[row].copy()
        return held

    def steps(self, dt: float) -> int:
        """How many steps of dt cover the trace (the last one may end past it)."""
        return max(1, math.ceil(self.duration / dt - TIME_TOLERANCE))


def parse_trace(text: str, source: str | Path = "<string>") -> Trace:
    """A ``Trace`` from the text of a trace file; ``SpecError(source, 'line N, field F', ...)`` otherwise."""
    rows: list[tuple[int, list[float]]] = []
    header_seen = False
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        fields = [f.strip() for f in line.split(",")]
        if not header_seen:
            if tuple(fields) != HEADER:
                raise SpecError(source, f"line {number}, header",
                                f"expected the header {','.join(HEADER)!r}, got {line!r}")
            header_seen = True
            continue
        if len(fields) != len(HEADER):
            raise SpecError(source, f"line {number}",
                            f"expected {len(HEADER)} comma-separated numbers ({','.join(HEADER)}), "
                            f"got {len(fields)} fields")
        values = []
        for name, field in zip(HEADER, fields, strict=True):
            try:
                value = float(field)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise SpecError(source, f"line {number}, field {name!r}",
                                f"expected a finite number, got {field!r}")
            values.append(value)
        if rows and values[0] <= rows[-1][1][0]:
            raise SpecError(source, f"line {number}, field 't'",
                            f"expected a time after {rows[-1][1][0]:g} (line {rows[-1][0]}), "
                            f"got {values[0]:g}")
        if not rows and values[0] != 0:
            raise SpecError(source, f"line {number}, field 't'",
                            f"expected the first time to be 0, got {values[0]:g}")
        rows.append((number, values))
    if not header_seen:
        raise SpecError(source, "header", f"expected the header {','.join(HEADER)!r}; the file has no data")
    if len(rows) < 2:
        raise SpecError(source, "rows", "expected at least two rows: a command at t = 0 and the end row")
    last_line, last = rows[-1]
    for name, value in zip(AXES, last[1:], strict=True):
        if value != 0:
            raise SpecError(source, f"line {last_line}, field {name!r}",
                            f"expected 0: the last row ends the trace (device released), got {value:g}")
    data = np.array([values for _, values in rows])
    return Trace(times=data[:, 0], axes=data[:, 1:], source=str(source))


def read_trace(path: str | Path) -> Trace:
    """Read and validate a trace file (see the module docstring for the format)."""
    path = Path(path)
    raw = read_input(path, "trace")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise SpecError(path, "trace", f"expected UTF-8 text ({e})") from e
    return parse_trace(text, path)


def format_trace(times: Sequence[float], axes: Sequence[Sequence[float] | NDArray[np.float64]],
                 comment: str = "") -> str:
    """Trace text for the given rows; a final all-zero row at ``times[-1]`` must be included by the caller."""
    lines = [f"# {line}" for line in comment.splitlines()]
    lines.append(",".join(HEADER))
    lines += [",".join(f"{v:.12g}" for v in (t, *a)) for t, a in zip(times, axes, strict=True)]
    return "\n".join(lines) + "\n"


# -- scaling of normalised device axes -----------------------------------------------------------------
@dataclass(frozen=True)
class Scales:
    """Rates per unit deflection: translation (m/s), rotation (rad/s), dilation (1/s)."""

    translation: float = 0.05
    rotation: float = 0.5
    dilation: float = 0.5

    def apply(self, deflection: Sequence[float]) -> NDArray[np.float64]:
        d = np.asarray(deflection, dtype=float)
        per_unit = np.array([self.translation] * 3 + [self.rotation] * 2 + [self.dilation])
        rates: NDArray[np.float64] = d * per_unit
        return rates


# -- keyboard ----------------------------------------------------------------------------------------
KEYMAP: dict[str, tuple[str, float]] = {
    "d": ("tx", 1.0), "a": ("tx", -1.0),
    "w": ("ty", 1.0), "s": ("ty", -1.0),
    "r": ("tz", 1.0), "f": ("tz", -1.0),
    "i": ("rx", 1.0), "k": ("rx", -1.0),
    "l": ("ry", 1.0), "j": ("ry", -1.0),
    "o": ("rz", 1.0), "u": ("rz", -1.0),   # rz: dilation, o opens, u closes
}
"""Key -> (axis, deflection): WASD + R/F translate, I/K J/L rotate about x/y, O/U open/close (rz)."""
QUIT_KEYS = frozenset({"q", "\x1b", "\x03"})  # q, Esc, Ctrl-C
HELP = ("keys: a/d x, s/w y, f/r z, k/i rot x, j/l rot y, u/o dilation (close/open), space stop, q quit")


def axes_from_keys(keys: Iterable[str]) -> NDArray[np.float64]:
    """Normalised deflections (6,) for the keys pressed in one tick: each mapped key sets its axis to ±1
    (opposite keys cancel); other keys are ignored. Upper case counts as lower case."""
    deflection = np.zeros(len(AXES))
    for key in keys:
        mapped = KEYMAP.get(key.lower())
        if mapped is not None:
            axis, sign = mapped
            deflection[AXES.index(axis)] += sign
    return np.clip(deflection, -1.0, 1.0)


class KeyboardReader:
    """Non-blocking keys from a terminal (POSIX termios, cbreak mode) as a context manager.

    Terminals send key repeats while a key is held, so a tick's deflection comes from the keys that
    arrived since the last read, kept for ``hold`` seconds to bridge the repeat delay."""

    def __init__(self, stream: Any = None, hold: float = 0.12) -> None:
        self.stream = stream if stream is not None else sys.stdin
        self.hold = hold
        self._held: dict[str, float] = {}
        self._saved: Any = None
        self.quit = False

    def __enter__(self) -> KeyboardReader:
        import termios
        import tty

        if not self.stream.isatty():
            raise RuntimeError("--keyboard needs an interactive terminal (stdin is not a TTY)")
        self._saved = termios.tcgetattr(self.stream.fileno())
        tty.setcbreak(self.stream.fileno())
        return self

    def __exit__(self, *exc: object) -> None:
        import termios

        if self._saved is not None:
            termios.tcsetattr(self.stream.fileno(), termios.TCSADRAIN, self._saved)

    def read(self, now: float) -> NDArray[np.float64]:
        """Deflections (6,) at wall time ``now``; sets ``quit`` on q / Esc / Ctrl-C, clears on space."""
        import os
        import select

        fd = self.stream.fileno()
        while select.select([fd], [], [], 0)[0]:
            key = os.read(fd, 1).decode(errors="ignore")
            if key in QUIT_KEYS:
                self.quit = True
            elif key == " ":
                self._held.clear()
            elif key.lower() in KEYMAP:
                self._held[key.lower()] = now
        self._held = {k: t for k, t in self._held.items() if now - t <= self.hold}
        return axes_from_keys(self._held)


# -- SpaceMouse --------------------------------------------------------------------------------------
class SpaceMouseReader:
    """A 3Dconnexion SpaceMouse through pyspacemouse (Z-up right-handed axes, counter-clockwise yaw +).

    (x, y, z, roll, pitch, yaw) -> (tx, ty, tz, rx, ry, rz): twisting the cap counter-clockwise opens
    (dilates), clockwise closes. A button press sets ``quit``."""

    def __init__(self) -> None:
        try:
            import pyspacemouse
        except ImportError as e:  # the package, or easyhid's hidapi C library, is missing
            raise RuntimeError("--spacemouse needs pyspacemouse and the hidapi C library: "
                               "pip install 'gagen[teleop]' (or pip install pyspacemouse) and "
                               f"e.g. apt-get install libhidapi-hidraw0 ({type(e).__name__}: {e})") from e
        try:
            self.device = pyspacemouse.open(axis_convention=pyspacemouse.AxisConvention.HID_Z_UP)
        except Exception as e:  # pyspacemouse raises RuntimeError / ValueError / HID errors
            raise RuntimeError(f"no SpaceMouse could be opened ({type(e).__name__}: {e}); is one connected, "
                               "is the hidapi C library installed (e.g. apt-get install libhidapi-hidraw0), "
                               "and may this user read /dev/hidraw* (a udev rule)?") from e
        self.quit = False

    def __enter__(self) -> SpaceMouseReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.device.close()

    def read(self, now: float) -> NDArray[np.float64]:
        state = self.device.read()
        if any(getattr(state, "buttons", ()) or ()):
            self.quit = True
        axes: NDArray[np.float64] = np.clip([state.x, state.y, state.z, state.roll, state.pitch, state.yaw],
                                            -1.0, 1.0)
        return axes
