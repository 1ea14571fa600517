"""Creating face points: uniform random samples and closest points to positions."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.types import SurfacePoints

__all__ = ["closest_surface_points", "random_surface_points"]


def random_surface_points(
    mesh: Mesh,
    n: int,
    rng: np.random.Generator | int | None = None,
    *,
    faces: ArrayLike | None = None,
) -> SurfacePoints:
    """Points distributed uniformly by area over the surface.

    Parameters
    ----------
    mesh : Mesh
    n : int
        Number of points.
    rng : numpy.random.Generator or int, optional
        Random source or seed.
    faces : (k,) int64, optional
        Restrict the samples to these faces.

    Returns
    -------
    SurfacePoints
        ``n`` points; each face is chosen with probability proportional to its area and the
        barycentrics are uniform on the triangle.
    """
    if n < 0:
        raise InputError(f"n must be >= 0, got {n}")
    rng = np.random.default_rng(rng)
    pool = np.arange(mesh.n_faces) if faces is None else np.asarray(faces, dtype=np.int64)
    if pool.size == 0 or pool.min() < 0 or pool.max() >= mesh.n_faces:
        raise InputError("faces must be a non-empty list of face indices of the mesh")
    w = mesh.face_areas[pool]
    cdf = np.cumsum(w)
    face = pool[
        np.minimum(np.searchsorted(cdf, rng.random(n) * cdf[-1], side="right"), pool.size - 1)
    ]
    r1 = np.sqrt(rng.random(n))
    r2 = rng.random(n)
    bary = np.stack([1.0 - r1, r1 * (1.0 - r2), r1 * r2], axis=1)
    return SurfacePoints(face, bary)


def closest_surface_points(mesh: Mesh, xyz: ArrayLike) -> SurfacePoints:
    """The closest face point to each position (global query on the mesh's kept tree).

    Parameters
    ----------
    mesh : Mesh
    xyz : (n, 3) float64
        Positions, model units.

    Returns
    -------
    SurfacePoints
    """
    return mesh.closest_points(xyz).points
