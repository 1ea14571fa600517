"""Command-line options shared by every command that reads a mesh."""

from __future__ import annotations

import argparse

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
