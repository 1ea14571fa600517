"""Numba kernels of the mesh cut: the dynamic triangulation that curve points are inserted into
and joined by edges, and the vertex copies that separate the fans of faces along the cut.

No validation here: :mod:`meshfit.surface.cut` passes contiguous arrays. ``fastmath`` stays off
(sign tests and exact zero coordinates decide faces and edges), and every float expression is
evaluated in the order of the plain per-point algorithm (``tests/reference/cut.py``), so the
results are bit-identical to it.

The triangulation is a struct of arrays, passed to every kernel and returned (grown) by the
top-level ones:

``S (10,) i8``
    Counters: ``S[N_TRI]`` triangles (ids below ``nf0`` are original faces), ``S[N_NEW]`` new
    vertices, ``S[SNAP_OK]`` the vertex a point may snap onto although it is on the path (-1:
    none), ``S[N_EDGE]`` used slots of the edge table, ``S[N_POOL]`` used length of ``P``,
    ``S[ERR]`` an error code (0: none) with its numbers in ``S[ERR + 1 :]``.
``TR (cap_t, 4) i8``
    Per triangle: its three vertices and its original (parent) face (for an original face only
    once it is loaded).
``FL (nf0, 4) i8``
    Per original face: offset and mask of its triangle table in ``P`` (-1: none yet), flags
    (``LOADED``, ``ACTIVE``), number of triangles.
``NV (cap_v, 6) f8``
    Per new vertex: position, then barycentric coordinates in its source face.
``NI (cap_v, 2) i8``
    Per new vertex: source face, whether it is on the cut path.
``OP0 (nv0,) bool``
    Whether an original vertex is on the cut path.
``H (cap_h, 7) i8``
    Open-addressing table of undirected edges ``(a, b), a < b`` (``a = -1``: empty slot): the
    key, the number of triangles using it and their ids in insertion order (at most two on a
    manifold), whether it is a cut edge, and the vertex that split it while it was a cut edge
    (-1: none). Entries are never removed.
``P (cap_p,) i8``
    The triangle tables of the original faces (-1: free slot). Each is laid out as CPython lays
    out a ``set`` of ints that only grows, so scanning its slots visits a face's triangles in
    the order the plain algorithm's ``set`` does: where two triangles tie exactly (a point on
    the edge between them), the same one wins.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from meshfit._kernels import inner

# counters in S
N_TRI = 0
N_NEW = 1
SNAP_OK = 2
N_EDGE = 3
N_POOL = 4
ERR = 5
# error codes in S[ERR]; their numbers follow in S[ERR + 1 :]
ERR_NOT_ON_FACE = 1  # vertex, face
ERR_NOT_JOINED = 2  # lo, hi, face
ERR_NO_TRIANGLE = 3  # face, vertex
ERR_WALK = 4  # from, to, face
ERR_NON_MANIFOLD = 5  # a, b
ERR_POOL = 6
# columns of H
_HA = 0
_HB = 1
_HN = 2
_HT0 = 3
_HT1 = 4
_HCUT = 5
_HSPLIT = 6
# CPython's set probing (Objects/setobject.c)
_LINEAR_PROBES = 9
_PERTURB_SHIFT = 5
#: free room kept in P before each insertion (a face's table grows to at most 8x its size)
_POOL_ROOM = 1 << 18
# flags in FL[:, 2]
LOADED = 1
ACTIVE = 2
#: a walk between two consecutive curve points never takes more steps than this
MAX_WALK_STEPS = 100_000


# ------------------------------------------------------------------------------- state
@njit(cache=True, nogil=True)
def new_state(F0, nv0, cap_v, cap_h):
    """An empty triangulation of the original faces ``F0 (nf0, 3) i8`` (none loaded yet)."""
    nf0 = F0.shape[0]
    S = np.zeros(10, dtype=np.int64)
    S[N_TRI] = nf0
    S[SNAP_OK] = -1
    cap_t = nf0 + 2 * cap_v + 16
    TR = np.empty((cap_t, 4), dtype=np.int64)  # rows of original faces are set on loading
    FL = np.full((nf0, 4), -1, dtype=np.int64)
    FL[:, 2] = 0
    FL[:, 3] = 0
    NV = np.zeros((cap_v, 6), dtype=np.float64)
    NI = np.zeros((cap_v, 2), dtype=np.int64)
    OP0 = np.zeros(nv0, dtype=np.bool_)
    size = 1024
    while size < 2 * cap_h:
        size *= 2
    H = np.full((size, 7), -1, dtype=np.int64)
    P = np.full(8 * cap_v + 2 * _POOL_ROOM, -1, dtype=np.int64)
    return S, TR, FL, NV, NI, OP0, H, P


@njit(cache=True, nogil=True)
def _hash(a, b, mask):
    h = a * 2654435761 + b * 40503
    h ^= h >> 15
    h *= 2246822519
    h ^= h >> 13
    return h & mask


@inner
def _find(H, a, b):
    """Slot of edge (a, b), a < b; -1 when absent."""
    mask = H.shape[0] - 1
    i = _hash(a, b, mask)
    while True:
        ka = H[i, _HA]
        if ka < 0:
            return -1
        if ka == a and H[i, _HB] == b:
            return i
        i = (i + 1) & mask


@inner
def _slot(S, H, a, b):
    """Slot of edge (a, b), a < b, made (empty) when absent."""
    mask = H.shape[0] - 1
    i = _hash(a, b, mask)
    while True:
        ka = H[i, _HA]
        if ka < 0:
            H[i, _HA] = a
            H[i, _HB] = b
            H[i, _HN] = 0
            H[i, _HT0] = -1
            H[i, _HT1] = -1
            H[i, _HCUT] = 0
            H[i, _HSPLIT] = -1
            S[N_EDGE] += 1
            return i
        if ka == a and H[i, _HB] == b:
            return i
        i = (i + 1) & mask


@inner
def edge_slot(H, a, b):
    """Slot of the undirected edge (a, b) in H, -1 when absent."""
    if a < b:
        return _find(H, a, b)
    return _find(H, b, a)


@inner
def _copy_rows(src, dst, n):
    """dst[:n] = src[:n] for 2-D arrays of one width, element by element (an array slice
    assignment compiles numba's shape-mismatch error path, with its string formatting,
    into every first run)."""
    for i in range(n):
        for c in range(src.shape[1]):
            dst[i, c] = src[i, c]


@njit(cache=True, nogil=True)
def reserve(S, TR, FL, NV, NI, OP0, H, P, n_vertices, n_edges):
    """The state with room for ``n_vertices`` more vertices, twice as many more triangles and
    ``n_edges`` more edges (arrays reallocated only when short)."""
    nt = S[N_TRI] + 2 * n_vertices
    if nt > TR.shape[0]:
        cap = max(2 * TR.shape[0], nt)
        T2 = np.empty((cap, 4), dtype=np.int64)
        _copy_rows(TR, T2, S[N_TRI])
        TR = T2
    nv = S[N_NEW] + n_vertices
    if nv > NV.shape[0]:
        cap = max(2 * NV.shape[0], nv)
        V2 = np.zeros((cap, 6), dtype=np.float64)
        _copy_rows(NV, V2, S[N_NEW])
        I2 = np.zeros((cap, 2), dtype=np.int64)
        _copy_rows(NI, I2, S[N_NEW])
        NV = V2
        NI = I2
    ne = S[N_EDGE] + n_edges
    if 2 * ne > H.shape[0]:
        size = H.shape[0]
        while 2 * ne > size:
            size *= 2
        H2 = np.full((size, 7), -1, dtype=np.int64)
        mask = size - 1
        for j in range(H.shape[0]):
            a = H[j, _HA]
            if a < 0:
                continue
            i = _hash(a, H[j, _HB], mask)
            while H2[i, _HA] >= 0:
                i = (i + 1) & mask
            for c in range(7):
                H2[i, c] = H[j, c]
        H = H2
    npool = S[N_POOL] + _POOL_ROOM + 64 * n_vertices
    if npool > P.shape[0]:
        P2 = np.full(max(2 * P.shape[0], npool), -1, dtype=np.int64)
        for i in range(S[N_POOL]):
            P2[i] = P[i]
        P = P2
    return S, TR, FL, NV, NI, OP0, H, P


# ------------------------------------------------------------------------------ lookups
@inner
def _xyz(V0, NV, v):
    nv0 = V0.shape[0]
    if v >= nv0:
        i = v - nv0
        return NV[i, 0], NV[i, 1], NV[i, 2]
    return V0[v, 0], V0[v, 1], V0[v, 2]


@inner
def _norm(x, y, z):
    return math.sqrt(x * x + y * y + z * z)


@inner
def _on_path(V0, NI, OP0, v):
    nv0 = V0.shape[0]
    if v >= nv0:
        return NI[v - nv0, 1] != 0
    return OP0[v]


@inner
def _set_on_path(V0, NI, OP0, v):
    nv0 = V0.shape[0]
    if v >= nv0:
        NI[v - nv0, 1] = 1
    else:
        OP0[v] = True


@inner
def _bary_in(V0, F0, S, NV, NI, v, g):
    """Barycentric coordinates of vertex ``v`` in original face ``g`` (exact mapping)."""
    f0 = F0[g, 0]
    f1 = F0[g, 1]
    f2 = F0[g, 2]
    nv0 = V0.shape[0]
    if v < nv0:
        return 1.0 if f0 == v else 0.0, 1.0 if f1 == v else 0.0, 1.0 if f2 == v else 0.0
    i = v - nv0
    sf = NI[i, 0]
    if sf == g:
        return NV[i, 3], NV[i, 4], NV[i, 5]
    o0 = 0.0
    o1 = 0.0
    o2 = 0.0
    for k in range(3):
        bk = NV[i, 3 + k]
        if bk == 0.0:
            continue
        ov = F0[sf, k]
        if ov == f0:
            o0 += bk
        elif ov == f1:
            o1 += bk
        elif ov == f2:
            o2 += bk
        elif S[ERR] == 0:
            S[ERR] = ERR_NOT_ON_FACE
            S[ERR + 1] = v
            S[ERR + 2] = g
    return o0, o1, o2


@njit(cache=True, nogil=True)
def _uv(V0, F0, S, NV, NI, v, g):
    _, b1, b2 = _bary_in(V0, F0, S, NV, NI, v, g)
    return b1, b2


# ------------------------------------------------------------------------ triangulation
@inner
def _edge_add(S, H, a, b, t):
    if a > b:
        a, b = b, a
    i = _slot(S, H, a, b)
    n = H[i, _HN]
    if n >= 2:
        if S[ERR] == 0:
            S[ERR] = ERR_NON_MANIFOLD
            S[ERR + 1] = a
            S[ERR + 2] = b
        return
    H[i, _HT0 + n] = t
    H[i, _HN] = n + 1


@inner
def _edge_remove(H, a, b, t):
    if a > b:
        a, b = b, a
    i = _find(H, a, b)
    if H[i, _HT0] == t:
        H[i, _HT0] = H[i, _HT1]
    H[i, _HT1] = -1
    H[i, _HN] -= 1


@njit(cache=True, nogil=True)
def _register(S, TR, H, t, a, b, c, parent):
    TR[t, 0] = a
    TR[t, 1] = b
    TR[t, 2] = c
    TR[t, 3] = parent
    _edge_add(S, H, a, b, t)
    _edge_add(S, H, b, c, t)
    _edge_add(S, H, c, a, t)


@njit(cache=True, nogil=True)
def _unregister(TR, H, t):
    a = TR[t, 0]
    b = TR[t, 1]
    c = TR[t, 2]
    _edge_remove(H, a, b, t)
    _edge_remove(H, b, c, t)
    _edge_remove(H, c, a, t)


@inner
def _set_place(P, off, mask, t):
    """Put ``t`` into the first free slot of its probe sequence (CPython's set insertion)."""
    i = t & mask
    perturb = t
    while True:
        if P[off + i] < 0:
            P[off + i] = t
            return
        if i + _LINEAR_PROBES <= mask:
            for j in range(1, _LINEAR_PROBES + 1):
                if P[off + i + j] < 0:
                    P[off + i + j] = t
                    return
        perturb >>= _PERTURB_SHIFT
        i = (i * 5 + 1 + perturb) & mask


@njit(cache=True, nogil=True)
def _face_add(S, FL, P, f, t):
    """Add triangle ``t`` (not yet there) to the set of triangles of original face ``f``: a
    table laid out as CPython lays out a ``set`` of ints grown by ``add`` alone, so that
    iterating its slots in order visits the triangles in the order a ``set`` would."""
    off = FL[f, 0]
    if off < 0:
        off = S[N_POOL]
        S[N_POOL] = off + 8
        FL[f, 0] = off
        FL[f, 1] = 7
        FL[f, 3] = 0
    mask = FL[f, 1]
    _set_place(P, off, mask, t)
    fill = FL[f, 3] + 1
    FL[f, 3] = fill
    if fill * 5 < mask * 3:
        return
    # grow as set_table_resize(so, used * 4), re-adding the entries in slot order
    minused = fill * 2 if fill > 50000 else fill * 4
    size = 8
    while size <= minused:
        size <<= 1
    new_off = S[N_POOL]
    if new_off + size > P.shape[0]:
        if S[ERR] == 0:
            S[ERR] = ERR_POOL
        return
    S[N_POOL] = new_off + size
    for j in range(mask + 1):
        u = P[off + j]
        if u >= 0:
            _set_place(P, new_off, size - 1, u)
    FL[f, 0] = new_off
    FL[f, 1] = size - 1


@njit(cache=True, nogil=True)
def _load(F0, S, TR, FL, H, P, f):
    if f >= 0 and (FL[f, 2] & LOADED) == 0:
        FL[f, 2] |= LOADED
        _register(S, TR, H, f, F0[f, 0], F0[f, 1], F0[f, 2], f)
        _face_add(S, FL, P, f, f)


@inner
def _ensure(F0, FN, S, TR, FL, H, P, g):
    """Make original face ``g`` and its neighbours editable."""
    if FL[g, 2] & ACTIVE:
        return
    FL[g, 2] |= ACTIVE
    _load(F0, S, TR, FL, H, P, g)
    for k in range(3):
        _load(F0, S, TR, FL, H, P, FN[g, k])


@njit(cache=True, nogil=True)
def _new_tri(S, TR, FL, H, P, a, b, c, parent):
    t = S[N_TRI]
    S[N_TRI] = t + 1
    _register(S, TR, H, t, a, b, c, parent)
    _face_add(S, FL, P, parent, t)
    return t


@inner
def _new_vertex(V0, S, NV, NI, x, y, z, g, b0, b1, b2):
    i = S[N_NEW]
    S[N_NEW] = i + 1
    NV[i, 0] = x
    NV[i, 1] = y
    NV[i, 2] = z
    NV[i, 3] = b0
    NV[i, 4] = b1
    NV[i, 5] = b2
    NI[i, 0] = g
    NI[i, 1] = 0
    return V0.shape[0] + i


@inner
def _tri_area(V0, NV, TR, t):
    px, py, pz = _xyz(V0, NV, TR[t, 0])
    qx, qy, qz = _xyz(V0, NV, TR[t, 1])
    rx, ry, rz = _xyz(V0, NV, TR[t, 2])
    u0 = qx - px
    u1 = qy - py
    u2 = qz - pz
    v0 = rx - px
    v1 = ry - py
    v2 = rz - pz
    c0 = u1 * v2 - u2 * v1
    c1 = u2 * v0 - u0 * v2
    c2 = u0 * v1 - u1 * v0
    return 0.5 * _norm(c0, c1, c2)


@inner
def _split_face(S, TR, FL, H, P, t, x):
    a = TR[t, 0]
    b = TR[t, 1]
    c = TR[t, 2]
    parent = TR[t, 3]
    _unregister(TR, H, t)
    _register(S, TR, H, t, a, b, x, parent)
    _new_tri(S, TR, FL, H, P, b, c, x, parent)
    _new_tri(S, TR, FL, H, P, c, a, x, parent)


@inner
def _split_edge(S, TR, FL, H, P, a, b, x):
    ka = min(a, b)
    kb = max(a, b)
    i = _find(H, ka, kb)
    n = 0
    t0 = -1
    t1 = -1
    if i >= 0:
        n = H[i, _HN]
        t0 = H[i, _HT0]
        t1 = H[i, _HT1]
    for j in range(n):
        t = t0 if j == 0 else t1
        p = -1
        q = -1
        r = -1
        for k in range(3):
            p = TR[t, k]
            q = TR[t, (k + 1) % 3]
            if min(p, q) == ka and max(p, q) == kb:
                r = TR[t, (k + 2) % 3]
                break
        parent = TR[t, 3]
        _unregister(TR, H, t)
        _register(S, TR, H, t, p, x, r, parent)
        _new_tri(S, TR, FL, H, P, x, q, r, parent)
    if i >= 0 and H[i, _HCUT] != 0:
        H[i, _HCUT] = 0
        _set_cut(S, H, a, x)
        _set_cut(S, H, x, b)
        H[i, _HSPLIT] = x


@inner
def _set_cut(S, H, a, b):
    if a > b:
        a, b = b, a
    i = _slot(S, H, a, b)
    H[i, _HCUT] = 1


@inner
def _may_snap(V0, S, NI, OP0, v):
    return (not _on_path(V0, NI, OP0, v)) or v == S[SNAP_OK]


@inner
def _edge_split_ok(V0, S, TR, NV, H, a, b, s, min_area):
    """Whether splitting edge (a, b) at parameter s keeps every piece above min_area."""
    m = s
    if 1.0 - s < m:
        m = 1.0 - s
    i = edge_slot(H, a, b)
    n = H[i, _HN]
    for j in range(n):
        t = H[i, _HT0 + j]
        if not _tri_area(V0, NV, TR, t) * m >= min_area:
            return False
    return True


@inner
def _split_edge_at(V0, F0, S, TR, FL, NV, NI, OP0, H, P, a, b, s, g, snap, min_area):
    """Split edge (a, b) at parameter s, or snap to its nearer end (see `_Cutter`)."""
    pax, pay, paz = _xyz(V0, NV, a)
    pbx, pby, pbz = _xyz(V0, NV, b)
    length = _norm(pbx - pax, pby - pay, pbz - paz)
    near = a if s < 0.5 else b
    if not (0.0 < s < 1.0) or not _edge_split_ok(V0, S, TR, NV, H, a, b, s, min_area):
        return near
    if (s * length < snap or (1.0 - s) * length < snap) and _may_snap(V0, S, NI, OP0, near):
        return near
    a0, a1, a2 = _bary_in(V0, F0, S, NV, NI, a, g)
    b0, b1, b2 = _bary_in(V0, F0, S, NV, NI, b, g)
    x = _new_vertex(
        V0,
        S,
        NV,
        NI,
        pax + s * (pbx - pax),
        pay + s * (pby - pay),
        paz + s * (pbz - paz),
        g,
        a0 + s * (b0 - a0),
        a1 + s * (b1 - a1),
        a2 + s * (b2 - a2),
    )
    _split_edge(S, TR, FL, H, P, a, b, x)
    return x


# ---------------------------------------------------------------------------- insertion
@inner
def _insert(V0, F0, FN, S, TR, FL, NV, NI, OP0, H, P, snap, min_area, cf, cb, cv, cx, g, tmp):
    """Insert a snapped curve point (face ``cf``, bary ``cb (3,)``, vertex ``cv`` or -1,
    position ``cx (3,)``) into original face ``g`` (which contains it); returns its vertex.
    ``tmp (6, 3)`` is scratch (allocated once per curve)."""
    if cv >= 0:
        return cv
    _ensure(F0, FN, S, TR, FL, H, P, g)
    if cf == g:
        b0 = cb[0]
        b1 = cb[1]
        b2 = cb[2]
    else:  # the point's coordinates mapped onto the corners of g
        b0 = 0.0
        b1 = 0.0
        b2 = 0.0
        for k in range(3):
            bk = cb[k]
            if bk != 0.0:
                ov = F0[cf, k]
                if ov == F0[g, 0]:
                    b0 += bk
                elif ov == F0[g, 1]:
                    b1 += bk
                else:
                    b2 += bk
    px = cx[0]
    py = cx[1]
    pz = cx[2]
    if b0 == 0.0 or b1 == 0.0 or b2 == 0.0:
        return _insert_on_edge(
            V0, F0, S, TR, FL, NV, NI, OP0, H, P, snap, min_area, px, py, pz, b0, b1, b2, g
        )
    pu0 = b1
    pu1 = b2
    # locate: the sub-triangle of g with the largest smallest barycentric coordinate
    best_t = -1
    best_min = -math.inf
    bl0 = 0.0
    bl1 = 0.0
    bl2 = 0.0
    off = FL[g, 0]
    for slot in range(FL[g, 1] + 1):
        t = P[off + slot]
        if t < 0:
            continue
        ua0, ua1 = _uv(V0, F0, S, NV, NI, TR[t, 0], g)
        ub0, ub1 = _uv(V0, F0, S, NV, NI, TR[t, 1], g)
        uc0, uc1 = _uv(V0, F0, S, NV, NI, TR[t, 2], g)
        e10 = ub0 - ua0
        e11 = ub1 - ua1
        e20 = uc0 - ua0
        e21 = uc1 - ua1
        d0 = pu0 - ua0
        d1 = pu1 - ua1
        det = e10 * e21 - e11 * e20
        l1 = (d0 * e21 - d1 * e20) / det
        l2 = (e10 * d1 - e11 * d0) / det
        l0 = 1.0 - l1 - l2
        m = l0
        if l1 < m:
            m = l1
        if l2 < m:
            m = l2
        if m > best_min:
            best_t = t
            best_min = m
            bl0 = l0
            bl1 = l1
            bl2 = l2
    abc = TR[best_t, :3]
    pos = tmp[0:3]
    for k in range(3):
        qx, qy, qz = _xyz(V0, NV, abc[k])
        pos[k, 0] = qx
        pos[k, 1] = qy
        pos[k, 2] = qz
    # an existing vertex
    dv = tmp[3]
    for k in range(3):
        dv[k] = _norm(px - pos[k, 0], py - pos[k, 1], pz - pos[k, 2])
    k = _argmin3(dv[0], dv[1], dv[2])
    if dv[k] < snap and _may_snap(V0, S, NI, OP0, abc[k]):
        return abc[k]
    # an existing edge
    edge_d = tmp[4]
    edge_s = tmp[5]
    for k in range(3):
        k1 = (k + 1) % 3
        e0 = pos[k1, 0] - pos[k, 0]
        e1 = pos[k1, 1] - pos[k, 1]
        e2 = pos[k1, 2] - pos[k, 2]
        ee = e0 * e0 + e1 * e1 + e2 * e2
        r = ((px - pos[k, 0]) * e0 + (py - pos[k, 1]) * e1 + (pz - pos[k, 2]) * e2) / ee
        if 0.0 > r:  # min(max(r, 0.0), 1.0) as Python evaluates it
            r = 0.0
        if 1.0 < r:
            r = 1.0
        edge_s[k] = r
        fx = pos[k, 0] + r * (pos[k1, 0] - pos[k, 0])
        fy = pos[k, 1] + r * (pos[k1, 1] - pos[k, 1])
        fz = pos[k, 2] + r * (pos[k1, 2] - pos[k, 2])
        edge_d[k] = _norm(px - fx, py - fy, pz - fz)
    area = _tri_area(V0, NV, TR, best_t)
    k = _argmin3(edge_d[0], edge_d[1], edge_d[2])
    lmin = bl0
    if bl1 < lmin:
        lmin = bl1
    if bl2 < lmin:
        lmin = bl2
    if edge_d[k] >= snap and lmin * area >= min_area:
        x = _new_vertex(V0, S, NV, NI, px, py, pz, g, b0, b1, b2)
        _split_face(S, TR, FL, H, P, best_t, x)
        return x
    if edge_d[k] >= snap:  # too thin to split the face: use the nearest edge
        k = (_argmin3(bl0, bl1, bl2) + 1) % 3
    a = abc[k]
    b = abc[(k + 1) % 3]
    return _split_edge_at(V0, F0, S, TR, FL, NV, NI, OP0, H, P, a, b, edge_s[k], g, snap, min_area)


@inner
def _argmin3(x0, x1, x2):
    """Index of the first smallest of three numbers."""
    k = 0
    m = x0
    if x1 < m:
        k = 1
        m = x1
    if x2 < m:
        k = 2
    return k


@njit(cache=True, nogil=True)
def _insert_on_edge(
    V0, F0, S, TR, FL, NV, NI, OP0, H, P, snap, min_area, px, py, pz, b0, b1, b2, g
):
    """Insert a point of an original edge of ``g`` (an exact zero coordinate) on the pieces of
    that edge, so that it stays a vertex of both faces sharing the edge."""
    if b0 == 0.0:
        z = 0
    elif b1 == 0.0:
        z = 1
    else:
        z = 2
    j = (z + 2) % 3  # parameter along the edge: the coordinate of its second vertex
    tp = b0 if j == 0 else (b1 if j == 1 else b2)
    lo = -1
    hi = -1
    t_lo = -math.inf
    t_hi = math.inf
    off = FL[g, 0]
    for slot in range(FL[g, 1] + 1):
        tri = P[off + slot]
        if tri < 0:
            continue
        for c in range(3):
            v = TR[tri, c]
            w0, w1, w2 = _bary_in(V0, F0, S, NV, NI, v, g)
            wz = w0 if z == 0 else (w1 if z == 1 else w2)
            if wz != 0.0:
                continue
            wj = w0 if j == 0 else (w1 if j == 1 else w2)
            if t_lo < wj <= tp:
                lo = v
                t_lo = wj
            if tp <= wj < t_hi:
                hi = v
                t_hi = wj
    if lo == hi:
        return lo
    lx, ly, lz = _xyz(V0, NV, lo)
    hx, hy, hz = _xyz(V0, NV, hi)
    d_lo = _norm(px - lx, py - ly, pz - lz)
    d_hi = _norm(px - hx, py - hy, pz - hz)
    near = lo if d_lo <= d_hi else hi
    dmin = d_hi if d_hi < d_lo else d_lo
    if dmin < snap and _may_snap(V0, S, NI, OP0, near):
        return near
    s = (tp - t_lo) / (t_hi - t_lo)
    i = edge_slot(H, lo, hi)
    if i < 0 or H[i, _HN] == 0:
        if S[ERR] == 0:
            S[ERR] = ERR_NOT_JOINED
            S[ERR + 1] = lo
            S[ERR + 2] = hi
            S[ERR + 3] = g
        return -1
    if not (0.0 < s < 1.0) or not _edge_split_ok(V0, S, TR, NV, H, lo, hi, s, min_area):
        return near
    x = _new_vertex(V0, S, NV, NI, px, py, pz, g, b0, b1, b2)
    _split_edge(S, TR, FL, H, P, lo, hi, x)
    return x


# --------------------------------------------------------------------------------- walk
@inner
def _walk_step(
    V0, F0, S, TR, FL, NV, NI, OP0, H, P, snap, min_area, cur, w, g, Wx, Wy, Wz, uw0, uw1
):
    """One step of the walk from ``cur`` towards ``w`` along a straight segment in face ``g``:
    the next vertex (-1 on an error in ``S[ERR]``)."""
    Px, Py, Pz = _xyz(V0, NV, cur)
    Dx = Wx - Px
    Dy = Wy - Py
    Dz = Wz - Pz
    L = _norm(Dx, Dy, Dz)
    uc0, uc1 = _uv(V0, F0, S, NV, NI, cur, g)
    dw0 = uw0 - uc0
    dw1 = uw1 - uc1
    nw = math.hypot(dw0, dw1)
    found = False
    best_score = -math.inf
    bb = -1
    bc = -1
    ub0 = 0.0
    ub1 = 0.0
    uC0 = 0.0
    uC1 = 0.0
    off = FL[g, 0]
    for slot in range(FL[g, 1] + 1):
        t = P[off + slot]
        if t < 0:
            continue
        i = -1
        for k in range(3):
            if TR[t, k] == cur:
                i = k
                break
        if i >= 0:
            b = TR[t, (i + 1) % 3]
            c = TR[t, (i + 2) % 3]
            xb0, xb1 = _uv(V0, F0, S, NV, NI, b, g)
            xc0, xc1 = _uv(V0, F0, S, NV, NI, c, g)
            db0 = xb0 - uc0
            db1 = xb1 - uc1
            dc0 = xc0 - uc0
            dc1 = xc1 - uc1
            s1 = (db0 * dw1 - db1 * dw0) / (math.hypot(db0, db1) * nw)
            s2 = (dw0 * dc1 - dw1 * dc0) / (math.hypot(dc0, dc1) * nw)
            score = s2 if s2 < s1 else s1
            if score > best_score:
                found = True
                best_score = score
                bb = b
                bc = c
                ub0 = xb0
                ub1 = xb1
                uC0 = xc0
                uC1 = xc1
    if not found:
        if S[ERR] == 0:
            S[ERR] = ERR_NO_TRIANGLE
            S[ERR + 1] = g
            S[ERR + 2] = cur
        return -1
    nxt = -1
    nxt_proj = math.inf
    for j in range(2):
        v = bb if j == 0 else bc
        vx, vy, vz = _xyz(V0, NV, v)
        Xx = vx - Px
        Xy = vy - Py
        Xz = vz - Pz
        proj = (Xx * Dx + Xy * Dy + Xz * Dz) / L
        perp = _norm(Xx - proj * Dx / L, Xy - proj * Dy / L, Xz - proj * Dz / L)
        if (
            perp < snap
            and 0.0 < proj < L + snap
            and proj < nxt_proj
            and (v == w or not _on_path(V0, NI, OP0, v))
        ):
            nxt = v
            nxt_proj = proj
    if nxt < 0:
        denom = dw0 * (uC1 - ub1) - dw1 * (uC0 - ub0)
        if denom != 0:
            s = (dw0 * (uc1 - ub1) - dw1 * (uc0 - ub0)) / denom
        else:
            s = 0.5
        if 0.0 > s:  # min(max(s, 0.0), 1.0) as Python evaluates it
            s = 0.0
        if 1.0 < s:
            s = 1.0
        nxt = _split_edge_at(V0, F0, S, TR, FL, NV, NI, OP0, H, P, bb, bc, s, g, snap, min_area)
    return nxt


@inner
def _has_edge(H, a, b):
    i = edge_slot(H, a, b)
    return i >= 0 and H[i, _HN] > 0


@njit(cache=True, nogil=True)
def insert_curve(
    V0, F0, FN, snap, min_area, S, TR, FL, NV, NI, OP0, H, P, qf, qb, qv, qx, seg_g, closed
):
    """Insert one curve's points (``qf (n,) i8`` face, ``qb (n, 3) f8`` bary, ``qv (n,) i8``
    vertex or -1, ``qx (n, 3) f8`` position; consecutive points share the original face
    ``seg_g``) and join consecutive ones by edges, marking the joining edges as cut.

    Returns the curve's vertices in order and the state; on an error the path is empty and
    ``S[ERR]`` says what went wrong.
    """
    n = qf.shape[0]
    nseg = n if closed else n - 1
    path = np.empty(2 * n + 16, dtype=np.int64)
    n_path = 0
    empty = np.empty(0, dtype=np.int64)
    tmp = np.empty((6, 3))
    S, TR, FL, NV, NI, OP0, H, P = reserve(S, TR, FL, NV, NI, OP0, H, P, 1, 32)
    first = _insert(
        V0,
        F0,
        FN,
        S,
        TR,
        FL,
        NV,
        NI,
        OP0,
        H,
        P,
        snap,
        min_area,
        qf[0],
        qb[0],
        qv[0],
        qx[0],
        seg_g[0],
        tmp,
    )
    if S[ERR]:
        return empty, S, TR, FL, NV, NI, OP0, H, P
    path[0] = first
    n_path = 1
    _set_on_path(V0, NI, OP0, first)
    prev = first
    for k in range(nseg):
        g = seg_g[k]
        q = (k + 1) % n
        S, TR, FL, NV, NI, OP0, H, P = reserve(S, TR, FL, NV, NI, OP0, H, P, 1, 64)
        _ensure(F0, FN, S, TR, FL, H, P, g)
        S[SNAP_OK] = prev
        if closed and k == nseg - 1:
            nxt = first
        else:
            nxt = _insert(
                V0,
                F0,
                FN,
                S,
                TR,
                FL,
                NV,
                NI,
                OP0,
                H,
                P,
                snap,
                min_area,
                qf[q],
                qb[q],
                qv[q],
                qx[q],
                g,
                tmp,
            )
        if S[ERR]:
            return empty, S, TR, FL, NV, NI, OP0, H, P
        # join prev -> nxt along the straight segment in g
        start = n_path
        cur = prev
        S[SNAP_OK] = nxt
        Wx, Wy, Wz = _xyz(V0, NV, nxt)
        uw0, uw1 = _uv(V0, F0, S, NV, NI, nxt, g)
        done = False
        for _ in range(MAX_WALK_STEPS):
            if cur == nxt:
                done = True
                break
            if _has_edge(H, cur, nxt):
                path, n_path = _push(path, n_path, nxt)
                done = True
                break
            S, TR, FL, NV, NI, OP0, H, P = reserve(S, TR, FL, NV, NI, OP0, H, P, 1, 16)
            v = _walk_step(
                V0,
                F0,
                S,
                TR,
                FL,
                NV,
                NI,
                OP0,
                H,
                P,
                snap,
                min_area,
                cur,
                nxt,
                g,
                Wx,
                Wy,
                Wz,
                uw0,
                uw1,
            )
            if S[ERR]:
                return empty, S, TR, FL, NV, NI, OP0, H, P
            path, n_path = _push(path, n_path, v)
            _set_on_path(V0, NI, OP0, v)
            cur = v
        if not done:
            S[ERR] = ERR_WALK
            S[ERR + 1] = prev
            S[ERR + 2] = nxt
            S[ERR + 3] = g
            return empty, S, TR, FL, NV, NI, OP0, H, P
        S, TR, FL, NV, NI, OP0, H, P = reserve(S, TR, FL, NV, NI, OP0, H, P, 0, n_path - start + 1)
        a = prev
        for i in range(start, n_path):
            b = path[i]
            _set_cut(S, H, a, b)
            a = b
        _set_on_path(V0, NI, OP0, nxt)
        prev = nxt
    if closed and n_path > 1 and path[n_path - 1] == path[0]:
        n_path -= 1  # the walk ended back at the first vertex
    return path[:n_path].copy(), S, TR, FL, NV, NI, OP0, H, P


@inner
def _push(a, n, v):
    if n == a.shape[0]:
        b = np.empty(2 * n, dtype=np.int64)
        for i in range(n):
            b[i] = a[i]
        a = b
    a[n] = v
    return a, n + 1


@njit(cache=True, nogil=True)
def set_on_path(V0, NI, OP0, v):
    """Mark vertex ``v`` as on the cut path."""
    _set_on_path(V0, NI, OP0, v)


# ------------------------------------------------------------------------------ results
@njit(cache=True, nogil=True)
def path_sides(TR, H, new_faces, path, closed):
    """The copies of each path vertex on the left and right of the curve after splitting."""
    k = path.shape[0]
    left = np.full(k, -1, dtype=np.int64)
    right = np.full(k, -1, dtype=np.int64)
    n_edges = k if closed else k - 1
    for i in range(k):
        e = i if i < n_edges else i - 1  # the edge leaving vertex i (entering, at an open end)
        a = path[e]
        b = path[(e + 1) % k]
        s = edge_slot(H, a, b)
        for j in range(H[s, _HN]):
            t = H[s, _HT0 + j]
            ia = 0
            iv = 0
            for c in range(3):
                if TR[t, c] == path[i]:
                    iv = c
                    break
            for c in range(3):
                if TR[t, c] == a:
                    ia = c
                    break
            v = new_faces[t, iv]
            if TR[t, (ia + 1) % 3] == b:  # half-edge a -> b: the face on the left
                left[i] = v
            else:
                right[i] = v
    for i in range(k):
        if left[i] < 0:
            left[i] = right[i]
        if right[i] < 0:
            right[i] = left[i]
    return left, right


@njit(cache=True, nogil=True)
def split_faces(faces, nv, cut):
    """Faces with each fan of faces that the cut edges ``cut (m, 2) i8`` (sorted rows, ``a <
    b``) separate around a vertex on its own vertex copy, and the vertex each copy copies.

    As `meshfit.mesh.topology.corner_fans` on a manifold mesh: corners of a vertex join across
    the edges at it with two faces that are not cut. Around each vertex the fan holding its
    first corner keeps the vertex; the other fans get new vertices ``nv, nv + 1, ...`` in the
    order of (vertex, first corner of the fan).
    """
    nf = faces.shape[0]
    m = cut.shape[0]
    keys = np.empty(m, dtype=np.int64)
    for i in range(m):
        keys[i] = cut[i, 0] * nv + cut[i, 1]
    on_cut = np.zeros(nv, dtype=np.bool_)
    for i in range(m):
        on_cut[cut[i, 0]] = True
        on_cut[cut[i, 1]] = True
    # corners of the cut vertices, grouped by vertex in corner order
    count = np.zeros(nv + 1, dtype=np.int64)
    for f in range(nf):
        for k in range(3):
            v = faces[f, k]
            if on_cut[v]:
                count[v + 1] += 1
    for v in range(nv):
        count[v + 1] += count[v]
    fill = count[:-1].copy()
    corners = np.empty(count[nv], dtype=np.int64)
    for f in range(nf):
        for k in range(3):
            v = faces[f, k]
            if on_cut[v]:
                corners[fill[v]] = 3 * f + k
                fill[v] += 1
    out = faces.copy()
    extra = np.empty(count[nv], dtype=np.int64)
    n_extra = 0
    for v in range(nv):
        lo = count[v]
        hi = count[v + 1]
        d = hi - lo
        if d == 0:
            continue
        root = np.arange(d)
        for i in range(d):
            ci = corners[lo + i]
            fi = ci // 3
            ki = ci % 3
            for side in range(1, 3):
                u = faces[fi, (ki + side) % 3]  # the edges (v, u) at corner i
                key = min(u, v) * nv + max(u, v)
                pos = np.searchsorted(keys, key)
                if pos < m and keys[pos] == key:
                    continue
                # the other corners whose faces hold edge (v, u)
                n_at = 0
                other = -1
                for j in range(d):
                    cj = corners[lo + j]
                    fj = cj // 3
                    if fj == fi:
                        continue
                    kj = cj % 3
                    if faces[fj, (kj + 1) % 3] == u or faces[fj, (kj + 2) % 3] == u:
                        n_at += 1
                        other = j
                if n_at != 1:
                    continue  # a boundary or non-manifold edge joins nothing
                ra = i
                while root[ra] != ra:
                    ra = root[ra]
                rb = other
                while root[rb] != rb:
                    rb = root[rb]
                if ra < rb:
                    root[rb] = ra
                elif rb < ra:
                    root[ra] = rb
        # fans in order of their first corner: the first keeps v
        label = np.full(d, -1, dtype=np.int64)
        n_fans = 0
        for i in range(d):
            r = i
            while root[r] != r:
                r = root[r]
            if label[r] < 0:
                if n_fans == 0:
                    label[r] = v
                else:
                    label[r] = nv + n_extra
                    extra[n_extra] = v
                    n_extra += 1
                n_fans += 1
            ci = corners[lo + i]
            out[ci // 3, ci % 3] = label[r]
    copy_of = np.empty(nv + n_extra, dtype=np.int64)
    for v in range(nv):
        copy_of[v] = v
    for i in range(n_extra):
        copy_of[nv + i] = extra[i]
    return out, copy_of


# ------------------------------------------------------------------------ curve points
# A curve point is a tuple ``(kind, vertex, face, other, b0, b1, b2, x, y, z)``: on vertex
# ``vertex`` (or -1), else at barycentrics ``b`` in ``face``; position ``(x, y, z)``. Its
# original faces are those around the original vertex ``vertex`` (kind 1) or ``face`` and
# ``other`` (kind 0; ``other`` -1 when there is no second face).
KIND_FACES = 0
KIND_VERTEX = 1
ERR_BRIDGE = 7  # i, j, face of i, face of j
ERR_COLLAPSE = 8  # points, distinct points


@inner
def _vertex_point(V0, F0, VFI, VFF, v):
    f = VFF[VFI[v]]  # the smallest face around v
    b0 = 1.0 if F0[f, 0] == v else 0.0
    b1 = 1.0 if F0[f, 1] == v else 0.0
    b2 = 1.0 if F0[f, 2] == v else 0.0
    return (KIND_VERTEX, v, f, -1, b0, b1, b2, V0[v, 0], V0[v, 1], V0[v, 2])


@inner
def _edge_point(V0, F0, FN, VFI, VFF, snap, face, k, s):
    """The point at parameter s along edge k of ``face`` (snapped to an end when close)."""
    a = F0[face, k]
    b = F0[face, (k + 1) % 3]
    ax = V0[a, 0]
    ay = V0[a, 1]
    az = V0[a, 2]
    bx = V0[b, 0]
    by = V0[b, 1]
    bz = V0[b, 2]
    length = _norm(bx - ax, by - ay, bz - az)
    if s * length < snap:
        return _vertex_point(V0, F0, VFI, VFF, a)
    if (1.0 - s) * length < snap:
        return _vertex_point(V0, F0, VFI, VFF, b)
    c0 = 0.0
    c1 = 0.0
    c2 = 0.0
    if k == 0:
        c0 = 1.0 - s
        c1 = s
    elif k == 1:
        c1 = 1.0 - s
        c2 = s
    else:
        c2 = 1.0 - s
        c0 = s
    other = FN[face, k]
    return (
        KIND_FACES,
        -1,
        face,
        other,
        c0,
        c1,
        c2,
        ax + s * (bx - ax),
        ay + s * (by - ay),
        az + s * (bz - az),
    )


@njit(cache=True, nogil=True)
def classify(V0, F0, FN, VFI, VFF, snap, face, bary):
    """`surface.cut._classify_all`: snap face points onto a vertex or an edge of their face
    when within ``snap``; the points as arrays ``(n, 4) i8`` (kind, vertex, face, other) and
    ``(n, 6) f8`` (barycentrics, position)."""
    n = face.shape[0]
    PI = np.empty((n, 4), dtype=np.int64)
    PF = np.empty((n, 6), dtype=np.float64)
    pos = np.empty((3, 3))
    for i in range(n):
        f = face[i]
        c0 = bary[i, 0]
        c1 = bary[i, 1]
        c2 = bary[i, 2]
        c0 = 0.0 if c0 < 0.0 else c0
        c1 = 0.0 if c1 < 0.0 else c1
        c2 = 0.0 if c2 < 0.0 else c2
        tot = c0 + c1 + c2
        c0 = c0 / tot
        c1 = c1 / tot
        c2 = c2 / tot
        for k in range(3):
            v = F0[f, k]
            for d in range(3):
                pos[k, d] = V0[v, d]
        px = c0 * pos[0, 0] + c1 * pos[1, 0] + c2 * pos[2, 0]
        py = c0 * pos[0, 1] + c1 * pos[1, 1] + c2 * pos[2, 1]
        pz = c0 * pos[0, 2] + c1 * pos[1, 2] + c2 * pos[2, 2]
        kv = 0
        dmin = _norm(px - pos[0, 0], py - pos[0, 1], pz - pos[0, 2])
        for k in range(1, 3):
            d = _norm(px - pos[k, 0], py - pos[k, 1], pz - pos[k, 2])
            if d < dmin:
                kv = k
                dmin = d
        if dmin < snap:
            p = _vertex_point(V0, F0, VFI, VFF, F0[f, kv])
        else:
            edge_k = -1
            edge_s = 0.0
            for k in range(3):  # the first edge that qualifies wins
                k1 = (k + 1) % 3
                e0 = pos[k1, 0] - pos[k, 0]
                e1 = pos[k1, 1] - pos[k, 1]
                e2 = pos[k1, 2] - pos[k, 2]
                sk = ((px - pos[k, 0]) * e0 + (py - pos[k, 1]) * e1 + (pz - pos[k, 2]) * e2) / (
                    e0 * e0 + e1 * e1 + e2 * e2
                )
                fx = pos[k, 0] + sk * e0
                fy = pos[k, 1] + sk * e1
                fz = pos[k, 2] + sk * e2
                if sk > 0.0 and sk < 1.0 and _norm(px - fx, py - fy, pz - fz) < snap:
                    edge_k = k
                    edge_s = sk
                    break
            if edge_k >= 0:
                p = _edge_point(V0, F0, FN, VFI, VFF, snap, f, edge_k, edge_s)
            else:
                p = (KIND_FACES, -1, f, -1, c0, c1, c2, px, py, pz)
        _put(PI, PF, i, p)
    return PI, PF


@inner
def _put(PI, PF, i, p):
    PI[i, 0] = p[0]
    PI[i, 1] = p[1]
    PI[i, 2] = p[2]
    PI[i, 3] = p[3]
    PF[i, 0] = p[4]
    PF[i, 1] = p[5]
    PF[i, 2] = p[6]
    PF[i, 3] = p[7]
    PF[i, 4] = p[8]
    PF[i, 5] = p[9]


@inner
def _get(PI, PF, i):
    return (
        PI[i, 0],
        PI[i, 1],
        PI[i, 2],
        PI[i, 3],
        PF[i, 0],
        PF[i, 1],
        PF[i, 2],
        PF[i, 3],
        PF[i, 4],
        PF[i, 5],
    )


@inner
def _has_face(F0, p, f):
    """Whether original face ``f >= 0`` is one of the point's faces."""
    if p[0] == KIND_VERTEX:
        v = p[1]
        return F0[f, 0] == v or F0[f, 1] == v or F0[f, 2] == v
    return f == p[2] or (p[3] >= 0 and f == p[3])


@inner
def _faces_of(VFI, VFF, p):
    """The point's original faces, ascending."""
    if p[0] == KIND_VERTEX:
        return VFF[VFI[p[1]] : VFI[p[1] + 1]]
    if p[3] < 0:
        out = np.empty(1, dtype=np.int64)
        out[0] = p[2]
        return out
    out = np.empty(2, dtype=np.int64)
    out[0] = min(p[2], p[3])
    out[1] = max(p[2], p[3])
    return out


@inner
def _same_faces(VFI, VFF, p, q):
    """Whether two points have the same original faces."""
    if p[0] == KIND_FACES and q[0] == KIND_FACES:  # no arrays for the common case
        return min(p[2], p[3]) == min(q[2], q[3]) and max(p[2], p[3]) == max(q[2], q[3])
    fp = _faces_of(VFI, VFF, p)
    fq = _faces_of(VFI, VFF, q)
    if fp.shape[0] != fq.shape[0]:
        return False
    for i in range(fp.shape[0]):
        if fp[i] != fq[i]:
            return False
    return True


@inner
def _same_point(VFI, VFF, snap, p, q):
    """Whether two points are one: the same vertex, or within ``snap`` on the same faces."""
    if p[1] >= 0 or q[1] >= 0:
        return p[1] == q[1]
    if not _same_faces(VFI, VFF, p, q):
        return False
    return _norm(p[7] - q[7], p[8] - q[8], p[9] - q[9]) < snap


@inner
def _common_face(F0, VFI, VFF, p, q):
    """The original face two points share: the first point's, else the second's, else the
    smallest shared one (-1: none)."""
    if _has_face(F0, q, p[2]):
        return p[2]
    if _has_face(F0, p, q[2]):
        return q[2]
    fp = _faces_of(VFI, VFF, p)
    for i in range(fp.shape[0]):
        if _has_face(F0, q, fp[i]):
            return fp[i]
    return -1


@inner
def _crossing(V0, F0, FN, VFI, VFF, snap, p, f, k, q):
    """Where the straight segment p -> q, unfolded about edge k of face f, crosses that edge."""
    i = F0[f, k]
    j = F0[f, (k + 1) % 3]
    e0 = V0[j, 0] - V0[i, 0]
    e1 = V0[j, 1] - V0[i, 1]
    e2 = V0[j, 2] - V0[i, 2]
    length = _norm(e0, e1, e2)
    h0 = e0 / length
    h1 = e1 / length
    h2 = e2 / length
    rp0 = p[7] - V0[i, 0]
    rp1 = p[8] - V0[i, 1]
    rp2 = p[9] - V0[i, 2]
    rq0 = q[7] - V0[i, 0]
    rq1 = q[8] - V0[i, 1]
    rq2 = q[9] - V0[i, 2]
    pa = rp0 * h0 + rp1 * h1 + rp2 * h2
    qa = rq0 * h0 + rq1 * h1 + rq2 * h2
    ph = _norm(rp0 - pa * h0, rp1 - pa * h1, rp2 - pa * h2)
    qh = _norm(rq0 - qa * h0, rq1 - qa * h1, rq2 - qa * h2)
    if ph + qh > 0:
        a = pa + (qa - pa) * ph / (ph + qh)
    else:
        a = 0.5 * (pa + qa)
    s = a / length
    if 0.0 > s:  # min(max(s, 0.0), 1.0) as Python evaluates it
        s = 0.0
    if 1.0 < s:
        s = 1.0
    return _edge_point(V0, F0, FN, VFI, VFF, snap, f, k, s)


@inner
def _dist_via(p, x, q):
    return _norm(x[7] - p[7], x[8] - p[8], x[9] - p[9]) + _norm(
        q[7] - x[7], q[8] - x[8], q[9] - x[9]
    )


@inner
def _fan_steps(F0, FN, VFI, VFF, p, q, v):
    """Edges ``(f, k)`` around vertex ``v`` between a face of p and a face of q, going round
    ``v`` the way that passes fewer faces (none: an empty array)."""
    lo = VFI[v]
    hi = VFI[v + 1]
    n_around = hi - lo
    best = np.empty((0, 2), dtype=np.int64)
    steps = np.empty((n_around, 2), dtype=np.int64)
    for a in range(lo, hi):  # the faces of p around v, ascending
        f0 = VFF[a]
        if not _has_face(F0, p, f0):
            continue
        for first in range(3):
            if v != F0[f0, first] and v != F0[f0, (first + 1) % 3]:
                continue  # only the two edges of f0 at v lead round the fan
            n = 0
            f = f0
            k = first
            ok = False
            for _ in range(n_around):
                h = FN[f, k]
                if h < 0 or not (F0[h, 0] == v or F0[h, 1] == v or F0[h, 2] == v) or h == f0:
                    n = 0
                    break
                steps[n, 0] = f
                steps[n, 1] = k
                n += 1
                if _has_face(F0, q, h):
                    ok = True
                    break
                # leave h by its other edge at v
                nk = -1
                for kk in range(3):
                    if (v == F0[h, kk] or v == F0[h, (kk + 1) % 3]) and FN[h, kk] != f:
                        nk = kk
                        break
                if nk < 0:
                    n = 0
                    break
                k = nk
                f = h
            if not ok:
                n = 0
            if n > 0 and (best.shape[0] == 0 or n < best.shape[0]):
                best = steps[:n].copy()
    return best


@inner
def _grow_points(PI, PF, n, extra):
    if n + extra <= PI.shape[0]:
        return PI, PF
    cap = max(2 * PI.shape[0], n + extra)
    I2 = np.empty((cap, 4), dtype=np.int64)
    F2 = np.empty((cap, 6), dtype=np.float64)
    _copy_rows(PI, I2, n)
    _copy_rows(PF, F2, n)
    return I2, F2


@njit(cache=True, nogil=True)
def bridge_curve(V0, F0, FN, VFI, VFF, snap, route_fans, CI, CF, closed, S):
    """Step 1 of the cut of one curve: the points ``CI, CF`` (as from `classify`) with the
    crossings of the edges between points on different faces inserted and repeats dropped,
    so that consecutive points share an original face. Returns the points (as ``CI, CF``) and
    the face each consecutive pair shares; on an error ``S[ERR]`` says what went wrong."""
    n = CI.shape[0]
    QI = np.empty((2 * n + 16, 4), dtype=np.int64)
    QF = np.empty((2 * n + 16, 6), dtype=np.float64)
    m = 0
    _put(QI, QF, 0, _get(CI, CF, 0))
    m = 1
    n_pairs = n if closed else n - 1
    for i in range(n_pairs):
        j = (i + 1) % n
        q = _get(CI, CF, j)
        p = _get(QI, QF, m - 1)
        if _same_point(VFI, VFF, snap, p, q):
            continue
        # the points to insert between p and q so each consecutive pair shares a face
        if _common_face(F0, VFI, VFF, p, q) < 0:
            # edge-adjacent faces: the crossing point on the shared edge
            found = False
            best_len = math.inf
            best = p
            fp = _faces_of(VFI, VFF, p)
            for a in range(fp.shape[0]):
                f = fp[a]
                for k in range(3):
                    h = FN[f, k]
                    if h >= 0 and _has_face(F0, q, h):
                        x = _crossing(V0, F0, FN, VFI, VFF, snap, p, f, k, q)
                        d = _dist_via(p, x, q)
                        if d < best_len:
                            best = x
                            best_len = d
                            found = True
            if found:
                QI, QF = _grow_points(QI, QF, m, 1)
                if not _same_point(VFI, VFF, snap, p, best):
                    _put(QI, QF, m, best)
                    m += 1
            else:
                # faces sharing a vertex only: through it (or across the fan around it)
                fq = _faces_of(VFI, VFF, q)
                v_best = -1
                d_best = math.inf
                for v in _sorted_shared(F0, VFI, VFF, p, fq):
                    d = _norm(V0[v, 0] - p[7], V0[v, 1] - p[8], V0[v, 2] - p[9]) + _norm(
                        q[7] - V0[v, 0], q[8] - V0[v, 1], q[9] - V0[v, 2]
                    )
                    if v_best < 0 or d < d_best:
                        v_best = v
                        d_best = d
                if v_best < 0:
                    S[ERR] = ERR_BRIDGE
                    S[ERR + 1] = i
                    S[ERR + 2] = j
                    S[ERR + 3] = p[2]
                    S[ERR + 4] = q[2]
                    return QI[:0], QF[:0], np.empty(0, dtype=np.int64)
                steps = np.empty((0, 2), dtype=np.int64)
                if route_fans:
                    steps = _fan_steps(F0, FN, VFI, VFF, p, q, v_best)
                QI, QF = _grow_points(QI, QF, m, steps.shape[0] + 1)
                if steps.shape[0] > 0:
                    prev = p
                    for a in range(steps.shape[0]):
                        x = _crossing(V0, F0, FN, VFI, VFF, snap, prev, steps[a, 0], steps[a, 1], q)
                        if not _same_point(VFI, VFF, snap, _get(QI, QF, m - 1), x):
                            _put(QI, QF, m, x)
                            m += 1
                        prev = x
                else:
                    x = _vertex_point(V0, F0, VFI, VFF, v_best)
                    if not _same_point(VFI, VFF, snap, p, x):
                        _put(QI, QF, m, x)
                        m += 1
        QI, QF = _grow_points(QI, QF, m, 1)
        if not _same_point(VFI, VFF, snap, _get(QI, QF, m - 1), q):
            _put(QI, QF, m, q)
            m += 1
    if closed and m > 1 and _same_point(VFI, VFF, snap, _get(QI, QF, m - 1), _get(QI, QF, 0)):
        m -= 1
    if m < 2 or (closed and m < 3):
        S[ERR] = ERR_COLLAPSE
        S[ERR + 1] = n
        S[ERR + 2] = m
        return QI[:0], QF[:0], np.empty(0, dtype=np.int64)
    n_seg = m if closed else m - 1
    seg_g = np.empty(n_seg, dtype=np.int64)
    for k in range(n_seg):
        seg_g[k] = _common_face(F0, VFI, VFF, _get(QI, QF, k), _get(QI, QF, (k + 1) % m))
    return QI[:m].copy(), QF[:m].copy(), seg_g


@inner
def _sorted_shared(F0, VFI, VFF, p, fq):
    """The original vertices of both a face of p and a face ``fq`` of q, ascending."""
    fp = _faces_of(VFI, VFF, p)
    out = np.empty(3 * fp.shape[0], dtype=np.int64)
    n = 0
    for a in range(fp.shape[0]):
        for k in range(3):
            v = F0[fp[a], k]
            shared = False
            for c in range(fq.shape[0]):
                if F0[fq[c], 0] == v or F0[fq[c], 1] == v or F0[fq[c], 2] == v:
                    shared = True
                    break
            if not shared:
                continue
            # insert v into the ascending out[:n] unless already there
            i = n
            while i > 0 and out[i - 1] > v:
                i -= 1
            if i > 0 and out[i - 1] == v:
                continue
            for j in range(n, i, -1):
                out[j] = out[j - 1]
            out[i] = v
            n += 1
    return out[:n]


# -------------------------------------------------------------------------------- paths
@njit(cache=True, nogil=True)
def expand_path(H, path, closed):
    """Re-insert the vertices that later splits put on the path's cut edges (recursively, in
    order along each edge); drop immediate repeats."""
    n = path.shape[0]
    out = np.empty(2 * n + 16, dtype=np.int64)
    out[0] = path[0]
    m = 1
    stack = np.empty(64, dtype=np.int64)
    n_ends = n if closed else n - 1
    for e in range(n_ends):
        b = path[(e + 1) % n]
        cur = out[m - 1]
        stack[0] = b
        top = 1
        while top > 0:
            t = stack[top - 1]
            i = edge_slot(H, cur, t)
            x = H[i, _HSPLIT] if i >= 0 else -1
            if x < 0:  # an edge of the path: its far end is next
                top -= 1
                if t != out[m - 1]:
                    out, m = _push(out, m, t)
                cur = t
            else:  # first the piece up to x
                if top == stack.shape[0]:
                    s2 = np.empty(2 * top, dtype=np.int64)
                    for i in range(top):
                        s2[i] = stack[i]
                    stack = s2
                stack[top] = x
                top += 1
    if closed and m > 1 and out[m - 1] == out[0]:
        m -= 1
    return out[:m].copy()


@njit(cache=True, nogil=True)
def drop_spikes(path, closed):
    """Remove immediate back-and-forth steps ``a, b, a`` (a cut of zero width)."""
    n = path.shape[0]
    stack = np.empty(n + 1, dtype=np.int64)
    m = 0
    for i in range(n + 1 if closed else n):
        v = path[i % n]
        if m >= 2 and stack[m - 2] == v:
            m -= 1
        else:
            stack[m] = v
            m += 1
    lo = 0
    if closed:
        while m - lo >= 3 and stack[lo + 1] == stack[m - 2]:
            lo += 1
            m -= 1
        m -= 1
    return stack[lo:m].copy()


@njit(cache=True, nogil=True)
def drop_loops(path):
    """Cut out closed detours ``v ... v`` of an open path, so each vertex appears once."""
    n = path.shape[0]
    out = np.empty(n, dtype=np.int64)
    m = 0
    where = dict()
    where[np.int64(-1)] = np.int64(-1)
    del where[np.int64(-1)]
    for i in range(n):
        v = path[i]
        if v in where:
            k = where[v]
            for j in range(k + 1, m):
                del where[out[j]]
            m = k + 1
            continue
        where[v] = np.int64(m)
        out[m] = v
        m += 1
    return out[:m].copy()
