"""Configuration grids (``gagen sweep manipulability --grid``): a 2-worker LocalCluster gives the serial
loop's rows bit for bit, the configurations are the grid's (against an independent enumeration), any chunk
recomputed alone on a worker gives its file's rows, and malformed grids are refused naming ``--grid``."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("distributed")  # the sweep extra
pytest.importorskip("pyarrow")

import pyarrow.parquet as pq

from gagen.sweep.engine import run, run_serial
from gagen.sweep.grid import MAX_POINTS, Axis
from gagen.sweep.problems import Manipulability, compute_chunk
from gagen.sweep.store import ChunkStore, SweepError, chunk_name

# 6 × 5 × 4 = 120 configurations in 8 chunks of 17 (the last one of 1): two joints of one arm over their
# limits or a sub-range, one of the third arm (by its index)
GRID = "arm0/panda_joint2=6, arm1/panda_joint4=5:-2.5:-0.5,20=4"


def _expected_grid(sweep: Manipulability) -> np.ndarray:
    """The grid enumerated here from the spec's numbers: itertools.product, last joint fastest."""
    from gagen.apps.cooperative.bundled import bundled_specs
    from gagen.check import joint_limits
    from gagen.robots.spec import load_system

    system, configurations = load_system(bundled_specs()["three_pandas_circle"])
    lower, upper, _ = joint_limits(system)
    values = [np.linspace(lower[1], upper[1], 6), np.linspace(-2.5, -0.5, 5),
              np.linspace(lower[20], upper[20], 4)]
    rows = []
    for a, b, c in itertools.product(*values):
        q = np.array(configurations["ready"], dtype=float)
        q[[1, 10, 20]] = a, b, c
        rows.append(q)
    return np.array(rows)


def test_a_grid_on_two_workers_equals_the_serial_loop(client, tmp_path):
    sweep = Manipulability(grid=GRID, chunk=17)
    assert sweep.rows == 120 and sweep.chunks == 8
    assert [(a.joint, a.name, a.count) for a in sweep.grid] == [
        (1, "arm0/panda_joint2", 6), (10, "arm1/panda_joint4", 5), (20, "arm2/panda_joint7", 4)]
    outcome = run(sweep, tmp_path / "dask", client=client, progress=False)
    assert outcome.workers == 2 and sorted(outcome.computed) == list(range(8)) and outcome.rows == 120
    run_serial(sweep, tmp_path / "serial")
    distributed = ChunkStore(tmp_path / "dask").read(8)
    assert distributed.equals(ChunkStore(tmp_path / "serial").read(8))  # exact: same bits, same order
    assert np.array_equal(distributed.column("sample").to_numpy(), np.arange(120))
    q = np.vstack([sweep.configurations(i) for i in range(8)])
    assert np.array_equal(q, _expected_grid(sweep))


def test_a_grid_chunk_recomputed_alone_gives_the_same_rows(client, tmp_path):
    """Chunk i from a sweep made afresh (from the first one's axes), computed on a worker by itself and
    in this process, equals the file the whole sweep wrote."""
    sweep = Manipulability(grid=GRID, chunk=17)
    run_serial(sweep, tmp_path)
    again = Manipulability(grid=tuple(sweep.grid), chunk=17)
    assert again.grid == sweep.grid and again.description() == sweep.description()
    for index in (0, 5, 7):
        written = pq.read_table(tmp_path / chunk_name(index))
        assert client.submit(compute_chunk, again, index, pure=False).result()[1].equals(written)
        assert compute_chunk(again, index)[1].equals(written)
    assert written.num_rows == 1  # the last chunk holds what is left


def test_the_grid_is_recorded_and_a_different_one_refused(tmp_path):
    run_serial(Manipulability(grid="1=3", chunk=2), tmp_path)
    recorded = ChunkStore(tmp_path).folder.joinpath("sweep.json").read_text()
    assert '"joint": "arm0/panda_joint2"' in recorded and '"count": 3' in recorded and "seed" not in recorded
    with pytest.raises(SweepError, match=r"this folder holds a sweep with grid = "):
        run_serial(Manipulability(grid="1=4", chunk=2), tmp_path)
    with pytest.raises(SweepError, match=r"holds a sweep with fixed = \[0\.0, -0\.785, .*, not None"):
        run_serial(Manipulability(samples=3, chunk=2), tmp_path)


@pytest.mark.parametrize(("grid", "message"), [
    ("arm0/panda_joint2", r"expected JOINT=COUNT or JOINT=COUNT:LOW:HIGH, got 'arm0/panda_joint2'"),
    ("1=5:0:1:2", r"expected JOINT=COUNT or JOINT=COUNT:LOW:HIGH, got '1=5:0:1:2'"),
    ("=5", r"expected JOINT=COUNT"),
    ("", r"expected at least one JOINT=COUNT"),
    ("nosuch=5", r"expected a joint label \(arm0/panda_joint1, .*\) or a 0-based index, got 'nosuch'"),
    ("21=5", r"joint index 21 is out of range: the system has 21 joints \(0 … 20\)"),
    ("1=1", r"expected a count ≥ 2 in '1=1'"),
    ("1=x", r"expected an integer count ≥ 2 in '1=x', got 'x'"),
    ("1=5,arm0/panda_joint2=3", r"joint arm0/panda_joint2 appears twice"),
    ("1=5:-9:0", r"'1=5:-9:0' leaves the limits of arm0/panda_joint2 \[-1.7628, 1.7628\]"),
    ("1=5:0.5:0.2", r"expected LOW < HIGH in '1=5:0.5:0.2'"),
    ("1=5:nan:0.2", r"expected a finite LOW in '1=5:nan:0.2', got 'nan'"),
    ("0=100,1=100,2=100,3=100,4=100", r"100 × 100 × 100 × 100 × 100 = 1e\+10 configurations exceed the "
                                      r"cap of 1e\+09"),
    ([1, 2], r"expected strings JOINT=COUNT\[:LOW:HIGH\]"),
])
def test_malformed_grids_are_refused_naming_the_grid(grid, message):
    with pytest.raises(SweepError, match=rf"^grid: {message}"):
        Manipulability(grid=grid)


def test_a_grid_excludes_samples_and_seed_and_checks_given_axes():
    with pytest.raises(SweepError, match=r"^grid: a sweep has random samples or a grid, not both"):
        Manipulability(samples=10, grid="1=3")
    with pytest.raises(SweepError, match=r"^seed: a grid has no random seed, got 4"):
        Manipulability(grid="1=3", seed=4)
    with pytest.raises(SweepError, match=r"^grid: .* leaves the limits of arm0/panda_joint2"):
        Manipulability(grid=(Axis(1, "arm0/panda_joint2", 3, -5.0, 0.0),))
    assert MAX_POINTS == 10**9


def test_the_command_line_names_the_grid_option(tmp_path, capsys):
    from gagen.cli import main

    out = ["sweep", "manipulability", "--out", str(tmp_path)]
    assert main([*out, "--grid", "1=3", "--grid", "nosuch=2"]) == 2
    assert "error: --grid: expected a joint label" in capsys.readouterr().err
    assert main([*out, "--grid", "1=3", "--seed", "2"]) == 2
    assert "error: --seed: a grid has no random seed" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        main([*out, "--grid", "1=3", "--samples", "5"])
    assert exit_.value.code == 2
    assert "argument --samples: not allowed with argument --grid" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())  # nothing written for a refused sweep


@settings(max_examples=60)
@given(counts=st.lists(st.integers(2, 5), min_size=1, max_size=3), chunk=st.integers(1, 40), data=st.data())
def test_chunks_of_any_grid_are_its_enumeration_in_order(counts, chunk, data):
    """Property (no kernels): for any axes and chunk size, the chunks' rows concatenated are the product of
    the axes' values, last axis fastest, and every other joint keeps its fixed value."""
    from gagen.sweep import grid

    joints = data.draw(st.lists(st.integers(0, 6), min_size=len(counts), max_size=len(counts), unique=True))
    labels = [f"j{i}" for i in range(7)]
    spec = ",".join(f"{labels[j]}={c}:{-j - 1}:{j + 0.5}" for j, c in zip(joints, counts, strict=True))
    axes = grid.parse(spec, labels, [-10.0] * 7, [10.0] * 7)
    fixed = np.arange(7.0) / 10
    total = grid.size(axes)
    rows = np.vstack([grid.configurations(axes, fixed, first, min(chunk, total - first))
                      for first in range(0, total, chunk)])
    expected = []
    for values in itertools.product(*(np.linspace(-j - 1, j + 0.5, c) for j, c in zip(joints, counts,
                                                                                      strict=True))):
        q = fixed.copy()
        q[joints] = values
        expected.append(q)
    assert np.array_equal(rows, np.array(expected))
