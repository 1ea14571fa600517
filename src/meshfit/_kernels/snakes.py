"""Numba kernels of many open surface snakes relaxed together (``meshfit.layout.auto``).

The curves are stored one after another: curve ``c`` holds rows ``start[c]:start[c + 1]``.
Each kernel applies the single-curve kernel of :mod:`meshfit._kernels.snake` to every curve,
so the forces and moves are exactly those of :func:`meshfit.curves.relax_snake`.
`relax_many` runs the whole relaxation, one curve per thread. ``fastmath`` stays off: the
walks' sign tests and the pair test decide faces.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from meshfit._kernels import inner, split
from meshfit._kernels.snake import capped_moves, positions, snake_forces
from meshfit._kernels.walk import DONE, _copy3, _start_direction, _walk_one

#: times the moves of the points on a segment whose faces stop sharing a vertex are halved
#: before those points are put back
HALVINGS = 6


@inner
def _put_rows(out, a, rows):
    """out[a : a + len(rows)] = rows for (n, 3) arrays, element by element (an array slice
    assignment compiles numba's shape-mismatch error path into every first run)."""
    for r in range(rows.shape[0]):
        for c in range(3):
            out[a + r, c] = rows[r, c]


@njit(cache=True, nogil=True, fastmath=False)
def forces_many(x, start, levels, w_fair, w_curv, w_arc):
    """Snake forces of every open curve; x (n, 3) f8, start (k + 1,) i8, levels (k,) i8.

    Kernel of the batched relaxation in `meshfit.layout.auto`.
    """
    out = np.zeros_like(x)
    for c in range(start.shape[0] - 1):
        a = start[c]
        b = start[c + 1]
        _put_rows(out, a, snake_forces(x[a:b], False, w_fair, w_curv, w_arc, levels[c]))
    return out


@njit(cache=True, nogil=True, fastmath=False)
def moves_many(x, force, nrm, fixed, start, gain, step, floor):
    """Capped tangent moves of every open curve; x, force, nrm (n, 3) f8, fixed (n,) bool,
    start (k + 1,) i8, floor (k,) f8 -> (n, 3) f8.

    Kernel of the batched relaxation in `meshfit.layout.auto`.
    """
    out = np.zeros_like(x)
    for c in range(start.shape[0] - 1):
        a = start[c]
        b = start[c + 1]
        ids = np.arange(b - a)
        _put_rows(
            out,
            a,
            capped_moves(
                x[a:b], force[a:b], ids, nrm[a:b], fixed[a:b], False, gain, step, floor[c]
            ),
        )
    return out


@njit(cache=True, nogil=True, fastmath=False)
def curve_max(values, start):
    """Largest of ``values (n,) f8`` per curve (0 for an empty curve) -> (k,) f8."""
    k = start.shape[0] - 1
    out = np.zeros(k)
    for c in range(k):
        for i in range(start[c], start[c + 1]):
            if values[i] > out[c]:
                out[c] = values[i]
    return out


@inner
def _share_vertex(F, a, b):
    """Faces ``a`` and ``b`` share a vertex (the pair test of `snake.pairs_ok`)."""
    for p in range(3):
        for q in range(3):
            if F[a, p] == F[b, q]:
                return True
    return False


@inner
def _mark_broken(F, ok0, face, mark):
    """Mark both points of every segment that shared a vertex (``ok0``) and no longer does;
    face (m,) i8, ok0 (m - 1,) bool, mark (m,) bool -> number of broken segments."""
    mark[:] = False
    n = 0
    for s in range(ok0.shape[0]):
        if ok0[s] and not _share_vertex(F, face[s], face[s + 1]):
            mark[s] = True
            mark[s + 1] = True
            n += 1
    return n


@inner
def _walk_from(V, F, FN, f, b, step, out_b, u, max_faces, eps_len, bary_eps):
    """One point of `walk.walk_points`: ``(f, b (3,))`` walked by ``step (3,)``; the new
    barycentrics into ``out_b (3,)``, ``u (3,)`` scratch -> (face, walked length)."""
    out_b[0] = b[0]
    out_b[1] = b[1]
    out_b[2] = b[2]
    total = _start_direction(V, F, f, step, u)
    if total <= eps_len:
        return f, 0.0
    g, rest, status, _ = _walk_one(V, F, FN, f, out_b, u, total, max_faces, bary_eps)
    return g, (total - rest if status != DONE else total)


@inner
def _vertex_normals_at(VN, F, face, bary, out):
    """Unit interpolated vertex normals of face points into ``out (m, 3)``, summed and
    normalised in the order of ``einsum("ij,ijk->ik")`` and ``linalg.norm(axis=1)``."""
    for i in range(face.shape[0]):
        f = face[i]
        for d in range(3):
            acc = 0.0
            acc += bary[i, 0] * VN[F[f, 0], d]
            acc += bary[i, 1] * VN[F[f, 1], d]
            acc += bary[i, 2] * VN[F[f, 2], d]
            out[i, d] = acc
        s = np.sqrt(out[i, 0] * out[i, 0] + out[i, 1] * out[i, 1] + out[i, 2] * out[i, 2])
        out[i, 0] /= s
        out[i, 1] /= s
        out[i, 2] /= s


@inner
def _relax_curve(
    V,
    F,
    FN,
    VN,
    face,
    bary,
    levels,
    floor,
    gain,
    step,
    stop,
    iterations,
    max_faces,
    eps_len,
    bary_eps,
):
    """Relax one open curve with fixed ends in place; face (m,) i8, bary (m, 3) f8.

    Returns ``(iterations run, halved walks, reverted points)``.
    """
    m = face.shape[0]
    if m < 3:  # no free point: stops after its first iteration
        return min(iterations, 1), 0, 0
    ids = np.arange(m)
    fixed = np.zeros(m, dtype=np.bool_)
    fixed[0] = True
    fixed[m - 1] = True
    nrm = np.empty((m, 3))
    nf = np.empty(m, dtype=np.int64)
    nb = np.empty((m, 3))
    ln = np.empty(m)
    ok0 = np.empty(m - 1, dtype=np.bool_)
    mark = np.empty(m, dtype=np.bool_)
    u = np.empty(3)
    x = positions(V, F, face, bary)
    x_prev = x
    x_prev2 = x
    done = 0
    halved = 0
    reverted = 0
    for it in range(iterations):
        done += 1
        force = snake_forces(x, False, 1.0, 0.0, 1.0, levels)
        _vertex_normals_at(VN, F, face, bary, nrm)
        move = capped_moves(x, force, ids, nrm, fixed, False, gain, step, floor)
        # walk every point, then keep the segments' faces sharing a vertex: halve the moves
        # of the points on a segment that broke, at most HALVINGS times, then put them back
        for s in range(m - 1):
            ok0[s] = _share_vertex(F, face[s], face[s + 1])
        for p in range(m):
            nf[p], ln[p] = _walk_from(
                V, F, FN, face[p], bary[p], move[p], nb[p], u, max_faces, eps_len, bary_eps
            )
        settled = False
        for _attempt in range(HALVINGS):
            if _mark_broken(F, ok0, nf, mark) == 0:
                settled = True
                break
            n_half = 0
            for p in range(m):
                mp = move[p]
                if mark[p] and np.sqrt(mp[0] * mp[0] + mp[1] * mp[1] + mp[2] * mp[2]) > 0:
                    mp[0] *= 0.5
                    mp[1] *= 0.5
                    mp[2] *= 0.5
                    nf[p], ln[p] = _walk_from(
                        V, F, FN, face[p], bary[p], mp, nb[p], u, max_faces, eps_len, bary_eps
                    )
                    n_half += 1
            if n_half == 0:
                break
            halved += n_half
        if not settled:
            while _mark_broken(F, ok0, nf, mark) > 0:
                for p in range(m):
                    if mark[p]:
                        nf[p] = face[p]
                        _copy3(bary[p], nb[p])
                        ln[p] = 0.0
                        reverted += 1
        moved = 0.0
        for p in range(1, m - 1):
            face[p] = nf[p]
            _copy3(nb[p], bary[p])
            if ln[p] > moved:
                moved = ln[p]
        active = moved >= stop
        x_new = positions(V, F, face, bary)
        if it > 0:  # net move over two iterations
            net = 0.0
            for p in range(m):
                d0 = x_new[p, 0] - x_prev2[p, 0]
                d1 = x_new[p, 1] - x_prev2[p, 1]
                d2 = x_new[p, 2] - x_prev2[p, 2]
                d = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                if d > net:
                    net = d
            active = active and net >= stop
        if not active:
            break
        x_prev2 = x_prev
        x_prev = x_new
        x = x_new
    return done, halved, reverted


def relax_many(
    V,
    F,
    FN,
    VN,
    face,
    bary,
    start,
    levels,
    floor,
    gain,
    step,
    stop,
    iterations,
    max_faces,
    eps_len,
    bary_eps,
):
    """Relax every open curve as a snake with fixed ends; kernel of the batched relaxation in
    `meshfit.layout.auto`.

    V, VN (nv, 3) f8 vertices and unit vertex normals; F, FN (nf, 3) i8; face (n,) i8,
    bary (n, 3) f8 (non-negative) the curves' points; start (k + 1,) i8; levels (k,) i8
    force resolutions; floor (k,) f8 least spacing of the move cap. Per iteration and curve:
    forces (w_fair 1, w_curv 0, w_arc 1), tangent moves (``gain``, capped at ``step`` times
    the spacing), walks, the pair guard, then the stopping tests (longest walk and longest
    move over two iterations below ``stop``) -> face (n,) i8, bary (n, 3) f8,
    stats (k, 3) i8: iterations run, halved walks, reverted points. Curves on several
    threads, each curve's iterations on one.
    """
    out_face = face.copy()
    out_bary = bary.copy()
    stats = np.zeros((start.shape[0] - 1, 3), dtype=np.int64)
    args = (V, F, FN, VN, start, levels, floor, gain, step, stop, iterations, max_faces)
    split(relax_range, start.shape[0] - 1, *args, eps_len, bary_eps, out_face, out_bary, stats)
    return out_face, out_bary, stats


@njit(cache=True, nogil=True, fastmath=False)
def relax_range(
    V,
    F,
    FN,
    VN,
    start,
    levels,
    floor,
    gain,
    step,
    stop,
    iterations,
    max_faces,
    eps_len,
    bary_eps,
    out_face,
    out_bary,
    stats,
    c0,
    c1,
):
    """`relax_many` of curves ``c0`` to ``c1`` (exclusive), in place in their rows of
    ``out_face`` and ``out_bary``, their ``stats`` rows written."""
    for c in range(c0, c1):  # iteration c writes the rows of curve c only
        a = start[c]
        b = start[c + 1]
        it, hv, rv = _relax_curve(
            V,
            F,
            FN,
            VN,
            out_face[a:b],
            out_bary[a:b],
            levels[c],
            floor[c],
            gain,
            step,
            stop,
            iterations,
            max_faces,
            eps_len,
            bary_eps,
        )
        stats[c, 0] = it
        stats[c, 1] = hv
        stats[c, 2] = rv
