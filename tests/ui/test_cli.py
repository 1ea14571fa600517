"""``meshfit ui``: arguments, defaults (loopback only) and refused input, without a browser."""

from __future__ import annotations

import urllib.request

import pytest

from meshfit.cli import build_parser, main
from meshfit.ui.cli import build_app
from tests.conftest import mesh_path
from tests.ui.helpers import SPOT_LAYOUT


def test_defaults_bind_loopback():
    args = build_parser().parse_args(["ui"])
    assert args.host == "127.0.0.1" and args.port == 8080 and args.mesh is None


def test_app_serves_the_mesh_and_layout(tmp_path):
    args = build_parser().parse_args(
        [
            "ui",
            str(mesh_path("spot")),
            "--layout",
            str(SPOT_LAYOUT),
            "--port",
            "0",
            "--workdir",
            str(tmp_path),
        ]
    )
    app = build_app(args)
    try:
        assert app.server.get_host() == "127.0.0.1"
        page = urllib.request.urlopen(f"http://127.0.0.1:{app.port}/", timeout=30).read()
        assert b"<html" in page.lower()
        s = app.session
        assert s.mesh.name == "spot.ply" and len(s.curves) > 0 and s.status().complete
        # files named on the command line are allowed even outside the working folder
        assert app.policy.check(str(SPOT_LAYOUT), suffixes=(".json",)) == SPOT_LAYOUT.resolve()
        assert s.autosave_path == (tmp_path / "spot.session.json").resolve()
        assert s.flush() and s.autosave_path.is_file()  # loading the layout was a change
    finally:
        app.stop()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["ui", "--workdir", "/no/such/folder", "--port", "0"], "no such folder"),
        (["ui", "--port", "70000"], "--port must be"),
        (["ui", "missing.ply", "--port", "0"], "missing.ply"),
        (["ui", "--max-upload-mb", "0", "--port", "0"], "--max-upload-mb"),
    ],
)
def test_bad_arguments(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("meshfit: error:") and message in err


def test_restart_resumes_the_autosave(tmp_path):
    argv = ["ui", str(mesh_path("spot")), "--port", "0", "--workdir", str(tmp_path)]
    app = build_app(build_parser().parse_args(argv))
    try:
        app.session.load_layout(SPOT_LAYOUT)
        app.session.delete_curve(0)
        n = len(app.session.curves)
    finally:
        app.stop()  # as good as a crash: nothing but the autosave file is kept
    again = build_app(build_parser().parse_args(argv))
    try:
        assert len(again.session.curves) == n
        assert again.session.can_undo  # the restore itself can be undone
    finally:
        again.stop()


@pytest.mark.parametrize(
    "text",
    [
        '{"meshfit_ui_session": 1, "mesh": {}}',  # another mesh's
        "{not json",
        '{"meshfit_ui_session": 2, "mesh": []}',
    ],
)
def test_an_autosave_that_cannot_be_resumed_is_moved_aside(tmp_path, capsys, text):
    """A damaged, hand-edited or foreign session file is never overwritten: it is renamed
    beside itself, the app says so and starts a new session."""
    (tmp_path / "spot.session.json").write_text(text)
    argv = ["ui", str(mesh_path("spot")), "--port", "0", "--workdir", str(tmp_path)]
    app = build_app(build_parser().parse_args(argv))
    try:
        assert not app.session.curves and not app.session.can_undo
        moved = tmp_path / "spot.session.unreadable-1.json"
        assert moved.read_text() == text
        out = capsys.readouterr().out
        assert f"moved it to {moved.name} and started a new session" in out
        assert sum("moved it to" in ln for ln in out.splitlines()) == 1
    finally:
        app.stop()


def test_restart_of_an_empty_session_resumes_it(tmp_path):
    """A session with nothing painted yet (no corners) is autosaved and resumed."""
    argv = ["ui", str(mesh_path("spot")), "--port", "0", "--workdir", str(tmp_path)]
    app = build_app(build_parser().parse_args(argv))
    try:
        app.session.autosave()
    finally:
        app.stop()
    assert (tmp_path / "spot.session.json").is_file()
    again = build_app(build_parser().parse_args(argv))
    try:
        assert len(again.session.curves) == 0
    finally:
        again.stop()
