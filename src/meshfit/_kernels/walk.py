"""Numba kernels: face points sliding over triangles (MovePointOnSurface) and attraction.

No validation here: the public wrappers in :mod:`meshfit.surface.walk` check every input and
pass contiguous arrays. ``fastmath`` stays off because sign tests pick the exit edge.

Conventions shared by every kernel: ``V (nv, 3) f8`` vertices, ``F (nf, 3) i8`` faces,
``FN (nf, 3) i8`` face across edge ``k = (F[f, k], F[f, (k + 1) % 3])`` (-1 on the boundary).
The coordinate ``(k + 2) % 3`` is the one that vanishes on edge ``k``.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from meshfit._kernels import inner

#: status codes returned by `_walk_one`
DONE = 0
BOUNDARY = 1
CAPPED = 2
#: `_walk_core` gave up: the walk cannot end within its bound of the target
FARTHER = 3
#: rows of (3,) scratch that `_attract_one_buf` needs
_ATTRACT_SCRATCH = 7


@inner
def _copy3(src, dst):
    """dst[:3] = src[:3], element by element (an array slice assignment compiles numba's
    shape-mismatch error path, with its string formatting, into every first run)."""
    dst[0] = src[0]
    dst[1] = src[1]
    dst[2] = src[2]


@inner
def _bary_rate(V, F, f, u, out):
    """Barycentric change per unit length along the in-plane vector ``u`` in face ``f``; (3,)."""
    out[0], out[1], out[2] = _bary_rate3(V, F, f, u)


@inner
def _bary_rate3(V, F, f, u):
    """`_bary_rate` as three scalars (no output array)."""
    return _bary_rate_of(V, F, f, u[0], u[1], u[2])


@inner
def _bary_rate_of(V, F, f, u0, u1, u2):
    """`_bary_rate` of the in-plane vector ``(u0, u1, u2)``, on scalars."""
    a = F[f, 0]
    b = F[f, 1]
    c = F[f, 2]
    e1x = V[b, 0] - V[a, 0]
    e1y = V[b, 1] - V[a, 1]
    e1z = V[b, 2] - V[a, 2]
    e2x = V[c, 0] - V[a, 0]
    e2y = V[c, 1] - V[a, 1]
    e2z = V[c, 2] - V[a, 2]
    a11 = e1x * e1x + e1y * e1y + e1z * e1z
    a12 = e1x * e2x + e1y * e2y + e1z * e2z
    a22 = e2x * e2x + e2y * e2y + e2z * e2z
    r1 = u0 * e1x + u1 * e1y + u2 * e1z
    r2 = u0 * e2x + u1 * e2y + u2 * e2z
    det = a11 * a22 - a12 * a12
    if det <= 0.0:  # a face of zero area (a sliver left by cutting): no direction moves in it
        return 0.0, 0.0, 0.0
    d1 = (a22 * r1 - a12 * r2) / det
    d2 = (a11 * r2 - a12 * r1) / det
    return -d1 - d2, d1, d2


@njit(cache=True, nogil=True, fastmath=False)
def _face_normal(V, F, f, out):
    """Unit normal of face ``f`` into ``out`` (3,)."""
    out[0], out[1], out[2] = _face_normal3(V, F, f)


@inner
def _face_normal3(V, F, f):
    """`_face_normal` as three scalars (no output array)."""
    a = F[f, 0]
    b = F[f, 1]
    c = F[f, 2]
    e1x = V[b, 0] - V[a, 0]
    e1y = V[b, 1] - V[a, 1]
    e1z = V[b, 2] - V[a, 2]
    e2x = V[c, 0] - V[a, 0]
    e2y = V[c, 1] - V[a, 1]
    e2z = V[c, 2] - V[a, 2]
    nx = e1y * e2z - e1z * e2y
    ny = e1z * e2x - e1x * e2z
    nz = e1x * e2y - e1y * e2x
    s = np.sqrt(nx * nx + ny * ny + nz * nz)
    if s == 0.0:  # zero area: no plane, no normal
        s = 1.0
    return nx / s, ny / s, nz / s


@njit(cache=True, nogil=True, fastmath=False)
def _clean_bary(b):
    """Clamp tiny negatives to 0 and renormalise ``b`` (3,) in place to sum to 1."""
    for j in range(3):
        if b[j] < 0.0:
            b[j] = 0.0
    s = b[0] + b[1] + b[2]
    b[0] /= s
    b[1] /= s
    b[2] /= s


@njit(cache=True, nogil=True, fastmath=False)
def _walk_one(V, F, FN, f, b, u, length, max_faces, bary_eps):
    """Slide one face point by ``length`` along the unit in-plane direction ``u`` (3,).

    ``b`` (3,) and ``u`` (3,) are updated in place (``u`` ends in the last face's plane).
    Returns ``(face, remaining_length, status, faces_crossed)``; status is DONE, BOUNDARY or
    CAPPED. Kernel of `meshfit.surface.walk.walk_points`.
    """
    return _walk_core(V, F, FN, f, b, u, length, max_faces, bary_eps, u, np.inf)


@inner
def _walk_core(V, F, FN, f, b, u, length, max_faces, bary_eps, tgt, bound):
    """`_walk_one` that gives up (status FARTHER) at an edge crossing from which the walk
    cannot end within ``bound`` of ``tgt`` (3,): the distance to ``tgt`` there minus the
    length still to walk exceeds ``bound`` (a surface path is never shorter than the chord).
    ``bound = inf`` never gives up. ``b`` is then the crossing point (in face ``f``)."""
    entered = -1  # coordinate that vanishes on the edge just entered through
    crossed = 0
    while True:
        db0, db1, db2 = _bary_rate3(V, F, f, u)
        scale = max(abs(db0), max(abs(db1), abs(db2)))
        # exit distance: the first coordinate to reach 0
        s_exit = np.inf
        i_exit = -1
        for j in range(3):
            if j == entered:
                continue
            dbj = db0 if j == 0 else (db1 if j == 1 else db2)
            if dbj >= 0.0:
                continue
            if b[j] <= bary_eps and -dbj <= bary_eps * scale:
                continue  # on edge j and running along it: not a crossing
            s = max(b[j], 0.0) / -dbj
            if s < s_exit:
                s_exit = s
                i_exit = j
        if i_exit < 0 or s_exit >= length:
            b[0] += length * db0
            b[1] += length * db1
            b[2] += length * db2
            _clean_bary(b)
            return f, 0.0, DONE, crossed
        b[0] += s_exit * db0
        b[1] += s_exit * db1
        b[2] += s_exit * db2
        b[i_exit] = 0.0
        _clean_bary(b)
        length -= s_exit
        if bound < np.inf:
            d0 = tgt[0] - (b[0] * V[F[f, 0], 0] + b[1] * V[F[f, 1], 0] + b[2] * V[F[f, 2], 0])
            d1 = tgt[1] - (b[0] * V[F[f, 0], 1] + b[1] * V[F[f, 1], 1] + b[2] * V[F[f, 2], 1])
            d2 = tgt[2] - (b[0] * V[F[f, 0], 2] + b[1] * V[F[f, 1], 2] + b[2] * V[F[f, 2], 2])
            if np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) - length > bound:
                return f, length, FARTHER, crossed
        k = (i_exit + 1) % 3  # edge opposite vertex slot i_exit
        g = FN[f, k]
        if g < 0:
            return f, length, BOUNDARY, crossed
        if crossed >= max_faces:
            return f, length, CAPPED, crossed
        va = F[f, k]
        vc = F[f, (k + 1) % 3]
        # the shared edge seen from g: slot of vc is kg, slot of va is kg + 1
        kg = 0
        for j in range(3):
            if F[g, j] == vc and F[g, (j + 1) % 3] == va:
                kg = j
        vo = F[g, (kg + 2) % 3]
        # unfold u about the edge: keep the along-edge part, turn the perpendicular part
        ex = V[vc, 0] - V[va, 0]
        ey = V[vc, 1] - V[va, 1]
        ez = V[vc, 2] - V[va, 2]
        el = np.sqrt(ex * ex + ey * ey + ez * ez)
        ex /= el
        ey /= el
        ez /= el
        along = u[0] * ex + u[1] * ey + u[2] * ez
        px = u[0] - along * ex
        py = u[1] - along * ey
        pz = u[2] - along * ez
        perp = np.sqrt(px * px + py * py + pz * pz)
        wx = V[vo, 0] - V[va, 0]
        wy = V[vo, 1] - V[va, 1]
        wz = V[vo, 2] - V[va, 2]
        t = wx * ex + wy * ey + wz * ez
        wx -= t * ex
        wy -= t * ey
        wz -= t * ez
        wl = np.sqrt(wx * wx + wy * wy + wz * wz)
        if wl == 0.0:  # g has zero area: only the along-edge part carries over
            wl = 1.0
            perp = 0.0
        u[0] = along * ex + perp * wx / wl
        u[1] = along * ey + perp * wy / wl
        u[2] = along * ez + perp * wz / wl
        ul = np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
        if ul == 0.0:  # heading straight into a zero-area face: it acts as a wall
            return f, length, BOUNDARY, crossed
        u[0] /= ul
        u[1] /= ul
        u[2] /= ul
        # the same point in g: exact copy of the two edge coordinates, the third is 0
        ba = b[(k + 0) % 3]
        bc = b[(k + 1) % 3]
        b[kg] = bc
        b[(kg + 1) % 3] = ba
        b[(kg + 2) % 3] = 0.0
        entered = (kg + 2) % 3
        f = g
        crossed += 1


@njit(cache=True, nogil=True, fastmath=False)
def _move_in_face(V, F, f, b0, b1, b2, u0, u1, u2, length, bary_eps):
    """`_walk_one` of face point ``(f, (b0, b1, b2))`` by ``length`` along the unit in-plane
    ``(u0, u1, u2)`` when the walk ends in face ``f``, on scalars (the same operations in
    the same order, so the same result bit for bit).

    Returns ``(ok, b0, b1, b2)``: ``ok`` False when the walk would leave the face or the
    coordinates would not renormalise (the caller then runs the full walk).
    """
    d0, d1, d2 = _bary_rate_of(V, F, f, u0, u1, u2)
    scale = max(abs(d0), max(abs(d1), abs(d2)))
    lim = bary_eps * scale
    # the walk leaves the face where a falling coordinate reaches 0 within ``length``
    if d0 < 0.0 and not (b0 <= bary_eps and -d0 <= lim) and max(b0, 0.0) / -d0 < length:
        return False, b0, b1, b2
    if d1 < 0.0 and not (b1 <= bary_eps and -d1 <= lim) and max(b1, 0.0) / -d1 < length:
        return False, b0, b1, b2
    if d2 < 0.0 and not (b2 <= bary_eps and -d2 <= lim) and max(b2, 0.0) / -d2 < length:
        return False, b0, b1, b2
    n0 = b0 + length * d0
    n1 = b1 + length * d1
    n2 = b2 + length * d2
    if n0 < 0.0:
        n0 = 0.0
    if n1 < 0.0:
        n1 = 0.0
    if n2 < 0.0:
        n2 = 0.0
    s = n0 + n1 + n2
    if s == 0.0:
        return False, b0, b1, b2
    n0 /= s
    n1 /= s
    n2 /= s
    if not np.isfinite(n0 + n1 + n2):
        return False, b0, b1, b2
    return True, n0, n1, n2


@njit(cache=True, nogil=True, fastmath=False)
def _start_direction(V, F, f, step, u):
    """Project ``step`` (3,) onto face ``f``'s plane; unit direction into ``u``, returns length."""
    n0, n1, n2 = _face_normal3(V, F, f)
    return _in_plane(n0, n1, n2, step, u)


@inner
def _in_plane(n0, n1, n2, step, u):
    """Project ``step`` (3,) onto the plane of unit normal ``(n0, n1, n2)``; unit direction
    into ``u``, returns length."""
    d = step[0] * n0 + step[1] * n1 + step[2] * n2
    u[0] = step[0] - d * n0
    u[1] = step[1] - d * n1
    u[2] = step[2] - d * n2
    length = np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
    if length > 0.0:
        u[0] /= length
        u[1] /= length
        u[2] /= length
    return length


@njit(cache=True, nogil=True, parallel=True, fastmath=False)
def walk_points(V, F, FN, face, bary, step, max_faces, eps_len, bary_eps):
    """Kernel of `meshfit.surface.walk.walk_points`.

    V (nv, 3) f8; F, FN (nf, 3) i8; face (n,) i8; bary, step (n, 3) f8 -> out_face (n,) i8,
    out_bary (n, 3) f8, length (n,) f8, hit_boundary (n,) bool, capped (n,) bool.
    """
    n = face.shape[0]
    out_face = face.copy()
    out_bary = bary.copy()
    length = np.zeros(n)
    hit = np.zeros(n, dtype=np.bool_)
    capped = np.zeros(n, dtype=np.bool_)
    for i in prange(n):  # iteration i writes row i only
        b = out_bary[i]
        u = np.empty(3)
        total = _start_direction(V, F, face[i], step[i], u)
        if total <= eps_len:
            continue
        f, rest, status, _ = _walk_one(V, F, FN, face[i], b, u, total, max_faces, bary_eps)
        out_face[i] = f
        length[i] = total - rest if status != DONE else total
        hit[i] = status == BOUNDARY
        capped[i] = status == CAPPED
    return out_face, out_bary, length, hit, capped


@inner
def _position(V, F, f, b, out):
    for d in range(3):
        out[d] = b[0] * V[F[f, 0], d] + b[1] * V[F[f, 1], d] + b[2] * V[F[f, 2], d]


@njit(cache=True, nogil=True, fastmath=False)
def _clip_at_boundary(V, F, FN, f, b, step, bary_eps):
    """Remove the outward part of ``step`` at boundary edges the point lies on; True if any."""
    clipped = False
    for rounds in range(2):
        for k in range(3):
            if FN[f, k] >= 0 or b[(k + 2) % 3] > bary_eps:
                continue
            va = F[f, k]
            vc = F[f, (k + 1) % 3]
            vo = F[f, (k + 2) % 3]
            e = V[vc] - V[va]
            e = e / np.sqrt(np.sum(e * e))
            w = V[vo] - V[va]
            w = w - np.sum(w * e) * e
            w = w / np.sqrt(np.sum(w * w))
            out = step[0] * w[0] + step[1] * w[1] + step[2] * w[2]
            if out < 0.0:
                clipped = True
                if rounds == 0:
                    for d in range(3):
                        step[d] -= out * w[d]
                else:  # still leaving through a second boundary edge: a corner blocks it
                    for d in range(3):
                        step[d] = 0.0
    return clipped


@inner
def _dist(t, x):
    """|t - x| for (3,) arrays, summed in the order of ``np.sum``."""
    d0 = t[0] - x[0]
    d1 = t[1] - x[1]
    d2 = t[2] - x[2]
    return np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@inner
def _closest_on_face(V, F, f, p, out):
    """Barycentrics ``out`` (3,) of the point of triangle ``f`` closest to ``p`` (3,).

    Exact zeros on the clamped coordinates (Ericson, Real-Time Collision Detection, 5.1.5).
    Scalar arithmetic (no temporaries), sums in the order of ``np.sum``.
    """
    ia = F[f, 0]
    ib = F[f, 1]
    ic = F[f, 2]
    ax = V[ia, 0]
    ay = V[ia, 1]
    az = V[ia, 2]
    abx = V[ib, 0] - ax
    aby = V[ib, 1] - ay
    abz = V[ib, 2] - az
    acx = V[ic, 0] - ax
    acy = V[ic, 1] - ay
    acz = V[ic, 2] - az
    apx = p[0] - ax
    apy = p[1] - ay
    apz = p[2] - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    if d1 <= 0.0 and d2 <= 0.0:
        out[0] = 1.0
        return
    bpx = p[0] - V[ib, 0]
    bpy = p[1] - V[ib, 1]
    bpz = p[2] - V[ib, 2]
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        out[1] = 1.0
        return
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        out[0] = 1.0 - v
        out[1] = v
        return
    cpx = p[0] - V[ic, 0]
    cpy = p[1] - V[ic, 1]
    cpz = p[2] - V[ic, 2]
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        out[2] = 1.0
        return
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        out[0] = 1.0 - w
        out[2] = w
        return
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        out[1] = 1.0 - w
        out[2] = w
        return
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    out[0] = 1.0 - v - w
    out[1] = v
    out[2] = w


@njit(cache=True, nogil=True, fastmath=False)
def _descend(V, F, FN, VFp, VF, f, b, tgt, dist, tmp, best, x):
    """One exact descent move of a face point toward ``tgt`` without leaving the surface.

    Moves to the closest point of the current face if that is closer; otherwise, from that
    closest point (on an edge or at a vertex), to the closest point of the neighbouring face
    or of the best face of the vertex's fan if one is closer. ``b`` (3,) is updated in place;
    ``tmp``, ``best``, ``x`` (3,) are scratch. Returns ``(face, distance, moved)``; ``moved``
    False certifies a local minimum.
    """
    _closest_on_face(V, F, f, tgt, best)
    _position(V, F, f, best, x)
    dc = _dist(tgt, x)
    if dc < dist:
        _copy3(best, b)
        return f, dc, True
    nz = 0
    for j in range(3):
        if best[j] == 0.0:
            nz += 1
    best_face = -1
    best_d = dist
    if nz == 1:
        for j in range(3):
            if best[j] == 0.0:
                g = FN[f, (j + 1) % 3]
                if g >= 0:
                    _closest_on_face(V, F, g, tgt, tmp)
                    _position(V, F, g, tmp, x)
                    d = _dist(tgt, x)
                    if d < best_d:
                        best_d = d
                        best_face = g
                        _copy3(tmp, best)
    elif nz == 2:
        v = F[f, 0]
        for j in range(3):
            if best[j] != 0.0:
                v = F[f, j]
        for r in range(VFp[v], VFp[v + 1]):
            g = VF[r]
            if g == f:
                continue
            _closest_on_face(V, F, g, tgt, tmp)
            _position(V, F, g, tmp, x)
            d = _dist(tgt, x)
            if d < best_d:
                best_d = d
                best_face = g
                _copy3(tmp, best)
    if best_face < 0:
        return f, dist, False
    _copy3(best, b)
    return best_face, best_d, True


@njit(cache=True, nogil=True, fastmath=False)
def _attract_one(V, F, FN, VFp, VF, f, b, tgt, max_iter, max_faces, eps_len, bary_eps):
    """Attract one face point (face ``f``, barycentrics ``b`` (3,) updated in place) to ``tgt``.

    Returns ``(face, distance, iterations, hit_boundary, converged)``. Shared by the parallel
    kernel below and the serial one in `meshfit._kernels.curves`.
    """
    buf = np.empty((_ATTRACT_SCRATCH, 3))
    return _attract_one_buf(
        V, F, FN, VFp, VF, f, b, tgt, max_iter, max_faces, eps_len, bary_eps, buf
    )


@inner
def _attract_one_buf(V, F, FN, VFp, VF, f, b, tgt, max_iter, max_faces, eps_len, bary_eps, buf):
    """`_attract_one` with caller-owned scratch ``buf (_ATTRACT_SCRATCH, 3) f8`` (a serial
    caller allocates it once for all its points)."""
    hit = False
    conv = False
    x = buf[0]
    nrm = buf[1]
    step = buf[2]
    u = buf[3]
    cb = buf[4]
    tmp = buf[5]
    y = buf[6]
    _position(V, F, f, b, x)
    dist = _dist(tgt, x)
    h = 1.0
    it = 0
    while it < max_iter:
        it += 1
        # the target projected onto the current face's plane, minus the point
        n0, n1, n2 = _face_normal3(V, F, f)
        off = (tgt[0] - x[0]) * n0 + (tgt[1] - x[1]) * n1 + (tgt[2] - x[2]) * n2
        step[0] = h * (tgt[0] - off * n0 - x[0])
        step[1] = h * (tgt[1] - off * n1 - x[1])
        step[2] = h * (tgt[2] - off * n2 - x[2])
        _clip_at_boundary(V, F, FN, f, b, step, bary_eps)
        moved = False
        if np.sqrt(step[0] * step[0] + step[1] * step[1] + step[2] * step[2]) >= eps_len:
            total = _start_direction(V, F, f, step, u)
            _copy3(b, cb)
            # a walk that cannot end closer than `dist` is cut short: it would be rejected
            # (the margin keeps the decision exact under rounding)
            g, _, status, _ = _walk_core(
                V, F, FN, f, cb, u, total, max_faces, bary_eps, tgt, dist + eps_len
            )
            cand = np.inf
            if status != FARTHER:
                _position(V, F, g, cb, nrm)  # nrm reused as the candidate position
                cand = _dist(tgt, nrm)
            if cand < dist:
                f = g
                _copy3(cb, b)
                dist = cand
                h = min(1.0, 2.0 * h)
                moved = True
            else:
                h *= 0.5
        if not moved:
            # a short or rejected step: an exact move within the face, across the
            # edge or around the vertex the point sits on, or a certified local minimum
            f, dist, moved = _descend(V, F, FN, VFp, VF, f, b, tgt, dist, tmp, cb, y)
            if not moved:
                conv = True
                break
        _position(V, F, f, b, x)
    _clean_bary(b)
    for k in range(3):
        if FN[f, k] < 0 and b[(k + 2) % 3] <= bary_eps:
            hit = True
    return f, dist, it, hit, conv


@njit(cache=True, nogil=True, parallel=True, fastmath=False)
def attract_points(V, F, FN, VFp, VF, face, bary, targets, max_iter, max_faces, eps_len, bary_eps):
    """Kernel of `meshfit.surface.walk.attract_points`.

    V (nv, 3) f8; F, FN (nf, 3) i8; VFp (nv + 1,), VF (3 nf,) i8 vertex-face CSR; face (n,) i8;
    bary, targets (n, 3) f8 -> out_face (n,) i8, out_bary (n, 3) f8, distance (n,) f8,
    iterations (n,) i8, hit_boundary (n,) bool, converged (n,) bool.
    """
    n = face.shape[0]
    out_face = face.copy()
    out_bary = bary.copy()
    distance = np.zeros(n)
    iterations = np.zeros(n, dtype=np.int64)
    hit = np.zeros(n, dtype=np.bool_)
    converged = np.zeros(n, dtype=np.bool_)
    for i in prange(n):  # iteration i writes row i only
        buf = np.empty((_ATTRACT_SCRATCH, 3))
        out_face[i], distance[i], iterations[i], hit[i], converged[i] = _attract_one_buf(
            V,
            F,
            FN,
            VFp,
            VF,
            face[i],
            out_bary[i],
            targets[i],
            max_iter,
            max_faces,
            eps_len,
            bary_eps,
            buf,
        )
    return out_face, out_bary, distance, iterations, hit, converged
