"""``gagen sweep --system``: the manipulability sweep of other bundled systems (shared waist joints, a
sphere, a point pair, a plane of fingers) against single kernel calls; reach targets for a sphere system
against a direct iLQR solve; systems the sweeps cannot handle refused naming ``--system``."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("distributed")  # the sweep extra
pytest.importorskip("pyarrow")

from gagen.sweep.engine import run_serial
from gagen.sweep.problems import Manipulability, Reach, build_module, cell
from gagen.sweep.store import ChunkStore, SweepError

UNIT_BALL = {3: 4 * math.pi / 3, 4: math.pi**2 / 2, 6: math.pi**3 / 6}  # volume of the unit r-ball


def _system(name):
    from gagen.apps.cooperative.bundled import bundled_specs
    from gagen.robots.spec import load_system

    return load_system(bundled_specs()[name])


@pytest.mark.compiling  # the modules of other systems than FAST_MODULES: built on first use
@pytest.mark.parametrize(("name", "grid"), [
    ("g1_torso_circle", None),  # three chains sharing the waist's three joints
    ("g1_torso_circle", "g1/waist_yaw_joint=3,g1/left_elbow_joint=4"),
    ("four_pandas_sphere", None),
    ("two_pandas_point_pair", None),
    ("leap_three_fingers_plane", None),
])
def test_another_systems_numbers_equal_single_kernel_calls(tmp_path, name, grid):
    """Per configuration: the similarity kernel called once, manipulability_index at the primitive's rank
    from CONTROLLABLE_DIMENSION, the chains' FK called one by one on ``System.split`` and the viewer's
    ``shape`` of the end points."""
    from gagen.apps.cooperative.bundled import system_module
    from gagen.check import joint_limits
    from gagen.control.differential import CONTROLLABLE_DIMENSION, manipulability_index
    from gagen.viewer.geometry import shape

    sweep = (Manipulability(samples=60, chunk=25, seed=7, system=name) if grid is None
             else Manipulability(grid=grid, chunk=5, system=name))
    run_serial(sweep, tmp_path)
    table = ChunkStore(tmp_path).read(sweep.chunks)
    system, _ = _system(name)
    module = system_module(name)
    rank = CONTROLLABLE_DIMENSION[system.kind]
    q = np.vstack([sweep.configurations(i) for i in range(sweep.chunks)])
    lower, upper, _ = joint_limits(system)
    assert q.shape == (sweep.rows, system.dof) and np.all((q >= lower) & (q <= upper))
    assert table.num_rows == sweep.rows
    column = {k: table.column(k).to_numpy() for k in table.column_names}
    for row in range(0, sweep.rows, 3):
        _, conditioning, J_G = module.c.similarity(q[row])
        assert column["conditioning"][row] == conditioning[0]
        index = manipulability_index(J_G, rank)
        singular = np.linalg.svd(J_G, compute_uv=False)
        assert rank == singular.size or singular[rank] < 1e-12 * singular[0]  # rank r: the whole ellipsoid
        assert column["index"][row] == pytest.approx(index, rel=1e-13, abs=0)
        assert column["volume"][row] == pytest.approx(UNIT_BALL[rank] * index, rel=1e-13, abs=0)
        points = [np.asarray(getattr(module.c, f"{chain.name}_fk")(np.array(qc))[1])[1:4]
                  for chain, qc in zip(system.chains, system.split(list(q[row])), strict=True)]
        expected = shape(system.kind, points)
        centre = np.array([column[f"centre_{k}"][row] for k in "xyz"])
        assert np.max(np.abs(centre - expected.centre)) < 1e-12 * max(1.0, expected.size)
        if system.kind in ("circle", "sphere", "point_pair"):
            assert column["radius"][row] == pytest.approx(expected.radius, rel=1e-12)
        else:
            assert np.isnan(column["radius"][row])


@pytest.mark.compiling
def test_a_sphere_systems_reach_target_equals_a_direct_solve(tmp_path):
    """One target sphere, the ready sphere's (rounded) centre and radius, solved by the sweep and by the
    iLQR called here on the spec's own pieces."""
    from gagen.apps.cooperative.bundled import system_module
    from gagen.check import joint_limits
    from gagen.control import goals
    from gagen.control.ilqr import ILQR

    sweep = Reach(grid=1, N=20, chunk=1, system="four_pandas_sphere")
    assert (sweep.x, sweep.y, sweep.height, sweep.radii) == (0.0, 0.0, 1.1, (0.7,))  # the ready sphere's
    run_serial(sweep, tmp_path)
    table = ChunkStore(tmp_path).read(1)
    system, configurations = _system("four_pandas_sphere")
    lower, upper, _ = joint_limits(system)
    result = ILQR(system_module("four_pandas_sphere").c.task, 28, N=20).solve(
        np.array(configurations["ready"]), goals.sphere([0.0, 0.0, 1.1], 0.7), limits=(lower, upper))
    assert table.column("error")[0].as_py() == result.error_norm
    assert table.column("status")[0].as_py() == result.status
    assert np.array_equal(table.column("q_final")[0].values.to_numpy(), result.q[-1])


def test_the_three_pandas_reach_defaults_are_unchanged():
    sweep = Reach()
    assert (sweep.x, sweep.y, sweep.height, sweep.radii, sweep.span, sweep.normal) == (
        0.0, 0.0, 0.59, (0.5,), 0.6, (0.0, 0.0, 1.0))
    tilted = Reach(system="g1_torso_circle")  # the ready circle's normal, to 0.01
    assert (tilted.x, tilted.height, tilted.radii, tilted.normal) == (0.36, 0.11, (0.35,), (0.59, 0.0, 0.8))


def test_systems_the_sweeps_cannot_handle_are_named(monkeypatch, tmp_path):
    with pytest.raises(SweepError, match=r"^system: expected a bundled cooperative system "
                       r"\(four_pandas_circle, four_pandas_sphere, .*three_pandas_circle.*\) or a spec file, "
                       r"got 'nope'"):
        Manipulability(samples=10, system="nope")
    with pytest.raises(SweepError, match=r"^system: the reach sweep has circle and sphere targets; "
                       r"two_iiwas_line spans a line"):
        Reach(system="two_iiwas_line")
    with pytest.raises(SweepError, match=r"^normal: only circle targets have a normal; four_pandas_sphere "
                       r"spans a sphere"):
        Reach(system="four_pandas_sphere", normal=(0.0, 0.0, 1.0))
    import gagen.check
    import gagen.modules
    from gagen.build import OutputError

    limits = gagen.check.joint_limits

    def continuous_first_joint(system):
        lower, upper, kinds = limits(system)
        lower[0], upper[0] = -np.inf, np.inf
        return lower, upper, kinds

    monkeypatch.setattr(gagen.check, "joint_limits", continuous_first_joint)
    with pytest.raises(SweepError, match=r"^system: panda_point has joints without limits "
                       r"\(arm0/panda_joint1\); the sweeps sample and grid within the joint limits"):
        cell.__wrapped__("panda_point")
    monkeypatch.setattr(gagen.check, "joint_limits", limits)

    def unwritable(spec):
        raise OutputError(tmp_path / "panda_point", "Read-only file system")

    monkeypatch.setattr(gagen.modules, "module_folder", unwritable)  # (the module is built on first use)
    with pytest.raises(SweepError, match=r"^system: cannot build the generated module of panda_point: "
                       r"cannot write .*panda_point: Read-only file system"):
        build_module("panda_point")


def test_the_command_line_names_the_system_option(tmp_path, capsys):
    from gagen.cli import main

    assert main(["sweep", "manipulability", "--out", str(tmp_path), "--system", "nope"]) == 2
    assert "error: --system: expected a bundled cooperative system" in capsys.readouterr().err
    assert main(["sweep", "reach", "--out", str(tmp_path), "--system", "three_iiwas_plane"]) == 2
    assert "error: --system: the reach sweep has circle and sphere targets; three_iiwas_plane spans a plane" \
        in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_the_volume_map_of_a_grid_of_another_system(tmp_path):
    """A grid over two joints of the G1: the places lie on a surface, not spread over a volume (a range
    that collapses is widened); the map is drawn from the ``volume`` column."""
    from gagen.sweep import plots

    sweep = Manipulability(grid="g1/waist_pitch_joint=12,g1/right_elbow_joint=10", chunk=60,
                           system="g1_torso_circle")
    run_serial(sweep, tmp_path)
    table = ChunkStore(tmp_path).read(sweep.chunks)
    path = plots.manipulability_map(table, tmp_path / "map.png", system=sweep.system)
    assert path.stat().st_size > 10_000
    with pytest.raises(ValueError, match="no configuration has a finite, positive ellipsoid volume"):
        plots.manipulability_map(table.filter(table.column("sample").to_numpy() < 0), tmp_path / "none.png")


@pytest.mark.compiling
def test_a_sweep_of_a_users_spec(tmp_path, capsys):
    """``--system`` takes a spec file: two Pandas written here, their hands spanning a point pair; each
    row's manipulability index against the module's own J_G, and the command line on the same file."""
    from gagen.cli import main
    from gagen.control.differential import CONTROLLABLE_DIMENSION, manipulability_index
    from gagen.modules import bundled_module
    from gagen.registry import bundled_specs
    from gagen.sweep.engine import run_serial
    from gagen.sweep.store import ChunkStore

    urdf = bundled_specs("cooperative")["panda_point"].parent / "panda" / "panda.urdf"
    chain = ("  - {{name: {name}, urdf: {urdf}, base_link: panda_link0, tip_link: panda_link8, "
             "base: {base}}}\n")
    spec = tmp_path / "facing_pandas.yaml"
    spec.write_text("name: facing_pandas\nprimitive: point_pair\nchains:\n"
                    + chain.format(name="left", urdf=urdf, base="{xyz: [0, -0.6, 0]}")
                    + chain.format(name="right", urdf=urdf, base="{xyz: [0, 0.6, 0], rpy: [0, 0, 3.14159]}")
                    + "configurations:\n  ready: ["
                    + ", ".join(["0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785"] * 2) + "]\n")
    sweep = Manipulability(samples=40, chunk=20, seed=1, system=str(spec))
    assert sweep.cell.joints[0] == "left/panda_joint1" and len(sweep.cell.joints) == 14
    run_serial(sweep, tmp_path / "serial")
    table = ChunkStore(tmp_path / "serial").read(sweep.chunks)
    module = bundled_module(spec)
    rank = CONTROLLABLE_DIMENSION["point_pair"]
    for row in range(0, 40, 3):
        q = sweep.configurations(row // 20)[row % 20]
        J_G = module.c.similarity(q)[2]
        assert table.column("index")[row].as_py() == pytest.approx(manipulability_index(J_G, rank), rel=1e-12)
    out = tmp_path / "cli"
    assert main(["sweep", "manipulability", "--system", str(spec), "--samples", "20", "--chunk", "20",
                 "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    assert "manipulability sweep of " in capsys.readouterr().out and (out / "sweep.json").is_file()
