"""Slow, obviously-correct oracles for `meshfit.curves`.

The B-spline basis here is the textbook Cox-de Boor recursion, one function value at a time,
with the convention 0 / 0 = 0; the right end of the domain belongs to the last non-empty
knot span (so the basis sums to one on the closed interval).
"""

from __future__ import annotations

import numpy as np


def _n(i: int, p: int, t: float, U: np.ndarray) -> float:
    if p == 0:
        last = U[-1]
        if U[i] <= t < U[i + 1]:
            return 1.0
        # t at the right end: the last span with U[i] < U[i + 1] holds it
        if t == last and U[i] < U[i + 1] == last:
            return 1.0
        return 0.0
    a = 0.0 if U[i + p] == U[i] else (t - U[i]) / (U[i + p] - U[i]) * _n(i, p - 1, t, U)
    b = (
        0.0
        if U[i + p + 1] == U[i + 1]
        else (U[i + p + 1] - t) / (U[i + p + 1] - U[i + 1]) * _n(i + 1, p - 1, t, U)
    )
    return a + b


def bspline_basis(t, knots, degree: int = 3) -> np.ndarray:
    """(n, k) matrix of B-spline basis values N_i,degree(t_j), k = len(knots) - degree - 1."""
    U = np.asarray(knots, dtype=float)
    k = U.size - degree - 1
    t = np.atleast_1d(np.asarray(t, dtype=float))
    return np.array([[_n(i, degree, float(tj), U) for i in range(k)] for tj in t])


def attract_chain(mesh, points, targets):
    """CurveAttract by continuation, one point at a time with the public ``attract_points``:
    point i starts from the nearer (to its target) of its own position and point i - 1's
    result. Returns ``(face (n,), bary (n, 3))``."""
    from meshfit.surface import attract_points
    from meshfit.types import SurfacePoints

    faces, barys = [], []
    for i in range(len(points)):
        start = points[i]
        if i > 0:
            prev = SurfacePoints(np.array([faces[-1]]), barys[-1][None])
            own = np.sum((targets[i] - mesh.xyz(start)[0]) ** 2)
            if np.sum((targets[i] - mesh.xyz(prev)[0]) ** 2) < own:
                start = prev
        end = attract_points(mesh, start, targets[i][None]).end
        faces.append(int(end.face[0]))
        barys.append(end.bary[0].copy())
    return np.array(faces), np.array(barys)


def _xyz(mesh, face, bary):
    c = mesh.vertices[mesh.faces[face]]
    return bary[:, 0, None] * c[:, 0] + bary[:, 1, None] * c[:, 1] + bary[:, 2, None] * c[:, 2]


def _pair_ok(mesh, fa, ba, fb, bb) -> bool:
    """Same or edge-adjacent faces, an edge point on both faces of its edge and a vertex
    point on every face around it (all representations tried)."""
    from meshfit.surface.walk import _representations

    for f, _ in _representations(mesh, int(fa), np.asarray(ba)):
        for g, _ in _representations(mesh, int(fb), np.asarray(bb)):
            if f == g or g in mesh.face_neighbors[f]:
                return True
    return False


def _graph_bridge(mesh, fa, ba, fb, bb):
    from meshfit.surface import greedy_path, path_to_surface_points

    V, F = mesh.vertices, mesh.faces
    xa = ba @ V[F[fa]]
    xb = bb @ V[F[fb]]
    va = int(F[fa][np.argmin(np.linalg.norm(V[F[fa]] - xb, axis=1))])
    vb = int(F[fb][np.argmin(np.linalg.norm(V[F[fb]] - xa, axis=1))])
    g = path_to_surface_points(mesh, greedy_path(mesh, va, vb).vertices, per_edge=1)
    return list(zip(g.face.tolist(), g.bary, strict=True))


def bridge(mesh, fa, ba, fb, bb, depth=0, max_depth=12):
    """Points to insert between face points a and b, one pair at a time and recursively:
    a walks halfway to b (public ``walk_points``) and is attracted to the 3-D midpoint
    (public ``attract_points``, 50 steps); both halves are bridged while the midpoint brings
    the ends closer (both halves under 0.8 of the gap), else a greedy graph path joins them.
    Returns a list of ``(face, bary)``."""
    from meshfit.surface import attract_points, walk_points
    from meshfit.types import SurfacePoints

    if _pair_ok(mesh, fa, ba, fb, bb):
        return []
    if depth >= max_depth:
        return _graph_bridge(mesh, fa, ba, fb, bb)
    xa = _xyz(mesh, np.array([fa]), np.asarray(ba)[None])[0]
    xb = _xyz(mesh, np.array([fb]), np.asarray(bb)[None])[0]
    gap = np.linalg.norm(xb - xa)
    start = SurfacePoints(np.array([fa]), np.asarray(ba, dtype=float)[None])
    half = walk_points(mesh, start, (0.5 * (xb - xa))[None]).end
    mid = attract_points(mesh, half, (0.5 * (xa + xb))[None], max_iter=50).end
    xm = mesh.xyz(mid)[0]
    if max(np.linalg.norm(xm - xa), np.linalg.norm(xb - xm)) >= 0.8 * gap:
        return _graph_bridge(mesh, fa, ba, fb, bb)
    fm, bm = int(mid.face[0]), mid.bary[0]
    return [
        *bridge(mesh, fa, ba, fm, bm, depth + 1, max_depth),
        (fm, bm),
        *bridge(mesh, fm, bm, fb, bb, depth + 1, max_depth),
    ]


def densify(mesh, curve):
    """Every consecutive pair of ``curve`` bridged by :func:`bridge`; returns ``(face (k,),
    bary (k, 3))`` of the whole densified curve."""
    p = curve.points
    m = len(p)
    faces, barys = [], []
    for i in range(m):
        faces.append(int(p.face[i]))
        barys.append(np.asarray(p.bary[i], dtype=float))
        if i == m - 1 and not curve.closed:
            break
        j = (i + 1) % m
        for f, b in bridge(mesh, int(p.face[i]), p.bary[i], int(p.face[j]), p.bary[j]):
            faces.append(int(f))
            barys.append(np.asarray(b, dtype=float))
    return np.array(faces, dtype=np.int64), np.array(barys)


def curve_pieces(mesh, points, closed: bool):
    """A face-point polyline as straight pieces, numpy throughout: returns ``(face (2n,),
    b0 (2n, 3), b1 (2n, 3), start (2n,), length (2n,), total)`` as
    `meshfit.surface.walk._curve_pieces`; segment i joins points i and i + 1."""
    from meshfit import tol
    from meshfit._kernels import curves as _curves
    from meshfit.surface.walk import _clean_bary

    m = len(points)
    P = np.arange(m if closed else m - 1)
    Q = (P + 1) % m
    pf = np.array(points.face[P], dtype=np.int64)
    qf = np.array(points.face[Q], dtype=np.int64)
    pb = _clean_bary(points.bary[P])
    qb = _clean_bary(points.bary[Q])
    FN = mesh.face_neighbors
    indptr, vf = mesh.vertex_faces
    via = np.empty(P.size, dtype=np.int64)
    bad = _curves.rewrite_pairs(
        np.ascontiguousarray(mesh.faces), np.ascontiguousarray(FN), indptr, vf, pf, pb, qf, qb,
        tol.BARY_EPS, via,
    )  # fmt: skip
    assert bad < 0, f"points {bad} and {bad + 1} share nothing"
    V, F = mesh.vertices, mesh.faces
    xp = np.einsum("ij,ijk->ik", pb, V[F[pf]])
    xq = np.einsum("ij,ijk->ik", qb, V[F[qf]])
    xf_b = qb.copy()
    xg_b = qb.copy()
    corner = np.flatnonzero(via >= 0)
    if corner.size:
        xf_b[corner] = 0.0
        xg_b[corner] = 0.0
        xf_b[corner, np.argmax(F[pf[corner]] == via[corner, None], axis=1)] = 1.0
        xg_b[corner, np.argmax(F[qf[corner]] == via[corner, None], axis=1)] = 1.0
    adj = np.flatnonzero((pf != qf) & (via < 0))
    if adj.size:
        f, g = pf[adj], qf[adj]
        k = np.argmax(FN[f] == g[:, None], axis=1)
        va = F[f, k]
        vc = F[f, (k + 1) % 3]
        a = V[va]
        e = V[vc] - a
        el = np.linalg.norm(e, axis=1)
        eh = e / el[:, None]
        dp = xp[adj] - a
        dq = xq[adj] - a
        along_p = np.einsum("ij,ij->i", dp, eh)
        along_q = np.einsum("ij,ij->i", dq, eh)
        h_p = np.linalg.norm(dp - along_p[:, None] * eh, axis=1)
        h_q = np.linalg.norm(dq - along_q[:, None] * eh, axis=1)
        hs = h_p + h_q
        t = np.divide(h_p, hs, out=np.ones_like(hs), where=hs > 0)
        mu = np.clip((along_p + t * (along_q - along_p)) / el, 0.0, 1.0)
        r = np.arange(adj.size)
        bf = np.zeros((adj.size, 3))
        bf[r, k] = 1.0 - mu
        bf[r, (k + 1) % 3] = mu
        slot_c = np.argmax(F[g] == vc[:, None], axis=1)
        slot_a = np.argmax(F[g] == va[:, None], axis=1)
        bg = np.zeros((adj.size, 3))
        bg[r, slot_a] = 1.0 - mu
        bg[r, slot_c] = mu
        xf_b[adj] = bf
        xg_b[adj] = bg
    xx = np.einsum("ij,ijk->ik", xf_b, V[F[pf]])
    face = np.stack([pf, qf], axis=1).reshape(-1)
    b0 = np.stack([pb, xg_b], axis=1).reshape(-1, 3)
    b1 = np.stack([xf_b, qb], axis=1).reshape(-1, 3)
    length = np.stack(
        [np.linalg.norm(xx - xp, axis=1), np.linalg.norm(xq - xx, axis=1)], axis=1
    ).reshape(-1)
    start = np.concatenate([[0.0], np.cumsum(length)])
    return face, b0, b1, start[:-1], length, float(start[-1])


def place_on_pieces(points, closed: bool, pieces, s):
    """Face points at arc lengths ``s`` on ``pieces`` (the tuple of :func:`curve_pieces`),
    one at a time: ``(face (k,), bary (k, 3), segment (k,))``."""
    face_p, b0, b1, start, length, total = pieces
    arc = np.append(start[0::2], total)
    m = len(points)
    faces, barys, segs = [], [], []
    for si in np.asarray(s, dtype=float):
        j = int(np.clip(np.searchsorted(start, si, side="right") - 1, 0, face_p.size - 1))
        t = (si - start[j]) / length[j] if length[j] > 0 else 1.0
        t = min(max(t, 0.0), 1.0)
        f, b, seg = int(face_p[j]), (1.0 - t) * b0[j] + t * b1[j], j // 2
        at = int(min(np.searchsorted(arc, si), arc.size - 1))
        if arc[at] == si:  # exactly on a curve point: that point
            at = at % m if closed else at
            f, b, seg = (
                int(points.face[at]),
                np.array(points.bary[at]),
                min(at, face_p.size // 2 - 1),
            )
        if (b < 0).any():
            b = np.clip(b, 0.0, None)
            b = b / b.sum()
        faces.append(f)
        barys.append(b)
        segs.append(seg)
    return np.array(faces, dtype=np.int64), np.array(barys), np.array(segs, dtype=np.int64)


def attract_uncut(mesh, face, bary, target, *, max_iter=200):
    """One point's attraction as `meshfit._kernels.walk._attract_one` does it, every
    walking step followed to its end (no early give-up), step by step in Python over the
    kernel's walking primitives (sums in the kernel's order). Returns ``(face, bary (3,),
    distance, iterations)``."""
    from meshfit import tol
    from meshfit._kernels import walk as K

    V = mesh.vertices
    F = np.ascontiguousarray(mesh.faces)
    FN = np.ascontiguousarray(mesh.face_neighbors)
    VFp, VF = mesh.vertex_faces
    eps_len = tol.length(mesh, tol.ATTRACT_EPS)

    def at(f, b):
        return b[0] * V[F[f, 0]] + b[1] * V[F[f, 1]] + b[2] * V[F[f, 2]]

    def norm(d):
        return float(np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]))

    f = int(face)
    b = np.array(bary, dtype=float)
    tgt = np.asarray(target, dtype=float)
    dist = norm(tgt - at(f, b))
    h = 1.0
    it = 0
    while it < max_iter:
        it += 1
        x = at(f, b)
        nrm = np.empty(3)
        K._face_normal(V, F, f, nrm)
        p = (tgt - x) * nrm
        off = p[0] + p[1] + p[2]
        step = h * (tgt - off * nrm - x)
        K._clip_at_boundary(V, F, FN, f, b, step, tol.BARY_EPS)
        moved = False
        if norm(step) >= eps_len:
            u = np.empty(3)
            total = K._start_direction(V, F, f, step, u)
            cb = b.copy()
            g, _, _, _ = K._walk_one(V, F, FN, f, cb, u, total, 10_000, tol.BARY_EPS)
            cand = norm(tgt - at(g, cb))
            if cand < dist:
                f, b, dist, h, moved = int(g), cb, cand, min(1.0, 2.0 * h), True
            else:
                h *= 0.5
        if not moved:
            f, dist, moved = K._descend(
                V, F, FN, VFp, VF, f, b, tgt, dist, np.empty(3), np.empty(3), np.empty(3)
            )
            f = int(f)
            if not moved:
                break
    K._clean_bary(b)
    return f, b, dist, it


def revert_jumps(mesh, face, bary, gface, gbary, keep, max_gap):
    """Where consecutive points jump (faces neither the same nor adjacent, as the sampling
    rule, and either sharing no vertex or more than ``max_gap`` apart) both go back to the
    graph samples ``(gface, gbary)``; the sweep steps back after each revert. Returns the
    final ``keep`` (n,) bool."""
    keep = np.array(keep, dtype=bool)
    F = mesh.faces

    def point(i):
        return (face[i], bary[i]) if keep[i] else (gface[i], gbary[i])

    i = 0
    while i < len(face) - 1:
        (f0, b0), (f1, b1) = point(i), point(i + 1)
        jump = False
        if not _pair_ok(mesh, f0, b0, f1, b1):
            share = bool(np.intersect1d(F[f0], F[f1]).size)
            gap = np.linalg.norm(_xyz(mesh, [f1], b1[None])[0] - _xyz(mesh, [f0], b0[None])[0])
            jump = not share or gap > max_gap
        if jump and (keep[i] or keep[i + 1]):
            keep[i] = keep[i + 1] = False
            i = max(i - 1, 0)
            continue
        i += 1
    return keep


def split_steps(pos, bad, a, b, kbest, inside):
    """Resampling positions with the broken steps split (numpy throughout): after
    ``pos[bad[q]]`` the k - 1 even split points of [a[q], b[q]] (k = kbest[q]), or where k is
    0 the values of ``inside`` strictly between a[q] and b[q]. Returns ``(pos2, regular)``."""
    counts = np.maximum(kbest - 1, 0)
    grp = np.repeat(np.arange(bad.size), counts)
    j = np.arange(grp.size) - np.repeat(np.cumsum(counts) - counts, counts) + 1
    extra = a[grp] + (b - a)[grp] * j / kbest[grp]
    at = bad[grp]
    none = np.flatnonzero(kbest == 0)
    lo = np.searchsorted(inside, a[none], side="right")
    hi = np.searchsorted(inside, b[none], side="left")
    n_own = np.maximum(hi - lo, 0)
    own = np.repeat(lo - (np.cumsum(n_own) - n_own), n_own) + np.arange(n_own.sum())
    extra = np.concatenate([extra, inside[own]])
    at = np.concatenate([at, np.repeat(bad[none], n_own)])
    order = np.argsort(at, kind="stable")
    where = at[order] + 1
    return (
        np.insert(pos, where, extra[order]),
        np.insert(np.ones(pos.size, dtype=bool), where, False),
    )


def chord_targets(mesh, points):
    """Chord points at the inner points' fractions of the polyline length (numpy)."""
    x = mesh.xyz(points)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(x, axis=0), axis=1))])
    m = len(points)
    t = (arc[1:-1] / arc[-1])[:, None] if arc[-1] > 0 else np.zeros((m - 2, 1))
    return x[0] + t * (x[-1] - x[0])
