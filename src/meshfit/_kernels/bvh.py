"""Bounding-volume hierarchy over triangles and parallel closest-point distance queries.

Kernels of `meshfit.mesh.locate.triangle_distances`; inputs already validated. The triangles
start in the Morton order of their centroids (neighbours in space near in memory); each node
is split at the median centroid along the longest axis of its centroids (quickselect), and
the boxes are made in one bottom-up pass. Each query descends nearer child first and prunes
boxes no nearer than the best triangle so far.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

#: triangles per leaf
LEAF_SIZE = 8
#: bits per axis of the Morton codes
_MORTON_BITS = 21


@njit(cache=True, nogil=True)
def _spread(x):
    """The low 21 bits of ``x`` spread to every third bit."""
    x &= 0x1FFFFF
    x = (x | (x << 32)) & 0x1F00000000FFFF
    x = (x | (x << 16)) & 0x1F0000FF0000FF
    x = (x | (x << 8)) & 0x100F00F00F00F00F
    x = (x | (x << 4)) & 0x10C30C30C30C30C3
    x = (x | (x << 2)) & 0x1249249249249249
    return x


@njit(cache=True, nogil=True, fastmath=False)
def morton_codes(V, F):
    """(m,) int64 Morton codes of the triangle centroids in the vertices' bounding box."""
    m = F.shape[0]
    lo = np.empty(3)
    hi = np.empty(3)
    for d in range(3):
        lo[d] = V[:, d].min()
        hi[d] = V[:, d].max()
    scale = np.empty(3)
    top = float((1 << _MORTON_BITS) - 1)
    for d in range(3):
        ext = hi[d] - lo[d]
        scale[d] = top / ext if ext > 0 else 0.0
    out = np.empty(m, dtype=np.int64)
    for t in range(m):
        code = 0
        for d in range(3):
            c = (V[F[t, 0], d] + V[F[t, 1], d] + V[F[t, 2], d]) / 3.0
            q = int((c - lo[d]) * scale[d])
            q = min(max(q, 0), (1 << _MORTON_BITS) - 1)
            code |= _spread(np.int64(q)) << d
        out[t] = code
    return out


@njit(cache=True, nogil=True, fastmath=False)
def build(V, F, order, leaf_size):
    """Tree over the triangles ``order`` (Morton-sorted); returns ``lo, hi (k, 3)`` node boxes,
    ``child (k,)`` first child (-1 for a leaf; the second is ``child + 1``), ``start, stop
    (k,)`` ranges of ``order`` under each node. Node 0 is the root."""
    m = order.shape[0]
    # a node splits when it holds more than leaf_size, so every leaf holds at least
    # (leaf_size + 1) // 2 triangles: at most m // that + 1 leaves, twice as many nodes
    cap = 2 * (m // max((leaf_size + 1) // 2, 1) + 1) + 1
    start = np.empty(cap, dtype=np.int64)
    stop = np.empty(cap, dtype=np.int64)
    child = np.full(cap, -1, dtype=np.int64)
    start[0] = 0
    stop[0] = m
    n = 1
    i = 0
    C = np.empty((F.shape[0], 3))
    for t in range(F.shape[0]):
        for d in range(3):
            C[t, d] = V[F[t, 0], d] + V[F[t, 1], d] + V[F[t, 2], d]
    while i < n:  # breadth first: children always follow their parent
        s, e = start[i], stop[i]
        if e - s > leaf_size:
            mid = (s + e) // 2
            _median_split(order, C, s, e, mid)
            child[i] = n
            start[n], stop[n] = s, mid
            start[n + 1], stop[n + 1] = mid, e
            n += 2
        i += 1
    lo = np.empty((n, 3))
    hi = np.empty((n, 3))
    for k in range(n - 1, -1, -1):  # children before parents
        c = child[k]
        if c < 0:
            for d in range(3):
                lo[k, d] = np.inf
                hi[k, d] = -np.inf
            for j in range(start[k], stop[k]):
                t = order[j]
                for a in range(3):
                    for d in range(3):
                        x = V[F[t, a], d]
                        if x < lo[k, d]:
                            lo[k, d] = x
                        if x > hi[k, d]:
                            hi[k, d] = x
        else:
            for d in range(3):
                lo[k, d] = min(lo[c, d], lo[c + 1, d])
                hi[k, d] = max(hi[c, d], hi[c + 1, d])
    return lo, hi, child[:n].copy(), start[:n].copy(), stop[:n].copy()


@njit(cache=True, nogil=True, fastmath=False)
def _median_split(order, C, s, e, mid):
    """Reorder ``order[s:e]`` so that ``order[mid]`` has the median centroid coordinate along
    the longest axis of the range's centroids, smaller ones before it, larger after
    (quickselect, Hoare partition)."""
    axis = 0
    best = -1.0
    for d in range(3):
        a = np.inf
        b = -np.inf
        for j in range(s, e):
            x = C[order[j], d]
            a = min(a, x)
            b = max(b, x)
        if b - a > best:
            best = b - a
            axis = d
    lo, hi = s, e - 1
    while lo < hi:
        pivot = C[order[(lo + hi) // 2], axis]
        i, j = lo, hi
        while i <= j:
            while C[order[i], axis] < pivot:
                i += 1
            while C[order[j], axis] > pivot:
                j -= 1
            if i <= j:
                order[i], order[j] = order[j], order[i]
                i += 1
                j -= 1
        if mid <= j:
            hi = j
        elif mid >= i:
            lo = i
        else:
            break


@njit(cache=True, nogil=True, fastmath=False)
def _box_sq(lo, hi, k, px, py, pz):
    s = 0.0
    for d in range(3):
        p = px if d == 0 else (py if d == 1 else pz)
        if p < lo[k, d]:
            s += (lo[k, d] - p) * (lo[k, d] - p)
        elif p > hi[k, d]:
            s += (p - hi[k, d]) * (p - hi[k, d])
    return s


@njit(cache=True, nogil=True, fastmath=False)
def _segment_sq(px, py, pz, ax, ay, az, bx, by, bz):
    """Squared distance from a point to the segment a-b (a point when a == b)."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    den = ux * ux + uy * uy + uz * uz
    t = 0.0
    if den > 0.0:
        t = ((px - ax) * ux + (py - ay) * uy + (pz - az) * uz) / den
        t = min(max(t, 0.0), 1.0)
    dx = px - (ax + t * ux)
    dy = py - (ay + t * uy)
    dz = pz - (az + t * uz)
    return dx * dx + dy * dy + dz * dz


@njit(cache=True, nogil=True, fastmath=False)
def point_triangle_sq(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Squared distance from a point to a triangle (Ericson, Real-Time Collision Detection,
    sec. 5.1.5: the Voronoi region of the closest feature). A triangle of zero area is its
    three edges (every denominator below is a squared edge length or the squared doubled
    area, so none is zero otherwise)."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    nx = aby * acz - abz * acy
    ny = abz * acx - abx * acz
    nz = abx * acy - aby * acx
    if nx * nx + ny * ny + nz * nz == 0.0:
        return min(
            _segment_sq(px, py, pz, ax, ay, az, bx, by, bz),
            min(
                _segment_sq(px, py, pz, bx, by, bz, cx, cy, cz),
                _segment_sq(px, py, pz, cx, cy, cz, ax, ay, az),
            ),
        )
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        qx, qy, qz = ax, ay, az
    else:
        bpx, bpy, bpz = px - bx, py - by, pz - bz
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        if d3 >= 0.0 and d4 <= d3:
            qx, qy, qz = bx, by, bz
        else:
            vc = d1 * d4 - d3 * d2
            if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
                v = d1 / (d1 - d3)
                qx, qy, qz = ax + v * abx, ay + v * aby, az + v * abz
            else:
                cpx, cpy, cpz = px - cx, py - cy, pz - cz
                d5 = abx * cpx + aby * cpy + abz * cpz
                d6 = acx * cpx + acy * cpy + acz * cpz
                if d6 >= 0.0 and d5 <= d6:
                    qx, qy, qz = cx, cy, cz
                else:
                    vb = d5 * d2 - d1 * d6
                    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
                        w = d2 / (d2 - d6)
                        qx, qy, qz = ax + w * acx, ay + w * acy, az + w * acz
                    else:
                        va = d3 * d6 - d5 * d4
                        if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
                            w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
                            qx = bx + w * (cx - bx)
                            qy = by + w * (cy - by)
                            qz = bz + w * (cz - bz)
                        else:
                            denom = 1.0 / (va + vb + vc)
                            v = vb * denom
                            w = vc * denom
                            qx = ax + abx * v + acx * w
                            qy = ay + aby * v + acy * w
                            qz = az + abz * v + acz * w
    dx, dy, dz = px - qx, py - qy, pz - qz
    return dx * dx + dy * dy + dz * dz


@njit(cache=True, nogil=True, parallel=True, fastmath=False)
def squared_distances(V, F, order, lo, hi, child, start, stop, Q):
    """(n,) squared distance from each query point ``Q (n, 3)`` to the nearest triangle, and
    (n,) that triangle."""
    n = Q.shape[0]
    out = np.empty(n)
    tri = np.empty(n, dtype=np.int64)
    depth = 2 * 64 + 2
    block = 1024
    for blk in prange((n + block - 1) // block):
        stack = np.empty(depth, dtype=np.int64)  # one per block, not per point
        for i in range(blk * block, min(n, (blk + 1) * block)):
            _nearest(V, F, order, lo, hi, child, start, stop, Q, i, stack, out, tri)
    return out, tri


@njit(cache=True, nogil=True, fastmath=False)
def _nearest(V, F, order, lo, hi, child, start, stop, Q, i, stack, out, tri):
    px, py, pz = Q[i, 0], Q[i, 1], Q[i, 2]
    best = np.inf
    best_t = -1
    top = 0
    stack[top] = 0
    top += 1
    while top > 0:
        top -= 1
        k = stack[top]
        if _box_sq(lo, hi, k, px, py, pz) >= best:
            continue
        c = child[k]
        if c < 0:
            for j in range(start[k], stop[k]):
                t = order[j]
                a, b, cc = F[t, 0], F[t, 1], F[t, 2]
                d = point_triangle_sq(
                    px, py, pz,
                    V[a, 0], V[a, 1], V[a, 2],
                    V[b, 0], V[b, 1], V[b, 2],
                    V[cc, 0], V[cc, 1], V[cc, 2],
                )  # fmt: skip
                if d < best:
                    best = d
                    best_t = t
        else:
            d0 = _box_sq(lo, hi, c, px, py, pz)
            d1 = _box_sq(lo, hi, c + 1, px, py, pz)
            # the nearer child is popped first
            if d0 <= d1:
                if d1 < best:
                    stack[top] = c + 1
                    top += 1
                if d0 < best:
                    stack[top] = c
                    top += 1
            else:
                if d0 < best:
                    stack[top] = c
                    top += 1
                if d1 < best:
                    stack[top] = c + 1
                    top += 1
    out[i] = best
    tri[i] = best_t
