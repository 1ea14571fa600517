"""Connected components by share of the surface: finding the small ones, dropping them."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from meshfit.errors import InputError
from meshfit.mesh.core import Mesh

__all__ = ["component_shares", "drop_small_components"]


def component_shares(mesh: Mesh) -> NDArray[np.float64]:
    """(n_components,) float64: each face component's share of the mesh's area."""
    areas = np.bincount(mesh.face_components, weights=mesh.face_areas, minlength=mesh.n_components)
    return areas / max(float(areas.sum()), 1e-300)


def drop_small_components(mesh: Mesh, share: float) -> tuple[Mesh, NDArray[np.int64]]:
    """The mesh without the components below ``share`` of its area.

    Debris of a scan (a floating sliver, a lone triangle) holds no surface a patch should
    fit; dropping it is the user's choice, never done silently.

    Parameters
    ----------
    mesh : Mesh
    share : float
        In [0, 1): components with a smaller share of the area are dropped (the largest
        component is always kept).

    Returns
    -------
    mesh : Mesh
        The kept faces in their order, the vertices they use in theirs (colours kept).
    face_map : (nf,) int64
        New index of every input face, -1 where it was dropped.

    Raises
    ------
    meshfit.errors.InputError
        ``share`` outside [0, 1).
    """
    share = float(share)
    if not 0.0 <= share < 1.0:
        raise InputError(f"the share of the area must be in [0, 1), got {share}")
    shares = component_shares(mesh)
    keep_comp = shares >= share
    keep_comp[int(np.argmax(shares))] = True
    keep = keep_comp[mesh.face_components]
    face_map = np.full(mesh.n_faces, -1, dtype=np.int64)
    face_map[keep] = np.arange(int(keep.sum()))
    if keep.all():
        return mesh, face_map
    faces = mesh.faces[keep]
    used, inverse = np.unique(faces, return_inverse=True)
    colors = None if mesh.vertex_colors is None else mesh.vertex_colors[used]
    out = Mesh(mesh.vertices[used], inverse.reshape(-1, 3).astype(np.int64), colors, name=mesh.name)
    return out, face_map
