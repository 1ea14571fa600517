"""What every command prints and returns: exit codes, JSON and tables on stdout.

The ``meshfit`` entry point and each stage's subcommands (``meshfit.<stage>.cli``) share
these; they live below the command lines so that no command line imports another.
"""

from __future__ import annotations

import json
import sys

__all__ = ["EXIT_ERROR", "EXIT_OK", "PIPE_COLUMNS", "console", "print_json", "print_table"]

EXIT_OK = 0
EXIT_ERROR = 2


def print_json(data: dict) -> None:
    json.dump(data, sys.stdout, indent=2, sort_keys=False)
    sys.stdout.write("\n")


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, list) and v and isinstance(v[0], float):
        return "[" + ", ".join(f"{x:.6g}" for x in v) + "]"
    return str(v)


#: line width of the tables printed to a file or a pipe (unless ``COLUMNS`` is set): wide
#: enough that no figure is cut short
PIPE_COLUMNS = 160


def console():
    """A rich console for stdout: the terminal's width, or `PIPE_COLUMNS` when stdout is
    not a terminal (rich would take 80 columns and wrap or cut the tables' cells)."""
    import os

    from rich.console import Console

    out = Console()
    if not out.is_terminal and not os.environ.get("COLUMNS"):
        out = Console(width=PIPE_COLUMNS)
    return out


def print_table(title: str, data: dict) -> None:
    from rich.table import Table

    table = Table(title=title, show_header=False, title_justify="left")
    table.add_column("quantity", style="bold")
    table.add_column("value")
    for k, v in data.items():
        if k in ("findings", "notes"):
            continue
        table.add_row(k.replace("_", " "), _fmt(v))
    console().print(table)
