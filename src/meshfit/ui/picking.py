"""Click picking: a camera ray from the browser to a face point of the mesh.

The browser sends the click's ray (origin and direction in world coordinates) and no hit
point; the server casts the ray on the mesh's AABB tree.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.types import SurfacePoints

__all__ = ["pick_point"]


def pick_point(mesh: Mesh, origin: ArrayLike, direction: ArrayLike) -> SurfacePoints | None:
    """The first face point a ray meets, or None when it misses the mesh.

    Parameters
    ----------
    mesh : Mesh
    origin : (3,) float64
        Ray origin (the camera), model units.
    direction : (3,) float64
        Ray direction; need not be unit length.

    Returns
    -------
    SurfacePoints or None
        One face point (``face (1,) int64``, ``bary (1, 3) float64``).

    Raises
    ------
    meshfit.errors.InputError
        A ray that is not two finite 3-vectors or has a zero direction.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.2 (the user paints curves by picking points on the
       polygonal model).
    """
    o = np.asarray(origin, dtype=np.float64).reshape(-1)
    d = np.asarray(direction, dtype=np.float64).reshape(-1)
    if o.shape != (3,) or d.shape != (3,):
        raise InputError(f"a click ray needs a 3-d origin and direction, got {o.shape}, {d.shape}")
    if not (np.isfinite(o).all() and np.isfinite(d).all()) or not np.any(d):
        raise InputError(f"bad click ray: origin {o.tolist()}, direction {d.tolist()}")
    hits = mesh.ray_first_hit(o[None, :], d[None, :])
    if not bool(hits.hit[0]):
        return None
    return hits.points
