"""Slow reference of the triangle-distance and closest-point queries (`meshfit._kernels.bvh`):
every point against every triangle, the distance to a triangle as the smaller of the distance
to its plane (when the projection falls inside) and the distances to its three edges; and the
tree build on one thread, breadth first."""

from __future__ import annotations

import numpy as np


def _segment_closest(p, a, b):
    """Closest point of each segment a-b to p (a point when a == b)."""
    ab = b - a
    den = np.einsum("ij,ij->i", ab, ab)
    t = np.where(den > 0, np.einsum("ij,ij->i", p - a, ab) / np.where(den > 0, den, 1.0), 0.0)
    return a + np.clip(t, 0.0, 1.0)[:, None] * ab


def _segment_sq(p, a, b):
    q = _segment_closest(p, a, b)
    return np.einsum("ij,ij->i", p - q, p - q)


def _closest_each(V, F, p):
    """(m,) squared distance from p (3,) to each triangle and (m, 3) the closest points."""
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    P = np.broadcast_to(p, A.shape)
    best = np.full(len(F), np.inf)
    X = np.empty_like(A)
    for a, b in ((A, B), (B, C), (C, A)):
        q = _segment_closest(P, a, b)
        d = np.einsum("ij,ij->i", P - q, P - q)
        closer = d < best
        best = np.where(closer, d, best)
        X[closer] = q[closer]
    n = np.cross(B - A, C - A)
    nn = np.einsum("ij,ij->i", n, n)
    ok = nn > 0
    h = np.where(ok, np.einsum("ij,ij->i", P - A, n) / np.where(ok, nn, 1.0), 0.0)
    proj = P - h[:, None] * n  # projection onto the plane
    inside = ok.copy()
    for a, b in ((A, B), (B, C), (C, A)):
        inside &= np.einsum("ij,ij->i", np.cross(b - a, proj - a), n) >= 0
    plane = h * h * nn
    use = inside & (plane < best)
    best = np.where(use, plane, best)
    X[use] = proj[use]
    return best, X


def squared_distances(V, F, Q):
    """(n,) squared distance from each point of ``Q`` to the nearest triangle of ``V, F``."""
    return np.array([_closest_each(V, F, p)[0].min() for p in Q])


def closest_points(V, F, Q):
    """Closest point of the triangles ``V, F`` to each point of ``Q``: (n,) squared distance,
    (n,) the first nearest triangle, (n, 3) the point."""
    sq = np.empty(len(Q))
    face = np.empty(len(Q), dtype=np.int64)
    xyz = np.empty((len(Q), 3))
    for i, p in enumerate(Q):
        d, X = _closest_each(V, F, p)
        face[i] = int(np.argmin(d))
        sq[i], xyz[i] = d[face[i]], X[face[i]]
    return sq, face, xyz


def build(V, F, order, leaf_size):
    """The tree of `meshfit._kernels.bvh.build` built breadth first on one thread, with the
    same median splits (longest centroid axis, Hoare quickselect on the centroid sums).
    Returns ``order, lo, hi, child, start, stop`` as the kernel does."""
    order = [int(t) for t in order]
    C = {t: V[F[t, 0]] + V[F[t, 1]] + V[F[t, 2]] for t in order}
    start, stop, child = [0], [len(order)], [-1]
    i = 0
    while i < len(start):
        s, e = start[i], stop[i]
        if e - s > leaf_size:
            mid = (s + e) // 2
            cs = np.array([C[order[j]] for j in range(s, e)])
            ext = cs.max(axis=0) - cs.min(axis=0)
            axis = max(range(3), key=lambda d: (ext[d], -d))
            lo, hi = s, e - 1
            while lo < hi:  # Hoare quickselect
                pivot = C[order[(lo + hi) // 2]][axis]
                a, b = lo, hi
                while a <= b:
                    while C[order[a]][axis] < pivot:
                        a += 1
                    while C[order[b]][axis] > pivot:
                        b -= 1
                    if a <= b:
                        order[a], order[b] = order[b], order[a]
                        a += 1
                        b -= 1
                if mid <= b:
                    hi = b
                elif mid >= a:
                    lo = a
                else:
                    break
            child[i] = len(start)
            start += [s, mid]
            stop += [mid, e]
            child += [-1, -1]
        i += 1
    return _with_boxes(V, F, order, child, start, stop)


def _with_boxes(V, F, order, child, start, stop):
    """``order, lo, hi, child, start, stop`` as arrays, the boxes made bottom up."""
    n = len(start)
    lo_box = np.empty((n, 3))
    hi_box = np.empty((n, 3))
    for k in range(n - 1, -1, -1):
        if child[k] < 0:
            pts = V[F[order[start[k] : stop[k]]]].reshape(-1, 3)
            lo_box[k], hi_box[k] = pts.min(axis=0), pts.max(axis=0)
        else:
            c = child[k]
            lo_box[k] = np.minimum(lo_box[c], lo_box[c + 1])
            hi_box[k] = np.maximum(hi_box[c], hi_box[c + 1])
    return (
        np.array(order, dtype=np.int64),
        lo_box,
        hi_box,
        np.array(child, dtype=np.int64),
        np.array(start, dtype=np.int64),
        np.array(stop, dtype=np.int64),
    )


def build_grids(V, F, shapes, leaf_cells: int = 4):
    """The tree of `meshfit._kernels.bvh.build_grids` over stacked grid triangulations
    (first triangles of grid ``g``'s cells, row-major, then their second ones), built
    recursively from explicit node descriptions: a list of grids, split at the median of the
    grid centroids along their longest axis (a stable sort), or one grid's cell rectangle,
    halved across its longer side down to ``leaf_cells`` cells (a leaf of their triangles,
    cell by cell, row-major); a split node's children take the next two numbers and the
    first child's subtree is numbered before the second's. Returns
    ``order, lo, hi, child, start, stop``."""
    shapes = [(int(a), int(b)) for a, b in shapes]
    cells = [(a - 1) * (b - 1) for a, b in shapes]
    tbase = np.concatenate([[0], np.cumsum([2 * c for c in cells])]).tolist()
    vbase = np.concatenate([[0], np.cumsum([a * b for a, b in shapes])]).tolist()
    cent = [V[vbase[g] : vbase[g + 1]].mean(axis=0) for g in range(len(shapes))]

    def size(node) -> int:
        if node[0] == "grids":
            return sum(2 * cells[g] for g in node[1])
        _, _, r0, r1, c0, c1 = node
        return 2 * (r1 - r0) * (c1 - c0)

    start, stop, child = [0], [sum(2 * c for c in cells)], [-1]
    order = [0] * stop[0]

    def split(i: int, node) -> None:
        if node[0] == "grids" and len(node[1]) == 1:
            g = node[1][0]
            node = ("cells", g, 0, shapes[g][0] - 1, 0, shapes[g][1] - 1)
        if node[0] == "grids":
            gs = node[1]
            cs = np.array([cent[g] for g in gs])
            ext = cs.max(axis=0) - cs.min(axis=0)
            axis = max(range(3), key=lambda d: (ext[d], -d))
            gs = [gs[j] for j in np.argsort(cs[:, axis], kind="stable")]
            halves = [("grids", gs[: len(gs) // 2]), ("grids", gs[len(gs) // 2 :])]
        else:
            _, g, r0, r1, c0, c1 = node
            if (r1 - r0) * (c1 - c0) <= leaf_cells:
                ts = [
                    tbase[g] + r * (shapes[g][1] - 1) + c
                    for r in range(r0, r1)
                    for c in range(c0, c1)
                ]
                order[start[i] : stop[i]] = [x for t in ts for x in (t, t + cells[g])]
                return
            if r1 - r0 >= c1 - c0:
                m = (r0 + r1) // 2
                halves = [("cells", g, r0, m, c0, c1), ("cells", g, m, r1, c0, c1)]
            else:
                m = (c0 + c1) // 2
                halves = [("cells", g, r0, r1, c0, m), ("cells", g, r0, r1, m, c1)]
        c = child[i] = len(start)
        cut = start[i] + size(halves[0])
        start.extend([start[i], cut])
        stop.extend([cut, stop[i]])
        child.extend([-1, -1])
        split(c, halves[0])
        split(c + 1, halves[1])

    split(0, ("grids", list(range(len(shapes)))))
    return _with_boxes(V, F, order, child, start, stop)
