"""Slow, obviously-correct graph searches on a mesh's edge graph (oracles for the path kernels).

Everything here is plain Python over adjacency dictionaries built from ``mesh.edges``.
"""

from __future__ import annotations

import heapq
import math
from collections import deque

from meshfit.mesh import Mesh


def adjacency(mesh: Mesh, allowed_edges=None) -> dict[int, list[int]]:
    """Sorted neighbour lists; ``allowed_edges`` is an optional set of ``(a, b)`` with a < b."""
    adj: dict[int, list[int]] = {v: [] for v in range(mesh.n_vertices)}
    for a, b in mesh.edges.tolist():
        if allowed_edges is not None and (a, b) not in allowed_edges:
            continue
        adj[a].append(b)
        adj[b].append(a)
    for v in adj:
        adj[v].sort()
    return adj


def distance(mesh: Mesh, a: int, b: int) -> float:
    """Euclidean distance between two vertices (the same formula as the kernels)."""
    p, q = mesh.vertices[a].tolist(), mesh.vertices[b].tolist()
    dx, dy, dz = p[0] - q[0], p[1] - q[1], p[2] - q[2]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


def reachable(mesh: Mesh, source: int, allowed_edges=None) -> set[int]:
    """Vertices reachable from ``source`` by breadth-first search."""
    adj = adjacency(mesh, allowed_edges)
    seen = {source}
    queue = deque([source])
    while queue:
        v = queue.popleft()
        for u in adj[v]:
            if u not in seen:
                seen.add(u)
                queue.append(u)
    return seen


def dijkstra(mesh: Mesh, sources, allowed_edges=None) -> tuple[dict[int, float], dict[int, int]]:
    """Distances (model units) and predecessors from the nearest of ``sources``."""
    adj = adjacency(mesh, allowed_edges)
    dist: dict[int, float] = {}
    pred: dict[int, int] = {}
    heap = [(0.0, int(s), -1) for s in sources]
    heapq.heapify(heap)
    while heap:
        d, v, p = heapq.heappop(heap)
        if v in dist:
            continue
        dist[v] = d
        pred[v] = p
        for u in adj[v]:
            if u not in dist:
                heapq.heappush(heap, (d + distance(mesh, v, u), u, v))
    return dist, pred


def greedy_descent(mesh: Mesh, source: int, target: int) -> tuple[list[int], bool]:
    """The thesis' greedy walk: step to the neighbour nearest the target while one is strictly
    nearer than the current vertex. Returns the walk and whether it stalled before the target."""
    adj = adjacency(mesh)
    path = [source]
    v = source
    while v != target:
        here = distance(mesh, v, target)
        best, best_d = None, here
        for u in adj[v]:
            du = distance(mesh, u, target)
            if du < best_d:
                best, best_d = u, du
        if best is None:
            return path, True
        path.append(best)
        v = best
    return path, False


def erase_loops(walk: list[int]) -> list[int]:
    """Chronological loop erasure: whenever a vertex comes back, drop the loop since its first
    visit."""
    out: list[int] = []
    for v in walk:
        if v in out:
            del out[out.index(v) + 1 :]
        else:
            out.append(v)
    return out


def weighted_astar(mesh: Mesh, source: int, target: int, weight: float) -> list[int]:
    """A* with the Euclidean heuristic times ``weight`` (>= 1), one vertex at a time: pop the
    smallest ``g + weight * h``, relax its open neighbours; the path by predecessors."""
    adj = adjacency(mesh)
    g = {source: 0.0}
    parent: dict[int, int] = {}
    closed: set[int] = set()
    heap = [(weight * distance(mesh, source, target), source)]
    while heap:
        _, v = heapq.heappop(heap)
        if v in closed:
            continue
        if v == target:
            break
        closed.add(v)
        for u in adj[v]:
            if u in closed:
                continue
            ng = g[v] + distance(mesh, v, u)
            if ng < g.get(u, math.inf):
                g[u] = ng
                parent[u] = v
                heapq.heappush(heap, (ng + weight * distance(mesh, u, target), u))
    else:
        return []
    path = [target]
    while path[-1] != source:
        path.append(parent[path[-1]])
    return path[::-1]
