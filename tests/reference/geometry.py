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
