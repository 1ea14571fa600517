"""Tessellated exports: OBJ (displaced or spline-only surfaces) and a glTF binary preview."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from meshfit.bspline import BSplineSurface
from meshfit.displacement import DisplacementMap
from meshfit.errors import InputError
from meshfit.export._common import (
    as_displacements,
    as_names,
    as_surfaces,
    atomic_write,
    tessellate,
)

__all__ = ["export_gltf", "export_obj", "export_objs"]


def _tessellations(surfaces, displacements, names, shape):
    surfaces = as_surfaces(surfaces)
    names = as_names(names, len(surfaces))
    disps = as_displacements(displacements, len(surfaces))
    shapes = _shapes(shape, len(surfaces))
    return names, [
        tessellate(s, d, shape=sh) for s, d, sh in zip(surfaces, disps, shapes, strict=True)
    ]


def _shapes(shape, n: int) -> list:
    """``shape`` as one vertex grid (or None) per patch: a pair applies to every patch."""
    if shape is None:
        return [None] * n
    if all(isinstance(x, (int, np.integer)) for x in shape):  # one (h, w) for all
        return [tuple(shape)] * n
    if len(shape) != n:
        raise InputError(f"{len(shape)} shapes for {n} patches")
    return [tuple(sh) for sh in shape]


def _uv_lines(UV) -> list[str]:
    """``vt`` lines of parameters ``UV (n, 2)``: each distinct u and v formatted once (a grid
    has few), the same text as formatting every pair."""
    u, iu = np.unique(UV[:, 0], return_inverse=True)
    v, iv = np.unique(UV[:, 1], return_inverse=True)
    su = [f"vt {x:.17g} " for x in u.tolist()]
    sv = [f"{x:.17g}" for x in v.tolist()]
    return [su[i] + sv[j] for i, j in zip(iu.ravel().tolist(), iv.ravel().tolist(), strict=True)]


def export_obj(
    path: str | os.PathLike,
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    *,
    displacements: DisplacementMap | Sequence[DisplacementMap | None] | None = None,
    names: Sequence[str] | None = None,
    shape: tuple[int, int] | Sequence[tuple[int, int]] | None = None,
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
    shape : (int, int) or sequence of them, optional
        Vertex grid of every patch, or one per patch; default the map's resolution, else 8
        per control point.

    Returns
    -------
    Path

    Notes
    -----
    Coordinates are written with 17 significant digits (exact float64); ``vt`` holds the
    (u, v) parameters; triangles turn like ``S_u x S_v``.
    """
    return export_objs({path: displacements}, surfaces, names=names, shape=shape)[0]


def export_objs(
    outputs: Mapping[str | os.PathLike, DisplacementMap | Sequence[DisplacementMap | None] | None],
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    *,
    names: Sequence[str] | None = None,
    shape: tuple[int, int] | Sequence[tuple[int, int]] | None = None,
) -> list[Path]:
    """Several OBJ files of the same patches, e.g. the displaced and the spline-only surface.

    Parameters
    ----------
    outputs : mapping of path to displacements
        ``{path: displacements}``: each file as :func:`export_obj` writes it with those
        displacements (None: the splines alone). Files whose patches have the same vertex
        grids share the text of their texture coordinates and faces, formatted once.
    surfaces : BSplineSurface or sequence of them
    names : sequence of str, optional
    shape : (int, int) or sequence of them, optional
        As for :func:`export_obj`, for every file.

    Returns
    -------
    list of Path
        The files, in the order of ``outputs`` (each written atomically).

    Raises
    ------
    meshfit.errors.InputError
        Bad names, displacements or shapes (as :func:`export_obj`).
    """
    topology: dict[tuple, list[tuple[list[str], list[str]]]] = {}
    out = []
    for path, displacements in outputs.items():
        names_, tess = _tessellations(surfaces, displacements, names, shape)
        key = tuple(V.shape[0] for V, _, _ in tess) + tuple(F.shape[0] for _, F, _ in tess)
        if key not in topology or not all(
            np.array_equal(a[2], b[2]) for a, b in zip(topology[key][1], tess, strict=True)
        ):
            text, base = [], 1
            for V, F, UV in tess:
                faces = map("f {0}/{0} {1}/{1} {2}/{2}".format, *(F + base).T.tolist())
                text.append((_uv_lines(UV), list(faces)))
                base += V.shape[0]
            topology[key] = (text, tess)
        text = topology[key][0]
        lines = ["# meshfit: tessellated B-spline patches; vt = (u, v) parameters"]
        for name, (V, _, _), (vt, faces) in zip(names_, tess, text, strict=True):
            lines.append(f"o {name}")
            # Python floats format faster than numpy scalars (the same text)
            lines.extend(map("v {:.17g} {:.17g} {:.17g}".format, *V.T.tolist()))
            lines.extend(vt)
            lines.extend(faces)

        def write(tmp: str, lines=lines) -> None:
            with open(tmp, "w", encoding="ascii", newline="\n") as fh:
                fh.write("\n".join(lines) + "\n")

        out.append(atomic_write(path, write))
    return out


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
