"""IGES 5.3 writer for B-spline surfaces: one entity 128 (rational B-spline surface) per patch.

The file has the five fixed-format sections of IGES 5.3 (Start, Global, Directory Entry,
Parameter Data, Terminate), 80-column records, comma / semicolon delimiters. Every surface is
written as a polynomial (all weights 1), open, non-periodic entity 128, form 0, with its
full clamped knot vectors (``mu + 4`` and ``mv + 4`` values), control points with u varying
fastest, and the parameter range [0, 1] x [0, 1]. Reals are written with 17 significant
digits, so a reader recovers the float64 values exactly.

References
----------
.. [1] US PRO, "Initial Graphics Exchange Specification IGES 5.3", 1996, sec. 2 (file
   structure) and sec. 4.24 (entity 128, rational B-spline surface).
"""

from __future__ import annotations

import datetime as _dt
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from meshfit.bspline import BSplineSurface
from meshfit.errors import InputError
from meshfit.export._common import as_names, as_surfaces, atomic_write
from meshfit.export.units import unit

__all__ = ["export_iges", "iges_entity_128"]


def _real(x: float) -> str:
    return f"{float(x):.16E}"


def _hollerith(s: str) -> str:
    """IGES string; an empty string is left to its default (nothing between delimiters)."""
    return f"{len(s)}H{s}" if s else ""


def iges_entity_128(surface: BSplineSurface) -> list[str]:
    """Parameter tokens of one surface as IGES entity 128 (without delimiters)."""
    P = surface.control_points
    mu, mv = surface.shape
    p = surface.degree
    tok = ["128", str(mu - 1), str(mv - 1), str(p), str(p), "0", "0", "1", "0", "0"]
    tok += [_real(k) for k in surface.knots_u]
    tok += [_real(k) for k in surface.knots_v]
    tok += [_real(1.0)] * (mu * mv)
    for j in range(mv):  # u varies fastest
        for i in range(mu):
            tok += [_real(c) for c in P[i, j]]
    tok += [_real(surface.knots_u[0]), _real(surface.knots_u[-1])]
    tok += [_real(surface.knots_v[0]), _real(surface.knots_v[-1])]
    return tok


def _pack(tokens: list[str], width: int) -> list[str]:
    """Tokens joined by ',' and ended by ';', cut into lines of at most ``width`` chars
    without splitting a token."""
    lines: list[str] = []
    cur = ""
    for k, t in enumerate(tokens):
        item = t + (";" if k == len(tokens) - 1 else ",")
        if len(item) > width:
            raise InputError(f"IGES parameter {t!r} is longer than a record")
        if len(cur) + len(item) > width:
            lines.append(cur)
            cur = ""
        cur += item
    lines.append(cur)
    return lines


def export_iges(
    path: str | os.PathLike,
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    *,
    names: Sequence[str] | None = None,
    units: str = "mm",
    author: str = "",
    organization: str = "",
) -> Path:
    """Write B-spline surfaces to an IGES 5.3 file, one entity 128 each.

    Parameters
    ----------
    path : str or path
        Output ``.igs`` / ``.iges`` file (written atomically).
    surfaces : BSplineSurface or sequence of them
    names : sequence of str, optional
        Entity labels (at most 8 characters are kept); default ``P0, P1, ...``.
    units : str
        Model unit declared in the Global section (unit flag and name), one of
        :data:`meshfit.export.units.UNITS` (``"mm"``, ``"cm"``, ``"m"``, ``"in"``, ``"ft"``,
        any case; default ``"mm"``); coordinates are written unchanged.
    author, organization : str
        Global section fields.

    Returns
    -------
    Path
        The file written.

    References
    ----------
    .. [1] IGES 5.3, sec. 4.24 (entity 128).
    """
    surfaces = as_surfaces(surfaces)
    labels = (
        as_names(names, len(surfaces))
        if names is not None
        else [f"P{k}" for k in range(len(surfaces))]
    )
    u = unit(units)
    path = Path(path)
    now = _dt.datetime.now(_dt.UTC).strftime("%Y%m%d.%H%M%S")
    cp = np.concatenate([s.control_points.reshape(-1, 3) for s in surfaces])
    max_coord = float(np.abs(cp).max()) if cp.size else 0.0
    diag = float(np.linalg.norm(np.ptp(cp, axis=0))) or 1.0
    glob = [
        "1H,",
        "1H;",
        _hollerith("meshfit"),
        _hollerith(path.name),
        _hollerith("meshfit"),
        _hollerith("meshfit IGES 5.3 writer"),
        "32",
        "38",
        "6",
        "308",
        "15",
        _hollerith("meshfit"),
        _real(1.0),
        str(u.iges_flag),
        _hollerith(u.iges_name),
        "1",
        _real(diag * 1e-3),
        _hollerith(now),
        _real(diag * 1e-12),
        _real(max_coord),
        _hollerith(author),
        _hollerith(organization),
        "11",
        "0",
        _hollerith(now),
    ]
    start = ["meshfit B-spline patches: IGES entity 128, polynomial, clamped knots"]
    g_lines = _pack(glob, 72)
    d_lines: list[str] = []
    p_lines: list[str] = []
    for k, s in enumerate(surfaces):
        de_seq = 2 * k + 1
        params = _pack(iges_entity_128(s), 64)
        p_start = len(p_lines) + 1
        for line in params:
            p_lines.append(f"{line:<64} {de_seq:>7d}")
        f = [128, p_start, 0, 0, 0, 0, 0, 0]
        d_lines.append("".join(f"{x:>8d}" for x in f) + "00000000")
        label = labels[k][:8]
        d_lines.append(
            "".join(f"{x:>8d}" for x in (128, 0, 0, len(params), 0))
            + " " * 16
            + f"{label:>8}"
            + f"{0:>8d}"
        )
    out = []
    for letter, lines in (("S", start), ("G", g_lines), ("D", d_lines), ("P", p_lines)):
        for n, line in enumerate(lines, start=1):
            out.append(f"{line:<72}{letter}{n:>7d}")
    term = f"S{len(start):>7d}G{len(g_lines):>7d}D{len(d_lines):>7d}P{len(p_lines):>7d}"
    out.append(f"{term:<72}T{1:>7d}")

    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="ascii", newline="\n") as fh:
            fh.write("\n".join(out) + "\n")

    return atomic_write(path, write)
