"""Per-face and per-vertex geometry of a triangle mesh (kernels of `meshfit.mesh.core`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from meshfit._kernels import split


@njit(cache=True, nogil=True, inline="always")
def _cross(V, i, j, k):
    """``(V[j] - V[i]) x (V[k] - V[i])`` as three floats, with the products and differences
    of ``np.cross`` in its order (``a1 b2 - a2 b1``, ...): bitwise the numpy expression's."""
    a0 = V[j, 0] - V[i, 0]
    a1 = V[j, 1] - V[i, 1]
    a2 = V[j, 2] - V[i, 2]
    b0 = V[k, 0] - V[i, 0]
    b1 = V[k, 1] - V[i, 1]
    b2 = V[k, 2] - V[i, 2]
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True, nogil=True, inline="always")
def _sq_dist(V, i, j):
    """Squared distance between vertices ``i`` and ``j``."""
    d0 = V[j, 0] - V[i, 0]
    d1 = V[j, 1] - V[i, 1]
    d2 = V[j, 2] - V[i, 2]
    return d0 * d0 + d1 * d1 + d2 * d2


#: faces per piece of `face_cross` on threads (fewer: one thread does the whole)
CROSS_PIECE = 65536


def face_cross(V, F):
    """``(p1 - p0) x (p2 - p0)`` per face: (nf, 3) float64, twice the area along the normal,
    bitwise the numpy expression's (`_cross`); pieces of faces on several threads."""
    out = np.empty((F.shape[0], 3))
    split(face_cross_range, F.shape[0], V, F, out, min_piece=CROSS_PIECE)
    return out


@njit(cache=True, nogil=True)
def face_cross_range(V, F, out, f0, f1):
    """`face_cross` of the faces ``f0`` to ``f1`` (exclusive), into their rows of ``out``."""
    for f in range(f0, f1):
        out[f, 0], out[f, 1], out[f, 2] = _cross(V, F[f, 0], F[f, 1], F[f, 2])


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


@njit(cache=True, nogil=True)
def polyline_gap(a, b):
    """Largest distance from the points ``a`` (n, 3) to the polyline through ``b`` (m, 3).

    Each point's distance is the smallest over the segments of ``b`` (a segment of zero
    length is its end point); the largest over the points is returned.
    """
    tiny = np.finfo(np.float64).tiny
    worst = 0.0
    for i in range(a.shape[0]):
        best = np.inf
        for j in range(b.shape[0] - 1):
            d0 = b[j + 1, 0] - b[j, 0]
            d1 = b[j + 1, 1] - b[j, 1]
            d2 = b[j + 1, 2] - b[j, 2]
            w0 = a[i, 0] - b[j, 0]
            w1 = a[i, 1] - b[j, 1]
            w2 = a[i, 2] - b[j, 2]
            s = (w0 * d0 + w1 * d1 + w2 * d2) / max(d0 * d0 + d1 * d1 + d2 * d2, tiny)
            s = min(max(s, 0.0), 1.0)
            e0 = a[i, 0] - (b[j, 0] + s * d0)
            e1 = a[i, 1] - (b[j, 1] + s * d1)
            e2 = a[i, 2] - (b[j, 2] + s * d2)
            dist = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
            if dist < best:
                best = dist
        if best > worst:
            worst = best
    return worst


@njit(cache=True, nogil=True)
def label_corner_max(F, label, value, n):
    """Largest ``value`` (per vertex) over the corners of the faces of each label: (n,)
    float64, ``-inf`` for a label without faces; faces labelled below 0 are skipped. Kernel
    of the pipeline's per-patch distance maxima."""
    out = np.full(n, -np.inf)
    for f in range(F.shape[0]):
        p = label[f]
        if p < 0:
            continue
        for k in range(3):
            x = value[F[f, k]]
            if x > out[p]:
                out[p] = x
    return out


#: faces per block of `needle_areas`: the sums of blocks are added in block order (pairs of
#: running sums of a few thousand faces, not one over millions)
_NEEDLE_BLOCK = 1 << 14


@njit(cache=True, nogil=True)
def needle_areas(V, F, ratio):
    """Total area of the triangles and the area of the needles among them: (2,) float64.

    A needle's longest edge is more than ``ratio`` times its height over that edge, i.e.
    ``longest**2 > ratio * |cross|`` (``|cross|`` twice the area; a face of zero area with
    an edge of any length is a needle). One pass over the faces without the corner arrays
    a numpy expression needs (some 250 bytes per face of a dense scan), on one thread: it
    is met at the start of a first run, where a parallel kernel's compilation would cost
    more than it saves.
    """
    nf = F.shape[0]
    nb = (nf + _NEEDLE_BLOCK - 1) // _NEEDLE_BLOCK
    part = np.zeros((nb, 2))
    tiny = np.finfo(np.float64).tiny
    for blk in range(nb):
        total = 0.0
        needle = 0.0
        for f in range(blk * _NEEDLE_BLOCK, min(nf, (blk + 1) * _NEEDLE_BLOCK)):
            i, j, k = F[f, 0], F[f, 1], F[f, 2]
            x0, x1, x2 = _cross(V, i, j, k)
            twice = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
            longest = max(_sq_dist(V, i, j), _sq_dist(V, i, k), _sq_dist(V, j, k))
            total += 0.5 * twice
            if longest > ratio * max(twice, tiny):
                needle += 0.5 * twice
        part[blk, 0] = total
        part[blk, 1] = needle
    out = np.zeros(2)
    for blk in range(nb):
        out[0] += part[blk, 0]
        out[1] += part[blk, 1]
    return out
