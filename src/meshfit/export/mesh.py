"""Tessellated exports: OBJ (displaced or spline-only surfaces) and a glTF binary preview."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from meshfit.bspline import BSplineSurface
from meshfit.displacement import DisplacementMap
from meshfit.export._common import (
    as_displacements,
    as_names,
    as_surfaces,
    atomic_write,
    tessellate,
)

__all__ = ["export_gltf", "export_obj"]


def _tessellations(surfaces, displacements, names, shape):
    surfaces = as_surfaces(surfaces)
    names = as_names(names, len(surfaces))
    disps = as_displacements(displacements, len(surfaces))
    return names, [tessellate(s, d, shape=shape) for s, d in zip(surfaces, disps, strict=True)]


def export_obj(
    path: str | os.PathLike,
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    *,
    displacements: DisplacementMap | Sequence[DisplacementMap | None] | None = None,
    names: Sequence[str] | None = None,
    shape: tuple[int, int] | None = None,
) -> Path:
    """Write the patches as triangulated grids to a Wavefront OBJ file.

    Parameters
    ----------
    path : str or path
        Output ``.obj`` (written atomically).
    surfaces : BSplineSurface or sequence of them
    displacements : DisplacementMap or sequence of (DisplacementMap or None), optional
        The displaced surface ``S + d`` for patches with a map, the spline alone otherwise
        (so ``None`` writes the spline-only surfaces).
    names : sequence of str, optional
        One object (``o``) per patch; default ``patch_0, ...``.
    shape : (int, int), optional
        Vertex grid per patch; default the map's resolution, else 8 per control point.

    Returns
    -------
    Path

    Notes
    -----
    Coordinates are written with 17 significant digits (exact float64); ``vt`` holds the
    (u, v) parameters; triangles turn like ``S_u x S_v``.
    """
    names, tess = _tessellations(surfaces, displacements, names, shape)
    lines = ["# meshfit: tessellated B-spline patches; vt = (u, v) parameters"]
    base = 1
    for name, (V, F, UV) in zip(names, tess, strict=True):
        lines.append(f"o {name}")
        lines.extend(f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in V)
        lines.extend(f"vt {a:.17g} {b:.17g}" for a, b in UV)
        lines.extend(f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in (F + base))
        base += V.shape[0]

    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="ascii", newline="\n") as fh:
            fh.write("\n".join(lines) + "\n")

    return atomic_write(path, write)


def export_gltf(
    path: str | os.PathLike,
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    *,
    displacements: DisplacementMap | Sequence[DisplacementMap | None] | None = None,
    names: Sequence[str] | None = None,
    shape: tuple[int, int] | None = None,
) -> Path:
    """Write a glTF binary (``.glb``) preview: one mesh per (displaced) patch.

    Same parameters as :func:`export_obj`. glTF stores float32 positions, so coordinates
    carry float32 rounding (about 6e-8 relative). No texture coordinates: trimesh needs
    Pillow to write them, which meshfit does not depend on.
    """
    import trimesh

    names, tess = _tessellations(surfaces, displacements, names, shape)
    scene = trimesh.Scene()
    for name, (V, F, _uv) in zip(names, tess, strict=True):
        mesh = trimesh.Trimesh(vertices=V, faces=F, process=False)
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    data = scene.export(file_type="glb")

    def write(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            fh.write(data)

    return atomic_write(path, write)
