"""Rhino ``.3dm`` export through rhino3dm: one NURBS surface object per patch."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from meshfit.bspline import BSplineSurface
from meshfit.errors import ExportError
from meshfit.export._common import as_names, as_surfaces, atomic_write
from meshfit.export.units import unit

__all__ = ["export_3dm", "rhino_knots"]


def rhino_knots(knots) -> list[float]:
    """openNURBS knot vector of a clamped knot vector: the first and last knots dropped.

    openNURBS stores ``order + n - 2`` knots for n control points (one fewer at each end
    than the textbook ``order + n``); the dropped end knots never influence the surface.
    """
    return [float(k) for k in knots[1:-1]]


def export_3dm(
    path: str | os.PathLike,
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    *,
    names: Sequence[str] | None = None,
    units: str = "mm",
    version: int = 8,
) -> Path:
    """Write the patches to a Rhino ``.3dm`` file.

    Parameters
    ----------
    path : str or path
        Output ``.3dm`` (written atomically).
    surfaces : BSplineSurface or sequence of them
    names : sequence of str, optional
        Object names; default ``patch_0, ...``.
    units : str
        The model's unit system, one of :data:`meshfit.export.units.UNITS` (``"mm"``,
        ``"cm"``, ``"m"``, ``"in"``, ``"ft"``, any case; default ``"mm"``, Rhino's own
        default); coordinates are written unchanged.
    version : int
        3dm archive version (default 8).

    Returns
    -------
    Path

    Notes
    -----
    Non-rational, order 4 x 4, ``Points[(i, j)] = P[i, j]`` (i along u), knots as
    :func:`rhino_knots`, domain [0, 1] x [0, 1].
    """
    import rhino3dm

    surfaces = as_surfaces(surfaces)
    names = as_names(names, len(surfaces))
    u = unit(units)
    model = rhino3dm.File3dm()
    model.Settings.ModelUnitSystem = getattr(rhino3dm.UnitSystem, u.rhino_name)
    for name, s in zip(names, surfaces, strict=True):
        mu, mv = s.shape
        srf = rhino3dm.NurbsSurface.Create(3, False, s.degree + 1, s.degree + 1, mu, mv)
        for k, x in enumerate(rhino_knots(s.knots_u)):
            srf.KnotsU[k] = x
        for k, x in enumerate(rhino_knots(s.knots_v)):
            srf.KnotsV[k] = x
        P = s.control_points
        for i in range(mu):
            for j in range(mv):
                srf.Points[(i, j)] = rhino3dm.Point4d(*(float(c) for c in P[i, j]), 1.0)
        if not srf.IsValid:
            raise ExportError(f"rhino3dm rejects the NURBS surface of patch {name!r}")
        attrs = rhino3dm.ObjectAttributes()
        attrs.Name = name
        model.Objects.AddSurface(srf, attrs)

    def write(tmp: str) -> None:
        if not model.Write(tmp, version):
            raise ExportError(f"rhino3dm could not write {path}")

    return atomic_write(path, write)
