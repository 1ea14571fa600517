"""Slow, obviously-correct oracle of the hole-filling kernel (`meshfit._kernels.holes`)."""

from __future__ import annotations

from functools import cache

import numpy as np


def least_area(P, forbidden) -> float:
    """Least total area of a triangulation of the polygon ``P`` with no ``forbidden``
    diagonal (``inf`` if there is none), by recursion over the triangle on the side
    ``(0, k - 1)``."""
    P = np.asarray(P, dtype=float)
    k = len(P)

    def area(i, m, j):
        return 0.5 * float(np.linalg.norm(np.cross(P[m] - P[i], P[j] - P[i])))

    @cache
    def w(i, j):
        if j - i < 2:
            return 0.0
        if forbidden[i, j] and not (i == 0 and j == k - 1):
            return np.inf
        return min(w(i, m) + w(m, j) + area(i, m, j) for m in range(i + 1, j))

    return w(0, k - 1)
