"""A fold-free planar map of a patch onto the unit square (convex-combination map, private).

The spring mesh's starting points and subdivision mid-points can be taken as the images of
regular parameter points under this map: a mean-value (Floater) map with the boundary fixed
by arc length along the four sides is a bijection onto the square (Tutte's theorem: positive
weights and a convex boundary), so a grid located in it never starts folded.
"""

from __future__ import annotations

import hashlib
import threading
import weakref

import numpy as np
from numpy.typing import NDArray

from meshfit import tol
from meshfit._kernels import springs as _k
from meshfit.mesh import Mesh
from meshfit.springs.features import Sides
from meshfit.types import SurfacePoints

__all__ = ["PlanarMap", "clear_map_cache", "square_map"]


def _mean_value_weights(mesh: Mesh):
    """Rows, columns and values of the mean-value weights ``w_ij`` (all positive).

    Corner ``c`` of face ``f`` (vertex ``i = F[f, c]``, ``j = F[f, c + 1]``, ``k = F[f, c + 2]``)
    gives ``tan(theta / 2) / |e_ij|`` to ``(i, j)`` and ``tan(theta / 2) / |e_ik|`` to ``(i, k)``,
    ``theta`` its angle; the entries come corner by corner (all faces' corner 0, then 1, 2).
    """
    V, F = mesh.vertices, mesh.faces
    P = V[F]  # (nf, 3, 3)
    E = P[:, [1, 2, 0]] - P  # E[:, c] = V[F[:, c + 1]] - V[F[:, c]]
    L = np.sqrt(np.einsum("fcd,fcd->fc", E, E))
    floor = tol.BARY_EPS * mesh.mean_edge_length
    L = np.maximum(L, floor)
    Lk = L[:, [2, 0, 1]]  # |e_ik| = |E[:, c + 2]|
    cos = -np.einsum("fcd,fcd->fc", E, E[:, [2, 0, 1]]) / (L * Lk)
    np.clip(cos, -1.0, 1.0, out=cos)
    # tan(theta / 2) = sqrt((1 - cos) / (1 + cos)); a zero angle gives a tiny weight
    half = np.sqrt(np.maximum(1.0 - cos, 0.0) / np.maximum(1.0 + cos, 1e-12))
    np.maximum(half, tol.BARY_EPS, out=half)
    Ft = F.T
    rows = np.concatenate([Ft, Ft], axis=1)  # (3, 2 nf): corner c: i twice
    cols = np.concatenate([Ft[[1, 2, 0]], Ft[[2, 0, 1]]], axis=1)  # j then k
    vals = np.concatenate([(half / L).T, (half / Lk).T], axis=1)
    return rows.ravel(), cols.ravel(), vals.ravel()


class PlanarMap:
    """Vertex positions of a patch mesh in the unit square and point location in it.

    Attributes
    ----------
    uv : (n_vertices, 2) float64
        Parameter of each vertex; the sides lie on ``v = 0`` (bottom), ``u = 1`` (right),
        ``v = 1`` (top) and ``u = 0`` (left).
    """

    def __init__(self, mesh: Mesh, uv: NDArray[np.float64]):
        self.mesh = mesh
        uv = np.ascontiguousarray(uv, dtype=np.float64)
        uv.flags.writeable = False  # shared by every caller of square_map on this patch
        self.uv = uv
        # about two faces per bucket
        self._g = max(1, int(np.sqrt(mesh.n_faces / 2.0)))
        self._buckets = _k.uv_buckets(uv, mesh.faces, self._g)

    def uv_of(self, face: NDArray[np.int64], bary: NDArray[np.float64]) -> NDArray[np.float64]:
        """(m, 2) parameters of face points."""
        return np.einsum("ij,ijk->ik", bary, self.uv[self.mesh.faces[face]])

    def locate(self, q: NDArray[np.float64]) -> SurfacePoints:
        """Face points of the patch mesh whose parameters are ``q`` (m, 2), clamped into the
        square (a point on an edge goes to either face)."""
        q = np.ascontiguousarray(q, dtype=np.float64)
        face, bary = _k.locate_uv(self.uv, self.mesh.faces, *self._buckets, self._g, q)
        return SurfacePoints(face, bary)


def _interior_system(mesh: Mesh, uv: NDArray, fixed: NDArray, free: NDArray):
    """The mean-value equations of the interior vertices: ``A`` (m, m) CSC over ``free`` and
    the right-hand side (m, 2) from the fixed boundary parameters ``uv[fixed]``.

    Row ``i``: ``sum_j w_ij (x_i - x_j) = 0``, the fixed ``x_j`` moved to the right.
    """
    import scipy.sparse as sp

    n, m = mesh.n_vertices, free.size
    r, c, w = _mean_value_weights(mesh)
    deg = np.bincount(r, weights=w, minlength=n)
    at = np.full(n, -1, dtype=np.int64)
    at[free] = np.arange(m)
    ri, ci = at[r], at[c]
    rows_free = ri >= 0
    inner = rows_free & (ci >= 0)
    edge = rows_free & (ci < 0)  # interior row, boundary column: to the right-hand side
    rows = np.concatenate([ri[inner], np.arange(m)])
    cols = np.concatenate([ci[inner], np.arange(m)])
    vals = np.concatenate([-w[inner], deg[free]])
    A = sp.csc_matrix((vals, (rows, cols)), shape=(m, m))
    rhs = np.empty((m, 2))
    for d in range(2):
        rhs[:, d] = np.bincount(ri[edge], weights=w[edge] * uv[c[edge], d], minlength=m)
    return A, rhs


def _solve_interior(mesh: Mesh, uv: NDArray, fixed: NDArray, free: NDArray) -> NDArray:
    """Parameters (m, 2) of the interior vertices ``free`` (a sparse LU solve)."""
    from scipy.sparse.linalg import splu

    A, rhs = _interior_system(mesh, uv, fixed, free)
    # A is an M-matrix (positive diagonal, negative off-diagonal, weakly diagonally dominant
    # rows, strictly next to the boundary): the diagonal pivots are stable, and a symmetric
    # fill-reducing ordering of its (symmetric) pattern keeps the factors small
    lu = splu(A, **_LU_OPTIONS)
    return lu.solve(rhs)


#: SuperLU options of the interior solve (see :func:`_solve_interior`)
_LU_OPTIONS: dict = {
    "permc_spec": "MMD_AT_PLUS_A",
    "diag_pivot_thresh": 0.0,
    "options": {"SymmetricMode": True},
}


#: square maps already made, per patch mesh (dropped with the mesh) and sides
_MAPS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_MAPS_LOCK = threading.Lock()


def _sides_key(sides: Sides) -> bytes:
    h = hashlib.blake2b(digest_size=16)
    for name in ("bottom", "right", "top", "left"):
        h.update(np.ascontiguousarray(sides.chains[name], dtype=np.int64).tobytes())
        h.update(b"|")
        h.update(np.ascontiguousarray(sides.arcs[name], dtype=np.float64).tobytes())
        h.update(b"/")
    return h.digest()


def clear_map_cache() -> None:
    """Forget the square maps :func:`square_map` keeps (they also go with their meshes)."""
    with _MAPS_LOCK:
        _MAPS.clear()


def square_map(mesh: Mesh, sides: Sides) -> PlanarMap:
    """Mean-value map of a four-sided disk patch onto the unit square.

    Boundary vertices go to the square's sides by arc length along each side; interior
    vertices are the mean-value convex combinations of their neighbours (one sparse solve
    for both coordinates). The map is kept while ``mesh`` lives: asking again for the same
    mesh object and sides (the next level of a coarse-to-fine preview) returns it at once.

    References
    ----------
    .. [1] Floater, "Mean value coordinates", CAGD 20 (2003); Tutte, "How to draw a graph"
       (1963). Used for the starting grid of Krishnamurthy 2000, sec. 5.4.
    """
    key = _sides_key(sides)
    with _MAPS_LOCK:
        hit = _MAPS.get(mesh, {}).get(key)
    if hit is not None:
        return hit
    pmap = _square_map(mesh, sides)
    with _MAPS_LOCK:
        _MAPS.setdefault(mesh, {})[key] = pmap
    return pmap


def _square_map(mesh: Mesh, sides: Sides) -> PlanarMap:
    """:func:`square_map` without the cache."""
    n = mesh.n_vertices
    uv = np.zeros((n, 2))
    fixed = np.zeros(n, dtype=bool)
    for name, (axis, const) in {
        "bottom": (0, 0.0),
        "top": (0, 1.0),
        "left": (1, 0.0),
        "right": (1, 1.0),
    }.items():
        chain, arc = sides.chains[name], sides.arcs[name]
        t = arc / arc[-1] if arc[-1] > 0 else np.linspace(0.0, 1.0, len(arc))
        uv[chain, axis] = t
        uv[chain, 1 - axis] = const
        fixed[chain] = True
    free = np.flatnonzero(~fixed)
    if free.size:
        uv[free] = _solve_interior(mesh, uv, fixed, free)
    return PlanarMap(mesh, uv)
