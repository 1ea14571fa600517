"""Numba kernels of the spring mesh's bookkeeping: face-point sums, side resampling and the
side chains' boundary edges.

No validation here: :mod:`meshfit.springs` checks every input and passes contiguous arrays.
Each kernel gives the same floating-point results, bit for bit, as the numpy expression it
stands for (named in its docstring): sums are formed in the same order.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, fastmath=False)
def face_point_sums(P, F, face, bary):
    """Barycentric combinations of per-vertex values at face points.

    Parameters
    ----------
    P : (n, d) float64
        Values at the vertices (positions, or parameters in the unit square).
    F : (n_faces, 3) int64
        Triangles.
    face : (m,) int64
        Face of each point.
    bary : (m, 3) float64
        Barycentric coordinates of each point.

    Returns
    -------
    (m, d) float64
        ``np.einsum("ij,ijk->ik", bary, P[F[face]])``, bit for bit: the three products are
        added to a zero in slot order, as einsum accumulates them.
    """
    m = face.shape[0]
    d = P.shape[1]
    out = np.empty((m, d))
    for i in range(m):
        f = face[i]
        a, b, c = F[f, 0], F[f, 1], F[f, 2]
        for k in range(d):
            s = 0.0 + bary[i, 0] * P[a, k]
            s = s + bary[i, 1] * P[b, k]
            out[i, k] = s + bary[i, 2] * P[c, k]
    return out


@njit(cache=True, nogil=True, fastmath=False)
def mid_parameters(uv, F, face, bary, a, b):
    """Mean parameters of pairs of grid points.

    Parameters
    ----------
    uv : (n, 2) float64
        Parameter of each vertex.
    F : (n_faces, 3) int64
        Triangles.
    face : (g,) int64
        Face of each grid point.
    bary : (g, 3) float64
        Barycentric coordinates of each grid point.
    a, b : (m,) int64
        The grid points of each pair.

    Returns
    -------
    (m, 2) float64
        ``0.5 * (uv_a + uv_b)`` with ``uv_a`` the parameters of the points ``a``
        (:func:`face_point_sums`), and ``uv_b`` those of ``b``.
    """
    m = a.shape[0]
    out = np.empty((m, 2))
    for i in range(m):
        p, q = a[i], b[i]
        fp, fq = face[p], face[q]
        for k in range(2):
            s = 0.0 + bary[p, 0] * uv[F[fp, 0], k]
            s = s + bary[p, 1] * uv[F[fp, 1], k]
            s = s + bary[p, 2] * uv[F[fp, 2], k]
            t = 0.0 + bary[q, 0] * uv[F[fq, 0], k]
            t = t + bary[q, 1] * uv[F[fq, 1], k]
            t = t + bary[q, 2] * uv[F[fq, 2], k]
            out[i, k] = 0.5 * (s + t)
    return out


@njit(cache=True, nogil=True, fastmath=False)
def section_positions(breaks, counts):
    """Arc-length positions of grid points along a side, uniform within each section.

    Parameters
    ----------
    breaks : (s + 1,) float64
        Section ends along the side.
    counts : (s,) int64
        Intervals per section, at least 1 each.

    Returns
    -------
    pos : (sum(counts) + 1,) float64
        ``breaks[0]``, then per section ``np.linspace(breaks[k], breaks[k + 1],
        counts[k] + 1)[1:]``, bit for bit (``i * step + start``, the last one the end).
    ends : (sum(counts) + 1,) bool
        The positions at section ends.
    """
    n = 1
    for k in range(counts.shape[0]):
        n += counts[k]
    out = np.empty(n)
    ends = np.zeros(n, dtype=np.bool_)
    out[0] = breaks[0]
    ends[0] = True
    at = 1
    for k in range(counts.shape[0]):
        c = counts[k]
        start, stop = breaks[k], breaks[k + 1]
        delta = stop - start
        step = delta / c
        for i in range(1, c):
            if step == 0.0:
                out[at] = (float(i) / c) * delta + start
            else:
                out[at] = float(i) * step + start
            at += 1
        out[at] = stop
        ends[at] = True
        at += 1
    return out, ends


@njit(cache=True, nogil=True, fastmath=False)
def chain_arc(V, chain):
    """Cumulative length along a vertex chain.

    Parameters
    ----------
    V : (n, 3) float64
        Vertex positions.
    chain : (k,) int64
        The chain's vertices, k >= 1.

    Returns
    -------
    (k,) float64
        0, then the running sums of the edge lengths: ``np.concatenate([[0.0],
        np.cumsum(np.linalg.norm(np.diff(V[chain], axis=0), axis=1))])``, bit for bit.
    """
    k = chain.shape[0]
    out = np.empty(k)
    out[0] = 0.0
    for i in range(1, k):
        p, q = chain[i - 1], chain[i]
        dx = V[q, 0] - V[p, 0]
        dy = V[q, 1] - V[p, 1]
        dz = V[q, 2] - V[p, 2]
        seg = np.sqrt(dx * dx + dy * dy + dz * dz)
        out[i] = seg if i == 1 else out[i - 1] + seg
    return out


@njit(cache=True, nogil=True, fastmath=False)
def chain_edge_faces(F, FN, n_vertices, chains, ends):
    """The boundary face holding each edge of vertex chains along the mesh boundary.

    Parameters
    ----------
    F : (n_faces, 3) int64
        Triangles.
    FN : (n_faces, 3) int64
        Face across edge ``k`` = (F[f, k], F[f, (k + 1) % 3]); -1 on the boundary.
    n_vertices : int
        Vertex count (edge keys are ``a * n_vertices + b``).
    chains : (t,) int64
        The chains' vertices, one after the other.
    ends : (c + 1,) int64
        Chain ``j`` is ``chains[ends[j]:ends[j + 1]]`` (at least one vertex each).

    Returns
    -------
    face, slot_a, slot_b : (t - c,) int64
        Per chain edge ``(a, b)``, in chain order: the face whose boundary edge joins ``a``
        and ``b`` and the slots of ``a`` and ``b`` in it (each directed boundary edge looked
        up by its key in the sorted keys of both directions).
    ok : bool
        Every chain edge is a boundary edge.
    """
    nf = F.shape[0]
    nb = 0
    for f in range(nf):
        for k in range(3):
            if FN[f, k] < 0:
                nb += 1
    # boundary edge k of face f, in the order of np.nonzero, under both directions
    key = np.empty(2 * nb, dtype=np.int64)
    bface = np.empty(2 * nb, dtype=np.int64)
    sa = np.empty(2 * nb, dtype=np.int64)
    sb = np.empty(2 * nb, dtype=np.int64)
    e = 0
    for f in range(nf):
        for k in range(3):
            if FN[f, k] < 0:
                k1 = (k + 1) % 3
                a, b = F[f, k], F[f, k1]
                key[e], bface[e], sa[e], sb[e] = a * n_vertices + b, f, k, k1
                key[nb + e], bface[nb + e], sa[nb + e], sb[nb + e] = b * n_vertices + a, f, k1, k
                e += 1
    order = np.argsort(key)
    skey = key[order]
    n_edges = chains.shape[0] - (ends.shape[0] - 1)
    face = np.empty(n_edges, dtype=np.int64)
    slot_a = np.empty(n_edges, dtype=np.int64)
    slot_b = np.empty(n_edges, dtype=np.int64)
    ok = True
    out = 0
    for j in range(ends.shape[0] - 1):
        for i in range(ends[j], ends[j + 1] - 1):
            want = chains[i] * n_vertices + chains[i + 1]
            pos = min(np.searchsorted(skey, want), 2 * nb - 1)
            hit = order[pos] if nb > 0 else 0
            if nb == 0 or key[hit] != want:
                ok = False
                hit = 0 if nb == 0 else hit
            face[out] = bface[hit] if nb > 0 else -1
            slot_a[out] = sa[hit] if nb > 0 else -1
            slot_b[out] = sb[hit] if nb > 0 else -1
            out += 1
    return face, slot_a, slot_b, ok


@njit(cache=True, nogil=True, fastmath=False)
def mean_face_edge(V, F):
    """Mean length of the faces' edges, each face's three counted (an interior edge twice).

    Parameters
    ----------
    V : (n, 3) float64
        Vertex positions.
    F : (n_faces, 3) int64
        Triangles.

    Returns
    -------
    float
        The mean over the ``3 n_faces`` face edges (0 without faces).
    """
    total = 0.0
    for f in range(F.shape[0]):
        for k in range(3):
            a = F[f, k]
            b = F[f, (k + 1) % 3]
            dx = V[b, 0] - V[a, 0]
            dy = V[b, 1] - V[a, 1]
            dz = V[b, 2] - V[a, 2]
            total += np.sqrt(dx * dx + dy * dy + dz * dz)
    return total / (3 * F.shape[0]) if F.shape[0] else 0.0
