"""The ``meshfit`` command line: a thin shell over the Python API.

Every :class:`meshfit.errors.MeshfitError` becomes one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import threading
import time
import warnings
from collections.abc import Sequence
from pathlib import Path

from meshfit import __version__, errors
from meshfit._cliargs import CLI_REPAIR_HINT, add_repair_option, refuse_own_input
from meshfit._cliout import EXIT_ERROR, EXIT_OK, print_json, print_table
from meshfit._malloc import tune_malloc

__all__ = ["EXIT_ERROR", "EXIT_OK", "build_parser", "main", "print_json", "print_table"]

#: Stage packages that add subcommands. Each module defines ``add_commands(sub)``, which adds
#: its parsers to the ``argparse`` sub-parser action and sets ``func`` on each of them; a
#: command's ``func(args)`` returns the exit code.
_COMMAND_MODULES: tuple[str, ...] = (
    "meshfit.bspline.cli",
    "meshfit.layout.cli",
    "meshfit.shrinkwrap.cli",
    "meshfit.springs.cli",
    "meshfit.fit_cli",
    "meshfit.pipeline.prepare",
    "meshfit.ui.cli",
)


def cmd_info(args: argparse.Namespace) -> int:
    """Statistics and validation findings of one mesh file."""
    from meshfit.mesh import Mesh, find_problems, read_mesh_arrays
    from meshfit.mesh.measures import mesh_statistics, raw_statistics
    from meshfit.mesh.validate import inside_out_finding

    t0 = time.perf_counter()
    raw = read_mesh_arrays(args.mesh)
    name = Path(args.mesh).name
    mesh = None
    try:  # a valid mesh is validated once, by its constructor
        mesh = Mesh(raw.vertices, raw.faces, raw.vertex_colors, name=name)
        findings = []
        inverted = None if args.repair else inside_out_finding(mesh.vertices, mesh.faces)
        if inverted is not None:  # valid, but the strict path does not take it
            findings, mesh = [inverted], None
        if args.repair:  # valid, but perhaps inside out
            fixed = Mesh.from_arrays(
                raw.vertices, raw.faces, raw.vertex_colors, name=name, repair=True
            )
            if fixed.repairs is not None and fixed.repairs.changed():
                mesh = fixed
    except errors.MeshValidationError:
        findings = find_problems(raw.vertices, raw.faces)
        if args.repair:  # raises, naming the problem, where the repair cannot fix it
            mesh = Mesh.from_arrays(
                raw.vertices, raw.faces, raw.vertex_colors, name=name, repair=True
            )
    out = raw_statistics(raw, findings)
    if mesh is not None:
        out.update(mesh_statistics(mesh))
        if mesh.repairs is not None:
            out["repair"] = mesh.repairs.summary()
    out["repaired"] = mesh is not None and mesh.repairs is not None and mesh.repairs.changed()
    out = {"file": str(args.mesh), **out, "seconds": round(time.perf_counter() - t0, 3)}
    if args.json:
        print_json(out)
    else:
        print_table(f"{args.mesh}", out)
        for note in out["notes"]:
            print(f"note: {note}")
        for f in findings:
            tag = "repaired" if mesh is not None else ("repairable" if f.repairable else "error")
            print(f"{tag}: {f.message}")
        if not findings:
            print("valid: no problems found")
    if mesh is None:
        first = findings[0]
        repairable = all(f.repairable for f in findings)
        hint = CLI_REPAIR_HINT if repairable and not args.repair else ""
        sys.stderr.write(f"meshfit: error: {args.mesh}: {first.message}{hint}\n")
        return EXIT_ERROR
    return EXIT_OK


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="meshfit", description="Turn dense scanned meshes into smooth surfaces."
    )
    parser.add_argument("--version", action="version", version=f"meshfit {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("info", help="print statistics and every validation finding of a mesh")
    p.add_argument("mesh", help="mesh file (.ply .obj .stl .off .glb .gltf)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    add_repair_option(p)
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("demo", help="run on the embedded default input (no files needed)")
    p.add_argument("--out", default="meshfit-demo", help="output folder (default: %(default)s)")
    p.add_argument(
        "--faces",
        type=int,
        default=200_000,
        help="approximate triangle count of the generated scan (default: %(default)s)",
    )
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=cmd_demo)

    for name in _COMMAND_MODULES:
        importlib.import_module(name).add_commands(sub)
    return parser


def cmd_demo(args: argparse.Namespace) -> int:
    from meshfit.demo import run_demo

    summary = run_demo(Path(args.out), faces=args.faces, quiet=args.json)
    if args.json:
        print_json(summary)
    return EXIT_OK


def _os_error(exc: OSError) -> str:
    """One line for a failed read or write: the path (the file standing where a folder is
    needed, or the folder that is missing) and the system's reason."""
    name = exc.filename
    if name is None:
        return str(exc)
    path = Path(os.fsdecode(name))
    while path.parent != path and path.parent.exists() and not path.parent.is_dir():
        path = path.parent  # a file where a folder is needed, named by itself
    if isinstance(exc, FileNotFoundError) and not path.parent.exists():
        return f"{path.parent}: no such folder"
    reason = exc.strerror or str(exc)
    if path.is_file() and isinstance(exc, (FileExistsError, NotADirectoryError)):
        reason = "a file, where a folder is needed"
    return f"{path}: {reason}"


def _terminate(signum, frame) -> None:
    """SIGTERM: end the process now, with one line and exit code 143.

    Raising an exception instead (as Ctrl-C does) is not safe here: inside a ctypes
    callback, as during a kernel's JIT compilation, Python swallows it and the library goes
    on in a broken state. Every output is written under a temporary name and renamed when
    whole (:mod:`meshfit._atomic`), so ending here leaves no half-written file; the
    temporary files of writes under way are removed first."""
    from meshfit._atomic import remove_pending
    from meshfit._compile_ahead import stop

    remove_pending()
    stop()
    try:
        sys.stderr.write("meshfit: terminated\n")
        sys.stderr.flush()
    finally:
        os._exit(143)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit code (0 ok, 2 bad input, 130 interrupted; SIGTERM ends
    the process with 143)."""
    tune_malloc()
    parser = build_parser()
    args = parser.parse_args(argv)
    main_thread = threading.current_thread() is threading.main_thread()
    before = signal.signal(signal.SIGTERM, _terminate) if main_thread else None
    try:
        return _run(args)
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, before)


def _run(args: argparse.Namespace) -> int:
    """The command with Python's warnings (numpy's floating-point ones, a library's
    deprecations) caught and shown as one line each, once, after it."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            return _command(args)
        finally:
            _show_warnings(caught)


#: most distinct warnings shown after a command
SHOWN_WARNINGS = 5


def _show_warnings(caught: list) -> None:
    seen: dict[str, int] = {}
    for w in caught:
        text = f"{w.category.__name__}: {str(w.message).splitlines()[0] if str(w.message) else ''}"
        seen[text] = seen.get(text, 0) + 1
    for text, n in list(seen.items())[:SHOWN_WARNINGS]:
        times = f" ({n} times)" if n > 1 else ""
        sys.stderr.write(f"meshfit: warning: {text}{times}\n")
    if len(seen) > SHOWN_WARNINGS:
        sys.stderr.write(f"meshfit: warning: {len(seen) - SHOWN_WARNINGS} more kinds\n")


#: commands that run kernels, with the kernels they run (a scope of
#: :mod:`meshfit._compile_ahead`): on a first run a second process compiles them ahead of need
COMPILING = {
    "demo": "fit",
    "layout": "fit",
    "springs": "fit",
    "fit": "fit",
    "prepare": "fit",
    "rebuild": "fit",
    "wrap": "wrap",
    "stream": "wrap",
    "ui": "fit",
}


def _command(args: argparse.Namespace) -> int:
    """The command, its failures as one line each and an exit code."""
    try:
        refuse_own_input(args)
        scope = COMPILING.get(getattr(args, "command", None) or "")
        if scope is not None:
            from meshfit._compile_ahead import start

            start(scope=scope)
        return int(args.func(args))
    except errors.MeshfitError as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if isinstance(exc, errors.MeshValidationError) and hasattr(args, "repair"):
            from meshfit.mesh.validate import REPAIR_HINT

            msg = msg.replace(REPAIR_HINT, CLI_REPAIR_HINT)
        sys.stderr.write(f"meshfit: error: {msg}\n")
        return EXIT_ERROR
    except BrokenPipeError:  # output piped into a pager or head that closed early
        sys.stderr.close()
        return EXIT_OK
    except OSError as exc:  # a file or folder that cannot be read or written
        sys.stderr.write(f"meshfit: error: {_os_error(exc)}\n")
        return EXIT_ERROR
    except MemoryError:
        sys.stderr.write(
            "meshfit: error: out of memory: ask for fewer levels, points or patches, or run "
            "on a larger machine\n"
        )
        return EXIT_ERROR
    except KeyboardInterrupt:
        sys.stderr.write("meshfit: interrupted\n")
        return 130


if __name__ == "__main__":
    sys.exit(main())
