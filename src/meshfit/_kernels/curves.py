"""Numba kernels for face-point curves.

The sampling rule (consecutive points on the same or edge-adjacent faces, edge and vertex
points written in every face that holds them), a curve as straight pieces and points placed
on them, the subdivision search and split positions of uniform resampling, bisecting pairs
that break the rule (densifying), serial walking / attraction, and painting's
straightening (attraction by continuation, then reverting jumps). Each has a slow
reference in ``tests/reference/curves.py``.

No validation here: the wrappers in :mod:`meshfit.curves.base` and
:mod:`meshfit.surface.walk` pass contiguous arrays of the right dtypes.

Conventions as in :mod:`meshfit._kernels.walk`: ``F (nf, 3) i8`` faces, ``FN (nf, 3) i8``
face across edge ``k = (F[f, k], F[f, (k + 1) % 3])`` (-1 on the boundary), ``VF_ptr
(nv + 1,) i8`` / ``VF (3 nf,) i8`` the faces around each vertex (CSR).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from meshfit._kernels import inner
from meshfit._kernels.walk import (
    _ATTRACT_SCRATCH,
    BOUNDARY,
    CAPPED,
    DONE,
    _attract_one_buf,
    _copy3,
    _position,
    _start_direction,
    _walk_one,
)


@njit(cache=True, nogil=True)
def _representations(F, FN, VF_ptr, VF, face, bary, eps, faces_out, bary_out):
    """Write every (face, bary) holding the point into the outputs; return how many.

    Same order as :func:`meshfit.surface.walk._representations`: the point's own face
    first, then the face across its edge (edge point) or the other faces around its vertex
    in CSR order (vertex point). Outputs must hold ``1 + max valence`` rows.
    """
    faces_out[0] = face
    bary_out[0, 0] = bary[0]
    bary_out[0, 1] = bary[1]
    bary_out[0, 2] = bary[2]
    nz = 0
    zi = -1
    ki = -1
    for c in range(3):
        if bary[c] <= eps:
            nz += 1
            zi = c
        else:
            ki = c
    n = 1
    if nz == 1:
        k = (zi + 1) % 3
        g = FN[face, k]
        if g >= 0:
            va = F[face, k]
            vc = F[face, (k + 1) % 3]
            b0 = 0.0
            b1 = 0.0
            b2 = 0.0
            ba = bary[k]
            bc = bary[(k + 1) % 3]
            # as the reference: slot of va is set first, then the slot of vc
            for s in range(3):
                if F[g, s] == va:
                    if s == 0:
                        b0 = ba
                    elif s == 1:
                        b1 = ba
                    else:
                        b2 = ba
                    break
            for s in range(3):
                if F[g, s] == vc:
                    if s == 0:
                        b0 = bc
                    elif s == 1:
                        b1 = bc
                    else:
                        b2 = bc
                    break
            tot = b0 + b1 + b2
            faces_out[1] = g
            bary_out[1, 0] = b0 / tot
            bary_out[1, 1] = b1 / tot
            bary_out[1, 2] = b2 / tot
            n = 2
    elif nz == 2:
        v = F[face, ki]
        for j in range(VF_ptr[v], VF_ptr[v + 1]):
            g = VF[j]
            if g != face:
                faces_out[n] = g
                for s in range(3):
                    bary_out[n, s] = 1.0 if F[g, s] == v else 0.0
                n += 1
    return n


@inner
def _adjacent(FN, f, g):
    return FN[f, 0] == g or FN[f, 1] == g or FN[f, 2] == g


@inner
def _max_valence(F, FN, VF_ptr, fa, fb):
    """Largest vertex valence over the faces of the pairs that are not trivially ok."""
    m = 0
    for i in range(fa.size):
        f = fa[i]
        g = fb[i]
        if f == g or _adjacent(FN, f, g):
            continue
        for c in range(3):
            for v in (F[f, c], F[g, c]):
                d = VF_ptr[v + 1] - VF_ptr[v]
                if d > m:
                    m = d
    return m


@inner
def _best_option(FN, fa_r, na, fb_r, nb):
    """First pair (i, j) on a shared face, else the first on adjacent faces, else (-1, -1)."""
    adj_i = -1
    adj_j = -1
    for i in range(na):
        for j in range(nb):
            if fa_r[i] == fb_r[j]:
                return i, j
            if adj_i < 0 and _adjacent(FN, fa_r[i], fb_r[j]):
                adj_i = i
                adj_j = j
    return adj_i, adj_j


@njit(cache=True, nogil=True)
def pairs_ok(F, FN, VF_ptr, VF, fa, ba, fb, bb, eps):
    """Whether each pair of face points lies on the same or edge-adjacent faces; (n,) bool."""
    n = fa.size
    ok = np.empty(n, dtype=np.bool_)
    max_val = _max_valence(F, FN, VF_ptr, fa, fb)
    fa_r = np.empty(max_val + 1, dtype=np.int64)
    fb_r = np.empty(max_val + 1, dtype=np.int64)
    ba_r = np.empty((max_val + 1, 3))
    bb_r = np.empty((max_val + 1, 3))
    for i in range(n):
        f = fa[i]
        g = fb[i]
        if f == g or _adjacent(FN, f, g):
            ok[i] = True
            continue
        na = _representations(F, FN, VF_ptr, VF, f, ba[i], eps, fa_r, ba_r)
        nb = _representations(F, FN, VF_ptr, VF, g, bb[i], eps, fb_r, bb_r)
        si, _ = _best_option(FN, fa_r, na, fb_r, nb)
        ok[i] = si >= 0
    return ok


@njit(cache=True, nogil=True)
def rewrite_pairs(F, FN, VF_ptr, VF, pf, pb, qf, qb, eps, via):
    """Rewrite pairs on non-adjacent faces in faces that hold both points, in place.

    For each pair whose faces are neither equal nor adjacent, the representations of both
    points are searched for a shared face (preferred) or adjacent faces, in the order of
    the reference implementation. A pair with no such representation whose faces share a
    vertex gets that vertex in ``via (n,) int64`` (-1 elsewhere). Returns the index of the
    first pair on faces sharing nothing, or -1. Wrapped by `meshfit.surface.walk`.
    """
    n = pf.size
    max_val = _max_valence(F, FN, VF_ptr, pf, qf)
    fa_r = np.empty(max_val + 1, dtype=np.int64)
    fb_r = np.empty(max_val + 1, dtype=np.int64)
    ba_r = np.empty((max_val + 1, 3))
    bb_r = np.empty((max_val + 1, 3))
    for i in range(n):
        via[i] = -1
        f = pf[i]
        g = qf[i]
        if f == g or _adjacent(FN, f, g):
            continue
        na = _representations(F, FN, VF_ptr, VF, f, pb[i], eps, fa_r, ba_r)
        nb = _representations(F, FN, VF_ptr, VF, g, qb[i], eps, fb_r, bb_r)
        si, sj = _best_option(FN, fa_r, na, fb_r, nb)
        if si < 0:
            for a in range(3):
                for b in range(3):
                    if F[f, a] == F[g, b]:
                        via[i] = F[f, a]
            if via[i] < 0:
                return i
            continue
        pf[i] = fa_r[si]
        qf[i] = fb_r[sj]
        for c in range(3):
            pb[i, c] = ba_r[si, c]
            qb[i, c] = bb_r[sj, c]
    return -1


# ------------------------------------------------------------- serial walking for few points
# The kernels in `meshfit._kernels.walk` are `parallel=True`; launching a parallel region costs
# far more than walking one point (threads must be woken, slowly on a loaded machine), which
# dominates when curve bisection moves one point at a time. These are the same per-point
# loops run serially: keep them in step with `walk_points` / `attract_points` there.


@inner
def walk_points_serial(V, F, FN, face, bary, step, max_faces, eps_len, bary_eps):
    """Serial `meshfit._kernels.walk.walk_points` (same arguments and results)."""
    n = face.shape[0]
    out_face = face.copy()
    out_bary = bary.copy()
    length = np.zeros(n)
    hit = np.zeros(n, dtype=np.bool_)
    capped = np.zeros(n, dtype=np.bool_)
    u = np.empty(3)
    for i in range(n):
        b = out_bary[i]
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
def _dist2(t, x):
    """|t - x|^2 for (3,) arrays, summed in the order of ``np.sum``."""
    d0 = t[0] - x[0]
    d1 = t[1] - x[1]
    d2 = t[2] - x[2]
    return d0 * d0 + d1 * d1 + d2 * d2


@njit(cache=True, nogil=True)
def attract_points_serial(
    V, F, FN, VFp, VF, face, bary, targets, max_iter, max_faces, eps_len, bary_eps, chain
):
    """Serial `meshfit._kernels.walk.attract_points` (same arguments and results); with
    ``chain`` (an ordered curve) each point starts from the nearer, to its target, of its own
    position and the previous point's result (attraction by continuation)."""
    n = face.shape[0]
    out_face = face.copy()
    out_bary = bary.copy()
    distance = np.zeros(n)
    iterations = np.zeros(n, dtype=np.int64)
    hit = np.zeros(n, dtype=np.bool_)
    converged = np.zeros(n, dtype=np.bool_)
    x = np.empty(3)
    buf = np.empty((_ATTRACT_SCRATCH, 3))
    for i in range(n):
        if chain and i > 0:
            _position(V, F, face[i], bary[i], x)
            own = _dist2(targets[i], x)
            _position(V, F, out_face[i - 1], out_bary[i - 1], x)
            if _dist2(targets[i], x) < own:
                out_face[i] = out_face[i - 1]
                out_bary[i] = out_bary[i - 1]
        out_face[i], distance[i], iterations[i], hit[i], converged[i] = _attract_one_buf(
            V,
            F,
            FN,
            VFp,
            VF,
            out_face[i],
            out_bary[i],
            targets[i],
            max_iter,
            max_faces,
            eps_len,
            bary_eps,
            buf,
        )
    return out_face, out_bary, distance, iterations, hit, converged


# ------------------------------------------------------------ subdividing steps of resampling


@inner
def _place(s, closed, p_face, p_b0, p_b1, p_start, p_len, arc, pt_face, pt_bary, out_b):
    """Face point at arc length ``s`` (already in range) of a curve given by its pieces.

    Same arithmetic as `meshfit.surface.walk._place_on_pieces` followed by `_clean_bary`;
    barycentrics into ``out_b`` (3,), returns the face and the curve segment it lies on.
    """
    npc = p_face.size
    j = np.searchsorted(p_start, s, side="right") - 1
    if j < 0:
        j = 0
    if j > npc - 1:
        j = npc - 1
    plen = p_len[j]
    t = (s - p_start[j]) / plen if plen > 0 else 1.0
    if t < 0.0:
        t = 0.0
    elif t > 1.0:
        t = 1.0
    f = p_face[j]
    for c in range(3):
        out_b[c] = (1.0 - t) * p_b0[j, c] + t * p_b1[j, c]
    segment = j // 2
    at = np.searchsorted(arc, s)
    if at > arc.size - 1:
        at = arc.size - 1
    if arc[at] == s:
        if closed:
            at = at % pt_face.size
        f = pt_face[at]
        for c in range(3):
            out_b[c] = pt_bary[at, c]
        segment = min(at, npc // 2 - 1)
    if out_b[0] < 0.0 or out_b[1] < 0.0 or out_b[2] < 0.0:
        for c in range(3):
            if out_b[c] < 0.0:
                out_b[c] = 0.0
        tot = out_b[0] + out_b[1] + out_b[2]
        for c in range(3):
            out_b[c] = out_b[c] / tot
    return f, segment


@njit(cache=True, nogil=True)
def _pair_ok(F, FN, VF_ptr, VF, f, ba, g, bb, eps, fa_r, ba_r, fb_r, bb_r):
    if f == g or _adjacent(FN, f, g):
        return True
    na = _representations(F, FN, VF_ptr, VF, f, ba, eps, fa_r, ba_r)
    nb = _representations(F, FN, VF_ptr, VF, g, bb, eps, fb_r, bb_r)
    si, _ = _best_option(FN, fa_r, na, fb_r, nb)
    return si >= 0


@inner
def _faces_valence(F, VF_ptr, faces, m):
    """Largest of ``m`` and the valences of the vertices of ``faces``."""
    for i in range(faces.size):
        for c in range(3):
            v = F[faces[i], c]
            d = VF_ptr[v + 1] - VF_ptr[v]
            if d > m:
                m = d
    return m


@inner
def _scratch_for(F, VF_ptr, faces_a, faces_b):
    """`_scratch` sized by the largest valence among the vertices of the given faces (face
    points on these faces only)."""
    m = _faces_valence(F, VF_ptr, faces_b, _faces_valence(F, VF_ptr, faces_a, 1))
    return (
        np.empty(m + 1, dtype=np.int64),
        np.empty((m + 1, 3)),
        np.empty(m + 1, dtype=np.int64),
        np.empty((m + 1, 3)),
    )


@njit(cache=True, nogil=True)
def _scratch(VF_ptr):
    """Buffers for the representations of two face points, sized by the largest valence."""
    m = 1
    for v in range(VF_ptr.size - 1):
        d = VF_ptr[v + 1] - VF_ptr[v]
        if d > m:
            m = d
    return (
        np.empty(m + 1, dtype=np.int64),
        np.empty((m + 1, 3)),
        np.empty(m + 1, dtype=np.int64),
        np.empty((m + 1, 3)),
    )


@njit(cache=True, nogil=True)
def revert_jumps(V, F, FN, VF_ptr, VF, face, bary, gface, gbary, keep, max_gap, eps):
    """Clear ``keep`` (n,) bool in place until no consecutive pair jumps; returns rounds.

    Point i is ``(face, bary)[i]`` where ``keep[i]`` and ``(gface, gbary)[i]`` elsewhere. A
    pair jumps when its faces are neither the same nor edge-adjacent (as `pairs_ok`) and
    either share no vertex or lie more than ``max_gap`` apart; both its points are then
    reverted, and the sweep steps back to recheck the pair before. Kernel of
    `meshfit.curves.paint.paint_curve`.
    """
    n = face.size
    fa_r, ba_r, fb_r, bb_r = _scratch_for(F, VF_ptr, face, gface)
    reverts = 0
    i = 0
    while i < n - 1:
        if not (keep[i] or keep[i + 1]):  # two graph samples: nothing to revert
            i += 1
            continue
        f0 = face[i] if keep[i] else gface[i]
        f1 = face[i + 1] if keep[i + 1] else gface[i + 1]
        b0 = bary[i] if keep[i] else gbary[i]
        b1 = bary[i + 1] if keep[i + 1] else gbary[i + 1]
        jump = False
        if not _pair_ok(F, FN, VF_ptr, VF, f0, b0, f1, b1, eps, fa_r, ba_r, fb_r, bb_r):
            share = False
            for a in range(3):
                for b in range(3):
                    if F[f0, a] == F[f1, b]:
                        share = True
            gap = 0.0
            for d in range(3):
                x0 = b0[0] * V[F[f0, 0], d] + b0[1] * V[F[f0, 1], d] + b0[2] * V[F[f0, 2], d]
                x1 = b1[0] * V[F[f1, 0], d] + b1[1] * V[F[f1, 1], d] + b1[2] * V[F[f1, 2], d]
                gap += (x1 - x0) ** 2
            jump = not share or np.sqrt(gap) > max_gap
        if jump and (keep[i] or keep[i + 1]):
            keep[i] = False
            keep[i + 1] = False
            reverts += 1
            if i > 0:
                i -= 1
            continue
        i += 1
    return reverts


@inner
def _place_part(
    ai, d, j, k, closed, total, p_face, p_b0, p_b1, p_start, p_len, arc, pt_face, pt_bary, out_b
):
    """Place part end j of k of the step from ``ai`` of length ``d`` (see `subdivide_steps`)."""
    s = ai + d * j / k
    if closed and s >= total:
        s = s - total
    if s < 0.0:
        s = 0.0
    elif s > total:
        s = total
    if closed and s >= total:
        s = 0.0
    return _place(s, closed, p_face, p_b0, p_b1, p_start, p_len, arc, pt_face, pt_bary, out_b)[0]


@njit(cache=True, nogil=True)
def subdivide_steps(
    F, FN, VF_ptr, VF, a, b, k_min, k_max, closed, total,
    p_face, p_b0, p_b1, p_start, p_len, arc, pt_face, pt_bary, eps,
):  # fmt: skip
    """Fewest parts k in [k_min, k_max] that split each step [a, b] of a curve's arc length
    evenly with every consecutive pair of parts on the same or adjacent faces; 0 if none.

    Part ends are ``a + (b - a) * j / k`` (j = 0..k), wrapped past ``total`` on a closed
    curve and clipped to [0, total], and placed as in `_place`; a k is abandoned at its
    first failing pair. A step holding a curve point at a mesh vertex gets 0 at once.
    """
    n = a.size
    out = np.zeros(n, dtype=np.int64)
    fa_r, ba_r, fb_r, bb_r = _scratch_for(F, VF_ptr, p_face, pt_face)
    prev = np.empty(3)
    cur = np.empty(3)
    for i in range(n):
        ai = a[i]
        d = b[i] - ai
        # curve points strictly inside the step: the pair of parts around one of them is the
        # one that usually fails (the curve passes a vertex there), so it is checked first
        lo = np.searchsorted(arc, ai, side="right")
        hi = np.searchsorted(arc, b[i], side="left")
        # where the last tried k failed: that pair of the next k is checked first too
        fail_at = ai + 0.5 * d
        # a curve point at a mesh vertex inside the step: parts on either side of it lie on
        # faces that share only that vertex whatever k is, so no even split keeps the rule
        at_vertex = False
        for q in range(lo, hi):
            for c in range(3):
                if pt_bary[q, c] >= 1.0 - eps:
                    at_vertex = True
        if at_vertex:
            continue
        for k in range(k_min, k_max + 1):
            ok = True
            for q in range(lo - 1, hi):
                v = fail_at if q < lo else arc[q]
                j = int((v - ai) / d * k) if d > 0 else 0
                if j > k - 1:
                    j = k - 1
                if j < 0:
                    j = 0
                f0 = _place_part(
                    ai, d, j, k, closed, total, p_face, p_b0, p_b1, p_start, p_len, arc,
                    pt_face, pt_bary, prev,
                )  # fmt: skip
                f1 = _place_part(
                    ai, d, j + 1, k, closed, total, p_face, p_b0, p_b1, p_start, p_len,
                    arc, pt_face, pt_bary, cur,
                )  # fmt: skip
                if not _pair_ok(F, FN, VF_ptr, VF, f0, prev, f1, cur, eps, fa_r, ba_r, fb_r, bb_r):
                    ok = False
                    break
            if not ok:
                continue
            fprev = -1
            for j in range(k + 1):
                fcur = _place_part(
                    ai, d, j, k, closed, total, p_face, p_b0, p_b1, p_start, p_len, arc,
                    pt_face, pt_bary, cur,
                )  # fmt: skip
                if j > 0 and not _pair_ok(
                    F, FN, VF_ptr, VF, fprev, prev, fcur, cur, eps, fa_r, ba_r, fb_r, bb_r
                ):
                    ok = False
                    fail_at = ai + d * (j - 0.5) / k
                    break
                fprev = fcur
                for c in range(prev.shape[0]):
                    prev[c] = cur[c]
            if ok:
                out[i] = k
                break
    return out


# ----------------------------------------------------------------- a curve as straight pieces


@inner
def _point_in(V, F, f, b, out):
    """Position of barycentrics ``b`` (3,) in face ``f`` into ``out`` (3,)."""
    for d in range(3):
        out[d] = b[0] * V[F[f, 0], d] + b[1] * V[F[f, 1], d] + b[2] * V[F[f, 2], d]


@inner
def _norm3(x0, x1, x2):
    return np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)


@njit(cache=True, nogil=True)
def curve_pieces(V, F, FN, VF_ptr, VF, pf, pb, qf, qb, eps):
    """Split each segment (p[i], q[i]) of a face-point polyline into two straight pieces.

    pf, qf (n,) i8 and pb, qb (n, 3) f8 (barycentrics >= 0) are rewritten in place as
    `rewrite_pairs` does. Returns ``(bad, face (2n,) i8, b0 (2n, 3), b1 (2n, 3), start
    (2n + 1,), length (2n,))``: piece 2i runs in p's face from p to the crossing X of the
    shared edge (the unfolded straight segment's, clamped to the edge; the shared vertex
    when the faces share only that; X = q on a shared face), piece 2i + 1 in q's face from X
    to q; ``start`` is the cumulative length (``start[-1]`` the total). ``bad`` is the first
    pair on faces sharing nothing, or -1 (the other outputs are then undefined). Kernel of
    `meshfit.surface.walk._curve_pieces`.
    """
    n = pf.size
    via = np.empty(n, dtype=np.int64)
    face = np.empty(2 * n, dtype=np.int64)
    b0 = np.empty((2 * n, 3))
    b1 = np.empty((2 * n, 3))
    start = np.zeros(2 * n + 1)
    length = np.empty(2 * n)
    bad = rewrite_pairs(F, FN, VF_ptr, VF, pf, pb, qf, qb, eps, via)
    if bad >= 0:
        return bad, face, b0, b1, start, length
    xp = np.empty(3)
    xq = np.empty(3)
    xx = np.empty(3)
    xf = np.empty(3)
    xg = np.empty(3)
    for i in range(n):
        f = pf[i]
        g = qf[i]
        _point_in(V, F, f, pb[i], xp)
        _point_in(V, F, g, qb[i], xq)
        for c in range(3):
            xf[c] = qb[i, c]
            xg[c] = qb[i, c]
        if via[i] >= 0:  # faces sharing only a vertex: through that vertex
            v = via[i]
            xf[:] = 0.0
            xg[:] = 0.0
            for c in range(3):
                if F[f, c] == v:
                    xf[c] = 1.0
                    break
            for c in range(3):
                if F[g, c] == v:
                    xg[c] = 1.0
                    break
        elif f != g:  # adjacent faces: where the unfolded straight segment meets the edge
            k = 0
            for c in range(3):
                if FN[f, c] == g:
                    k = c
                    break
            va = F[f, k]
            vc = F[f, (k + 1) % 3]
            e0 = V[vc, 0] - V[va, 0]
            e1 = V[vc, 1] - V[va, 1]
            e2 = V[vc, 2] - V[va, 2]
            el = _norm3(e0, e1, e2)
            h0 = e0 / el
            h1 = e1 / el
            h2 = e2 / el
            p0 = xp[0] - V[va, 0]
            p1 = xp[1] - V[va, 1]
            p2 = xp[2] - V[va, 2]
            q0 = xq[0] - V[va, 0]
            q1 = xq[1] - V[va, 1]
            q2 = xq[2] - V[va, 2]
            # (0 + 2) + 1: the order numpy's einsum sums three products in
            along_p = (p0 * h0 + p2 * h2) + p1 * h1
            along_q = (q0 * h0 + q2 * h2) + q1 * h1
            h_p = _norm3(p0 - along_p * h0, p1 - along_p * h1, p2 - along_p * h2)
            h_q = _norm3(q0 - along_q * h0, q1 - along_q * h1, q2 - along_q * h2)
            hs = h_p + h_q
            t = h_p / hs if hs > 0 else 1.0
            # outside the edge the shortest path inside the two faces bends at its end vertex
            mu = (along_p + t * (along_q - along_p)) / el
            if mu < 0.0:
                mu = 0.0
            elif mu > 1.0:
                mu = 1.0
            xf[:] = 0.0
            xf[k] = 1.0 - mu
            xf[(k + 1) % 3] = mu
            xg[:] = 0.0
            for c in range(3):
                if F[g, c] == va:
                    xg[c] = 1.0 - mu
                    break
            for c in range(3):
                if F[g, c] == vc:
                    xg[c] = mu
                    break
        _point_in(V, F, f, xf, xx)
        face[2 * i] = f
        face[2 * i + 1] = g
        for c in range(3):
            b0[2 * i, c] = pb[i, c]
            b1[2 * i, c] = xf[c]
            b0[2 * i + 1, c] = xg[c]
            b1[2 * i + 1, c] = qb[i, c]
        length[2 * i] = _norm3(xx[0] - xp[0], xx[1] - xp[1], xx[2] - xp[2])
        length[2 * i + 1] = _norm3(xq[0] - xx[0], xq[1] - xx[1], xq[2] - xx[2])
    for j in range(2 * n):
        start[j + 1] = start[j] + length[j]
    return -1, face, b0, b1, start, length


@njit(cache=True, nogil=True)
def place_on_pieces(p_face, p_b0, p_b1, p_start, p_len, arc, pt_face, pt_bary, closed, s):
    """Face points at arc lengths ``s (k,) f8`` (already in range) of a curve's pieces.

    Pieces as returned by `curve_pieces` (``p_start`` without the total), ``arc`` the
    curve's points' arc lengths (plus the total when closed), ``pt_face (m,)``, ``pt_bary
    (m, 3)`` its points. Returns ``(face (k,) i8, bary (k, 3) f8, segment (k,) i8)``: a
    position equal to a point's arc length gives that point. Kernel of
    `meshfit.surface.walk._place_on_pieces` (same arithmetic as its numpy form).
    """
    k = s.size
    face = np.empty(k, dtype=np.int64)
    bary = np.empty((k, 3))
    segment = np.empty(k, dtype=np.int64)
    for i in range(k):
        face[i], segment[i] = _place(
            s[i], closed, p_face, p_b0, p_b1, p_start, p_len, arc, pt_face, pt_bary, bary[i]
        )
    return face, bary, segment


# --------------------------------------------------------- bisecting pairs that break the rule


@inner
def _clean_copy(b, out):
    """``out`` = ``b`` (3,) with tiny negatives clamped and renormalised, only when there is
    one (as `meshfit.surface.walk._clean_bary`)."""
    for c in range(3):
        out[c] = b[c]
    if out[0] < 0.0 or out[1] < 0.0 or out[2] < 0.0:
        for c in range(3):
            if out[c] < 0.0:
                out[c] = 0.0
        tot = out[0] + out[1] + out[2]
        for c in range(3):
            out[c] = out[c] / tot


@inner
def _grow(face, bary, pair, need):
    if need <= face.size:
        return face, bary, pair
    cap = max(need, 2 * face.size)
    f2 = np.empty(cap, dtype=np.int64)
    b2 = np.empty((cap, 3))
    p2 = np.empty(cap, dtype=np.int64)
    for i in range(face.size):
        f2[i] = face[i]
        p2[i] = pair[i]
        for c in range(3):
            b2[i, c] = bary[i, c]
    return f2, b2, p2


@njit(cache=True, nogil=True)
def bridge_pairs(
    V, F, FN, VF_ptr, VF, fa, ba, fb, bb, max_depth, max_iter, max_faces, walk_eps, att_eps,
    bary_eps,
):  # fmt: skip
    """Points that bridge each pair (a, b) of face points breaking the sampling rule.

    fa, fb (n,) i8; ba, bb (n, 3) f8. A pair still apart is bisected on the surface: a walks
    halfway towards b (`_walk_one`, ``max_faces`` crossings, no move under ``walk_eps``) and
    is attracted to the 3-D midpoint (``max_iter`` steps, ``att_eps``); both halves are
    bisected further, depth first, while the midpoint brings the ends closer (both halves
    under 0.8 of the gap) and the depth is below ``max_depth``. Returns ``(pair (k,) i8,
    face (k,) i8, bary (k, 3) f8, gfa, gba, gfb, gbb)``: the inserted entries in curve order
    with the pair each belongs to; an entry with ``face = -1 - j`` stands for a graph path
    between the ends ``(gfa, gba)[j]`` and ``(gfb, gbb)[j]`` (a pair that would not come
    closer or ran out of depth). Kernel of `meshfit.curves.base.densify_curve`.
    """
    n = fa.size
    fa_r, ba_r, fb_r, bb_r = _scratch(VF_ptr)
    cap = 16 * n + 16
    out_face = np.empty(cap, dtype=np.int64)
    out_bary = np.empty((cap, 3))
    out_pair = np.empty(cap, dtype=np.int64)
    k = 0
    g_face = np.empty((n + 4, 2), dtype=np.int64)
    g_bary = np.empty((n + 4, 2, 3))
    ng = 0
    # depth-first stack of tasks: kind 0 bisects (face, bary)[0] -> (face, bary)[1], kind 1
    # emits (face, bary)[0]
    ns = 3 * (max_depth + 2)
    s_kind = np.empty(ns, dtype=np.int64)
    s_depth = np.empty(ns, dtype=np.int64)
    s_face = np.empty((ns, 2), dtype=np.int64)
    s_bary = np.empty((ns, 2, 3))
    buf = np.empty((_ATTRACT_SCRATCH, 3))
    xa = np.empty(3)
    xb = np.empty(3)
    xm = np.empty(3)
    step = np.empty(3)
    u = np.empty(3)
    hb = np.empty(3)
    tgt = np.empty(3)
    for i in range(n):
        top = 0
        s_kind[0] = 0
        s_depth[0] = 0
        s_face[0, 0] = fa[i]
        s_face[0, 1] = fb[i]
        for c in range(3):
            s_bary[0, 0, c] = ba[i, c]
            s_bary[0, 1, c] = bb[i, c]
        top = 1
        while top > 0:
            top -= 1
            f0 = s_face[top, 0]
            f1 = s_face[top, 1]
            if s_kind[top] == 1:
                out_face, out_bary, out_pair = _grow(out_face, out_bary, out_pair, k + 1)
                out_face[k] = f0
                for c in range(3):
                    out_bary[k, c] = s_bary[top, 0, c]
                out_pair[k] = i
                k += 1
                continue
            b0 = s_bary[top, 0].copy()
            b1 = s_bary[top, 1].copy()
            depth = s_depth[top]
            if _pair_ok(F, FN, VF_ptr, VF, f0, b0, f1, b1, bary_eps, fa_r, ba_r, fb_r, bb_r):
                continue
            closer = False
            fm = -1
            if depth < max_depth:
                _position(V, F, f0, b0, xa)
                _position(V, F, f1, b1, xb)
                gap = np.sqrt(_dist2(xb, xa))
                for d in range(3):
                    step[d] = 0.5 * (xb[d] - xa[d])
                    tgt[d] = 0.5 * (xa[d] + xb[d])
                _clean_copy(b0, hb)
                fh = f0
                total = _start_direction(V, F, f0, step, u)
                if total > walk_eps:
                    fh, _, _, _ = _walk_one(V, F, FN, f0, hb, u, total, max_faces, bary_eps)
                mb = np.empty(3)
                _clean_copy(hb, mb)
                fm, _, _, _, _ = _attract_one_buf(
                    V, F, FN, VF_ptr, VF, fh, mb, tgt, max_iter, max_faces, att_eps,
                    bary_eps, buf,
                )  # fmt: skip
                _position(V, F, fm, mb, xm)
                da = np.sqrt(_dist2(xm, xa))
                db = np.sqrt(_dist2(xb, xm))
                closer = max(da, db) < 0.8 * gap
            if closer:
                # left half first: push (m, b), emit m, (a, m)
                s_kind[top] = 0
                s_depth[top] = depth + 1
                s_face[top, 0] = fm
                s_face[top, 1] = f1
                _copy3(mb, s_bary[top, 0])
                _copy3(b1, s_bary[top, 1])
                s_kind[top + 1] = 1
                s_face[top + 1, 0] = fm
                s_face[top + 1, 1] = fm
                _copy3(mb, s_bary[top + 1, 0])
                s_kind[top + 2] = 0
                s_depth[top + 2] = depth + 1
                s_face[top + 2, 0] = f0
                s_face[top + 2, 1] = fm
                _copy3(b0, s_bary[top + 2, 0])
                _copy3(mb, s_bary[top + 2, 1])
                top += 3
                continue
            if ng == g_face.shape[0]:
                gf2 = np.empty((2 * ng, 2), dtype=np.int64)
                gb2 = np.empty((2 * ng, 2, 3))
                for r in range(ng):
                    for s in range(2):
                        gf2[r, s] = g_face[r, s]
                        for c in range(3):
                            gb2[r, s, c] = g_bary[r, s, c]
                g_face = gf2
                g_bary = gb2
            g_face[ng, 0] = f0
            g_face[ng, 1] = f1
            _copy3(b0, g_bary[ng, 0])
            _copy3(b1, g_bary[ng, 1])
            out_face, out_bary, out_pair = _grow(out_face, out_bary, out_pair, k + 1)
            out_face[k] = -1 - ng
            out_bary[k] = 0.0
            out_pair[k] = i
            k += 1
            ng += 1
    return out_pair[:k], out_face[:k], out_bary[:k], g_face[:ng], g_bary[:ng]


@njit(cache=True, nogil=True)
def broken_pairs(F, FN, VF_ptr, VF, face, bary, closed, eps):
    """Indices i (k,) i8 whose pair (i, i + 1) of a face-point curve (face (m,) i8, bary
    (m, 3) f8; the pair (m - 1, 0) too when ``closed``) breaks the sampling rule, as
    `pairs_ok`. Kernel of `meshfit.curves.check_sampling`."""
    m = face.size
    npairs = m if closed and m > 1 else max(m - 1, 0)
    out = np.empty(npairs, dtype=np.int64)
    k = 0
    fa_r, ba_r, fb_r, bb_r = _scratch_for(F, VF_ptr, face, face[:0])
    for i in range(npairs):
        j = i + 1 if i + 1 < m else 0
        f = face[i]
        g = face[j]
        if f == g or _adjacent(FN, f, g):
            continue
        na = _representations(F, FN, VF_ptr, VF, f, bary[i], eps, fa_r, ba_r)
        nb = _representations(F, FN, VF_ptr, VF, g, bary[j], eps, fb_r, bb_r)
        si, _ = _best_option(FN, fa_r, na, fb_r, nb)
        if si < 0:
            out[k] = i
            k += 1
    return out[:k]


@njit(cache=True, nogil=True)
def positions(V, F, face, bary):
    """Positions (n, 3) f8 of face points face (n,) i8, bary (n, 3) f8, summed in the order
    of ``Mesh.xyz``. Used by `meshfit.curves.paint`."""
    n = face.size
    out = np.empty((n, 3))
    for i in range(n):
        _point_in(V, F, face[i], bary[i], out[i])
    return out


@njit(cache=True, nogil=True)
def straighten_chain(
    V, F, FN, VF_ptr, VF, face, bary, targets, max_iter, max_faces, eps_len, bary_eps, max_gap
):
    """Attract the inner points of a sampled graph path toward ``targets`` by continuation,
    then revert where neighbours jump: `attract_points_serial` (``chain``) on points 1 ..
    m - 2 followed by `revert_jumps` against the samples themselves.

    face (m,) i8, bary (m, 3) f8: the samples, ends kept; targets (m - 2, 3) f8. Returns
    ``(face (m,) i8, bary (m, 3) f8)``. Kernel of `meshfit.curves.paint.paint_curve`.
    """
    m = face.size
    inner_b = np.empty((m - 2, 3))
    for i in range(m - 2):
        _clean_copy(bary[i + 1], inner_b[i])
    af, ab, _, _, _, _ = attract_points_serial(
        V, F, FN, VF_ptr, VF, face[1 : m - 1], inner_b, targets, max_iter, max_faces,
        eps_len, bary_eps, True,
    )  # fmt: skip
    out_f = face.copy()
    out_b = bary.copy()
    for i in range(m - 2):
        out_f[i + 1] = af[i]
        for c in range(3):
            out_b[i + 1, c] = ab[i, c]
    keep = np.ones(m, dtype=np.bool_)
    keep[0] = False
    keep[m - 1] = False
    revert_jumps(V, F, FN, VF_ptr, VF, out_f, out_b, face, bary, keep, max_gap, bary_eps)
    for i in range(m):
        if not keep[i]:
            out_f[i] = face[i]
            out_b[i] = bary[i]
    return out_f, out_b


@njit(cache=True, nogil=True)
def split_steps(pos, bad, a, b, kbest, inside):
    """Resampling positions with the broken steps split: after ``pos[bad[q]]`` come
    ``a[q] + (b[q] - a[q]) * j / k`` (j = 1 .. k - 1, k = ``kbest[q]``) or, where ``k`` is 0,
    the curve's own arc lengths ``inside`` strictly between ``a[q]`` and ``b[q]``.

    pos (n,) f8; bad (q,) i8 ascending; a, b (q,) f8; kbest (q,) i8; inside (p,) f8
    ascending. Returns ``(pos2 (n2,) f8, regular (n2,) bool)`` (False: inserted). Kernel of
    `meshfit.curves.resample_curve`.
    """
    n = pos.size
    extra = 0
    for q in range(bad.size):
        if kbest[q] > 0:
            extra += kbest[q] - 1
        else:
            lo = np.searchsorted(inside, a[q], side="right")
            hi = np.searchsorted(inside, b[q], side="left")
            extra += max(hi - lo, 0)
    pos2 = np.empty(n + extra)
    regular = np.zeros(n + extra, dtype=np.bool_)
    r = 0
    q = 0
    for i in range(n):
        pos2[r] = pos[i]
        regular[r] = True
        r += 1
        while q < bad.size and bad[q] == i:
            k = kbest[q]
            if k > 0:
                for j in range(1, k):
                    pos2[r] = a[q] + (b[q] - a[q]) * j / k
                    r += 1
            else:
                lo = np.searchsorted(inside, a[q], side="right")
                hi = np.searchsorted(inside, b[q], side="left")
                for t in range(lo, hi):
                    pos2[r] = inside[t]
                    r += 1
            q += 1
    return pos2, regular


@njit(cache=True, nogil=True)
def splice(face, bary, after, new_face, new_bary):
    """Face points with ``(new_face, new_bary)[e]`` inserted right after point ``after[e]``
    (ascending, in [0, m)), in order. face (m,) i8, bary (m, 3) f8 -> (m + k,) i8,
    (m + k, 3) f8. Used by `meshfit.curves.densify_curve`."""
    m = face.size
    k = new_face.size
    out_f = np.empty(m + k, dtype=np.int64)
    out_b = np.empty((m + k, 3))
    r = 0
    e = 0
    for i in range(m):
        out_f[r] = face[i]
        _copy3(bary[i], out_b[r])
        r += 1
        while e < k and after[e] == i:
            out_f[r] = new_face[e]
            _copy3(new_bary[e], out_b[r])
            r += 1
            e += 1
    return out_f, out_b


@njit(cache=True, nogil=True)
def chord_targets(V, F, face, bary):
    """The point of the chord from the first to the last of m face points (face (m,) i8,
    bary (m, 3) f8) at the same fraction of the polyline's length as each inner point;
    (m - 2, 3) f8 (all the first point when the length is 0). Used by
    `meshfit.curves.paint_curve`."""
    x = positions(V, F, face, bary)
    m = face.size
    arc = np.zeros(m)
    for i in range(1, m):
        d0 = x[i, 0] - x[i - 1, 0]
        d1 = x[i, 1] - x[i - 1, 1]
        d2 = x[i, 2] - x[i - 1, 2]
        arc[i] = arc[i - 1] + np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    total = arc[m - 1]
    out = np.empty((max(m - 2, 0), 3))
    for i in range(1, m - 1):
        t = arc[i] / total if total > 0 else 0.0
        for d in range(3):
            out[i - 1, d] = x[0, d] + t * (x[m - 1, d] - x[0, d])
    return out
