"""Slow references of the mesh geometry kernels (meshfit._kernels.geometry)."""

from __future__ import annotations

import itertools

import numpy as np


def face_cross(V, F):
    """Per-face cross product of the two edges from corner 0, one face at a time."""
    out = np.empty((len(F), 3))
    for f, (i, j, k) in enumerate(F.tolist()):
        out[f] = np.cross(V[j] - V[i], V[k] - V[i])
    return out


def vertex_sums(F, W, nv):
    """Per-vertex sums of the rows of ``W`` of the faces around it, faces in index order."""
    out = np.zeros((nv, 3))
    for f, tri in enumerate(F.tolist()):
        for v in tri:
            out[v] += W[f]
    return out


def polyline_gap(a, b):
    """Largest over the points ``a`` of the distance to the nearest segment of ``b``."""
    worst = 0.0
    for p in a:
        best = np.inf
        for q0, q1 in itertools.pairwise(b):
            d = q1 - q0
            s = 0.0 if d @ d == 0 else float(np.clip((p - q0) @ d / (d @ d), 0.0, 1.0))
            best = min(best, float(np.linalg.norm(p - (q0 + s * d))))
        worst = max(worst, best)
    return worst


def label_corner_max(F, label, value, n):
    """Largest value over the corners of each label's faces, one face at a time."""
    out = np.full(n, -np.inf)
    for f, tri in enumerate(F.tolist()):
        if label[f] >= 0:
            out[label[f]] = max(out[label[f]], *(value[v] for v in tri))
    return out


def needle_areas(V, F, ratio):
    """Total and needle area, one face at a time: a needle's longest edge is more than
    ``ratio`` times its height over it (height: twice the area over that edge)."""
    total = needle = 0.0
    for tri in F.tolist():
        P = V[tri]
        area = 0.5 * np.linalg.norm(np.cross(P[1] - P[0], P[2] - P[0]))
        longest = max(np.linalg.norm(P[(c + 1) % 3] - P[c]) for c in range(3))
        total += area
        if longest > 0.0 and longest > ratio * (2.0 * area / longest):
            needle += area
    return total, needle
