"""``meshfit ui``: open the painting and fitting web app on a mesh."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from meshfit._cliargs import add_repair_option
from meshfit.errors import InputError
from meshfit.mesh.io import load_cli_mesh

__all__ = ["add_commands", "build_app", "cmd_ui"]

LOOPBACK = ("127.0.0.1", "localhost", "::1")


def add_commands(sub) -> None:
    p = sub.add_parser(
        "ui",
        help="open the web app to paint curves, check the layout and preview the fit",
        description="Serve the meshfit web app (viser) on this machine. Only the files named "
        "here and files inside --workdir are read or written.",
    )
    p.add_argument("mesh", nargs="?", help="mesh file to open (or upload one in the app)")
    p.add_argument("--layout", help="layout JSON to load at start and to save to")
    p.add_argument(
        "--host",
        default="127.0.0.1",
        help="interface to listen on (default: %(default)s, this machine only)",
    )
    p.add_argument("--port", type=int, default=8080, help="TCP port (default: %(default)s)")
    p.add_argument(
        "--workdir",
        default=".",
        help="folder the app may read and write layouts and exports in (default: current)",
    )
    p.add_argument(
        "--autosave",
        help="session file rewritten after every change (default: "
        "<workdir>/<mesh name>.session.json)",
    )
    p.add_argument(
        "--max-upload-mb",
        type=float,
        default=200.0,
        help="largest mesh upload accepted, MB (default: %(default)s)",
    )
    add_repair_option(p)
    p.set_defaults(func=cmd_ui)


def build_app(args: argparse.Namespace):
    """The :class:`meshfit.ui.app.App` for parsed ``meshfit ui`` arguments (started)."""
    from meshfit.ui.app import App
    from meshfit.ui.files import FilePolicy
    from meshfit.ui.state import Session

    if not 0 <= int(args.port) <= 65535:
        raise InputError(f"--port must be in 0..65535, got {args.port}")
    if args.max_upload_mb <= 0:
        raise InputError(f"--max-upload-mb must be positive, got {args.max_upload_mb}")
    workdir = Path(args.workdir)
    if not workdir.is_dir():
        raise InputError(f"--workdir {workdir}: no such folder")
    policy = FilePolicy(workdir, max_upload=int(args.max_upload_mb * 1024 * 1024))
    mesh = None
    if args.mesh:
        policy.allow(args.mesh)
        mesh = load_cli_mesh(args.mesh, args.repair)
    stem = Path(args.mesh).stem if args.mesh else "untitled"
    autosave = Path(args.autosave) if args.autosave else policy.workdir / f"{stem}.session.json"
    policy.allow(autosave)
    session = Session(mesh)
    restored = mesh is not None and session.resume_autosave(autosave)
    if session.set_aside is not None:
        moved, why = session.set_aside
        print(f"meshfit ui: {why}: moved it to {moved.name} and started a new session")
    if not restored:
        session.autosave_path = autosave
    if args.layout:
        policy.allow(args.layout)
        if restored:
            print(f"meshfit ui: resumed the session in {autosave} (not loading {args.layout})")
        elif mesh is not None and Path(args.layout).is_file():
            session.load_layout(args.layout)
    return App(session, policy, host=args.host, port=args.port, layout_path=args.layout)


def cmd_ui(args: argparse.Namespace) -> int:
    """Serve the app until interrupted."""
    if args.host not in LOOPBACK:
        sys.stderr.write(
            f"meshfit: warning: listening on {args.host}: other machines can reach the app\n"
        )
    app = build_app(args)
    print(f"meshfit ui: {app.url(args.host)}  (Ctrl-C to stop)", flush=True)
    try:
        while True:
            time.sleep(1.0)
    finally:
        app.stop()
