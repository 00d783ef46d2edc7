"""Who may use the viewer: listening on 127.0.0.1 is not enough, since any web page the user opens can
make the browser request http://127.0.0.1:PORT (a DNS-rebinding page even reads the answers). So the
server wants the per-run token of the URL it prints (or the cookie the first page sets with it), a Host
header that names the loopback interface, and no Origin but its own — for pages and websockets alike.
Raw HTTP here (http.client, to set any header) and websockets' own client; the real browser, which
must still get in through the printed URL, is tests/viewer/test_browser.py."""

import base64
import http.client
import logging
import os
import re
from collections.abc import Iterator

import pytest

from gagen.apps.cooperative.bundled import bundled_systems, ready_configuration
from gagen.viewer.scene import Scene

viser = pytest.importorskip("viser")  # the viewer extra
from websockets.exceptions import InvalidStatus  # noqa: E402  (viser brings websockets)
from websockets.sync.client import connect  # noqa: E402


@pytest.fixture(scope="module")
def scene() -> Iterator[Scene]:
    system = bundled_systems()["three_pandas_circle"]
    logger = logging.getLogger("websockets.server")  # a refused or dropped handshake logs at ERROR
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        with Scene(system, ready_configuration(system), port=0) as s:
            yield s
    finally:
        logger.setLevel(level)


def token(scene: Scene) -> str:
    match = re.fullmatch(rf"http://127\.0\.0\.1:{scene.port}/\?token=([A-Za-z0-9_-]{{32,}})", scene.url)
    assert match, f"no token in {scene.url}"
    return match[1]


def request(scene: Scene, path: str, headers: dict[str, str] | None = None,
            websocket: bool = False) -> tuple[int, http.client.HTTPResponse]:
    """(status, response) of a GET on the scene's port; ``websocket``: as a websocket upgrade (viser's
    subprotocol). Host defaults to 127.0.0.1:PORT, as a browser sends it."""
    headers = {"Host": f"127.0.0.1:{scene.port}", **(headers or {})}
    if websocket:
        headers |= {"Connection": "Upgrade", "Upgrade": "websocket", "Sec-WebSocket-Version": "13",
                    "Sec-WebSocket-Key": base64.b64encode(os.urandom(16)).decode(),
                    "Sec-WebSocket-Protocol": f"viser-v{viser.__version__}"}
    connection = http.client.HTTPConnection("127.0.0.1", scene.port, timeout=10)
    try:
        connection.request("GET", path, headers=headers)
        response = connection.getresponse()
        if response.status != 101:
            response.read()
        return response.status, response
    finally:
        connection.close()


def cookie(scene: Scene) -> str:
    """The cookie the page served for the token sets (``name=value``)."""
    status, response = request(scene, f"/?token={token(scene)}")
    assert status == 200
    set_cookie = response.headers.get("Set-Cookie")
    assert set_cookie, "the page served for the token sets no cookie"
    attributes = [a.strip().lower() for a in set_cookie.split(";")]
    assert "httponly" in attributes and "samesite=strict" in attributes
    return set_cookie.split(";")[0].strip()


def test_the_printed_url_carries_a_fresh_token(scene):
    assert len(token(scene)) >= 32
    with Scene(scene.system, port=0) as other:
        assert token(other) != token(scene)


def test_pages_need_the_token(scene):
    assert request(scene, "/")[0] == 403
    assert request(scene, "/index.html")[0] == 403
    assert request(scene, "/?token=wrong")[0] == 403
    assert request(scene, f"/?token={token(scene)[:-1]}")[0] == 403
    assert request(scene, "/?token=%C3%A9")[0] == 403  # not ASCII
    assert request(scene, f"/?token={token(scene)}")[0] == 200
    # then the page's own requests (its scripts, its websocket) carry the cookie it was given
    assert request(scene, "/", {"Cookie": cookie(scene)})[0] == 200
    assert request(scene, "/", {"Cookie": cookie(scene) + "x"})[0] == 403
    name = cookie(scene).split("=")[0]
    assert request(scene, "/", {"Cookie": f"{name}=wrong"})[0] == 403


def test_a_foreign_host_is_refused(scene):
    """DNS rebinding: a page of evil.example whose name now resolves to 127.0.0.1 sends its own Host."""
    page = f"/?token={token(scene)}"
    assert request(scene, page, {"Host": f"evil.example:{scene.port}"})[0] == 403
    assert request(scene, page, {"Host": "evil.example"})[0] == 403
    assert request(scene, page, {"Host": f"127.0.0.1:{scene.port + 1}"})[0] == 403
    assert request(scene, "/", {"Host": f"evil.example:{scene.port}", "Cookie": cookie(scene)})[0] == 403
    assert request(scene, page, {"Host": f"localhost:{scene.port}"})[0] == 200


def test_a_foreign_origin_is_refused(scene):
    page = f"/?token={token(scene)}"
    assert request(scene, page, {"Origin": "http://evil.example"})[0] == 403
    assert request(scene, page, {"Origin": "null"})[0] == 403
    assert request(scene, page, {"Origin": f"http://127.0.0.1:{scene.port}"})[0] == 200


def test_websockets_need_the_token_a_loopback_host_and_their_own_origin(scene):
    own = f"http://127.0.0.1:{scene.port}"
    assert request(scene, "/", websocket=True)[0] == 403
    assert request(scene, "/", {"Origin": own}, websocket=True)[0] == 403
    assert request(scene, "/?token=wrong", {"Origin": own}, websocket=True)[0] == 403
    foreign = {"Origin": "http://evil.example", "Cookie": cookie(scene)}
    assert request(scene, "/", foreign, websocket=True)[0] == 403
    rebound = {"Host": f"evil.example:{scene.port}", "Origin": f"http://evil.example:{scene.port}",
               "Cookie": cookie(scene)}
    assert request(scene, "/", rebound, websocket=True)[0] == 403
    assert request(scene, "/", {"Origin": own, "Cookie": cookie(scene)}, websocket=True)[0] == 101
    assert request(scene, f"/?token={token(scene)}", websocket=True)[0] == 101


def test_a_websocket_client_with_the_cookie_gets_the_scene(scene):
    """viser's page opens ws://127.0.0.1:PORT without the query string: the cookie lets it in."""
    uri = f"ws://127.0.0.1:{scene.port}"
    subprotocols = [f"viser-v{viser.__version__}"]
    with pytest.raises(InvalidStatus) as refused:
        connect(uri, subprotocols=subprotocols, open_timeout=10).close()
    assert refused.value.response.status_code == 403
    with connect(uri, subprotocols=subprotocols, origin=f"http://127.0.0.1:{scene.port}",
                 additional_headers={"Cookie": cookie(scene)}, open_timeout=10) as websocket:
        assert websocket.recv(timeout=10)  # the scene's messages


@pytest.mark.parametrize(("host", "origin", "allowed"), [
    ("127.0.0.1:8080", None, True),
    ("localhost:8080", "http://localhost:8080", True),
    ("[::1]:8080", "http://[::1]:8080", True),
    ("LOCALHOST:8080", "http://127.0.0.1:8080", True),
    ("127.0.0.1:8081", None, False),
    ("127.0.0.1", None, False),  # port 80
    ("127.0.0.1:http", None, False),
    ("evil@127.0.0.1:8080", None, False),
    ("127.0.0.1.evil.example:8080", None, False),
    ("", None, False),
    ("127.0.0.1:8080", "https://127.0.0.1:8080", False),
    ("127.0.0.1:8080", "http://127.0.0.1:8081", False),
    ("127.0.0.1:8080", "http://127.0.0.1", False),
])
def test_hosts_and_origins(host, origin, allowed):
    from websockets.datastructures import Headers
    from websockets.http11 import Request

    from gagen.viewer.access import Guard

    headers = Headers(Host=host) if origin is None else Headers(Host=host, Origin=origin)
    refusal = Guard("t0ken").refusal(8080, Request("/?token=t0ken", headers))
    assert (refusal is None) == allowed, refusal


def test_a_viser_that_cannot_be_guarded_is_not_served(scene, monkeypatch):
    """Should viser start its server some other way, the check is not in front of it: no Scene then."""
    import contextlib

    import websockets.asyncio.server

    from gagen.viewer import access

    original = websockets.asyncio.server.serve
    with Scene(scene.system, port=0):
        assert websockets.asyncio.server.serve is original  # the patch lasts only for the start

    @contextlib.contextmanager
    def unguarded(guard: access.Guard) -> Iterator[list[bool]]:
        yield []

    monkeypatch.setattr(access, "guarded", unguarded)
    with pytest.raises(RuntimeError, match="cannot put the viewer's access check in front of its server"):
        Scene(scene.system, port=0)
