"""Slow reference of the triangle-distance and closest-point queries (`meshfit._kernels.bvh`):
every point against every triangle, the distance to a triangle as the smaller of the distance
to its plane (when the projection falls inside) and the distances to its three edges."""

from __future__ import annotations

import numpy as np


def _segment_closest(p, a, b):
    """Closest point of each segment a-b to p (a point when a == b)."""
    ab = b - a
    den = np.einsum("ij,ij->i", ab, ab)
    t = np.where(den > 0, np.einsum("ij,ij->i", p - a, ab) / np.where(den > 0, den, 1.0), 0.0)
    return a + np.clip(t, 0.0, 1.0)[:, None] * ab


def _segment_sq(p, a, b):
    q = _segment_closest(p, a, b)
    return np.einsum("ij,ij->i", p - q, p - q)


def _closest_each(V, F, p):
    """(m,) squared distance from p (3,) to each triangle and (m, 3) the closest points."""
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    P = np.broadcast_to(p, A.shape)
    best = np.full(len(F), np.inf)
    X = np.empty_like(A)
    for a, b in ((A, B), (B, C), (C, A)):
        q = _segment_closest(P, a, b)
        d = np.einsum("ij,ij->i", P - q, P - q)
        closer = d < best
        best = np.where(closer, d, best)
        X[closer] = q[closer]
    n = np.cross(B - A, C - A)
    nn = np.einsum("ij,ij->i", n, n)
    ok = nn > 0
    h = np.where(ok, np.einsum("ij,ij->i", P - A, n) / np.where(ok, nn, 1.0), 0.0)
    proj = P - h[:, None] * n  # projection onto the plane
    inside = ok.copy()
    for a, b in ((A, B), (B, C), (C, A)):
        inside &= np.einsum("ij,ij->i", np.cross(b - a, proj - a), n) >= 0
    plane = h * h * nn
    use = inside & (plane < best)
    best = np.where(use, plane, best)
    X[use] = proj[use]
    return best, X


def squared_distances(V, F, Q):
    """(n,) squared distance from each point of ``Q`` to the nearest triangle of ``V, F``."""
    return np.array([_closest_each(V, F, p)[0].min() for p in Q])


def closest_points(V, F, Q):
    """Closest point of the triangles ``V, F`` to each point of ``Q``: (n,) squared distance,
    (n,) the first nearest triangle, (n, 3) the point."""
    sq = np.empty(len(Q))
    face = np.empty(len(Q), dtype=np.int64)
    xyz = np.empty((len(Q), 3))
    for i, p in enumerate(Q):
        d, X = _closest_each(V, F, p)
        face[i] = int(np.argmin(d))
        sq[i], xyz[i] = d[face[i]], X[face[i]]
    return sq, face, xyz
