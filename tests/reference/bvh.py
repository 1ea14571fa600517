"""Slow reference of the triangle-distance queries (`meshfit._kernels.bvh`): every point
against every triangle, the distance to a triangle as the smaller of the distance to its
plane (when the projection falls inside) and the distances to its three edges."""

from __future__ import annotations

import numpy as np


def _segment_sq(p, a, b):
    ab = b - a
    den = np.einsum("ij,ij->i", ab, ab)
    t = np.where(den > 0, np.einsum("ij,ij->i", p - a, ab) / np.where(den > 0, den, 1.0), 0.0)
    q = a + np.clip(t, 0.0, 1.0)[:, None] * ab
    return np.einsum("ij,ij->i", p - q, p - q)


def squared_distances(V, F, Q):
    """(n,) squared distance from each point of ``Q`` to the nearest triangle of ``V, F``."""
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    out = np.empty(len(Q))
    for i, p in enumerate(Q):
        P = np.broadcast_to(p, A.shape)
        best = np.minimum(
            np.minimum(_segment_sq(P, A, B), _segment_sq(P, B, C)), _segment_sq(P, C, A)
        )
        n = np.cross(B - A, C - A)
        nn = np.einsum("ij,ij->i", n, n)
        ok = nn > 0
        h = np.where(ok, np.einsum("ij,ij->i", P - A, n) / np.where(ok, nn, 1.0), 0.0)
        X = P - h[:, None] * n  # projection onto the plane
        inside = ok.copy()
        for a, b in ((A, B), (B, C), (C, A)):
            inside &= np.einsum("ij,ij->i", np.cross(b - a, X - a), n) >= 0
        plane = h * h * nn
        best = np.where(inside, np.minimum(best, plane), best)
        out[i] = best.min()
    return out
