"""Bounding-volume hierarchy over triangles and parallel closest-point queries.

Kernels of `meshfit.mesh.locate.triangle_distances` and `meshfit.mesh.locate.closest_points`;
inputs already validated. The triangles start in the Morton order of their centroids
(neighbours in space near in memory); each node is split at the median centroid along the
longest axis of its centroids (quickselect), and the boxes are made in one bottom-up pass.
Each query descends nearer child first and prunes boxes no nearer than the best triangle so
far. The queries are taken in Morton order, each search starting from the previous query's
triangle.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from meshfit._kernels import inner, split
from meshfit._kernels.walk import _closest_on_face

#: triangles per leaf: smaller leaves cost a few more box tests and a slightly slower build,
#: and save more triangle tests, which dominate a query
LEAF_SIZE = 2
#: most grid cells per leaf of `build_grids`: a displaced surface's soup has more triangles
#: than the scan, and single-cell leaves made its tree (about 80 bytes a triangle) the
#: largest array of the error stage
GRID_LEAF_CELLS = 4
#: bits per axis of the Morton codes
_MORTON_BITS = 21


@inner
def _spread(x):
    """The low 21 bits of ``x`` spread to every third bit."""
    x &= 0x1FFFFF
    x = (x | (x << 32)) & 0x1F00000000FFFF
    x = (x | (x << 16)) & 0x1F0000FF0000FF
    x = (x | (x << 8)) & 0x100F00F00F00F00F
    x = (x | (x << 4)) & 0x10C30C30C30C30C3
    x = (x | (x << 2)) & 0x1249249249249249
    return x


@inner
def _grid(X):
    """Lower corner (3,) of the bounding box of the points ``X (k, 3)`` and the scale (3,)
    that maps the box onto the Morton grid (0 along a flat axis)."""
    lo = np.empty(3)
    hi = np.empty(3)
    for d in range(3):
        lo[d] = X[:, d].min()
        hi[d] = X[:, d].max()
    scale = np.empty(3)
    top = float((1 << _MORTON_BITS) - 1)
    for d in range(3):
        ext = hi[d] - lo[d]
        scale[d] = top / ext if ext > 0 else 0.0
    return lo, scale


@inner
def _morton(x, y, z, lo, scale):
    """Morton code of the point (x, y, z) on the grid of `_grid`."""
    code = 0
    for d in range(3):
        c = x if d == 0 else (y if d == 1 else z)
        q = int((c - lo[d]) * scale[d])
        q = min(max(q, 0), (1 << _MORTON_BITS) - 1)
        code |= _spread(np.int64(q)) << d
    return code


@njit(cache=True, nogil=True, fastmath=False)
def morton_codes(V, F):
    """(m,) int64 Morton codes of the triangle centroids in the vertices' bounding box."""
    m = F.shape[0]
    lo, scale = _grid(V)
    out = np.empty(m, dtype=np.int64)
    for t in range(m):
        a, b, c = F[t, 0], F[t, 1], F[t, 2]
        out[t] = _morton(
            (V[a, 0] + V[b, 0] + V[c, 0]) / 3.0,
            (V[a, 1] + V[b, 1] + V[c, 1]) / 3.0,
            (V[a, 2] + V[b, 2] + V[c, 2]) / 3.0,
            lo,
            scale,
        )
    return out


@njit(cache=True, nogil=True, fastmath=False)
def point_morton_codes(Q):
    """(n,) int64 Morton codes of the points ``Q (n, 3)`` in their own bounding box."""
    lo, scale = _grid(Q)
    out = np.empty(Q.shape[0], dtype=np.int64)
    for i in range(Q.shape[0]):
        out[i] = _morton(Q[i, 0], Q[i, 1], Q[i, 2], lo, scale)
    return out


#: the top of the tree is split on one thread until this many nodes wait; their subtrees
#: are then split in parallel
_PARALLEL_FRONTIER = 64


@njit(cache=True, nogil=True, parallel=True, fastmath=False)
def build(V, F, order, leaf_size):
    """Tree over the triangles ``order`` (Morton-sorted); returns ``order`` rearranged so
    each node's triangles are a range, ``lo, hi (k, 3)`` node boxes, ``child (k,)`` first
    child (-1 for a leaf; the second is ``child + 1``), ``start, stop (k,)`` ranges of the
    rearranged order under each node. Node 0 is the root; nodes are numbered breadth first.

    The top of the tree is split on one thread, the subtrees below `_PARALLEL_FRONTIER`
    waiting nodes in parallel, each into its own slice of scratch arrays; a breadth-first
    pass then numbers the nodes as a one-thread breadth-first build would (the splits of
    disjoint ranges do not interact, so the tree is the same).
    """
    m = order.shape[0]
    ords = order.copy()
    C = np.empty((m, 3))  # centroid sums, row j for triangle ords[j]: moved with it
    for j in prange(m):
        t = ords[j]
        for d in range(3):
            C[j, d] = V[F[t, 0], d] + V[F[t, 1], d] + V[F[t, 2], d]
    minleaf = max((leaf_size + 1) // 2, 1)

    def cap_of(r):
        # a node splits when it holds more than leaf_size, so every leaf holds at least
        # minleaf triangles: at most r // minleaf + 1 leaves, twice as many nodes
        return 2 * (r // minleaf + 1) + 1

    # top: breadth first on one thread until enough nodes wait
    top_cap = 4 * _PARALLEL_FRONTIER + 3
    tstart = np.empty(top_cap, dtype=np.int64)
    tstop = np.empty(top_cap, dtype=np.int64)
    tchild = np.full(top_cap, -1, dtype=np.int64)
    tstart[0] = 0
    tstop[0] = m
    n_top = 1
    i = 0
    while i < n_top and n_top - i < _PARALLEL_FRONTIER:
        s, e = tstart[i], tstop[i]
        if e - s > leaf_size:
            mid = (s + e) // 2
            _median_split(ords, C, s, e, mid)
            tchild[i] = n_top
            tstart[n_top], tstop[n_top] = s, mid
            tstart[n_top + 1], tstop[n_top + 1] = mid, e
            n_top += 2
        i += 1
    first_wait = i
    n_wait = n_top - first_wait
    # scratch: each waiting node's descendants get their own slice after the top nodes
    off = np.empty(n_wait + 1, dtype=np.int64)
    off[0] = n_top
    for w in range(n_wait):
        q = first_wait + w
        off[w + 1] = off[w] + cap_of(tstop[q] - tstart[q])
    total = off[n_wait]
    start = np.empty(total, dtype=np.int64)
    stop = np.empty(total, dtype=np.int64)
    child = np.full(total, -1, dtype=np.int64)
    lo = np.empty((total, 3))
    hi = np.empty((total, 3))
    for q in range(n_top):
        start[q] = tstart[q]
        stop[q] = tstop[q]
        child[q] = tchild[q]
    used = np.empty(n_wait, dtype=np.int64)  # end of each slice's used part
    for w in prange(n_wait):
        q = first_wait + w
        n = off[w]
        k = q
        while True:  # breadth first within the slice: q, then the slice's nodes in order
            s, e = start[k], stop[k]
            if e - s > leaf_size:
                mid = (s + e) // 2
                _median_split(ords, C, s, e, mid)
                child[k] = n
                start[n], stop[n] = s, mid
                start[n + 1], stop[n + 1] = mid, e
                n += 2
            k = off[w] if k == q else k + 1
            if k >= n:
                break
        used[w] = n
        for k in range(n - 1, off[w] - 1, -1):  # children before parents
            _node_box(V, F, ords, lo, hi, child, start, stop, k)
        _node_box(V, F, ords, lo, hi, child, start, stop, q)
    for k in range(first_wait - 1, -1, -1):
        _node_box(V, F, ords, lo, hi, child, start, stop, k)
    # number breadth first: children pairs in the order their parents are reached
    n_all = n_top
    for w in range(n_wait):
        n_all += used[w] - off[w]
    new_of = np.empty(n_all, dtype=np.int64)  # old index of each new node
    new_of[0] = 0
    nn = 1
    for k in range(n_all):
        c = child[new_of[k]]
        if c >= 0:
            new_of[nn] = c
            new_of[nn + 1] = c + 1
            nn += 2
    olo = np.empty((n_all, 3))
    ohi = np.empty((n_all, 3))
    ochild = np.full(n_all, -1, dtype=np.int64)
    ostart = np.empty(n_all, dtype=np.int64)
    ostop = np.empty(n_all, dtype=np.int64)
    nxt = 1
    for k in range(n_all):
        o = new_of[k]
        for d in range(3):
            olo[k, d] = lo[o, d]
            ohi[k, d] = hi[o, d]
        ostart[k] = start[o]
        ostop[k] = stop[o]
        if child[o] >= 0:
            ochild[k] = nxt
            nxt += 2
    return ords, olo, ohi, ochild, ostart, ostop


@njit(cache=True, nogil=True, fastmath=False)
def build_grids(V, F, shapes, tbase, centroid):
    """Tree over a soup of stacked row-major grids, each triangulated as
    `meshfit.springs.grid_triangles` does (grid ``g`` of ``shapes[g] = (nu, nv)`` points has
    its ``(nu - 1) (nv - 1)`` cells' first triangles from ``tbase[g]``, then their second
    ones), in the arrays of `build`.

    The grids are split at the median of their ``centroid (n_grids, 3)`` along the longest
    axis of those (a stable sort), down to one grid; a grid's cell rectangle in halves across
    its longer index direction, down to at most `GRID_LEAF_CELLS` cells (a leaf of their
    triangles, cell by cell). No triangle is sorted. Depth first: a node's two children get
    the next two numbers when it is split, and the first child's subtree is built before the
    second's (only the open nodes are kept, on a stack).
    """
    n_grids = shapes.shape[0]
    cells = np.empty(n_grids, dtype=np.int64)
    m = 0
    for g in range(n_grids):
        cells[g] = (shapes[g, 0] - 1) * (shapes[g, 1] - 1)
        m += 2 * cells[g]
    cap = m + 2 * n_grids + 1  # a leaf per cell (m / 2), fewer than twice as many nodes
    child = np.full(cap, -1, dtype=np.int64)
    start = np.empty(cap, dtype=np.int64)
    stop = np.empty(cap, dtype=np.int64)
    order = np.empty(m, dtype=np.int64)
    perm = np.arange(n_grids)
    # open nodes: number, then a range [a, b) of ``perm`` (kind 0: grids) or a cell
    # rectangle of grid g (kind 1: rows [a, b), columns [c0, c1))
    st = np.empty((_STACK, 7), dtype=np.int64)
    st[0, 0], st[0, 1], st[0, 2], st[0, 3], st[0, 4] = 0, 0, -1, 0, n_grids
    start[0], stop[0] = 0, m
    top = 1
    n = 1
    while top > 0:
        top -= 1
        k, kind, g, a, b, c0, c1 = st[top]
        if kind == 0 and b - a == 1:  # one grid: its whole cell rectangle
            g = perm[a]
            kind, a, b, c0, c1 = 1, 0, shapes[g, 0] - 1, 0, shapes[g, 1] - 1
        if kind == 1 and (b - a) * (c1 - c0) <= GRID_LEAF_CELLS:  # a leaf: its cells'
            j = start[k]  # two triangles each, cell by cell (row-major)
            for r in range(a, b):
                for c in range(c0, c1):
                    t = tbase[g] + r * (shapes[g, 1] - 1) + c
                    order[j] = t
                    order[j + 1] = t + cells[g]
                    j += 2
            continue
        child[k] = n
        # the second child below the first on the stack: the first one's subtree is built
        # first (entry top + 1 is the first child, n; entry top the second, n + 1)
        for h in range(2):
            st[top + h, 0] = n + 1 - h
            st[top + h, 1] = kind
            st[top + h, 2] = g
            st[top + h, 3] = a
            st[top + h, 4] = b
            st[top + h, 5] = c0
            st[top + h, 6] = c1
        if kind == 0:
            sub = centroid[perm[a:b]]
            srt = np.argsort(sub[:, _longest_axis(sub, 0, b - a)], kind="mergesort")
            part = perm[a:b].copy()
            for j in range(b - a):
                perm[a + j] = part[srt[j]]
            mid = (a + b) // 2
            left = 0
            for j in range(a, mid):
                left += 2 * cells[perm[j]]
            st[top + 1, 4] = mid
            st[top, 3] = mid
        elif b - a >= c1 - c0:
            mid = (a + b) // 2
            st[top + 1, 4] = mid
            st[top, 3] = mid
            left = 2 * (mid - a) * (c1 - c0)
        else:
            mid = (c0 + c1) // 2
            st[top + 1, 6] = mid
            st[top, 5] = mid
            left = 2 * (b - a) * (mid - c0)
        start[n], stop[n] = start[k], start[k] + left
        start[n + 1], stop[n + 1] = start[k] + left, stop[k]
        n += 2
        top += 2
    lo = np.empty((n, 3))
    hi = np.empty((n, 3))
    child = child[:n]
    start = start[:n]
    stop = stop[:n]
    for k in range(n - 1, -1, -1):  # children are numbered after their parents
        _node_box(V, F, order, lo, hi, child, start, stop, k)
    return order, lo, hi, child, start, stop


@inner
def _node_box(V, F, ords, lo, hi, child, start, stop, k):
    """Box of node ``k`` from its children's boxes, or from its triangles for a leaf."""
    c = child[k]
    if c < 0:
        for d in range(3):
            lo[k, d] = np.inf
            hi[k, d] = -np.inf
        for j in range(start[k], stop[k]):
            t = ords[j]
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


@inner
def _longest_axis(C, s, e):
    """Axis (0, 1, 2) along which rows ``s:e`` of ``C (n, 3)`` spread the most (the first
    on a tie)."""
    axis = 0
    best = -1.0
    for d in range(3):
        a = np.inf
        b = -np.inf
        for j in range(s, e):
            x = C[j, d]
            a = min(a, x)
            b = max(b, x)
        if b - a > best:
            best = b - a
            axis = d
    return axis


@inner
def _median_split(order, C, s, e, mid):
    """Reorder ``order[s:e]`` (and the rows of ``C``, the centroids in that order, with it)
    so that position ``mid`` holds the median centroid coordinate along the longest axis of
    the range's centroids, smaller ones before it, larger after (quickselect, Hoare
    partition)."""
    axis = _longest_axis(C, s, e)
    lo, hi = s, e - 1
    while lo < hi:
        pivot = C[(lo + hi) // 2, axis]
        i, j = lo, hi
        while i <= j:
            while C[i, axis] < pivot:
                i += 1
            while C[j, axis] > pivot:
                j -= 1
            if i <= j:
                order[i], order[j] = order[j], order[i]
                for d in range(3):
                    C[i, d], C[j, d] = C[j, d], C[i, d]
                i += 1
                j -= 1
        if mid <= j:
            hi = j
        elif mid >= i:
            lo = i
        else:
            break


@inner
def _box_sq(lo, hi, k, px, py, pz):
    s = 0.0
    for d in range(3):
        p = px if d == 0 else (py if d == 1 else pz)
        if p < lo[k, d]:
            s += (lo[k, d] - p) * (lo[k, d] - p)
        elif p > hi[k, d]:
            s += (p - hi[k, d]) * (p - hi[k, d])
    return s


@inner
def _segment_t(px, py, pz, ax, ay, az, bx, by, bz):
    """Parameter in [0, 1] of the point of the segment a-b closest to a point (0 when a == b)."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    den = ux * ux + uy * uy + uz * uz
    t = 0.0
    if den > 0.0:
        t = ((px - ax) * ux + (py - ay) * uy + (pz - az) * uz) / den
        t = min(max(t, 0.0), 1.0)
    return t


@inner
def _segment_sq(px, py, pz, ax, ay, az, bx, by, bz):
    """Squared distance from a point to the segment a-b (a point when a == b)."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    t = _segment_t(px, py, pz, ax, ay, az, bx, by, bz)
    dx = px - (ax + t * ux)
    dy = py - (ay + t * uy)
    dz = pz - (az + t * uz)
    return dx * dx + dy * dy + dz * dz


@njit(cache=True, nogil=True, fastmath=False)
def zero_area(V, F):
    """(m,) bool: triangles whose edge vectors' cross product is exactly zero."""
    out = np.empty(F.shape[0], dtype=np.bool_)
    for t in range(F.shape[0]):
        a, b, c = F[t, 0], F[t, 1], F[t, 2]
        abx, aby, abz = V[b, 0] - V[a, 0], V[b, 1] - V[a, 1], V[b, 2] - V[a, 2]
        acx, acy, acz = V[c, 0] - V[a, 0], V[c, 1] - V[a, 1], V[c, 2] - V[a, 2]
        nx = aby * acz - abz * acy
        ny = abz * acx - abx * acz
        nz = abx * acy - aby * acx
        out[t] = nx * nx + ny * ny + nz * nz == 0.0
    return out


@inner
def _triangle_sq(V, F, flat, t, p, bary):
    """Squared distance from ``p`` (3,) to triangle ``t``; ``bary`` (3,) receives the
    barycentrics of the closest point. That point is
    `meshfit._kernels.walk._closest_on_face`'s; a triangle of zero area (``flat[t]``, see
    `zero_area`) is its three edges (that routine divides by the doubled area), the first
    nearest of them in the order ab, bc, ca."""
    a, b, c = F[t, 0], F[t, 1], F[t, 2]
    px, py, pz = p[0], p[1], p[2]
    if flat[t]:
        e0 = _segment_sq(px, py, pz, V[a, 0], V[a, 1], V[a, 2], V[b, 0], V[b, 1], V[b, 2])
        e1 = _segment_sq(px, py, pz, V[b, 0], V[b, 1], V[b, 2], V[c, 0], V[c, 1], V[c, 2])
        e2 = _segment_sq(px, py, pz, V[c, 0], V[c, 1], V[c, 2], V[a, 0], V[a, 1], V[a, 2])
        e = min(e0, min(e1, e2))
        bary[0] = 0.0
        bary[1] = 0.0
        bary[2] = 0.0
        if e0 == e:
            s = _segment_t(px, py, pz, V[a, 0], V[a, 1], V[a, 2], V[b, 0], V[b, 1], V[b, 2])
            bary[0] = 1.0 - s
            bary[1] = s
        elif e1 == e:
            s = _segment_t(px, py, pz, V[b, 0], V[b, 1], V[b, 2], V[c, 0], V[c, 1], V[c, 2])
            bary[1] = 1.0 - s
            bary[2] = s
        else:
            s = _segment_t(px, py, pz, V[c, 0], V[c, 1], V[c, 2], V[a, 0], V[a, 1], V[a, 2])
            bary[2] = 1.0 - s
            bary[0] = s
        return e
    _closest_on_face(V, F, t, p, bary)
    dx = px - (bary[0] * V[a, 0] + bary[1] * V[b, 0] + bary[2] * V[c, 0])
    dy = py - (bary[0] * V[a, 1] + bary[1] * V[b, 1] + bary[2] * V[c, 1])
    dz = pz - (bary[0] * V[a, 2] + bary[1] * V[b, 2] + bary[2] * V[c, 2])
    return dx * dx + dy * dy + dz * dz


#: stack entries per query: median splits halve every node, so the tree is less than 64
#: levels deep, and each level leaves at most one far child on the stack
_STACK = 2 * 64 + 2
#: query points per block, searched in order on one thread (one stack and scratch per block)
_BLOCK = 1024


def closest_points(V, F, flat, order, lo, hi, child, start, stop, Q, qorder):
    """Closest point of the triangles to each query point ``Q (n, 3)``: (n,) squared
    distance, (n,) triangle, (n, 3) barycentrics of the point on that triangle (each >= 0,
    summing to 1).

    The queries are taken in the order ``qorder (n,)`` (a permutation; Morton order keeps
    consecutive queries near each other), in blocks of `_BLOCK` on several threads. Each
    search descends the tree from the distance to the previous query's triangle in the same
    block, which prunes most of the tree when that query was near. Also the kernel of
    distance-only queries, which drop the barycentrics.
    """
    n = Q.shape[0]
    out = np.empty(n)
    tri = np.empty(n, dtype=np.int64)
    bary_out = np.empty((n, 3))
    args = (V, F, flat, order, lo, hi, child, start, stop, Q, qorder, out, tri, bary_out)
    split(closest_blocks, (n + _BLOCK - 1) // _BLOCK, *args)
    return out, tri, bary_out


@njit(cache=True, nogil=True, fastmath=False)
def closest_blocks(
    V, F, flat, order, lo, hi, child, start, stop, Q, qorder, out, tri, bary_out, b0, b1
):
    """`closest_points` of the queries of blocks ``b0`` to ``b1`` (exclusive), written
    into their rows of ``out``, ``tri`` and ``bary_out``."""
    n = Q.shape[0]
    for blk in range(b0, b1):
        stack = np.empty(_STACK, dtype=np.int64)
        near_sq = np.empty(_STACK)
        bary = np.empty(3)
        best = np.empty(3)
        prev = -1
        for r in range(blk * _BLOCK, min(n, (blk + 1) * _BLOCK)):
            i = qorder[r]
            d0 = np.inf
            if prev >= 0:
                d0 = _triangle_sq(V, F, flat, prev, Q[i], best)
            out[i], tri[i] = _nearest(
                V,
                F,
                flat,
                order,
                lo,
                hi,
                child,
                start,
                stop,
                Q[i],
                stack,
                near_sq,
                bary,
                best,
                d0,
                prev,
            )
            prev = tri[i]
            # the interior case sets 1 - v - w, which rounding can leave a hair below 0
            if best[0] < 0.0 or best[1] < 0.0 or best[2] < 0.0:
                for a in range(3):
                    best[a] = max(best[a], 0.0)
                s = best[0] + best[1] + best[2]
                for a in range(3):
                    best[a] /= s
            bary_out[i, 0] = best[0]
            bary_out[i, 1] = best[1]
            bary_out[i, 2] = best[2]


def within(V, F, flat, order, lo, hi, child, start, stop, Q, qorder, r2):
    """Whether each query point ``Q (n, 3)`` has a triangle within squared distance ``r2``:
    (n,) bool.

    The distance of a point to a triangle is the one `closest_points` finds. A search stops
    at the first triangle within ``r2``, and starts with the triangle that answered the
    previous query of its block (taken in the order ``qorder``, as in `closest_points`),
    which settles most queries when the radius is a few spacings of the surface.
    """
    n = Q.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    args = (V, F, flat, order, lo, hi, child, start, stop, Q, qorder, float(r2), out)
    split(within_blocks, (n + _BLOCK - 1) // _BLOCK, *args)
    return out


@njit(cache=True, nogil=True, fastmath=False)
def within_blocks(V, F, flat, order, lo, hi, child, start, stop, Q, qorder, r2, out, b0, b1):
    """`within` for the queries of blocks ``b0`` to ``b1`` (exclusive), written into their
    rows of ``out``."""
    n = Q.shape[0]
    for blk in range(b0, b1):
        stack = np.empty(_STACK, dtype=np.int64)
        near_sq = np.empty(_STACK)
        bary = np.empty(3)
        prev = -1
        for r in range(blk * _BLOCK, min(n, (blk + 1) * _BLOCK)):
            i = qorder[r]
            if prev >= 0 and _triangle_sq(V, F, flat, prev, Q[i], bary) <= r2:
                out[i] = True
                continue
            t = _first_within(
                V, F, flat, order, lo, hi, child, start, stop, Q[i], stack, near_sq, bary, r2
            )
            if t >= 0:
                out[i] = True
                prev = t


@inner
def _first_within(V, F, flat, order, lo, hi, child, start, stop, p, stack, near_sq, bary, r2):
    """A triangle within squared distance ``r2`` of ``p`` (3,), the nearer subtree searched
    first; -1 when there is none. ``stack``, ``near_sq`` and ``bary`` are scratch."""
    px, py, pz = p[0], p[1], p[2]
    top = 0
    stack[top] = 0
    near_sq[top] = _box_sq(lo, hi, 0, px, py, pz)
    top += 1
    while top > 0:
        top -= 1
        k = stack[top]
        if near_sq[top] > r2:
            continue
        c = child[k]
        if c < 0:
            for j in range(start[k], stop[k]):
                t = order[j]
                if _triangle_sq(V, F, flat, t, p, bary) <= r2:
                    return t
        else:
            top = _push_children(lo, hi, c, px, py, pz, r2, True, stack, near_sq, top)
    return -1


@njit(cache=True, nogil=True, fastmath=False)
def _nearest(
    V, F, flat, order, lo, hi, child, start, stop, p, stack, near_sq, bary, best_bary, d0, t0
):
    """Squared distance from ``p`` (3,) to the nearest triangle and that triangle, searching
    for triangles nearer than ``d0`` (triangle ``t0``, whose closest point's barycentrics are
    already in ``best_bary``; ``inf, -1`` for none). ``best_bary`` (3,) receives the
    barycentrics of the closest point; ``stack`` and ``bary`` are scratch."""
    px, py, pz = p[0], p[1], p[2]
    best = d0
    best_t = t0
    top = 0
    stack[top] = 0
    near_sq[top] = _box_sq(lo, hi, 0, px, py, pz)
    top += 1
    while top > 0:
        top -= 1
        k = stack[top]
        if near_sq[top] >= best:  # the box's distance, kept from when it was pushed
            continue
        c = child[k]
        if c < 0:
            for j in range(start[k], stop[k]):
                t = order[j]
                d = _triangle_sq(V, F, flat, t, p, bary)
                if d < best:
                    best = d
                    best_t = t
                    best_bary[0] = bary[0]
                    best_bary[1] = bary[1]
                    best_bary[2] = bary[2]
        else:
            top = _push_children(lo, hi, c, px, py, pz, best, False, stack, near_sq, top)
    return best, best_t


@inner
def _push_children(lo, hi, c, px, py, pz, bound, inclusive, stack, near_sq, top):
    """Push children ``c`` and ``c + 1`` of a node onto the search stack with their boxes'
    squared distances to ``(px, py, pz)``, each only if that distance is within ``bound``
    (``<=`` when ``inclusive``, else ``<``), the nearer last so that it is popped first;
    returns the new stack top."""
    d0 = _box_sq(lo, hi, c, px, py, pz)
    d1 = _box_sq(lo, hi, c + 1, px, py, pz)
    near, far, dn, df = (c, c + 1, d0, d1) if d0 <= d1 else (c + 1, c, d1, d0)
    if df <= bound if inclusive else df < bound:
        stack[top] = far
        near_sq[top] = df
        top += 1
    if dn <= bound if inclusive else dn < bound:
        stack[top] = near
        near_sq[top] = dn
        top += 1
    return top
