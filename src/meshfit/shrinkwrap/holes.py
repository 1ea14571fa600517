"""Closing small holes so that an open genus-0 scan can be shrink wrapped."""

from __future__ import annotations

import numpy as np

from meshfit import errors
from meshfit.mesh import Mesh

__all__ = ["fill_holes"]


def fill_holes(mesh: Mesh, *, max_edges: int = 1000) -> Mesh:
    """Close every boundary loop of at most ``max_edges`` edges with a fan around a new vertex
    at the loop's centroid.

    Parameters
    ----------
    mesh : Mesh
    max_edges : int
        Largest hole closed, in boundary edges (default 1000).

    Returns
    -------
    Mesh
        The input vertices and faces first (same indices), then one new vertex per hole and
        its fan faces. Raises :class:`meshfit.errors.TopologyError` when a hole is larger.
    """
    loops = mesh.boundary_loops
    big = [len(lp) for lp in loops if len(lp) > max_edges]
    if big:
        raise errors.TopologyError(
            f"mesh {mesh.name!r}: hole of {big[0]} edges is larger than max_edges={max_edges}"
        )
    v = [mesh.vertices]
    f = [mesh.faces]
    n = mesh.n_vertices
    for lp in loops:
        c = n + len(v) - 1
        v.append(mesh.vertices[lp].mean(axis=0, keepdims=True))
        nxt = np.roll(lp, -1)
        # boundary half-edges run lp[i] -> lp[i+1] in the existing faces: the fan uses the
        # opposite direction
        f.append(np.stack([nxt, lp, np.full(len(lp), c)], axis=1))
    colors = mesh.vertex_colors
    if colors is not None and loops:
        extra = [colors[lp].mean(axis=0).round().astype(np.uint8)[None] for lp in loops]
        colors = np.vstack([colors, *extra])
    return Mesh(np.vstack(v), np.vstack(f), colors, name=mesh.name)
