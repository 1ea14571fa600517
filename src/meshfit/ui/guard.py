"""Same-origin guard of the app's server: HTTP and websocket requests from other origins
are refused at the handshake.

Browsers let any web page open a websocket to ``ws://127.0.0.1:<port>``, and a name that
a hostile DNS server points at 127.0.0.1 reaches the app as that page's own origin (DNS
rebinding). So every request must name the app in ``Host`` (a loopback name and the
app's port when it is bound to loopback), and a request from a browser (``Origin``) must
come from a page of that same host: ``http://<Host>``. Other local programs, which send
no ``Origin``, already run as the user and are let in.

Bound to anything but loopback, the app is reachable from other machines: it then also
asks for a per-run token (:func:`new_token`), which the address it prints carries as
``?token=``; the page's response sets it as a cookie (HttpOnly, SameSite=Strict), which the
browser sends with the page's assets and its websocket, as Jupyter does.

viser builds its server with ``websockets.asyncio.server.serve`` and answers HTTP through
its ``process_request`` hook; :func:`install` wraps that function once per process, so
the check runs first for every server viser starts here.
"""

from __future__ import annotations

import http
import secrets
from http.cookies import SimpleCookie
from typing import Any
from urllib.parse import parse_qs, urlsplit

__all__ = ["LOOPBACK_HOSTS", "LOOPBACK_NAMES", "allowed", "install", "new_token"]

#: names a browser may use for a server bound to loopback
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")
#: addresses a server may be bound to that are loopback
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")
#: the cookie that carries the token
COOKIE = "meshfit_token"
#: tokens of this process's apps bound beyond loopback
_TOKENS: set[str] = set()


def new_token() -> str:
    """A per-run token for an app bound beyond loopback (registered with the guard)."""
    token = secrets.token_urlsafe(24)
    _TOKENS.add(token)
    return token


def _token_of(request) -> tuple[str | None, bool]:
    """The token a request carries and whether it came in the URL (not the cookie)."""
    query = parse_qs(urlsplit(request.path).query).get("token")
    if query:
        return query[0], True
    jar = SimpleCookie()
    try:
        jar.load(request.headers.get("Cookie", ""))
    except Exception:  # (a malformed cookie header carries no token)
        return None, False
    return (jar[COOKIE].value if COOKIE in jar else None), False


def allowed(headers, port: int, loopback: bool) -> str | None:
    """None when the request may go on, else why it is refused."""
    host = headers.get("Host", "")
    if loopback and host not in {f"{name}:{port}" for name in LOOPBACK_NAMES}:
        return f"Host {host!r} is not this app's address"
    origin = headers.get("Origin")
    if origin is not None and origin != f"http://{host}":
        return f"Origin {origin!r} is not this app's page"
    return None


def install() -> None:
    """Wrap ``websockets.asyncio.server.serve`` so every server checks :func:`allowed`
    before its own ``process_request`` (idempotent)."""
    import websockets.asyncio.server as srv

    if getattr(srv.serve, "_meshfit_guard", False):
        return
    original = srv.serve

    def serve(handler, host=None, port=None, *args: Any, process_request=None, **kw: Any):
        loopback = host in LOOPBACK_HOSTS

        def check(connection, request):
            why = allowed(request.headers, connection.local_address[1], loopback)
            token, in_url = (None, False) if loopback else _token_of(request)
            if why is None and not loopback and token not in _TOKENS:
                why = "open the address meshfit ui printed, with its token"
            if why is not None:
                return connection.respond(http.HTTPStatus.FORBIDDEN, f"Forbidden: {why}\n")
            out = process_request(connection, request) if process_request else None
            if out is not None and in_url:
                out.headers["Set-Cookie"] = f"{COOKIE}={token}; HttpOnly; SameSite=Strict; Path=/"
            return out

        return original(handler, host, port, *args, process_request=check, **kw)

    serve._meshfit_guard = True  # type: ignore[attr-defined]
    srv.serve = serve  # type: ignore[assignment]
