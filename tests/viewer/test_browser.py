"""A real headless browser draws the viewer: Chromium (software WebGL) renders three Pandas and their
circle, and the pixels show the primitive where the camera projects it — and nothing of its colour
once it is hidden. Also the PNG export from the command line. Each test starts a server on 127.0.0.1
and a browser, and stops both (bounded waits)."""

import os

import numpy as np
import pytest

from gagen.apps.cooperative.bundled import bundled_systems, ready_configuration
from gagen.viewer.browser import capturing, find_chromium, headless_browser
from gagen.viewer.geometry import ring, system_pose

viser = pytest.importorskip("viser")  # the viewer extra

MISSING = "no Chromium on PATH: apt-get install chromium (.ci/run installs it), or set GAGEN_CHROMIUM"
pytestmark = pytest.mark.slow  # a browser start and software rendering: 5-25 s a test


@pytest.fixture(autouse=True)
def chromium():
    """Skip without Chromium, except in CI, which installs it (.ci/run): there its absence fails."""
    if find_chromium() is None:
        if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
            pytest.fail(f"{MISSING}: CI must run the browser tests")
        pytest.skip(MISSING)

WIDTH, HEIGHT = 800, 600


def primitive_pixels(image: np.ndarray) -> np.ndarray:
    """Mask of the primitive's colour (magenta, lit or not): red and blue well above green."""
    r, g, b, a = (image[..., k].astype(int) for k in range(4))
    return (a > 128) & (r - g > 90) & (b - g > 90) & (abs(r - b) < 90)


def joint_pixels(image: np.ndarray) -> np.ndarray:
    """Mask of the joints' orange."""
    r, g, b, a = (image[..., k].astype(int) for k in range(4))
    return (a > 128) & (r > 140) & (r - b > 90) & (g > 50) & (r - g > 40)


def _distances(pixels: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """For each pixel (row, column), the distance to the nearest target point (u, v)."""
    ys, xs = np.nonzero(pixels)
    d = np.hypot(xs[:, None] - targets[None, :, 0], ys[:, None] - targets[None, :, 1])
    return d.min(axis=1)


def _near(mask: np.ndarray, uv: np.ndarray, radius: float) -> np.ndarray:
    """For each point (u, v), whether a masked pixel lies within ``radius`` pixels."""
    ys, xs = np.nonzero(mask)
    d = np.hypot(uv[:, None, 0] - xs[None, :], uv[:, None, 1] - ys[None, :])
    return (d <= radius).any(axis=1)


def test_the_primitive_is_drawn_where_the_camera_puts_it(tmp_path):
    from gagen.viewer.scene import Scene

    system = bundled_systems()["three_pandas_circle"]
    q = np.array(ready_configuration(system))
    with Scene(system, q, port=0) as scene:
        camera = scene.default_camera(WIDTH / HEIGHT)
        with capturing(scene, width=WIDTH, height=HEIGHT, timeout=90) as frame:
            shown = frame(camera)
            scene.show_primitive(False)
            hidden = frame(camera)
            s, ball_radius = scene.shape, scene._point_radius
            # live: arm0 turns at its first joint, and the next frame shows the new circle
            q_moved = q.copy()
            q_moved[0] += 0.6
            scene.show_primitive(True)
            scene.update(q_moved)
            moved, moved_shape = frame(camera), scene.shape
    assert shown.shape == (HEIGHT, WIDTH, 4)

    circle = camera.project(ring(s.centre, s.radius, s.normal, 2000), WIDTH, HEIGHT)
    points = camera.project(s.points, WIDTH, HEIGHT)
    magenta = primitive_pixels(shown)
    count = int(magenta.sum())
    assert count > 1500, f"only {count} pixels of the primitive's colour"
    # every one of them on the projected circle or on a spanning point's ball (its radius projected)
    depth = (s.points - camera.position) @ camera.rotation()[:, 2]
    ball = (HEIGHT / 2 / np.tan(camera.fov / 2)) * ball_radius / depth.min()
    d = np.minimum(_distances(magenta, circle), _distances(magenta, points) - ball)
    assert np.mean(d <= 3.0) > 0.995, f"{np.mean(d > 3.0):.1%} of the primitive's pixels are off the circle"
    # and the circle drawn all round, but where an arm or a frame passes in front of it (a camera moved
    # by 5 cm sideways makes this 0.43)
    covered = _near(magenta, circle[::10], 3.0)
    assert covered.mean() > 0.7, f"the circle shows at {covered.mean():.0%} of its projected samples"

    moved_circle = camera.project(ring(moved_shape.centre, moved_shape.radius, moved_shape.normal, 2000),
                                  WIDTH, HEIGHT)
    moved_points = camera.project(moved_shape.points, WIDTH, HEIGHT)

    def off_moved(mask: np.ndarray) -> float:  # the fraction of the mask's pixels off the moved primitive
        d = np.minimum(_distances(mask, moved_circle), _distances(mask, moved_points) - ball)
        return float(np.mean(d > 3.0))

    assert off_moved(magenta) > 0.3  # the first frame's circle is not the moved one: the check can fail
    assert off_moved(primitive_pixels(moved)) < 0.005, "the moved primitive is not drawn where it projects"

    hidden_count = int(primitive_pixels(hidden).sum())
    assert hidden_count < 0.005 * count, f"{hidden_count} pixels of the primitive's colour with it hidden"
    # the robots are still drawn: an orange joint ball where each joint origin projects (a few hidden)
    origins = np.vstack([pose.origins[:-1][list(pose.moving)] for pose in system_pose(system, q)])
    seen = _near(joint_pixels(hidden), camera.project(origins, WIDTH, HEIGHT), 4.0)
    assert seen.mean() > 0.75, f"only {seen.sum()} of {len(seen)} joints are drawn where they project"


def test_a_browser_needs_the_printed_url():
    """The page without its ?token= gets no scene (gagen.viewer.access): the browser opened on the bare
    address first, and one opened later on the printed URL, are given as long; only the second connects."""
    import time

    from gagen.viewer.scene import Scene

    system = bundled_systems()["two_pandas_point_pair"]
    with Scene(system, port=0) as scene:
        bare = scene.url.split("?")[0]
        assert bare != scene.url
        with headless_browser(bare, width=320, height=240), \
                headless_browser(scene.url, width=320, height=240) as browser:
            try:
                scene.wait_for_client(90)
            except TimeoutError as e:
                pytest.fail(f"{e}; {browser.state()}")
            time.sleep(2.0)
            assert len(scene.server.get_clients()) == 1


def test_frames_of_a_trajectory(tmp_path):
    import cv2

    from gagen.viewer.browser import export_frames

    system = bundled_systems()["two_pandas_point_pair"]
    q0 = np.array(ready_configuration(system))
    paths = export_frames(system, [q0, q0 + 0.3], tmp_path, width=320, height=240)
    assert [p.name for p in paths] == ["frame_0000.png", "frame_0001.png"]
    first, second = (cv2.imread(str(p)) for p in paths)
    assert first.shape == (240, 320, 3)
    assert np.mean(np.any(first != second, axis=2)) > 0.01  # the robots moved between the frames


def test_png_export_from_the_command_line(tmp_path):
    import cv2

    from gagen.viewer.command import main

    path = tmp_path / "frame.png"
    assert main(["three_pandas_circle", "--png", str(path), "--size", "640x480"]) == 0
    image = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)
    assert image.shape == (480, 640, 3)  # flattened onto white
    rgba = np.dstack([image, np.full(image.shape[:2], 255, np.uint8)])
    assert primitive_pixels(rgba).sum() > 800
    assert (image == 255).all(axis=2).mean() > 0.3  # the white background around the scene
