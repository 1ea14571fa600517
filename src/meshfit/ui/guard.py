"""Same-origin guard of the app's server: HTTP and websocket requests from other origins
are refused at the handshake.

Browsers let any web page open a websocket to ``ws://127.0.0.1:<port>``, and a name that
a hostile DNS server points at 127.0.0.1 reaches the app as that page's own origin (DNS
rebinding). So every request must name the app in ``Host`` (a loopback name and the
app's port when it is bound to loopback), and a request from a browser (``Origin``) must
come from a page of that same host: ``http://<Host>``. Other local programs, which send
no ``Origin``, already run as the user and are let in.

viser builds its server with ``websockets.asyncio.server.serve`` and answers HTTP through
its ``process_request`` hook; :func:`install` wraps that function once per process, so
the check runs first for every server viser starts here.
"""

from __future__ import annotations

import http
from typing import Any

__all__ = ["LOOPBACK_NAMES", "allowed", "install"]

#: names a browser may use for a server bound to loopback
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")


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
        loopback = host in ("127.0.0.1", "localhost", "::1")

        def check(connection, request):
            why = allowed(request.headers, connection.local_address[1], loopback)
            if why is not None:
                return connection.respond(http.HTTPStatus.FORBIDDEN, f"Forbidden: {why}\n")
            return process_request(connection, request) if process_request else None

        return original(handler, host, port, *args, process_request=check, **kw)

    serve._meshfit_guard = True  # type: ignore[attr-defined]
    srv.serve = serve  # type: ignore[assignment]
