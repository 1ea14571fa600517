"""Slow, obviously correct oracles for the shrink-wrap kernels."""

from __future__ import annotations

import numpy as np


def spherical_dets(sphere, faces):
    """det[a, b, c] of each triangle, one at a time."""
    return np.array(
        [np.linalg.det(np.stack([sphere[a], sphere[b], sphere[c]])) for a, b, c in faces]
    )


def locate_sphere(sphere, faces, queries):
    """For each query the face with the largest smallest edge determinant (over chord
    length), and the central-projection barycentric coordinates, by testing every face."""
    face = np.empty(len(queries), dtype=np.int64)
    bary = np.empty((len(queries), 3))
    for i, q in enumerate(queries):
        best, bf = -np.inf, 0
        for f, tri in enumerate(faces):
            vals = []
            for k in range(3):
                a, b = sphere[tri[k]], sphere[tri[(k + 1) % 3]]
                vals.append(np.linalg.det(np.stack([a, b, q])) / np.linalg.norm(a - b))
            if min(vals) > best:
                best, bf = min(vals), f
        face[i] = bf
        a, b, c = sphere[faces[bf]]
        # solve t q = alpha a + beta b + gamma c with alpha + beta + gamma = 1
        w = np.linalg.solve(np.stack([a, b, c], axis=1), q)
        w = np.clip(w / w.sum(), 0.0, None)
        bary[i] = w / w.sum()
    return face, bary
