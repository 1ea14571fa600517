"""Graph-path kernels on the vertex/edge graph of a mesh: greedy descent and A*."""

from __future__ import annotations

import heapq

import numpy as np
from numba import njit

from meshfit._kernels import inner


@inner
def _dist(V, a, b):
    dx = V[a, 0] - V[b, 0]
    dy = V[a, 1] - V[b, 1]
    dz = V[a, 2] - V[b, 2]
    return np.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True, nogil=True)
def astar(V, indptr, indices, source, target, allowed, weight=1.0):
    """Kernel of `surface.paths.astar_path`: A* with the Euclidean heuristic times ``weight``.

    V (nv, 3) f8; indptr (nv+1,) i8; indices (2 ne,) i8; allowed (nv,) bool or (0,) for all;
    weight >= 1 (1: shortest paths; w: paths at most w times the shortest, far fewer vertices
    searched). Returns the vertex path (k,) i8 from source to target, empty when unreachable.
    """
    n = V.shape[0]
    restrict = allowed.shape[0] > 0
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    g[source] = 0.0
    heap = [(weight * _dist(V, source, target), source)]
    found = False
    while len(heap) > 0:
        item = heapq.heappop(heap)
        v = item[1]
        if closed[v]:
            continue
        if v == target:
            found = True
            break
        closed[v] = True
        gv = g[v]
        for k in range(indptr[v], indptr[v + 1]):
            u = indices[k]
            if closed[u] or (restrict and not allowed[u]):
                continue
            ng = gv + _dist(V, v, u)
            if ng < g[u]:
                g[u] = ng
                parent[u] = v
                heapq.heappush(heap, (ng + weight * _dist(V, u, target), u))
    if not found:
        return np.zeros(0, dtype=np.int64)
    count = 1
    v = target
    while v != source:
        v = parent[v]
        count += 1
    out = np.empty(count, dtype=np.int64)
    v = target
    for i in range(count - 1, -1, -1):
        out[i] = v
        v = parent[v]
    return out


@njit(cache=True, nogil=True)
def greedy_descent(V, indptr, indices, source, target):
    """Greedy part of `surface.paths.greedy_path`: step to the neighbour nearest the target.

    V (nv, 3) f8; indptr (nv+1,) i8; indices (2 ne,) i8. Returns (path (k,) i8, stalled): the
    walk stops at the target or at a vertex with no neighbour strictly nearer the target.
    """
    path = [source]
    v = source
    d = _dist(V, v, target)
    while v != target:
        best = -1
        bd = d
        for k in range(indptr[v], indptr[v + 1]):
            u = indices[k]
            du = _dist(V, u, target)
            if du < bd:
                best = u
                bd = du
        if best < 0:
            break
        path.append(best)
        v = best
        d = bd
    out = np.empty(len(path), dtype=np.int64)
    for i in range(len(path)):
        out[i] = path[i]
    return out, v != target


@njit(cache=True, nogil=True)
def erase_loops(path, n_vertices):
    """Loop-erase a vertex walk (k,) i8 so that no vertex repeats (chronological erasure)."""
    pos = np.full(n_vertices, -1, dtype=np.int64)
    out = np.empty(path.shape[0], dtype=np.int64)
    m = 0
    for i in range(path.shape[0]):
        v = path[i]
        if pos[v] >= 0:
            j = pos[v]
            for t in range(j + 1, m):
                pos[out[t]] = -1
            m = j + 1
        else:
            pos[v] = m
            out[m] = v
            m += 1
    return out[:m].copy()


@njit(cache=True, nogil=True)
def greedy_path(V, indptr, indices, source, target, fallback, weight):
    """Kernel of `surface.paths.greedy_path`: greedy descent, then weighted A* from a stall.

    V (nv, 3) f8; indptr (nv+1,) i8; indices (2 ne,) i8. Returns (path (k,) i8, used_fallback,
    stall vertex or -1); the path is empty when the stall is left unresolved or A* fails.
    """
    head, stalled = greedy_descent(V, indptr, indices, source, target)
    if not stalled:
        return head, False, np.int64(-1)
    stall = head[head.shape[0] - 1]
    if not fallback:
        return np.zeros(0, dtype=np.int64), True, stall
    tail = astar(V, indptr, indices, stall, target, np.zeros(0, dtype=np.bool_), weight)
    if tail.shape[0] == 0:
        return tail, True, stall
    walk = np.concatenate((head[:-1], tail))
    return erase_loops(walk, V.shape[0]), True, stall
