"""Teleoperation command sources: the trace format and its errors, the keyboard mapping, the SpaceMouse
guard (gagen.apps.cooperative.teleop_input). Pure Python, no kernels."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gagen.apps.cooperative.teleop import TRACES
from gagen.apps.cooperative.teleop_input import (
    AXES,
    KEYMAP,
    Scales,
    SpaceMouseReader,
    axes_from_keys,
    format_trace,
    parse_trace,
    read_trace,
)
from gagen.errors import SpecError

GOOD = "# a comment\n\nt,tx,ty,tz,rx,ry,rz\n0,0.1,0,0,0,0,-4\n0.25, 0,0,0,0,0,4\n0.5,0,0,0,0,0,0\n"


def test_a_trace_holds_each_row_until_the_next():
    trace = parse_trace(GOOD, "good.csv")
    assert trace.duration == 0.5
    np.testing.assert_array_equal(trace.at(0.0), [0.1, 0, 0, 0, 0, -4])
    np.testing.assert_array_equal(trace.at(0.2499), [0.1, 0, 0, 0, 0, -4])
    # 25 · 0.01 is 0.25000000000000006 or 0.24999999999999997 in floats: both are the second row
    np.testing.assert_array_equal(trace.at(25 * 0.01), [0, 0, 0, 0, 0, 4])
    np.testing.assert_array_equal(trace.at(0.2499999999999), [0, 0, 0, 0, 0, 4])
    np.testing.assert_array_equal(trace.at(0.5), np.zeros(6))
    assert trace.steps(0.01) == 50 and trace.steps(0.25) == 2 and trace.steps(0.3) == 2


@pytest.mark.parametrize("text, field, expected", [
    ("", "header", "no data"),
    ("t,tx,ty,tz,rx,ry\n0,0,0,0,0,0\n", "line 1, header", "expected the header"),
    ("t,tx,ty,tz,rx,ry,rz\n0,0,0,0,0,0,0\n", "rows", "at least two rows"),
    ("t,tx,ty,tz,rx,ry,rz\n0,0,0,0,0,0\n1,0,0,0,0,0,0\n", "line 2", "got 6 fields"),
    ("t,tx,ty,tz,rx,ry,rz\n0,0,0,x,0,0,0\n1,0,0,0,0,0,0\n", "line 2, field 'tz'", "finite number, got 'x'"),
    ("t,tx,ty,tz,rx,ry,rz\n0,0,0,0,nan,0,0\n1,0,0,0,0,0,0\n", "line 2, field 'rx'", "finite number"),
    ("t,tx,ty,tz,rx,ry,rz\n0,0,0,0,0,0,inf\n1,0,0,0,0,0,0\n", "line 2, field 'rz'", "finite number"),
    ("t,tx,ty,tz,rx,ry,rz\n0.1,0,0,0,0,0,0\n1,0,0,0,0,0,0\n", "line 2, field 't'", "first time to be 0"),
    ("t,tx,ty,tz,rx,ry,rz\n0,0,0,0,0,0,1\n# c\n0,0,0,0,0,0,0\n", "line 4, field 't'", "after 0 (line 2)"),
    ("t,tx,ty,tz,rx,ry,rz\n0,0,0,0,0,0,1\n1,0,0,0,0,0.5,0\n", "line 3, field 'ry'",
     "last row ends the trace"),
])
def test_malformed_traces_name_the_line_and_field(text, field, expected):
    with pytest.raises(SpecError) as info:
        parse_trace(text, "bad.csv")
    assert info.value.file == "bad.csv" and info.value.field == field
    assert expected in info.value.message
    assert str(info.value).startswith(f"bad.csv: {field}: ")


def test_unreadable_trace_files_name_the_file(tmp_path):
    with pytest.raises(SpecError, match=r"missing\.csv: trace: file not found"):
        read_trace(tmp_path / "missing.csv")
    binary = tmp_path / "binary.csv"
    binary.write_bytes(b"t,tx\xff\n")
    with pytest.raises(SpecError, match=r"binary\.csv: trace: expected UTF-8 text"):
        read_trace(binary)


@settings(max_examples=40)
@given(st.lists(st.tuples(st.floats(1e-3, 10), *[st.floats(-5, 5)] * 6), min_size=1, max_size=8))
def test_format_and_parse_round_trip(rows):
    times = np.cumsum([0.0] + [r[0] for r in rows])
    axes = [list(r[1:]) for r in rows] + [[0.0] * 6]
    trace = parse_trace(format_trace(times, axes, comment="round trip\nsecond line"))
    np.testing.assert_allclose(trace.times, times, rtol=1e-11)
    np.testing.assert_allclose(trace.axes, axes, rtol=1e-11, atol=0)


def test_bundled_traces_parse():
    names = sorted(p.name for p in TRACES.glob("*.csv"))
    assert "fig17_dilation.csv" in names and len(names) >= 3
    for name in names:
        assert read_trace(TRACES / name).duration > 0


def test_keyboard_mapping():
    """Each axis has a key for each direction; opposite keys cancel; unknown keys do nothing."""
    assert sorted({axis for axis, _ in KEYMAP.values()}) == sorted(AXES)
    for axis in AXES:
        assert sorted(sign for a, sign in KEYMAP.values() if a == axis) == [-1.0, 1.0]
    np.testing.assert_array_equal(axes_from_keys("d"), [1, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(axes_from_keys(["W", "u", "x", "?"]), [0, 1, 0, 0, 0, -1])
    np.testing.assert_array_equal(axes_from_keys("ad"), np.zeros(6))
    np.testing.assert_array_equal(axes_from_keys("dd"), [1, 0, 0, 0, 0, 0])  # repeats saturate at ±1


def test_scales_turn_deflections_into_rates():
    np.testing.assert_allclose(Scales(0.1, 2.0, 3.0).apply([1, -1, 0.5, 1, -0.5, -1]),
                               [0.1, -0.1, 0.05, 2.0, -1.0, -3.0])


def test_spacemouse_missing_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyspacemouse", None)  # import fails as if not installed
    with pytest.raises(RuntimeError, match=r"pip install 'gagen\[teleop\]'"):
        SpaceMouseReader()


class _FakeSpaceMouse:
    """Stands in for pyspacemouse 2.x: open(axis_convention=...) -> device with read() and close()."""

    class AxisConvention:
        HID_Z_UP = "hid_z_up"

    def __init__(self, connected: bool) -> None:
        self.connected, self.convention, self.closed = connected, None, False

    def open(self, axis_convention=None):
        if not self.connected:
            raise RuntimeError("No connected or supported devices found.")
        self.convention = axis_convention
        fake = self

        class Device:
            def read(self):
                from types import SimpleNamespace
                return SimpleNamespace(x=0.5, y=-0.25, z=1.5, roll=0.1, pitch=0.2, yaw=-0.3, buttons=[0, 0])

            def close(self):
                fake.closed = True

        return Device()


def test_spacemouse_not_connected_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyspacemouse", _FakeSpaceMouse(connected=False))
    with pytest.raises(RuntimeError, match=r"no SpaceMouse could be opened.*No connected or supported"):
        SpaceMouseReader()


def test_spacemouse_axes(monkeypatch):
    fake = _FakeSpaceMouse(connected=True)
    monkeypatch.setitem(sys.modules, "pyspacemouse", fake)
    with SpaceMouseReader() as reader:
        np.testing.assert_allclose(reader.read(0.0), [0.5, -0.25, 1.0, 0.1, 0.2, -0.3])  # clipped to [-1, 1]
        assert not reader.quit
    assert fake.convention == "hid_z_up" and fake.closed
