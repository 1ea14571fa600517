"""Slow references of the connectivity kernels (meshfit._kernels.topology): boundary-loop
tracing, the edge table and connected components."""

from __future__ import annotations

import numpy as np


def trace_loops(t, h):
    """Loops of boundary half-edges ``t[i] -> h[i]`` as lists of tails (dict of lists)."""
    by_tail: dict[int, list[int]] = {}
    for i, v in enumerate(t.tolist()):
        by_tail.setdefault(v, []).append(i)
    used = np.zeros(len(t), dtype=bool)
    loops = []
    for s in range(len(t)):
        if used[s]:
            continue
        loop = []
        i = s
        while not used[i]:
            used[i] = True
            loop.append(int(t[i]))
            nxt = [j for j in by_tail.get(int(h[i]), []) if not used[j]]
            if not nxt:
                break
            i = nxt[0]
        loops.append(np.asarray(loop, dtype=np.int64))
    return loops


def edge_table(faces, nv):
    """Edge table from ``np.unique`` of the half-edge keys ``lo * nv + hi``: edges,
    half-edge -> edge, edge counts, half-edges stably sorted by edge, offsets."""
    tail = faces.reshape(-1)
    head = np.roll(faces, -1, axis=1).reshape(-1)
    lo = np.minimum(tail, head)
    hi = np.maximum(tail, head)
    m = np.int64(max(nv, 1))
    uniq, inverse, counts = np.unique(lo * m + hi, return_inverse=True, return_counts=True)
    order = np.argsort(inverse, kind="stable")
    start = np.zeros(uniq.size, dtype=np.int64)
    np.cumsum(counts[:-1], out=start[1:])
    edges = np.stack([uniq // m, uniq % m], axis=1)
    return edges, inverse.reshape(-1), counts, order, start


def components(n, a, b):
    """Connected components of ``n`` nodes joined by pairs, by scipy's csgraph."""
    from scipy import sparse
    from scipy.sparse.csgraph import connected_components

    graph = sparse.coo_matrix((np.ones(a.size, dtype=np.int8), (a, b)), shape=(n, n))
    count, labels = connected_components(graph, directed=False)
    return int(count), labels.astype(np.int64)


def vertex_faces(faces, nv, alive=None):
    """Faces around each vertex (only the ``alive`` ones, when given), ascending, as CSR:
    lists read off face by face."""
    around: list[list[int]] = [[] for _ in range(nv)]
    for f, row in enumerate(faces.tolist()):
        if alive is not None and not alive[f]:
            continue
        for v in row:
            around[v].append(f)
    indptr = np.cumsum([0] + [len(a) for a in around]).astype(np.int64)
    return indptr, np.array([f for a in around for f in sorted(a)], dtype=np.int64)


def vertex_adjacency(edges, nv):
    """Neighbours of each vertex, ascending, as CSR, from unique undirected edges."""
    around: list[set[int]] = [set() for _ in range(nv)]
    for a, b in edges.tolist():
        around[a].add(b)
        around[b].add(a)
    indptr = np.cumsum([0] + [len(a) for a in around]).astype(np.int64)
    return indptr, np.array([w for a in around for w in sorted(a)], dtype=np.int64)
