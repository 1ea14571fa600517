"""Numpy oracles of the welded patch mesh's kernels (``_kernels.weld``): the same sums in
the same order, as whole-array expressions."""

from __future__ import annotations

import numpy as np


def welded_means(points, vertex_of, nv):
    count = np.bincount(vertex_of, minlength=nv).astype(np.float64)
    return np.stack(
        [np.bincount(vertex_of, weights=points[:, c], minlength=nv) / count for c in range(3)],
        axis=1,
    )


def grid_faces(h, w):
    """Per cell ``(i,j) (i+1,j) (i+1,j+1)``, then per cell ``(i,j) (i+1,j+1) (i,j+1)``."""
    i, j = np.meshgrid(np.arange(h - 1), np.arange(w - 1), indexing="ij")
    a = (i * w + j).ravel()
    b, c, d = a + w, a + w + 1, a + 1
    return np.concatenate([np.stack([a, b, c], axis=1), np.stack([a, c, d], axis=1)])


def welded_faces(shapes, offs, vertex_of):
    face_uv = np.concatenate(
        [grid_faces(h, w) + o for (h, w), o in zip(shapes, offs[:-1], strict=True)]
    ).astype(np.int64)
    face_patch = np.repeat(
        np.arange(len(shapes), dtype=np.int64), [2 * (h - 1) * (w - 1) for h, w in shapes]
    )
    faces = vertex_of[face_uv]
    keep = (
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])
    )
    return faces[keep], face_uv[keep], face_patch[keep]


def _cross(x, y):
    out = np.empty_like(x)
    out[..., 0] = x[..., 1] * y[..., 2] - x[..., 2] * y[..., 1]
    out[..., 1] = x[..., 2] * y[..., 0] - x[..., 0] * y[..., 2]
    out[..., 2] = x[..., 0] * y[..., 1] - x[..., 1] * y[..., 0]
    return out


def vertex_normals(vertices, vertex_of, shapes, offs):
    """Area-weighted unit normals of the welded vertices (NaN where the sum is 0): each
    grid's node sums as whole-grid slices, then added per vertex in node order."""
    node_sum = np.empty((len(vertex_of), 3))
    for p, (h, w) in enumerate(shapes):
        nodes = offs[p] + np.arange(h * w).reshape(h, w)
        P = vertices[vertex_of[nodes]]
        a, b, c, d = P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]
        ca = c - a
        n1 = _cross(b - a, ca)
        n2 = _cross(ca, d - a)
        S = np.zeros_like(P)
        S[:-1, :-1] += n1 + n2
        S[1:, 1:] += n1 + n2
        S[1:, :-1] += n1
        S[:-1, 1:] += n2
        node_sum[nodes.ravel()] = S.reshape(-1, 3)
    nv = len(vertices)
    acc = np.stack(
        [np.bincount(vertex_of, weights=node_sum[:, c], minlength=nv) for c in range(3)], axis=1
    )
    norm = np.sqrt(acc[:, 0] * acc[:, 0] + acc[:, 1] * acc[:, 1] + acc[:, 2] * acc[:, 2])
    with np.errstate(invalid="ignore", divide="ignore"):
        acc /= norm[:, None]
    acc[~(norm > 0)] = np.nan
    return acc
