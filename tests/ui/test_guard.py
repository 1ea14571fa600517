"""The app answers only its own origin: a web page elsewhere cannot open its websocket or
read its pages, and a name pointed at 127.0.0.1 (DNS rebinding) is not its address."""

from __future__ import annotations

import urllib.error
import urllib.request

import pytest
import viser
import websockets.sync.client as ws_client

from meshfit.cli import build_parser
from meshfit.ui.cli import build_app
from meshfit.ui.guard import allowed
from tests.conftest import mesh_path


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    work = tmp_path_factory.mktemp("guard")
    argv = ["ui", str(mesh_path("spot")), "--port", "0", "--workdir", str(work)]
    a = build_app(build_parser().parse_args(argv))
    yield a
    a.stop()


def _connect(port: int, origin: str | None):
    return ws_client.connect(
        f"ws://127.0.0.1:{port}",
        origin=origin,
        subprotocols=[f"viser-v{viser.__version__}"],
        open_timeout=10,
    )


def test_a_websocket_from_another_origin_is_refused(app):
    with pytest.raises(Exception, match="HTTP 403"):
        _connect(app.port, "http://evil.example.com")
    with pytest.raises(Exception, match="HTTP 403"):
        _connect(app.port, f"http://localhost:{app.port + 1}")
    # the app's own page, and a local program that sends no Origin, are let in
    for origin in (f"http://127.0.0.1:{app.port}", None):
        _connect(app.port, origin).close()


def test_a_host_that_is_not_the_app_is_refused(app):
    def status(host: str) -> int:
        req = urllib.request.Request(f"http://127.0.0.1:{app.port}/", headers={"Host": host})
        try:
            return urllib.request.urlopen(req, timeout=10).status
        except urllib.error.HTTPError as exc:
            return exc.code

    assert status("evil.example.com") == 403
    assert status(f"evil.example.com:{app.port}") == 403
    assert status(f"localhost:{app.port}") == 200


@pytest.mark.parametrize(
    "headers, loopback, ok",
    [
        ({"Host": "127.0.0.1:8080"}, True, True),
        ({"Host": "[::1]:8080", "Origin": "http://[::1]:8080"}, True, True),
        ({"Host": "10.0.0.5:8080", "Origin": "http://10.0.0.5:8080"}, False, True),
        ({"Host": "10.0.0.5:8080"}, True, False),
        ({"Host": "127.0.0.1:8081"}, True, False),
        ({"Host": "10.0.0.5:8080", "Origin": "http://evil.example.com"}, False, False),
        ({"Host": "127.0.0.1:8080", "Origin": "null"}, True, False),
    ],
)
def test_the_rule(headers, loopback, ok):
    assert (allowed(headers, 8080, loopback) is None) == ok


def test_an_upload_over_the_cap_is_refused_as_its_bytes_arrive(tmp_path):
    """Declared over the cap, an upload is never buffered; declared under it, its buffer is
    dropped at the part that passes the cap (a client may lie about the size), so no more
    than the cap is ever held for it."""
    import asyncio

    from viser._messages import FileTransferPart, FileTransferStartUpload

    argv = ["ui", str(mesh_path("spot")), "--port", "0", "--workdir", str(tmp_path)]
    a = build_app(build_parser().parse_args([*argv, "--max-upload-mb", "1"]))
    try:
        gui = a.server.gui
        uuid = a.gui_upload._impl.uuid
        iface = gui._websock_interface

        def send(m):
            asyncio.run(iface._handle_incoming_message(0, m))

        send(FileTransferStartUpload(uuid, "t1", "big.ply", "*/*", 300, 300 * 1024 * 1024))
        assert "t1" not in gui._current_file_upload_states
        assert "refused" in a.messages[-1] and "big.ply" in a.messages[-1]
        chunk = b"x" * (256 * 1024)
        send(FileTransferStartUpload(uuid, "t2", "liar.ply", "*/*", 10, 1000))
        held = []
        for i in range(10):
            send(FileTransferPart(uuid, "t2", i, chunk))
            state = gui._current_file_upload_states.get("t2")
            held.append(0 if state is None else state["transferred_bytes"])
        assert max(held) <= 1024 * 1024 and held[-1] == 0
        assert "refused" in a.messages[-1] and "liar.ply" in a.messages[-1]
    finally:
        a.stop()


def test_bound_beyond_loopback_the_app_asks_for_its_token(tmp_path):
    """On 0.0.0.0 the printed address carries a per-run token; the page's response sets it
    as a cookie, which then lets the page's assets and its websocket in; without it every
    request is refused."""
    from meshfit.ui.guard import COOKIE

    argv = ["ui", str(mesh_path("spot")), "--port", "0", "--workdir", str(tmp_path)]
    a = build_app(build_parser().parse_args([*argv, "--host", "0.0.0.0"]))
    try:
        token = a.token
        assert token and a.url("0.0.0.0").endswith(f"/?token={token}")
        base = f"http://127.0.0.1:{a.port}"

        def get(path: str, headers=None):
            req = urllib.request.Request(base + path, headers=headers or {})
            try:
                with urllib.request.urlopen(req, timeout=10) as r:
                    return r.status, r.headers.get("Set-Cookie", "")
            except urllib.error.HTTPError as exc:
                return exc.code, ""

        assert get("/")[0] == 403
        assert get("/?token=wrong")[0] == 403
        status, cookie = get(f"/?token={token}")
        assert status == 200 and cookie.startswith(f"{COOKIE}={token};") and "HttpOnly" in cookie
        assert get("/", {"Cookie": f"{COOKIE}={token}"})[0] == 200
        with pytest.raises(Exception, match="HTTP 403"):
            _connect(a.port, base)
        ws_client.connect(
            f"ws://127.0.0.1:{a.port}",
            origin=base,
            additional_headers={"Cookie": f"{COOKIE}={token}"},
            subprotocols=[f"viser-v{viser.__version__}"],
            open_timeout=10,
        ).close()
    finally:
        a.stop()
