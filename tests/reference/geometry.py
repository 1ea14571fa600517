"""Slow references of the mesh geometry kernels (meshfit._kernels.geometry)."""

from __future__ import annotations

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
