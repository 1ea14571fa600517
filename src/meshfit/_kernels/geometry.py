"""Per-face and per-vertex geometry of a triangle mesh (kernels of `meshfit.mesh.core`)."""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, nogil=True, parallel=True)
def face_cross(V, F):
    """``(p1 - p0) x (p2 - p0)`` per face: (nf, 3) float64, twice the area along the normal.

    The products and differences of ``np.cross`` in its order (``a1 b2 - a2 b1``, ...), so
    the result is bitwise the numpy expression's.
    """
    nf = F.shape[0]
    out = np.empty((nf, 3))
    for f in prange(nf):
        i, j, k = F[f, 0], F[f, 1], F[f, 2]
        a0 = V[j, 0] - V[i, 0]
        a1 = V[j, 1] - V[i, 1]
        a2 = V[j, 2] - V[i, 2]
        b0 = V[k, 0] - V[i, 0]
        b1 = V[k, 1] - V[i, 1]
        b2 = V[k, 2] - V[i, 2]
        out[f, 0] = a1 * b2 - a2 * b1
        out[f, 1] = a2 * b0 - a0 * b2
        out[f, 2] = a0 * b1 - a1 * b0
    return out


@njit(cache=True, nogil=True)
def vertex_sums(F, W, nv):
    """``sum`` of the rows ``W[f]`` of the faces around each vertex: (nv, 3) float64.

    Faces are added in index order (corners 0, 1, 2 of one face in turn), the order of
    ``np.bincount(F.ravel(), weights)``, so the sums are bitwise those of that expression.
    """
    out = np.zeros((nv, 3))
    for f in range(F.shape[0]):
        for c in range(3):
            v = F[f, c]
            out[v, 0] += W[f, 0]
            out[v, 1] += W[f, 1]
            out[v, 2] += W[f, 2]
    return out
