"""Command-line options shared by every command that reads a mesh."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

#: what a validation error's hint becomes on the command line (repair is on unless
#: ``--no-repair`` is given, so the hint only shows on the strict path)
CLI_REPAIR_HINT = " (repairable: run without --no-repair)"


def add_repair_option(parser: argparse.ArgumentParser) -> None:
    """``--repair`` (the default) / ``--no-repair``: repair harmless defects while loading
    (:func:`meshfit.mesh.validate.repair_arrays`), or take the file strictly as it is."""
    parser.add_argument(
        "--repair",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="repair harmless defects while loading: unreferenced vertices, degenerate, "
        "duplicate and back-to-back faces, non-manifold edges and vertices (split apart), "
        "inconsistent or inside-out orientation; each repair is noted (default: on; "
        "--no-repair refuses such a mesh)",
    )


def own_inputs(parser: argparse.ArgumentParser, inputs: tuple[str, ...], outputs: tuple[str, ...]):
    """Declare which of a command's arguments name files it reads (``inputs``) and which
    name what it writes (``outputs``: a file or a folder), for :func:`refuse_own_input`."""
    parser.set_defaults(_inputs=inputs, _outputs=outputs)


def refuse_own_input(args: argparse.Namespace) -> None:
    """Refuse, before any work, an output that is one of the command's input files (the same
    file by any path: relative, absolute, through a link), so that no command overwrites
    what it reads.

    Raises
    ------
    meshfit.errors.InputError
        Naming the output and the input.
    """
    from meshfit.errors import InputError

    sources = []
    for name in getattr(args, "_inputs", ()):
        value = getattr(args, name, None)
        for v in value if isinstance(value, list) else [value]:
            if v is not None and Path(v).is_file():
                sources.append(Path(v))
    for name in getattr(args, "_outputs", ()):
        out = getattr(args, name, None)
        if out is None:
            continue
        for src in sources:
            if _same_file(Path(out), src):
                raise InputError(
                    f"the output {out} is the input {src}: write to another path "
                    "(nothing was written)"
                )


def _same_file(a: Path, b: Path) -> bool:
    try:
        if a.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return a.resolve() == b.resolve()
