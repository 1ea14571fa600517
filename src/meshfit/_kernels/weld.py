"""Kernels of the welded patch mesh (:mod:`meshfit.export.weld`).

Every sum runs in the order of the numpy expressions it replaces (grid nodes ascending, each
node's cell terms in one fixed order), so the welded vertices and normals are the same bits
whichever computes them; only the per-patch work, which writes disjoint ranges, runs on
several threads (`meshfit._kernels.split`). Oracles: ``tests/reference/weld.py``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from meshfit._kernels import split


@njit(cache=True, nogil=True)
def welded_means(points, vertex_of, nv):
    """Mean ``(nv, 3)`` of the grid nodes ``points (k, 3)`` welded into each vertex
    (``vertex_of (k,)``, every vertex in ``range(nv)`` used), summed in node order."""
    out = np.zeros((nv, 3))
    count = np.zeros(nv)
    for k in range(points.shape[0]):
        v = vertex_of[k]
        out[v, 0] += points[k, 0]
        out[v, 1] += points[k, 1]
        out[v, 2] += points[k, 2]
        count[v] += 1.0
    for v in range(nv):
        out[v, 0] /= count[v]
        out[v, 1] /= count[v]
        out[v, 2] /= count[v]
    return out


@njit(cache=True, nogil=True, inline="always")
def _corner(vertices, vertex_of, node, out):
    v = vertex_of[node]
    out[0] = vertices[v, 0]
    out[1] = vertices[v, 1]
    out[2] = vertices[v, 2]


def node_normal_sums(vertices, vertex_of, shapes, offs):
    """Per grid node ``(k, 3)``: the area-weighted normals of its grid's triangles at it.

    Cell ``(i, j)`` of a patch of ``shapes[p] = (h, w)`` nodes (numbered ``offs[p] + i w +
    j``; corners ``a (i, j)``, ``b (i+1, j)``, ``c (i+1, j+1)``, ``d (i, j+1)`` at their
    welded ``vertices``) has the triangles ``a b c`` and ``a c d``, with cross products
    ``n1 = (b - a) x (c - a)`` and ``n2 = (c - a) x (d - a)``. A node sums, in this order,
    ``n1 + n2`` of the cell it is ``a`` of, ``n1 + n2`` of the one it is ``c`` of, ``n1``
    of the one it is ``b`` of and ``n2`` of the one it is ``d`` of. Patches on several threads.
    """
    out = np.zeros((vertex_of.shape[0], 3))
    split(node_normal_range, shapes.shape[0], vertices, vertex_of, shapes, offs, out)
    return out


@njit(cache=True, nogil=True)
def node_normal_range(vertices, vertex_of, shapes, offs, out, p0, p1):
    """`node_normal_sums` of the nodes of patches ``p0`` to ``p1`` (exclusive), into their
    rows of ``out``."""
    for p in range(p0, p1):
        h, w, base = shapes[p, 0], shapes[p, 1], offs[p]
        n1 = np.empty((h - 1, w - 1, 3))
        n2 = np.empty((h - 1, w - 1, 3))
        a, b, c, d = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
        for i in range(h - 1):
            for j in range(w - 1):
                node = base + i * w + j
                _corner(vertices, vertex_of, node, a)
                _corner(vertices, vertex_of, node + w, b)
                _corner(vertices, vertex_of, node + w + 1, c)
                _corner(vertices, vertex_of, node + 1, d)
                ca0, ca1, ca2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
                ba0, ba1, ba2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
                da0, da1, da2 = d[0] - a[0], d[1] - a[1], d[2] - a[2]
                n1[i, j, 0] = ba1 * ca2 - ba2 * ca1
                n1[i, j, 1] = ba2 * ca0 - ba0 * ca2
                n1[i, j, 2] = ba0 * ca1 - ba1 * ca0
                n2[i, j, 0] = ca1 * da2 - ca2 * da1
                n2[i, j, 1] = ca2 * da0 - ca0 * da2
                n2[i, j, 2] = ca0 * da1 - ca1 * da0
        for i in range(h):
            for j in range(w):
                node = base + i * w + j
                for q in range(3):
                    s = 0.0
                    if i < h - 1 and j < w - 1:
                        s += n1[i, j, q] + n2[i, j, q]
                    if i > 0 and j > 0:
                        s += n1[i - 1, j - 1, q] + n2[i - 1, j - 1, q]
                    if i > 0 and j < w - 1:
                        s += n1[i - 1, j, q]
                    if i < h - 1 and j > 0:
                        s += n2[i, j - 1, q]
                    out[node, q] = s


@njit(cache=True, nogil=True)
def unit_vertex_normals(node_sum, vertex_of, nv):
    """The nodes' sums ``(k, 3)`` added into their welded vertices in node order, each sum
    scaled to unit length; NaN where it is not longer than 0."""
    acc = np.zeros((nv, 3))
    for k in range(node_sum.shape[0]):
        v = vertex_of[k]
        acc[v, 0] += node_sum[k, 0]
        acc[v, 1] += node_sum[k, 1]
        acc[v, 2] += node_sum[k, 2]
    for v in range(nv):
        n = np.sqrt(acc[v, 0] * acc[v, 0] + acc[v, 1] * acc[v, 1] + acc[v, 2] * acc[v, 2])
        if n > 0.0:
            acc[v, 0] /= n
            acc[v, 1] /= n
            acc[v, 2] /= n
        else:
            acc[v, 0] = np.nan
            acc[v, 1] = np.nan
            acc[v, 2] = np.nan
    return acc


@njit(cache=True, nogil=True, inline="always")
def _put(faces, face_uv, face_patch, t, p, vertex_of, x, y, z):
    """Write triangle ``x y z`` (grid nodes) at row ``t`` unless two corners weld together;
    the next free row."""
    fx, fy, fz = vertex_of[x], vertex_of[y], vertex_of[z]
    if fx == fy or fy == fz or fz == fx:
        return t
    face_uv[t, 0], face_uv[t, 1], face_uv[t, 2] = x, y, z
    faces[t, 0], faces[t, 1], faces[t, 2] = fx, fy, fz
    face_patch[t] = p
    return t + 1


def welded_faces(shapes, offs, vertex_of):
    """The triangles of every patch's grid (per patch, first ``(i,j) (i+1,j) (i+1,j+1)`` of
    every cell, then ``(i,j) (i+1,j+1) (i,j+1)``, cells row-major), without those whose
    corners weld together: their welded vertices ``(m, 3)``, their grid nodes ``(m, 3)``,
    their patch ``(m,)``, and ``m``. The arrays have a row per triangle before the drop;
    rows from ``m`` on are unused. Patches on several threads: first the kept count of
    each, which places each one's rows, then the rows."""
    n = shapes.shape[0]
    kept = np.zeros(n + 1, dtype=np.int64)
    split(kept_counts, n, shapes, offs, vertex_of, kept)
    np.cumsum(kept, out=kept)
    total = int(2 * ((shapes[:, 0] - 1) * (shapes[:, 1] - 1)).sum())
    faces = np.empty((total, 3), dtype=np.int64)
    face_uv = np.empty((total, 3), dtype=np.int64)
    face_patch = np.empty(total, dtype=np.int64)
    split(kept_faces, n, shapes, offs, vertex_of, kept, faces, face_uv, face_patch)
    return faces, face_uv, face_patch, int(kept[n])


@njit(cache=True, nogil=True)
def kept_counts(shapes, offs, vertex_of, kept, p0, p1):
    """The triangles `welded_faces` keeps of patches ``p0`` to ``p1`` (exclusive), into
    ``kept[p + 1]``."""
    for p in range(p0, p1):
        h, w, base = shapes[p, 0], shapes[p, 1], offs[p]
        c = 0
        for i in range(h - 1):
            for j in range(w - 1):
                a = vertex_of[base + i * w + j]
                b = vertex_of[base + (i + 1) * w + j]
                cc = vertex_of[base + (i + 1) * w + j + 1]
                d = vertex_of[base + i * w + j + 1]
                c += (a != b) and (b != cc) and (cc != a)
                c += (a != cc) and (cc != d) and (d != a)
        kept[p + 1] = c


@njit(cache=True, nogil=True)
def kept_faces(shapes, offs, vertex_of, kept, faces, face_uv, face_patch, p0, p1):
    """The kept triangles of patches ``p0`` to ``p1`` (exclusive), written from row
    ``kept[p]`` of the arrays on (``kept`` summed up to each patch)."""
    for p in range(p0, p1):
        h, w, base = shapes[p, 0], shapes[p, 1], offs[p]
        t = kept[p]
        for i in range(h - 1):
            for j in range(w - 1):
                a = base + i * w + j
                t = _put(faces, face_uv, face_patch, t, p, vertex_of, a, a + w, a + w + 1)
        for i in range(h - 1):
            for j in range(w - 1):
                a = base + i * w + j
                t = _put(faces, face_uv, face_patch, t, p, vertex_of, a, a + w + 1, a + 1)
