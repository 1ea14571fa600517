"""Helpers shared by the exporters: patch lists, names, tessellation, atomic writes."""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from meshfit._atomic import atomic_write  # noqa: F401  (re-exported for the writers)
from meshfit.bspline import BSplineSurface, grid_parameters
from meshfit.displacement import DisplacementMap, reconstruct
from meshfit.errors import InputError


def as_surfaces(surfaces) -> list[BSplineSurface]:
    """A single surface or a sequence of them, as a non-empty list."""
    if isinstance(surfaces, BSplineSurface):
        return [surfaces]
    out = list(surfaces)
    if not out:
        raise InputError("no surfaces to export")
    for k, s in enumerate(out):
        if not isinstance(s, BSplineSurface):
            raise InputError(f"surfaces[{k}] is a {type(s).__name__}, not a BSplineSurface")
    return out


def as_names(names: Sequence[str] | None, n: int) -> list[str]:
    """Patch names: ``patch_0 ...`` by default; given names must be unique identifiers."""
    if names is None:
        return [f"patch_{k}" for k in range(n)]
    names = [str(x) for x in names]
    if len(names) != n:
        raise InputError(f"{len(names)} names for {n} surfaces")
    for x in names:
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", x):
            raise InputError(
                f"patch name {x!r} must be a letter or _ followed by letters, digits, _"
            )
    if len(set(names)) != n:
        raise InputError("patch names must be unique")
    return names


def as_displacements(displacements, n: int) -> list[DisplacementMap | None]:
    if displacements is None:
        return [None] * n
    if isinstance(displacements, DisplacementMap):
        displacements = [displacements]
    out = list(displacements)
    if len(out) != n:
        raise InputError(f"{len(out)} displacement maps for {n} surfaces")
    for k, d in enumerate(out):
        if d is not None and (not isinstance(d, DisplacementMap) or d.kind == "bump"):
            what = d.kind if isinstance(d, DisplacementMap) else type(d).__name__
            raise InputError(
                f"displacements[{k}] must be a vector, scalar or magnitude map or None, "
                f"not a {what}"
            )
    return out


def as_maps(maps, n: int) -> list[DisplacementMap | None]:
    """One DisplacementMap (any kind, bump included) or None per patch."""
    if maps is None:
        return [None] * n
    if isinstance(maps, DisplacementMap):
        maps = [maps]
    out = list(maps)
    if len(out) != n:
        raise InputError(f"{len(out)} maps for {n} surfaces")
    for k, d in enumerate(out):
        if d is not None and not isinstance(d, DisplacementMap):
            raise InputError(f"maps[{k}] is a {type(d).__name__}, not a DisplacementMap")
    return out


def as_shapes(shape, n: int) -> list[tuple[int, int] | None]:
    """``shape`` as one vertex grid ``(h, w)`` (or None) per patch: a pair applies to every
    patch; each needs at least 2 x 2 vertices."""
    if shape is None:
        return [None] * n
    if len(shape) == 2 and all(isinstance(x, (int, np.integer)) for x in shape):
        shape = [shape] * n
    if len(shape) != n:
        raise InputError(f"{len(shape)} shapes for {n} patches")
    out: list[tuple[int, int] | None] = []
    for sh in shape:
        if len(sh) != 2 or not all(isinstance(x, (int, np.integer)) for x in sh):
            raise InputError(f"a vertex grid is a pair of integers (h, w), got {sh!r}")
        if min(sh) < 2:
            raise InputError(f"a vertex grid needs at least 2 x 2 vertices, got {tuple(sh)}")
        out.append((int(sh[0]), int(sh[1])))
    return out


def grid_faces(h: int, w: int) -> NDArray[np.int64]:
    """Triangles of an ``(h, w)`` grid of vertices numbered ``i * w + j``: ``(2 (h-1)(w-1), 3)``.

    Each cell ``(i, j)`` gives ``(i,j) (i+1,j) (i+1,j+1)`` and ``(i,j) (i+1,j+1) (i,j+1)``,
    both turning like ``S_u x S_v`` (outward).
    """
    i, j = np.meshgrid(np.arange(h - 1), np.arange(w - 1), indexing="ij")
    a = (i * w + j).ravel()
    b = a + w
    c = b + 1
    d = a + 1
    return np.concatenate(
        [np.stack([a, b, c], axis=1), np.stack([a, c, d], axis=1)], axis=0
    ).astype(np.int64)


def tessellate(
    surface: BSplineSurface,
    displacement: DisplacementMap | None = None,
    *,
    shape: tuple[int, int] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """Triangulated grid of a (displaced) surface.

    Parameters
    ----------
    surface : BSplineSurface
    displacement : DisplacementMap, optional
        Vector, scalar or magnitude map; the spline alone when None.
    shape : (int, int), optional
        Vertex grid ``(h, w)``; default the map's resolution, else ``(8 mu, 8 mv)``.

    Returns
    -------
    vertices : (h w, 3) float64
        ``vertices[i * w + j]`` at ``(u, v) = (i / (h - 1), j / (w - 1))``.
    faces : (2 (h-1)(w-1), 3) int64
    uv : (h w, 2) float64
        Parameters of the vertices.
    """
    if shape is None:
        shape = (
            displacement.shape
            if displacement is not None
            else (8 * surface.shape[0], 8 * surface.shape[1])
        )
    h, w = (int(x) for x in shape)
    if h < 2 or w < 2:
        raise InputError(f"tessellation needs at least 2 x 2 vertices, got {shape}")
    if displacement is None:
        P = surface.evaluate_grid(grid_parameters(h), grid_parameters(w))
    else:
        P = reconstruct(surface, displacement, shape=(h, w))
    U, V = np.meshgrid(grid_parameters(h), grid_parameters(w), indexing="ij")
    return P.reshape(-1, 3), grid_faces(h, w), np.stack([U.ravel(), V.ravel()], axis=1)
