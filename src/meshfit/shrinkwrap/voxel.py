"""The paper's sphere map: grow the mesh toward a convex shape along the gradient of a
volumetric distance field, then project it onto the sphere (Kobbelt et al. 1999, sec. 6)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from meshfit.mesh import Mesh
from meshfit.shrinkwrap import _topo

__all__ = ["voxel_sphere"]


def _voxelize(mesh: Mesh, resolution: int):
    """Occupancy grid: voxels met by surface samples, the inside filled (flood fill)."""
    from scipy import ndimage

    lo, hi = mesh.bbox
    size = (hi - lo).max()
    h = size / resolution
    lo = lo - 4 * h
    shape = np.ceil((hi - lo) / h).astype(int) + 5
    p = mesh.vertices[mesh.faces]
    # vertices, face centroids and edge midpoints: enough while h > the longest edge / 2
    samples = np.vstack(
        [mesh.vertices, p.mean(axis=1), 0.5 * (p + np.roll(p, 1, axis=1)).reshape(-1, 3)]
    )
    idx = np.floor((samples - lo) / h).astype(int)
    surf = np.zeros(shape, dtype=bool)
    surf[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    surf = ndimage.binary_dilation(surf)
    solid = ndimage.binary_fill_holes(surf)
    return solid, lo, h


def voxel_sphere(
    mesh: Mesh,
    *,
    resolution: int = 96,
    steps: int = 200,
    step: float = 0.5,
    smoothing: float = 0.5,
    progress: Callable[[str, float], None] | None = None,
) -> tuple[NDArray[np.float64] | None, str]:
    """Move the vertices outward along the gradient of the distance to the voxelized object,
    with umbrella smoothing, until the shape is close to convex; project radially onto the
    unit sphere around the centroid.

    Parameters
    ----------
    mesh : Mesh
    resolution : int
        Voxels along the longest bbox side (default 96).
    steps : int
        Flow steps (default 200).
    step : float
        Step length in voxels (default 0.5).
    smoothing : float
        Umbrella weight per step, in [0, 1] (default 0.5).
    progress : callable(stage, fraction), optional

    Returns
    -------
    sphere : (nv, 3) float64 or None
        The projected vertices (None if the flow diverged).
    note : str
        What happened (flips after projection are counted by the caller).

    References
    ----------
    .. [1] Kobbelt, Vorsatz, Labsik & Seidel 1999, sec. 6.
    """
    from scipy import ndimage

    solid, lo, h = _voxelize(mesh, resolution)
    dist = ndimage.distance_transform_edt(~solid)  # voxels; 0 inside the object
    grad = np.stack(np.gradient(dist), axis=0)
    n = mesh.n_vertices
    adj = _topo.adjacency(mesh.faces, n)
    deg = np.asarray(adj.sum(axis=1)).ravel()
    x = (mesh.vertices - lo) / h  # voxel coordinates
    centre = x.mean(axis=0)
    for it in range(steps):
        g = np.stack(
            [ndimage.map_coordinates(grad[k], x.T, order=1, mode="nearest") for k in range(3)],
            axis=1,
        )
        ln = np.linalg.norm(g, axis=1, keepdims=True)
        radial = x - centre
        radial /= np.maximum(np.linalg.norm(radial, axis=1, keepdims=True), 1e-300)
        # inside the object or on a plateau the field has no gradient: move radially
        d = np.where(ln > 1e-6, g / np.maximum(ln, 1e-300), radial)
        x = x + step * d
        x = (1 - smoothing) * x + smoothing * (adj @ x) / deg[:, None]
        if progress and it % 20 == 0:
            progress("sphere map (voxel flow)", it / steps)
        if not np.isfinite(x).all():
            return None, "voxel flow diverged"
    s = x - x.mean(axis=0)
    s /= np.maximum(np.linalg.norm(s, axis=1, keepdims=True), 1e-300)
    return s, f"voxel flow: {resolution} voxels across, {steps} steps of {step} voxel"
