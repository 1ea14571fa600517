"""Argument checks shared by the public functions: shapes, dtypes, finiteness."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit.errors import InputError
from meshfit.types import SurfacePoints

if TYPE_CHECKING:
    from meshfit.mesh import Mesh


def _finite_rows(a: NDArray, name: str) -> NDArray:
    if not np.isfinite(a).all():
        bad = int(np.flatnonzero(~np.isfinite(a).reshape(a.shape[0], -1).all(axis=1))[0])
        raise InputError(f"{name} has a NaN or infinite value in row {bad}")
    return a


def as_points(xyz: ArrayLike, *, name: str = "xyz") -> NDArray[np.float64]:
    """(n, 3) float64 C-contiguous, finite; a single (3,) point becomes (1, 3)."""
    try:
        a = np.asarray(xyz, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be numeric with shape (n, 3)") from None
    if a.ndim == 1 and a.shape[0] == 3:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != 3:
        raise InputError(f"{name} must have shape (n, 3), got {a.shape}")
    return np.ascontiguousarray(_finite_rows(a, name))


def as_vectors(v: ArrayLike, *, n: int, name: str) -> NDArray[np.float64]:
    """(n, 3) float64 C-contiguous, finite, with exactly ``n`` rows (a (3,) vector broadcasts)."""
    a = as_points(v, name=name)
    if a.shape[0] == 1 and n != 1:
        a = np.repeat(a, n, axis=0)
    if a.shape[0] != n:
        raise InputError(f"{name} must have {n} rows, got {a.shape[0]}")
    return a


def as_surface_points(mesh: Mesh, points: SurfacePoints, *, name: str = "points") -> SurfacePoints:
    """Check that face points belong to ``mesh``: faces in range, barycentrics summing to 1."""
    if not isinstance(points, SurfacePoints):
        raise InputError(f"{name} must be SurfacePoints, got {type(points).__name__}")
    if len(points):
        bad = np.flatnonzero((points.face < 0) | (points.face >= mesh.n_faces))
        if bad.size:
            raise InputError(
                f"{name}[{bad[0]}] is on face {points.face[bad[0]]}, outside the "
                f"mesh's {mesh.n_faces} faces"
            )
        s = points.bary.sum(axis=1)
        bad = np.flatnonzero(np.abs(s - 1.0) > 1e-9)
        if bad.size:
            raise InputError(
                f"{name}[{bad[0]}] has barycentric coordinates summing to {s[bad[0]]}, not 1"
            )
        bad = np.flatnonzero((points.bary < -1e-9).any(axis=1))
        if bad.size:
            raise InputError(
                f"{name}[{bad[0]}] has a negative barycentric coordinate "
                f"{points.bary[bad[0]].tolist()}: it lies outside its face"
            )
    return points


def as_vertex_index(mesh: Mesh, v: int, *, name: str = "vertex") -> int:
    """A vertex index of ``mesh`` as a Python int."""
    try:
        i = int(v)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a vertex index, got {v!r}") from None
    if i != v or not 0 <= i < mesh.n_vertices:
        raise InputError(f"{name} {v!r} is not a vertex index in [0, {mesh.n_vertices})")
    return i
