"""Who may use a viewer's server: the holder of its per-run token, through a loopback name, from its own
page — checked on every HTTP request and websocket handshake before viser answers.

Listening on 127.0.0.1 keeps other machines out, not other web pages: any page the user opens can make
the browser request http://127.0.0.1:PORT, and a DNS-rebinding page (its own name made to resolve to
127.0.0.1) can even read the answers and open the websocket. So, as Jupyter does:

- a random token (``secrets.token_urlsafe``) in the URL the viewer prints, ``http://127.0.0.1:PORT/?token=…``;
  the page served for it sets an HttpOnly, SameSite=Strict cookie holding the token, which the page's
  own requests carry — its scripts, and its websocket, which viser's client opens at the page's URL
  *without* the query string. A request with neither the token nor the cookie gets 403;
- the Host header must name the loopback interface (127.0.0.1, localhost or [::1]) and the server's
  port: a rebinding page sends its own name;
- an Origin header, where there is one (browsers send it with every websocket handshake), must be the
  server's own.

viser builds its request handler (it serves the client's files) inside its server thread and hands it to
``websockets.asyncio.server.serve`` as ``process_request``; it offers no hook of its own. ``guarded``
replaces that function while a ``viser.ViserServer`` is constructed (which starts the server), so that
viser's handler is wrapped in the check before the first connection is accepted, and says whether it
was: a viser that starts its server some other way gets no Scene (fail closed, see ``Scene``).
"""

from __future__ import annotations

import contextlib
import http
import inspect
import secrets
import threading
from collections.abc import Awaitable, Callable, Iterator
from typing import TYPE_CHECKING, Any
from urllib.parse import parse_qs, urlsplit

if TYPE_CHECKING:  # websockets comes with viser, the optional dependency
    from websockets.asyncio.server import ServerConnection
    from websockets.http11 import Request, Response

    ProcessRequest = Callable[[ServerConnection, Request], Awaitable[Response | None] | Response | None]

LOOPBACK_NAMES = ("127.0.0.1", "localhost", "::1")
COOKIE_PREFIX = "gagen-viewer-"  # + the port: cookies are per host, not per port, and viewers may share one
_patching = threading.Lock()  # one ViserServer starts under the patch at a time


def new_token() -> str:
    return secrets.token_urlsafe(32)


def cookie_name(port: int) -> str:
    return f"{COOKIE_PREFIX}{port}"


def _loopback_port(netloc: str) -> int | None:
    """The port of a Host header (or an Origin's host part) that names the loopback interface (port 80
    if none is given), or None for any other name, or a malformed one."""
    if not netloc or any(c in netloc for c in "@/?#\\ "):
        return None
    try:
        parts = urlsplit(f"//{netloc}")
        return (parts.port or 80) if parts.hostname in LOOPBACK_NAMES else None
    except ValueError:  # a port out of range, or not a number
        return None


def _cookies(request: Request) -> dict[str, str]:
    cookies: dict[str, str] = {}
    for header in request.headers.get_all("Cookie"):
        for pair in header.split(";"):
            name, _, value = pair.strip().partition("=")
            cookies.setdefault(name, value)
    return cookies


class Guard:
    """The check of one server's requests against its token; see the module docstring."""

    def __init__(self, token: str) -> None:
        self.token = token

    def refusal(self, port: int, request: Request) -> str | None:
        """Why ``request`` (to the server on ``port``) is refused, or None if it may pass."""
        if _loopback_port(request.headers.get("Host", "")) != port:
            return "the Host header does not name this viewer on the loopback interface"
        origin = request.headers.get("Origin")
        if origin is not None and not (origin.lower().startswith("http://")
                                       and _loopback_port(origin[len("http://"):]) == port):
            return "the request comes from another site's page"
        if not (self._given(request) or self._matches(_cookies(request).get(cookie_name(port), ""))):
            return "no valid token: open the URL the viewer printed, with its ?token="
        return None

    def _matches(self, text: str) -> bool:
        # in constant time; as bytes, since compare_digest refuses a str with non-ASCII characters
        return secrets.compare_digest(text.encode(), self.token.encode())

    def _given(self, request: Request) -> bool:
        """Whether the request's query string carries the token."""
        return any(self._matches(t) for t in parse_qs(urlsplit(request.path).query).get("token", []))

    def wrap(self, process_request: ProcessRequest | None) -> ProcessRequest:
        """viser's ``process_request`` behind the check; a page served for the token sets the cookie."""

        async def checked(connection: ServerConnection, request: Request) -> Response | None:
            port = int(connection.local_address[1])
            reason = self.refusal(port, request)
            if reason is not None:
                return connection.respond(http.HTTPStatus.FORBIDDEN, f"gagen viewer: {reason}\n")
            response = process_request(connection, request) if process_request is not None else None
            if inspect.isawaitable(response):
                response = await response
            if response is not None and response.status_code == 200 and self._given(request):
                response.headers["Set-Cookie"] = (f"{cookie_name(port)}={self.token}; Path=/; HttpOnly; "
                                                  f"SameSite=Strict")
            return response

        return checked


@contextlib.contextmanager
def guarded(guard: Guard) -> Iterator[list[bool]]:
    """For the block, each websockets server that viser starts has its ``process_request`` wrapped by
    ``guard``; yields a list that holds True for each one so wrapped (empty: none was)."""
    import websockets.asyncio.server as server

    wrapped: list[bool] = []
    original = server.serve

    def serve(handler: Callable[..., Any], *args: Any, process_request: ProcessRequest | None = None,
              **kwargs: Any) -> Any:
        if getattr(handler, "__module__", "").startswith("viser."):  # not another server of the process
            process_request = guard.wrap(process_request)
            wrapped.append(True)
        return original(handler, *args, process_request=process_request, **kwargs)

    with _patching:
        server.serve = serve  # type: ignore[misc, assignment]
        try:
            yield wrapped
        finally:
            server.serve = original  # type: ignore[misc]
