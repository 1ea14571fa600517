"""Numba kernels of mesh simplification: one pass of independent half-edge collapses, and
the compaction of the arrays between passes.

No validation here: :func:`meshfit.shrinkwrap.proxy.simplify_mesh` checks the input (one
closed manifold surface) and passes contiguous arrays. ``fastmath`` stays off: the normal
test of a collapse is a sign test.

Conventions: ``V (nv, 3) f8`` positions (never moved: a half-edge collapse ``v -> u`` keeps
``u`` where it is), ``F (nf, 3) i8`` faces, ``alive (nf,) bool`` the faces still in the mesh.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from meshfit._kernels import inner
from meshfit._kernels.geometry import _cross
from meshfit._kernels.topology import faces_around

_DIGIT = 16  # bits per radix pass of `stable_order`


@njit(cache=True, nogil=True, fastmath=False)
def stable_order(values):
    """``np.argsort(values, kind="stable")`` of non-negative float64 (``+inf`` allowed).

    For such values the IEEE bit patterns, read as unsigned integers, order as the values
    do, so a least-significant-digit radix sort of the bits (four passes of 16 bits,
    skipping digits all values share) gives the stable order in linear time, well ahead of
    a merge sort on the many squared edge lengths of a proxy's first pass.
    """
    n = values.shape[0]
    keys = values.view(np.uint64)
    radix = 1 << _DIGIT
    mask = np.uint64(radix - 1)
    counts = np.zeros((4, radix + 1), dtype=np.int64)
    for i in range(n):
        k = keys[i]
        for d in range(4):
            counts[d, ((k >> np.uint64(_DIGIT * d)) & mask) + 1] += 1
    order = np.arange(n, dtype=np.int64)
    spare = np.empty(n, dtype=np.int64)
    for d in range(4):
        c = counts[d]
        if c.max() == n:  # one bucket: the pass would not move anything
            continue
        for b in range(radix):
            c[b + 1] += c[b]
        shift = np.uint64(_DIGIT * d)
        for i in range(n):
            j = order[i]
            b = (keys[j] >> shift) & mask
            spare[c[b]] = j
            c[b] += 1
        order, spare = spare, order
    return order


@inner
def _neighbors(F, indptr, star, v, buf):
    """Distinct neighbours of ``v`` into ``buf``; returns their count."""
    n = 0
    for i in range(indptr[v], indptr[v + 1]):
        f = star[i]
        for k in range(3):
            w = F[f, k]
            if w == v:
                continue
            seen = False
            for j in range(n):
                if buf[j] == w:
                    seen = True
                    break
            if not seen:
                buf[n] = w
                n += 1
    return n


@inner
def _quality(V, a, b, c):
    """``4 sqrt(3) area / (l0^2 + l1^2 + l2^2)``: 1 equilateral, 0 degenerate."""
    nx, ny, nz = _cross(V, a, b, c)
    area2 = np.sqrt(nx * nx + ny * ny + nz * nz)
    s = 0.0
    for p, q in ((a, b), (b, c), (c, a)):
        for d in range(3):
            e = V[q, d] - V[p, d]
            s += e * e
    if s <= 0.0:
        return 0.0
    return 2.0 * np.sqrt(3.0) * area2 / s


@njit(cache=True, nogil=True, fastmath=False)
def collapse_pass(V, F, alive, frozen, max_collapses, max_sq, max_valence, min_cos, min_quality):
    """One pass of independent half-edge collapses, shortest edges first, in place.

    V (nv, 3) f8; F (nf, 3) i8 and alive (nf,) bool, updated in place; frozen (nv,) bool:
    vertices that never go (a piece's rim, whose stars reach faces the kernel does not see)
    and take a collapse only from a vertex none of whose other frozen neighbours is off the
    collapsed edge's two faces (an edge between two frozen vertices may be unseen); max_sq:
    only vertices whose shortest edge's squared length is at most this go. A vertex ``v`` is
    collapsed into its nearest neighbour ``u`` (then the next nearest, ...) when: the link
    condition holds (``u`` and ``v`` share exactly two neighbours), neither ``u`` nor ``v`` was
    touched by an earlier collapse of the pass (a collapse touches ``v``, ``u`` and the
    one-ring of ``v``: the vertices whose stars change), ``u`` ends with at most
    ``max_valence`` neighbours and the two opposite vertices with at least three, every face
    that keeps ``v`` -> ``u`` turns its normal by less than ``arccos(min_cos)`` and has
    quality (``4 sqrt(3) area / sum l^2``) at least ``min_quality`` or at least its old one.
    Stops after ``max_collapses``. Returns the number of collapses. Wrapped by
    ``meshfit.shrinkwrap.proxy.simplify_mesh``.
    """
    nv = V.shape[0]
    indptr, star = faces_around(F, alive, nv)
    # shortest incident edge per vertex: the visiting order
    short = np.full(nv, np.inf)
    for f in range(F.shape[0]):
        if alive[f]:
            for k in range(3):
                a = F[f, k]
                b = F[f, (k + 1) % 3]
                d = 0.0
                for j in range(3):
                    e = V[b, j] - V[a, j]
                    d += e * e
                if d < short[a]:
                    short[a] = d
                if d < short[b]:
                    short[b] = d
    order = stable_order(short)
    valence = np.zeros(nv, dtype=np.int64)  # faces around a vertex == its valence (closed)
    for v in range(nv):
        valence[v] = indptr[v + 1] - indptr[v]
    locked = np.zeros(nv, dtype=np.bool_)
    nbv = np.empty(64, dtype=np.int64)
    nbu = np.empty(64, dtype=np.int64)
    dist = np.empty(64)
    cand = np.empty(64, dtype=np.int64)
    done = 0
    for oi in range(nv):
        if done >= max_collapses:
            break
        v = order[oi]
        if short[v] > max_sq:
            break
        if locked[v] or frozen[v] or not np.isfinite(short[v]):
            continue
        if indptr[v + 1] - indptr[v] > 64:
            continue
        nv_v = _neighbors(F, indptr, star, v, nbv)
        if nv_v < 3:
            continue
        # neighbours by distance (insertion sort)
        for j in range(nv_v):
            w = nbv[j]
            d = 0.0
            for c in range(3):
                e = V[w, c] - V[v, c]
                d += e * e
            i = j
            while i > 0 and dist[i - 1] > d:
                dist[i] = dist[i - 1]
                cand[i] = cand[i - 1]
                i -= 1
            dist[i] = d
            cand[i] = w
        for ci in range(nv_v):
            u = cand[ci]
            if locked[u] or indptr[u + 1] - indptr[u] > 64:
                continue
            nu_u = _neighbors(F, indptr, star, u, nbu)
            # link condition: exactly two common neighbours (the two faces on edge uv)
            common = 0
            o0 = -1
            o1 = -1
            for i in range(nv_v):
                for j in range(nu_u):
                    if nbv[i] == nbu[j]:
                        if common == 0:
                            o0 = nbv[i]
                        else:
                            o1 = nbv[i]
                        common += 1
            if common != 2:
                continue
            if frozen[u]:
                # u's star reaches faces not seen here: an edge from u to a frozen
                # neighbour of v may be among them, unless that neighbour is opposite
                far = False
                for i in range(nv_v):
                    w = nbv[i]
                    if frozen[w] and w != u and w != o0 and w != o1:
                        far = True
                        break
                if far:
                    continue
            if nu_u + nv_v - 4 > max_valence:
                continue
            # the opposite vertices lose one neighbour each
            if valence[o0] - 1 < 3 or valence[o1] - 1 < 3:
                continue
            ok = True
            # faces around v that survive: normal turn and quality
            for i in range(indptr[v], indptr[v + 1]):
                f = star[i]
                a = F[f, 0]
                b = F[f, 1]
                c = F[f, 2]
                if a == u or b == u or c == u:
                    continue
                ox, oy, oz = _cross(V, a, b, c)
                a2 = u if a == v else a
                b2 = u if b == v else b
                c2 = u if c == v else c
                nx, ny, nz = _cross(V, a2, b2, c2)
                on = np.sqrt(ox * ox + oy * oy + oz * oz)
                nn = np.sqrt(nx * nx + ny * ny + nz * nz)
                if nn <= 0.0 or on <= 0.0:
                    ok = False
                    break
                if ox * nx + oy * ny + oz * nz < min_cos * on * nn:
                    ok = False
                    break
                q_new = _quality(V, a2, b2, c2)
                if q_new < min_quality and q_new < _quality(V, a, b, c):
                    ok = False
                    break
            if not ok:
                continue
            # collapse v -> u
            for i in range(indptr[v], indptr[v + 1]):
                f = star[i]
                if F[f, 0] == u or F[f, 1] == u or F[f, 2] == u:
                    alive[f] = False
                else:
                    for k in range(3):
                        if F[f, k] == v:
                            F[f, k] = u
            valence[o0] -= 1
            valence[o1] -= 1
            valence[u] = nu_u + nv_v - 4
            valence[v] = 0
            locked[v] = True
            locked[u] = True
            for j in range(nv_v):
                locked[nbv[j]] = True
            done += 1
            break
    return done


@njit(cache=True, nogil=True, fastmath=False)
def compact(V, F, alive, kept):
    """The alive faces and the vertices they use, both in their order: ``(V', F', kept')``
    with ``F'`` renumbered and ``kept'`` the entry of ``kept`` of each remaining vertex (a
    monotone renumbering, so a pass on the result breaks ties as on the input)."""
    nv = V.shape[0]
    remap = np.full(nv, -1, dtype=np.int64)
    m = 0
    for f in range(F.shape[0]):
        if alive[f]:
            m += 1
            for k in range(3):
                remap[F[f, k]] = 0
    n = 0
    for v in range(nv):
        if remap[v] == 0:
            remap[v] = n
            n += 1
    V2 = np.empty((n, 3))
    kept2 = np.empty(n, dtype=np.int64)
    for v in range(nv):
        r = remap[v]
        if r >= 0:
            for d in range(3):
                V2[r, d] = V[v, d]
            kept2[r] = kept[v]
    F2 = np.empty((m, 3), dtype=np.int64)
    m = 0
    for f in range(F.shape[0]):
        if alive[f]:
            for k in range(3):
                F2[m, k] = remap[F[f, k]]
            m += 1
    return V2, F2, kept2


@njit(cache=True, nogil=True, fastmath=False)
def face_cells(V, F, lo, scale, bits):
    """The Morton code of the grid cell holding each face's centroid: the centroid's
    offset from ``lo`` times ``scale`` (per axis), truncated and clipped to ``2**bits``
    cells per axis, the axes' bits interleaved (x lowest). One pass, no temporaries: the
    bricks of a scan of tens of millions of faces."""
    n = F.shape[0]
    top = (1 << bits) - 1
    out = np.empty(n, dtype=np.int64)
    for f in range(n):
        code = 0
        for d in range(3):
            c = (V[F[f, 0], d] + V[F[f, 1], d] + V[F[f, 2], d]) / 3.0
            q = int((c - lo[d]) * scale[d])
            q = min(max(q, 0), top)
            for k in range(bits):
                code |= ((q >> k) & 1) << (3 * k + d)
        out[f] = code
    return out


@njit(cache=True, nogil=True, fastmath=False)
def cell_order(codes, n_cells):
    """``np.argsort(codes, kind="stable")`` of codes in ``[0, n_cells)``, by one counting
    sort."""
    count = np.zeros(n_cells, dtype=np.int64)
    for c in codes:
        count[c] += 1
    at = np.empty(n_cells, dtype=np.int64)
    s = 0
    for c in range(n_cells):
        at[c] = s
        s += count[c]
    order = np.empty(codes.shape[0], dtype=np.int64)
    for i in range(codes.shape[0]):
        c = codes[i]
        order[at[c]] = i
        at[c] += 1
    return order


@njit(cache=True, nogil=True, fastmath=False)
def survey_brick(V, faces, b, first, shared):
    """Brick ``b``'s faces seen after those of bricks ``0..b-1``: a vertex first used here
    gets ``first = b``, one first used by another brick becomes ``shared``; returns the
    faces' area."""
    area = 0.0
    for f in range(faces.shape[0]):
        for k in range(3):
            v = faces[f, k]
            if first[v] < 0:
                first[v] = b
            elif first[v] != b:
                shared[v] = True
        nx, ny, nz = _cross(V, faces[f, 0], faces[f, 1], faces[f, 2])
        area += 0.5 * np.sqrt(nx * nx + ny * ny + nz * nz)
    return area
