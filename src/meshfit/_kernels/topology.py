"""Mesh connectivity kernels."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def trace_loops(t, h, nv):
    """Chain boundary half-edges ``t[i] -> h[i]`` into loops; kernel of
    `meshfit.mesh.topology.boundary_loops`.

    From each unused half-edge in index order, the successor of a half-edge is the unused
    half-edge of lowest index leaving its head; a loop ends when none is left. Returns the
    tails in loop order (k,) and the loop starts (n_loops + 1,).
    """
    k = t.shape[0]
    # half-edges by tail vertex, in index order (a stable counting sort)
    count = np.zeros(nv + 1, dtype=np.int64)
    for i in range(k):
        count[t[i] + 1] += 1
    for v in range(nv):
        count[v + 1] += count[v]
    fill = count[:-1].copy()
    by_tail = np.empty(k, dtype=np.int64)
    for i in range(k):
        by_tail[fill[t[i]]] = i
        fill[t[i]] += 1
    nxt_unused = count[:-1].copy()  # first entry of each vertex's list that may be unused
    used = np.zeros(k, dtype=np.bool_)
    out = np.empty(k, dtype=np.int64)
    starts = [0]
    n = 0
    for s in range(k):
        if used[s]:
            continue
        i = s
        while not used[i]:
            used[i] = True
            out[n] = t[i]
            n += 1
            v = h[i]
            j = -1
            p = nxt_unused[v]
            while p < count[v + 1]:
                if not used[by_tail[p]]:
                    j = by_tail[p]
                    break
                p += 1
            nxt_unused[v] = p
            if j < 0:
                break
            i = j
        starts.append(n)
    return out, np.array(starts, dtype=np.int64)


_SMALL_BUCKET = 32  # insertion sort below this many half-edges per vertex, merge sort above


@njit(cache=True, nogil=True)
def edge_table(faces, nv):
    """Undirected edge table of a triangle list; kernel of `meshfit.mesh.topology.edge_table`.

    The half-edges are counting-sorted by their smaller vertex and, within one vertex,
    stably sorted by the larger one, so edges come out in ascending ``(lo, hi)`` order and
    the half-edges of one edge in ascending index: the layout of ``np.unique`` on the keys
    ``lo * nv + hi`` and a stable argsort of its inverse. Returns ``edges (ne, 2)``,
    ``halfedge_edge (3 nf,)``, ``edge_count (ne,)``, ``order (3 nf,)``, ``start (ne,)``.
    """
    nf = faces.shape[0]
    nh = 3 * nf
    lo = np.empty(nh, dtype=np.int64)
    hi = np.empty(nh, dtype=np.int64)
    for f in range(nf):
        for k in range(3):
            a = faces[f, k]
            b = faces[f, (k + 1) % 3]
            h = 3 * f + k
            if a < b:
                lo[h] = a
                hi[h] = b
            else:
                lo[h] = b
                hi[h] = a
    count = np.zeros(nv + 1, dtype=np.int64)
    for h in range(nh):
        count[lo[h] + 1] += 1
    for v in range(nv):
        count[v + 1] += count[v]
    fill = count[:-1].copy()
    order = np.empty(nh, dtype=np.int64)
    for h in range(nh):
        order[fill[lo[h]]] = h
        fill[lo[h]] += 1
    # within each vertex's bucket: stable sort by the larger vertex
    for v in range(nv):
        s = count[v]
        e = count[v + 1]
        if e - s <= _SMALL_BUCKET:
            for i in range(s + 1, e):
                h = order[i]
                key = hi[h]
                j = i - 1
                while j >= s and hi[order[j]] > key:
                    order[j + 1] = order[j]
                    j -= 1
                order[j + 1] = h
        else:
            seg = order[s:e].copy()
            idx = np.argsort(hi[seg], kind="mergesort")
            for i in range(e - s):
                order[s + i] = seg[idx[i]]
    halfedge_edge = np.empty(nh, dtype=np.int64)
    ne = 0
    for i in range(nh):
        h = order[i]
        if i == 0 or lo[h] != lo[order[i - 1]] or hi[h] != hi[order[i - 1]]:
            ne += 1
        halfedge_edge[h] = ne - 1
    edges = np.empty((ne, 2), dtype=np.int64)
    edge_count = np.zeros(ne, dtype=np.int64)
    start = np.empty(ne, dtype=np.int64)
    for i in range(nh):
        h = order[i]
        e = halfedge_edge[h]
        if edge_count[e] == 0:
            edges[e, 0] = lo[h]
            edges[e, 1] = hi[h]
            start[e] = i
        edge_count[e] += 1
    return edges, halfedge_edge, edge_count, order, start


@njit(cache=True, nogil=True)
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True, nogil=True)
def components(n, a, b):
    """Connected components of ``n`` nodes joined by the pairs ``(a[i], b[i])`` (union-find).

    Labels are numbered in the order of each component's smallest node, as
    ``scipy.sparse.csgraph.connected_components`` numbers them. Returns ``(n_components,
    labels (n,))``.
    """
    parent = np.arange(n)
    for i in range(a.shape[0]):
        ra = _root(parent, a[i])
        rb = _root(parent, b[i])
        if ra != rb:
            if ra < rb:
                parent[rb] = ra
            else:
                parent[ra] = rb
    labels = np.full(n, -1, dtype=np.int64)
    count = 0
    for i in range(n):
        r = _root(parent, i)
        if labels[r] < 0:
            labels[r] = count
            count += 1
        labels[i] = labels[r]
    return count, labels
