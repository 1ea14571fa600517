"""Slow, obviously-correct oracles of the spring-mesh kernels (`meshfit._kernels.springs`)."""

from __future__ import annotations

import numpy as np

from meshfit.mesh import Mesh
from meshfit.surface import walk_points
from meshfit.types import SurfacePoints


def _dot(a, b) -> float:
    """Dot product of two short vectors summed in index order, as the kernels do (``a @ b``
    goes to BLAS, whose CPU-specific kernels may round differently)."""
    return float((np.asarray(a) * np.asarray(b)).sum())


def _norm(a) -> float:
    """Euclidean length of a short vector (see `_dot`)."""
    return float(np.sqrt(_dot(a, a)))


def spring_force(X, nv, p, w_arc, w_fair, nrm=None, N=None):
    """Eq. 5.1 (per direction: toward the farther neighbour by the length difference) and
    the fairness sum (sec. 5.5.2), both over 4; returns (force (3,), mean spring length).
    With a unit normal ``nrm`` every spring vector is first turned into its tangent plane,
    keeping its length. With the grid points' unit normals ``N``, a spring vector to a
    neighbour whose normal is at more than 90 degrees to ``nrm`` (the other neighbour on the
    line's not) points away from that other neighbour instead, keeping its length."""

    def vec(q):
        d = X[q] - X[p]
        if nrm is None:
            return d
        t = d - _dot(d, nrm) * nrm
        n = _norm(t)
        return t * (_norm(d) / n) if n > 0 else t

    def along(q, r):
        """The spring vector to q across a fold: away from r, with q's length."""
        fq, fr = vec(q), vec(r)
        return -fr * (_norm(fq) / _norm(fr)) if _norm(fr) > 0 else fq

    def line(a, b):
        if N is not None and nrm is not None:
            ca, cb = _dot(N[a], nrm), _dot(N[b], nrm)
            if ca < 0.0 <= cb:
                return along(a, b), vec(b)
            if cb < 0.0 <= ca:
                return vec(a), along(b, a)
        return vec(a), vec(b)

    arc = np.zeros(3)
    lengths = []
    vecs = []
    for a, b in ((p - nv, p + nv), (p - 1, p + 1)):
        fa, fb = line(a, b)
        vecs += [fa, fb]
        la, lb = _norm(fa), _norm(fb)
        lengths += [la, lb]
        if la > lb:
            arc += (la - lb) * fa / la
        elif lb > la:
            arc += (lb - la) * fb / lb
    fair = vecs[0] + vecs[1] + vecs[2] + vecs[3]
    return 0.25 * (w_fair * fair + w_arc * arc), float(np.mean(lengths))


def _walk_inside(mesh: Mesh, f, b, vec, tries=6):
    """Walk by ``vec`` (in the face plane); undo and halve when the walk reaches the boundary."""
    for _ in range(tries + 1):
        res = walk_points(mesh, SurfacePoints(np.array([f]), b[None]), vec[None])
        if not res.hit_boundary[0]:
            return int(res.end.face[0]), res.end.bary[0].copy(), _norm(vec)
        vec = 0.5 * vec
    return f, b.copy(), 0.0


def _bad_around(X, N, nu, nv, p):
    """Triangles of the (up to four) cells around grid point p that face against the summed
    normals at their corners."""
    i, j = divmod(p, nv)
    bad = 0
    for ci in (i - 1, i):
        for cj in (j - 1, j):
            if 0 <= ci < nu - 1 and 0 <= cj < nv - 1:
                a, b = ci * nv + cj, (ci + 1) * nv + cj
                c, d = b + 1, a + 1
                for t in ((a, b, c), (a, c, d)):
                    n = np.cross(X[t[1]] - X[t[0]], X[t[2]] - X[t[0]])
                    bad += int(_dot(n, N[list(t)].sum(axis=0)) <= 0)
    return bad


def relax_sweeps(
    mesh: Mesh,
    face,
    bary,
    nu,
    nv,
    movable,
    tangent,
    guard,
    alpha,
    prev,
    n_sweeps,
    it0,
    ramp,
    w_fair_end,
    omega,
    eps_rel,
    lazy=0.0,
    fold=False,
):
    """Gauss-Seidel sweeps as documented in the kernel, one point at a time in Python."""
    face = face.copy()
    bary = bary.copy()
    alpha = alpha.copy()
    prev = prev.copy()
    X = mesh.xyz(SurfacePoints(face, bary))
    N = mesh.face_normals[face].copy()
    done, worst, rms = 0, 0.0, 0.0
    size = nu * nv
    active = set(range(size))  # the points to move in this sweep (all, without lazy)
    for k in range(n_sweeps):
        moving = set()  # points that moved, and their neighbours: the next sweep's
        it = it0 + k
        t = min(1.0, it / ramp) if ramp > 0 else 1.0
        w_fair = w_fair_end * t
        order = range(nu * nv) if it % 2 == 0 else range(nu * nv - 1, -1, -1)
        moves = []
        for p in order:
            if not movable[p]:
                continue
            if lazy > 0 and p not in active:
                moves.append(0.0)  # settled
                continue
            n = mesh.face_normals[face[p]]
            force, h = spring_force(
                X, nv, p, 1.0 - w_fair, w_fair, n if tangent else None, N if fold else None
            )
            step = force - _dot(force, n) * n
            total = _norm(step)
            if total <= 0:
                continue
            turn = _dot(step / total, prev[p])
            alpha[p] = alpha[p] * 0.5 if turn < 0 else min(1.0, alpha[p] * 1.25)
            step = step * omega * alpha[p]
            before = _bad_around(X, N, nu, nv, p)
            f0, b0, x0, n0 = face[p], bary[p].copy(), X[p].copy(), N[p].copy()
            for attempt in range(4):
                f, b, moved = _walk_inside(mesh, f0, b0.copy(), step / 2.0**attempt)
                fn = mesh.face_neighbors[f]
                if moved == 0 and any(fn[e] < 0 and b[(e + 2) % 3] <= 1e-12 for e in range(3)):
                    b = 0.99 * b + 0.01 / 3  # stuck on the boundary: step off it
                face[p], bary[p] = f, b
                X[p] = mesh.xyz(SurfacePoints(face[p : p + 1], bary[p : p + 1]))[0]
                N[p] = mesh.face_normals[f]
                if not guard or _bad_around(X, N, nu, nv, p) <= before:
                    break
                if attempt == 3:  # every try folds a cell: stay
                    face[p], bary[p], X[p], N[p], moved = f0, b0, x0, n0, 0.0
            prev[p] = X[p] - x0
            moves.append(moved / h)
            if h > 0 and moved > lazy * h:
                near = {r for r in (p, p - 1, p + 1, p - nv, p + nv) if 0 <= r < size}
                moving |= near
                active |= near  # those still ahead in this sweep move in it too
        if lazy > 0:
            active = moving
        done = k + 1
        worst = max(moves) if moves else 0.0
        rms = float(np.sqrt(np.mean(np.square(moves)))) if moves else 0.0
        if it + 1 >= ramp and rms < eps_rel:
            break
    return face, bary, done, worst, rms


def _greedy_mid(mesh: Mesh, v1, v2, max_steps):
    if v1 == v2:
        return v1
    V = mesh.vertices
    path = [v1]
    while path[-1] != v2:
        if len(path) > max_steps:
            return -1
        cur = path[-1]
        nbrs = mesh.vertex_neighbors(cur)
        d = np.sum((V[nbrs] - V[v2]) ** 2, axis=1)
        k = int(np.argmin(d))
        if d[k] >= np.sum((V[cur] - V[v2]) ** 2):
            return -1
        path.append(int(nbrs[k]))
    seg = np.linalg.norm(np.diff(V[path], axis=0), axis=1)
    acc = np.concatenate([[0.0], np.cumsum(seg)])
    half = 0.5 * acc[-1]
    k = int(np.searchsorted(acc, half))  # first vertex at or past half the length
    return path[k - 1] if half - acc[k - 1] < acc[k] - half else path[k]


def find_midpoints(mesh: Mesh, a: SurfacePoints, b: SurfacePoints, n_fair, max_steps, on_boundary):
    """FindMidPoint (sec. 5.6): greedy path mid vertex, then local fairness walks."""
    xa, xb = mesh.xyz(a), mesh.xyz(b)
    out_f = np.empty(len(a), dtype=np.int64)
    out_b = np.empty((len(a), 3))
    indptr, vf = mesh.vertex_faces
    for i in range(len(a)):
        v1 = int(mesh.faces[a.face[i], np.argmax(a.bary[i])])
        v2 = int(mesh.faces[b.face[i], np.argmax(b.bary[i])])
        mid = _greedy_mid(mesh, v1, v2, max_steps)
        if mid >= 0 and mid not in (v1, v2) and not on_boundary[mid]:
            fan = vf[indptr[mid] : indptr[mid + 1]]
            cen = mesh.vertices[mesh.faces[fan]].mean(axis=1)
            f = int(fan[np.argmin(np.sum((cen - 0.5 * (xa[i] + xb[i])) ** 2, axis=1))])
            bb = (mesh.faces[f] == mid).astype(float)
        else:
            fn = mesh.face_neighbors
            on_edge = any(
                fn[a.face[i], k] < 0 and a.bary[i, (k + 2) % 3] <= 1e-12 for k in range(3)
            )
            if not on_edge:
                f, bb, step = int(a.face[i]), a.bary[i].copy(), 0.5 * (xb[i] - xa[i])
            else:
                f, bb, step = int(b.face[i]), b.bary[i].copy(), 0.5 * (xa[i] - xb[i])
            n = mesh.face_normals[f]
            step = step - _dot(step, n) * n
            if _norm(step) > 0:
                f, bb, _ = _walk_inside(mesh, f, bb, step)
        for _ in range(n_fair):
            x = mesh.xyz(SurfacePoints(np.array([f]), bb[None]))[0]
            n = mesh.face_normals[f]
            step = 0.5 * (xa[i] + xb[i]) - x
            step = step - _dot(step, n) * n
            if _norm(step) <= 0:
                break
            f, bb, _ = _walk_inside(mesh, f, bb, step)
        out_f[i], out_b[i] = f, bb
    return out_f, out_b


def locate_uv(uv, F, q):
    """Point location in a planar triangulation by testing every face: the face in which
    each query is most inside (largest smallest barycentric), barycentrics clamped to >= 0
    and renormalised."""
    face = np.zeros(len(q), dtype=np.int64)
    bary = np.zeros((len(q), 3))
    for k, p in enumerate(np.clip(q, 0.0, 1.0)):
        best = -np.inf
        for f, (a, b, c) in enumerate(F):
            M = np.column_stack([uv[b] - uv[a], uv[c] - uv[a]])
            if abs(np.linalg.det(M)) == 0:
                continue
            s, r = np.linalg.solve(M, p - uv[a])
            w = np.array([1 - s - r, s, r])
            if w.min() > best:
                best, face[k], bary[k] = w.min(), f, w
        bary[k] = np.maximum(bary[k], 0.0)
        bary[k] /= bary[k].sum()
    return face, bary


def _fold_score(X, N, nu, nv, p, margin):
    """Folded triangles of the cells around p and the shortfall of their normals' cosines
    from ``margin``."""
    i, j = divmod(p, nv)
    bad, short = 0, 0.0
    for ci in (i - 1, i):
        for cj in (j - 1, j):
            if 0 <= ci < nu - 1 and 0 <= cj < nv - 1:
                a, b = ci * nv + cj, (ci + 1) * nv + cj
                c, d = b + 1, a + 1
                for t in ((a, b, c), (a, c, d)):
                    n = np.cross(X[t[1]] - X[t[0]], X[t[2]] - X[t[0]])
                    s = N[list(t)].sum(axis=0)
                    bad += int(_dot(n, s) <= 0)
                    den = _norm(n) * _norm(s)
                    cos = _dot(n, s) / den if den > 0 else -1.0
                    short += max(0.0, margin - cos)
    return bad, short


def repair_folds(mesh: Mesh, face, bary, nu, nv, movable, rounds, n_dirs, margin):
    """Fold repair as documented in the kernel: every movable corner of a folded cell tries
    the centroid of its neighbours (all and half the way) and ``n_dirs`` tangent directions
    at 0.15, 0.35 and 0.7 of its mean spring length; keeps the lexicographically best of
    (folded triangles, shortfall, move length) if it beats staying."""
    face, bary = face.copy(), bary.copy()
    X = mesh.xyz(SurfacePoints(face, bary))
    N = mesh.face_normals[face].copy()
    for _ in range(rounds):
        left, changed = 0, False
        for p in range(nu * nv):
            if not movable[p]:
                continue
            bad0, short0 = _fold_score(X, N, nu, nv, p, margin)
            if bad0 == 0:
                continue
            f0, b0, x0 = face[p], bary[p].copy(), X[p].copy()
            nbrs = X[[p - nv, p + nv, p - 1, p + 1]]
            h = np.linalg.norm(nbrs - x0, axis=1).mean()
            n = mesh.face_normals[f0]
            e1 = X[p + nv] - X[p - nv]
            e1 = e1 - _dot(e1, n) * n
            if _norm(e1) <= 0 or h <= 0:
                continue
            e1 /= _norm(e1)
            e2 = np.cross(n, e1)
            steps = [0.25 * (nbrs.sum(axis=0) - 4 * x0), 0.125 * (nbrs.sum(axis=0) - 4 * x0)]
            for r in (0.15, 0.35, 0.7):
                for d in range(n_dirs):
                    a = 2 * np.pi * d / n_dirs
                    steps.append(r * h * (np.cos(a) * e1 + np.sin(a) * e2))
            best = (bad0, short0, 0.0, f0, b0)
            for step in steps:
                step = step - _dot(step, n) * n
                if _norm(step) <= 0:
                    continue
                f, b, moved = _walk_inside(mesh, f0, b0.copy(), step, tries=2)
                if moved == 0:
                    continue
                X[p] = mesh.xyz(SurfacePoints(np.array([f]), b[None]))[0]
                N[p] = mesh.face_normals[f]
                bad, short = _fold_score(X, N, nu, nv, p, margin)
                fewer = short < best[1] - 1e-12 or (short <= best[1] and moved < best[2])
                if bad < best[0] or (bad == best[0] and fewer):
                    best = (bad, short, moved, f, b)
            face[p], bary[p] = best[3], best[4]
            X[p] = mesh.xyz(SurfacePoints(face[p : p + 1], bary[p : p + 1]))[0]
            N[p] = mesh.face_normals[face[p]]
            changed |= best[3] != f0 or best[2] > 0
            left += best[0]
        if left == 0 or not changed:
            break
    return face, bary


def chord_positions(xyz, arc, breaks, counts, rounds):
    """Slow reference of `meshfit.springs.state.chord_positions` (numpy rounds)."""
    from meshfit.springs.state import section_positions

    pos = section_positions(breaks, counts)
    ends = np.cumsum([0, *counts])
    free = np.ones(len(pos), dtype=bool)
    free[ends] = False
    if not free.any():
        return pos
    k = np.flatnonzero(free)
    seg = np.diff(arc)
    last = len(arc) - 2
    for _ in range(rounds):
        e = np.clip(np.searchsorted(arc, pos, side="right") - 1, 0, last)
        t = np.where(seg[e] > 0, (pos - arc[e]) / np.where(seg[e] > 0, seg[e], 1.0), 0.0)
        P = xyz[e] + t[:, None] * (xyz[e + 1] - xyz[e])
        d = P[1:] - P[:-1]
        c = np.sqrt(np.einsum("ij,ij->i", d, d))
        ca, cb = c[k - 1], c[k]
        span = pos[k + 1] - pos[k - 1]
        step = 0.5 * (cb - ca) * span / np.maximum(ca + cb, 1e-300)
        pos[k] = np.clip(pos[k] + 0.5 * step, pos[k - 1], pos[k + 1])
    return pos


def chain_points(arc, ef, ea, eb, positions):
    """Face points at arc lengths along a boundary chain (numpy, all at once)."""
    positions = np.clip(np.asarray(positions, dtype=np.float64), 0.0, arc[-1])
    k = np.clip(np.searchsorted(arc, positions, side="right") - 1, 0, len(arc) - 2)
    seg = arc[k + 1] - arc[k]
    t = np.where(seg > 0, (positions - arc[k]) / np.where(seg > 0, seg, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    bary = np.zeros((len(positions), 3))
    rows = np.arange(len(positions))
    bary[rows, ea[k]] = 1.0 - t
    bary[rows, eb[k]] += t
    return ef[k], bary


def spacing(X, u_lines=(), v_lines=()):
    """Coefficients of variation of the spacing per iso-curve piece (u pieces first) and the
    cells' aspect ratios of a grid X (nu, nv, 3), with numpy."""
    nu, nv = X.shape[:2]

    def pieces(n, lines):
        ends = [0, *[int(x) for x in lines], n - 1]
        return [(ends[k], ends[k + 1]) for k in range(len(ends) - 1)]

    du = np.linalg.norm(np.diff(X, axis=0), axis=2)
    dv = np.linalg.norm(np.diff(X, axis=1), axis=2)
    cvs = []
    for a, b in pieces(nu, u_lines):
        m = du[a:b].mean(axis=0)
        cvs.append(np.where(m > 0, du[a:b].std(axis=0) / np.where(m > 0, m, 1.0), 0.0))
    for a, b in pieces(nv, v_lines):
        m = dv[:, a:b].mean(axis=1)
        cvs.append(np.where(m > 0, dv[:, a:b].std(axis=1) / np.where(m > 0, m, 1.0), 0.0))
    a_len = 0.5 * (du[:, :-1] + du[:, 1:])
    b_len = 0.5 * (dv[:-1, :] + dv[1:, :])
    lo = np.minimum(a_len, b_len)
    with np.errstate(invalid="ignore", divide="ignore"):
        aspect = np.maximum(a_len, b_len) / np.where(lo > 0, lo, np.nan)
    return np.concatenate(cvs), np.where(np.isfinite(aspect), aspect, np.inf)


def pinched_side_points(V, F, face, bary, nu, nv, ratio):
    """(side, place) of the side points whose shorter chord to a neighbour on their side is
    below ratio times the side's median chord (sides bottom, top, left, right)."""
    X = np.einsum("ij,ijk->ik", bary, V[F[face]]).reshape(nu, nv, 3)
    out = []
    for side, pts in enumerate((X[:, 0], X[:, -1], X[0, :], X[-1, :])):
        d = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        short = np.minimum(d[:-1], d[1:]) < ratio * np.median(d)
        out += [(side, int(k) + 1) for k in np.flatnonzero(short)]
    return np.array(out, dtype=np.int64).reshape(-1, 2)


def red_black_mean(uv, ii, jj, sweeps):
    """Red-black Gauss-Seidel sweeps of the four-neighbour mean at the listed points."""
    uv = uv.copy()
    red = (ii + jj) % 2 == 0
    for _ in range(sweeps):
        for a, b in ((ii[red], jj[red]), (ii[~red], jj[~red])):
            uv[a, b] = 0.25 * (uv[a - 1, b] + uv[a + 1, b] + uv[a, b - 1] + uv[a, b + 1])
    return uv


def line_spacing(V, F, face, bary, nu, nv, u_lines, v_lines):
    """Largest spacing CV per grid column and row over its sections, median aspect ratio."""
    X = np.einsum("ij,ijk->ik", bary, V[F[face]]).reshape(nu, nv, 3)
    cv, aspect = spacing(X, u_lines, v_lines)
    n_u = (len(u_lines) + 1) * nv
    return (
        cv[:n_u].reshape(-1, nv).max(axis=0),
        cv[n_u:].reshape(-1, nu).max(axis=0),
        np.median(aspect),
    )


def maxmin_point(A, m, px, py, h):
    """The largest least value of ``A[:m] @ (x, y, 1)`` over the box ``|x - px|, |y - py| <= h``,
    by SciPy's linear programming (HiGHS); -> the optimal value."""
    from scipy.optimize import linprog

    A = np.asarray(A, dtype=float)[:m]
    res = linprog(
        [0.0, 0.0, -1.0],
        A_ub=np.column_stack([-A[:, 0], -A[:, 1], np.ones(m)]),
        b_ub=A[:, 2],
        bounds=[(px - h, px + h), (py - h, py + h), (None, None)],
        method="highs",
    )
    assert res.status == 0, res.message
    return -res.fun


def chart_least_area(Y, nu, nv, var):
    """Least twice-signed area of the triangles (a b c), (a c d) of the cells with a corner in
    ``var`` (a = (i, j), b = (i + 1, j), c = (i + 1, j + 1), d = (i, j + 1))."""
    G = np.asarray(Y, dtype=float).reshape(nu, nv, 2)
    V = np.asarray(var, dtype=bool).reshape(nu, nv)
    out = np.inf
    for i in range(nu - 1):
        for j in range(nv - 1):
            if not V[i : i + 2, j : j + 2].any():
                continue
            a, b, c, d = G[i, j], G[i + 1, j], G[i + 1, j + 1], G[i, j + 1]
            for p, q, r in ((a, b, c), (a, c, d)):
                u, w = q - p, r - p
                out = min(out, u[0] * w[1] - u[1] * w[0])
    return out


def window_trials(mesh: Mesh, face, bary, rows, cols, at, t_face, t_bary):
    """Folded cells and shortest neighbour chord of a window of grid face points as it is
    and with the points ``at`` put at each trial's face points, one trial at a time."""
    from meshfit.springs import grid_metrics

    folds, short = [], []
    for t in range(len(t_face) + 1):
        f, b = np.array(face), np.array(bary)
        if t > 0:
            f[at], b[at] = t_face[t - 1], t_bary[t - 1]
        X = mesh.xyz(SurfacePoints(f, b)).reshape(rows, cols, 3)
        N = mesh.face_normals[f].reshape(rows, cols, 3)
        folds.append(grid_metrics(mesh, X, N, fidelity=False)["folded"])
        du = np.linalg.norm(np.diff(X, axis=0), axis=2)
        dv = np.linalg.norm(np.diff(X, axis=1), axis=2)
        short.append(min(du.min(initial=np.inf), dv.min(initial=np.inf)))
    return np.array(folds), np.array(short)
