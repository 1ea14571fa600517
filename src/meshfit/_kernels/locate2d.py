"""Numba kernel: point location in a planar triangulation by walking from triangle to triangle.

No validation here: :mod:`meshfit.layout.regions` passes contiguous arrays of a valid
triangulation of a convex polygon (a cell's disc map).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from meshfit._kernels import inner


@inner
def _bary(uv, T, t, x, y):
    a0, a1 = uv[T[t, 0], 0], uv[T[t, 0], 1]
    v0x, v0y = uv[T[t, 1], 0] - a0, uv[T[t, 1], 1] - a1
    v1x, v1y = uv[T[t, 2], 0] - a0, uv[T[t, 2], 1] - a1
    v2x, v2y = x - a0, y - a1
    den = v0x * v1y - v1x * v0y
    if den == 0.0:
        return -1.0, -1.0, -1.0
    l1 = (v2x * v1y - v1x * v2y) / den
    l2 = (v0x * v2y - v2x * v0y) / den
    return 1.0 - l1 - l2, l1, l2


@njit(cache=True, nogil=True)
def walk_locate(uv, T, nbr, q, start, eps):
    """Triangle holding each query point and its barycentrics, walking from ``start`` for
    the first point and from the previous point's triangle for each next one.

    uv (n, 2) f8; T (nt, 3) i8, counter-clockwise; nbr (nt, 3) i8 (the triangle across edge
    ``k`` = ``(T[t, k], T[t, (k + 1) % 3])``, -1 on the boundary); q (m, 2) f8; start
    (triangle); eps (barycentric slack) -> tri (m,) i8 (-1 where the walk left the
    triangulation or did not settle within ``nt`` steps), bary (m, 3) f8.
    Each step crosses the edge opposite the most negative barycentric coordinate.
    """
    m = q.shape[0]
    nt = T.shape[0]
    tri = np.full(m, -1, dtype=np.int64)
    bary = np.zeros((m, 3))
    t = start
    for i in range(m):
        x, y = q[i, 0], q[i, 1]
        found = False
        for _ in range(nt):
            b0, b1, b2 = _bary(uv, T, t, x, y)
            k = 0
            lo = b0
            if b1 < lo:
                k, lo = 1, b1
            if b2 < lo:
                k, lo = 2, b2
            if lo >= -eps:
                found = True
                bary[i, 0], bary[i, 1], bary[i, 2] = b0, b1, b2
                break
            nxt = nbr[t, (k + 1) % 3]  # the edge opposite corner k
            if nxt < 0:
                break
            t = nxt
        if found:
            tri[i] = t
        else:
            t = start
    return tri, bary
