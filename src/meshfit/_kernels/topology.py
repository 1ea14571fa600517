"""Mesh connectivity kernels."""

from __future__ import annotations

import numpy as np
from numba import njit

from meshfit._kernels import inner


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


@inner
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@inner
def _union(parent, a, b):
    """Join the sets of ``a`` and ``b`` under the smaller root."""
    ra = _root(parent, a)
    rb = _root(parent, b)
    if ra != rb:
        if ra < rb:
            parent[rb] = ra
        else:
            parent[ra] = rb


@inner
def _labels(parent):
    """``(count, labels)`` of a union-find forest, numbered by each set's smallest node."""
    n = parent.shape[0]
    labels = np.full(n, -1, dtype=np.int64)
    count = 0
    for i in range(n):
        r = _root(parent, i)
        if labels[r] < 0:
            labels[r] = count
            count += 1
        labels[i] = labels[r]
    return count, labels


@njit(cache=True, nogil=True)
def components(n, a, b):
    """Connected components of ``n`` nodes joined by the pairs ``(a[i], b[i])`` (union-find).

    Labels are numbered in the order of each component's smallest node, as
    ``scipy.sparse.csgraph.connected_components`` numbers them. Returns ``(n_components,
    labels (n,))``.
    """
    parent = np.arange(n)
    for i in range(a.shape[0]):
        _union(parent, a[i], b[i])
    return _labels(parent)


@njit(cache=True, nogil=True)
def vertex_face_components(faces, nv):
    """Components of a triangle list joined through shared vertices: ``(count, labels
    (nf,))``, numbered in order of each component's first face. On a manifold mesh (one fan
    of faces around every vertex) these are its edge-connected components.
    """
    parent = np.arange(nv)
    for f in range(faces.shape[0]):
        _union(parent, faces[f, 0], faces[f, 1])
        _union(parent, faces[f, 0], faces[f, 2])
    root_label = np.full(nv, -1, dtype=np.int64)
    labels = np.empty(faces.shape[0], dtype=np.int64)
    count = 0
    for f in range(faces.shape[0]):
        r = _root(parent, faces[f, 0])
        if root_label[r] < 0:
            root_label[r] = count
            count += 1
        labels[f] = root_label[r]
    return count, labels


@njit(cache=True, nogil=True)
def neighbor_components(neighbors):
    """`components` of the rows of ``neighbors (n, k)``, row ``i`` joined to every
    ``neighbors[i, j] >= 0`` (faces across their edges; -1 for none)."""
    n = neighbors.shape[0]
    parent = np.arange(n)
    for i in range(n):
        for j in range(neighbors.shape[1]):
            g = neighbors[i, j]
            if g >= 0:
                _union(parent, i, g)
    return _labels(parent)


@njit(cache=True, nogil=True)
def simple_ok(vertices, faces):
    """True when every coordinate is finite, every index in range, no face repeats an index
    and every vertex is used: the checks of `meshfit.mesh.validate.clean_edge_table` that
    need no edge table."""
    nv = vertices.shape[0]
    nf = faces.shape[0]
    used = np.zeros(nv, dtype=np.bool_)
    for f in range(nf):
        a = faces[f, 0]
        b = faces[f, 1]
        c = faces[f, 2]
        if a < 0 or a >= nv or b < 0 or b >= nv or c < 0 or c >= nv:
            return False
        if a == b or b == c or c == a:
            return False
        used[a] = True
        used[b] = True
        used[c] = True
    for i in range(nv):
        if not used[i]:
            return False
        for d in range(3):
            if not np.isfinite(vertices[i, d]):
                return False
    return True


@njit(cache=True, nogil=True)
def manifold_ok(vertices, faces, edge_count, order, start, area2_floor):
    """True when the mesh (which passed `simple_ok`) is manifold and consistently oriented,
    has no two faces on one vertex set, no face with ``|cross|^2 <= area2_floor`` and one fan
    of faces around every vertex; kernel of `meshfit.mesh.validate.clean_edge_table`.

    The fans are walked around each vertex across its shared edges: from corner ``3f + k``
    the next corner is the one of the same vertex in the face across the edge leaving it,
    the previous one in the face across the edge entering it. On an oriented manifold mesh
    the next-corner map is one-to-one, so every walk closes on its start or stops at the
    boundary.
    """
    nf = faces.shape[0]
    nv = vertices.shape[0]
    nh = 3 * nf
    twin = np.full(nh, -1, dtype=np.int64)
    for e in range(edge_count.shape[0]):
        c = edge_count[e]
        if c > 2:
            return False
        if c == 2:
            ha = order[start[e]]
            hb = order[start[e] + 1]
            fa = ha // 3
            ka = ha % 3
            fb = hb // 3
            kb = hb % 3
            if faces[fa, ka] == faces[fb, kb]:  # both run the same way
                return False
            if faces[fa, (ka + 2) % 3] == faces[fb, (kb + 2) % 3]:  # the same three vertices
                return False
            twin[ha] = hb
            twin[hb] = ha
    for f in range(nf):
        p0 = vertices[faces[f, 0]]
        p1 = vertices[faces[f, 1]]
        p2 = vertices[faces[f, 2]]
        ux = p1[0] - p0[0]
        uy = p1[1] - p0[1]
        uz = p1[2] - p0[2]
        wx = p2[0] - p0[0]
        wy = p2[1] - p0[1]
        wz = p2[2] - p0[2]
        cx = uy * wz - uz * wy
        cy = uz * wx - ux * wz
        cz = ux * wy - uy * wx
        if not (cx * cx + cy * cy + cz * cz > area2_floor):
            return False
    seen = np.zeros(nh, dtype=np.bool_)
    has_fan = np.zeros(nv, dtype=np.bool_)
    for c0 in range(nh):
        if seen[c0]:
            continue
        v = faces[c0 // 3, c0 % 3]
        if has_fan[v]:
            return False
        has_fan[v] = True
        seen[c0] = True
        c = c0
        closed = False
        while True:  # forward, across the edge leaving v
            t = twin[c]
            if t < 0:
                break
            c = 3 * (t // 3) + (t % 3 + 1) % 3
            if c == c0:
                closed = True
                break
            seen[c] = True
        if not closed:
            c = c0
            while True:  # backward, across the edge entering v
                t = twin[3 * (c // 3) + (c % 3 + 2) % 3]
                if t < 0:
                    break
                c = t
                seen[c] = True
    return True


@njit(cache=True, nogil=True)
def faces_around(faces, alive, nv):
    """The ``alive`` faces around each vertex as CSR ``(indptr (nv + 1,), faces)``, each
    vertex's faces ascending, by a counting sort in linear time."""
    indptr = np.zeros(nv + 1, dtype=np.int64)
    for f in range(faces.shape[0]):
        if alive[f]:
            for k in range(3):
                indptr[faces[f, k] + 1] += 1
    for v in range(nv):
        indptr[v + 1] += indptr[v]
    out = np.empty(indptr[nv], dtype=np.int64)
    fill = indptr[:nv].copy()
    for f in range(faces.shape[0]):
        if alive[f]:
            for k in range(3):
                v = faces[f, k]
                out[fill[v]] = f
                fill[v] += 1
    return indptr, out


@njit(cache=True, nogil=True)
def vertex_faces(faces, nv):
    """Faces around each vertex as CSR ``(indptr (nv + 1,), faces (3 nf,))``, each vertex's
    faces ascending: ``np.argsort(faces.ravel(), kind="stable") // 3`` in linear time (the
    comparison sort of three indices per face was seconds on a dense scan)."""
    return faces_around(faces, np.ones(faces.shape[0], dtype=np.bool_), nv)


@njit(cache=True, nogil=True)
def vertex_adjacency(edges, nv):
    """Neighbours of each vertex as CSR ``(indptr (nv + 1,), indices (2 ne,))``, each row
    ascending, from unique undirected ``edges (ne, 2)``: a counting sort by the first end,
    then an insertion sort of each (short) row."""
    indptr = np.zeros(nv + 1, dtype=np.int64)
    for i in range(edges.shape[0]):
        indptr[edges[i, 0] + 1] += 1
        indptr[edges[i, 1] + 1] += 1
    for v in range(nv):
        indptr[v + 1] += indptr[v]
    out = np.empty(indptr[nv], dtype=np.int64)
    fill = indptr[:nv].copy()
    for i in range(edges.shape[0]):
        a = edges[i, 0]
        b = edges[i, 1]
        out[fill[a]] = b
        fill[a] += 1
        out[fill[b]] = a
        fill[b] += 1
    for v in range(nv):
        for j in range(indptr[v] + 1, indptr[v + 1]):
            x = out[j]
            i = j
            while i > indptr[v] and out[i - 1] > x:
                out[i] = out[i - 1]
                i -= 1
            out[i] = x
    return indptr, out
