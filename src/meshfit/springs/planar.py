"""A fold-free planar map of a patch onto the unit square (convex-combination map, private).

The spring mesh's starting points and subdivision mid-points can be taken as the images of
regular parameter points under this map: a mean-value (Floater) map with the boundary fixed
by arc length along the four sides is a bijection onto the square (Tutte's theorem: positive
weights and a convex boundary), so a grid located in it never starts folded.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from meshfit import tol
from meshfit._kernels import springs as _k
from meshfit.mesh import Mesh
from meshfit.springs.features import Sides
from meshfit.types import SurfacePoints

__all__ = ["PlanarMap", "square_map"]


def _mean_value_weights(mesh: Mesh):
    """Rows, columns and values of the mean-value weights ``w_ij`` (all positive)."""
    V, F = mesh.vertices, mesh.faces
    rows, cols, vals = [], [], []
    for c in range(3):
        i, j, k = F[:, c], F[:, (c + 1) % 3], F[:, (c + 2) % 3]
        eij = V[j] - V[i]
        eik = V[k] - V[i]
        lij = np.linalg.norm(eij, axis=1)
        lik = np.linalg.norm(eik, axis=1)
        floor = tol.BARY_EPS * mesh.mean_edge_length
        lij = np.maximum(lij, floor)
        lik = np.maximum(lik, floor)
        cos = np.clip(np.einsum("ij,ij->i", eij, eik) / (lij * lik), -1.0, 1.0)
        # tan(theta / 2) = sqrt((1 - cos) / (1 + cos)); a zero angle gives a tiny weight
        half = np.sqrt(np.maximum(1.0 - cos, 0.0) / np.maximum(1.0 + cos, 1e-12))
        half = np.maximum(half, tol.BARY_EPS)
        rows += [i, i]
        cols += [j, k]
        vals += [half / lij, half / lik]
    return np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)


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


def square_map(mesh: Mesh, sides: Sides) -> PlanarMap:
    """Mean-value map of a four-sided disk patch onto the unit square.

    Boundary vertices go to the square's sides by arc length along each side; interior
    vertices are the mean-value convex combinations of their neighbours (one sparse solve
    for both coordinates).

    References
    ----------
    .. [1] Floater, "Mean value coordinates", CAGD 20 (2003); Tutte, "How to draw a graph"
       (1963). Used for the starting grid of Krishnamurthy 2000, sec. 5.4.
    """
    import scipy.sparse as sp
    from scipy.sparse.linalg import spsolve

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
    r, c, w = _mean_value_weights(mesh)
    W = sp.csr_matrix((w, (r, c)), shape=(n, n))
    free = np.flatnonzero(~fixed)
    if free.size:
        fix = np.flatnonzero(fixed)
        deg = np.asarray(W.sum(axis=1)).ravel()
        A = sp.diags(deg[free]) - W[free][:, free]
        rhs = W[free][:, fix] @ uv[fix]
        uv[free] = np.asarray(spsolve(A.tocsc(), rhs)).reshape(-1, 2)
    return PlanarMap(mesh, uv)
