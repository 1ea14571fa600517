"""Numba kernel of hole filling: the least-area triangulation of a closed polygon.

No validation here: :mod:`meshfit.shrinkwrap.holes` passes contiguous arrays.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def least_area_table(P, forbidden):
    """Dynamic programme of the least-area triangulation of the polygon ``P (k, 3) f8``.

    ``forbidden (k, k) bool`` marks diagonals no triangle may use. Returns ``W (k, k) f8``,
    the least total area of the sub-polygon ``i .. j`` (``inf`` where every triangulation of
    it uses a forbidden diagonal), and ``best (k, k) i8``, the apex ``m`` (``i < m < j``) of
    the triangle on ``(i, j)`` in it (the first of equal ones).
    """
    k = P.shape[0]
    W = np.zeros((k, k))
    best = np.zeros((k, k), dtype=np.int64)
    for gap in range(2, k):
        for i in range(0, k - gap):
            j = i + gap
            lo = np.inf
            arg = i + 1
            vx = P[j, 0] - P[i, 0]
            vy = P[j, 1] - P[i, 1]
            vz = P[j, 2] - P[i, 2]
            for m in range(i + 1, j):
                ux = P[m, 0] - P[i, 0]
                uy = P[m, 1] - P[i, 1]
                uz = P[m, 2] - P[i, 2]
                cx = uy * vz - uz * vy
                cy = uz * vx - ux * vz
                cz = ux * vy - uy * vx
                c = W[i, m] + W[m, j] + 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz)
                if c < lo:
                    lo = c
                    arg = m
            W[i, j] = np.inf if forbidden[i, j] else lo
            best[i, j] = arg
    return W, best
