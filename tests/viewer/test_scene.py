"""The viewer's scene without a browser: a server on the loopback interface only, the drawn nodes where the
generated FK puts the robots, trajectories played in time, malformed input refused."""

import logging
import socket
import threading
import time

import numpy as np
import pytest

from gagen.apps.cooperative.bundled import bundled_systems, ready_configuration
from gagen.cli import main as gagen_main
from gagen.viewer.geometry import system_pose
from gagen.viewer.scene import Scene, serve

pytest.importorskip("viser")  # the viewer extra


@pytest.fixture(scope="module")
def scene():
    system = bundled_systems()["three_pandas_circle"]
    with Scene(system, ready_configuration(system), port=0) as s:
        yield s


def _outside_address() -> str | None:
    """An address of this machine other than loopback (the one its default route uses), if any."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect(("10.255.255.255", 1))  # UDP: no packet is sent
            address = probe.getsockname()[0]
        except OSError:
            return None
    return None if address.startswith("127.") or address == "0.0.0.0" else address


def test_the_server_listens_on_loopback_only(scene):
    assert scene.url == f"http://127.0.0.1:{scene.port}/?token={scene.token}"
    logger = logging.getLogger("websockets.server")  # a bare TCP connection makes it log a traceback
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        with socket.create_connection(("127.0.0.1", scene.port), timeout=5):
            pass
    finally:
        logger.setLevel(level)
    outside = _outside_address()
    if outside is None:
        pytest.skip("this machine has no non-loopback address to try")
    with pytest.raises(OSError), socket.create_connection((outside, scene.port), timeout=2):
        pass
    with pytest.raises(ValueError, match="loopback"):
        Scene(scene.system, host="0.0.0.0", port=0)


def test_nodes_follow_the_configuration(scene):
    q = np.random.default_rng(11).uniform(-1, 1, scene.system.dof)
    scene.update(q)
    poses = system_pose(scene.system, q)
    for c, i, handle in scene._joints:
        np.testing.assert_allclose(handle.position, poses[c].origins[i], atol=1e-6)  # float32 on the wire
    for c, i, handle in scene._links:
        length = np.linalg.norm(poses[c].origins[i + 1] - poses[c].origins[i])
        assert handle.visible == (length > 1e-6)  # a joint's zero-length offset draws nothing
        if handle.visible:
            np.testing.assert_allclose(handle.scale, (1.0, 1.0, length), rtol=1e-6)
            middle = 0.5 * (poses[c].origins[i] + poses[c].origins[i + 1])
            np.testing.assert_allclose(handle.position, middle, atol=1e-6)
    points = np.array([p.end_point for p in poses])
    spheres = [h for h in scene._primitive if h.name.startswith("/primitive/point")]
    np.testing.assert_allclose([h.position for h in spheres], points, atol=1e-6)
    assert scene.shape.kind == "circle"
    np.testing.assert_allclose(np.linalg.norm(points - scene.shape.centre, axis=1), scene.shape.radius)
    scene.show_primitive(False)
    assert not any(h.visible for h in scene._primitive)
    assert scene._toggle.value is False  # the panel's checkbox follows
    scene.update(q)  # redrawn nodes stay hidden
    assert not any(h.visible for h in scene._primitive)
    scene.show_primitive(True)
    assert all(h.visible for h in scene._primitive)


def test_degenerate_points_draw_the_polyline_through_them(scene):
    scene._draw_primitive(np.array([[0.0, 0, 0.5], [0.1, 0.1, 0.5], [0.2, 0.2, 0.5]]))  # collinear
    assert scene.shape.degenerate
    (lines,) = [h for h in scene._primitive if h.name == "/primitive/lines"]
    a, b, c = [0, 0, 0.5], [0.1, 0.1, 0.5], [0.2, 0.2, 0.5]
    np.testing.assert_allclose(lines.points, [[a, b], [b, c]], atol=1e-7)
    scene.update(ready_configuration(scene.system))
    assert not scene.shape.degenerate


def test_play_runs_in_real_time_and_ends_on_the_last_configuration(scene):
    q0 = np.array(ready_configuration(scene.system))
    times = np.linspace(0.0, 0.3, 301)  # 1 kHz samples: shown at the viewer's frame rate
    qs = q0 + np.outer(times, np.ones(scene.system.dof))
    start = time.monotonic()
    scene.play(times, qs)
    elapsed = time.monotonic() - start
    assert 0.3 <= elapsed < 3.0  # real time, with room for a loaded machine
    np.testing.assert_array_equal(scene.q, qs[-1])
    stop = threading.Event()
    stop.set()
    start = time.monotonic()
    scene.play(times, qs, loop=True, stop=stop)  # a set stop event ends even a looping play at once
    assert time.monotonic() - start < 0.5


def test_malformed_input_is_refused(scene):
    with pytest.raises(ValueError, match="expected 21 finite joint values, got 3"):
        scene.update([0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="not all finite"):
        scene.update(np.full(21, np.nan))
    with pytest.raises(ValueError, match="2 times for 3 configurations"):
        scene.play([0.0, 1.0], np.zeros((3, 21)))
    with pytest.raises(ValueError, match="times must increase"):
        scene.play([1.0, 0.0], np.zeros((2, 21)))
    with pytest.raises(ValueError, match="frames 'some'"):
        Scene(scene.system, port=0, frames="some")


def test_serve_plays_the_runs_until_stopped():
    system = bundled_systems()["three_pandas_circle"]
    q0 = np.array(ready_configuration(system))
    runs = [("first", [0.0, 0.1], [q0, q0 + 0.1]), ("second", [0.0, 0.1], [q0 + 0.2, q0 + 0.3])]
    stop = threading.Event()
    scene = Scene(system, q0, port=0)
    thread = threading.Thread(target=serve, args=(scene, runs), kwargs={"stop": stop}, daemon=True)
    thread.start()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and not np.allclose(scene.q, q0 + 0.3):  # the second run's end
        time.sleep(0.02)
    np.testing.assert_allclose(scene.q, q0 + 0.3)
    stop.set()
    thread.join(5)
    assert not thread.is_alive()
    with pytest.raises(OSError):  # the server is stopped
        socket.create_connection(("127.0.0.1", scene.port), timeout=2).close()


@pytest.mark.slow  # the nullspace demo's run and plot: 3 s
def test_the_demos_view_flags_play_their_trajectories(monkeypatch, tmp_path):
    """``gagen nullspace --view`` and ``gagen reach … --view`` hand their joint trajectories to serve()."""
    from types import SimpleNamespace

    from gagen.apps.cooperative import scenarios
    from gagen.viewer import scene as scene_module

    served = []

    def fake_serve(scene, runs, **_):
        served.append((scene.system.name, scene.host, [(label, np.shape(qs)) for label, _, qs in runs]))
        scene.close()

    monkeypatch.setattr(scene_module, "serve", fake_serve)
    assert gagen_main(["nullspace", "--out", str(tmp_path), "--steps", "4", "--view", "--port", "0"]) == 0
    assert served.pop() == ("three_pandas_circle", "127.0.0.1", [("projected: q̇ = N(q) q̇_sec", (5, 21)),
                                                                 ("not projected: q̇ = q̇_sec", (5, 21))])
    q = np.zeros((11, 17))
    result = SimpleNamespace(scenario=scenarios.SCENARIOS["line"], result=SimpleNamespace(dt=0.025, q=q))
    scenarios.view([result], port=0)
    assert served.pop() == ("g1_arms_line", "127.0.0.1", [("line", (11, 17))])
