"""Slow, obviously correct oracle of the half-edge collapse pass (``_kernels.decimate``)."""

from __future__ import annotations

import numpy as np


def _normal(V, tri):
    a, b, c = V[list(tri)]
    return np.cross(b - a, c - a)


def _quality(V, tri):
    a, b, c = V[list(tri)]
    s = sum(float(np.dot(q - p, q - p)) for p, q in ((a, b), (b, c), (c, a)))
    return 0.0 if s <= 0 else 2.0 * np.sqrt(3.0) * float(np.linalg.norm(_normal(V, tri))) / s


def collapse_pass(
    V, F, alive, frozen, max_collapses, max_valence, min_cos, min_quality, max_sq=np.inf
):
    """Same rules as the kernel, on Python sets and lists; returns (F, alive, count)."""
    F = [list(f) for f in np.asarray(F)]
    alive = list(np.asarray(alive))
    nv = len(V)
    star = {v: [] for v in range(nv)}
    for f, tri in enumerate(F):
        if alive[f]:
            for v in tri:
                star[v].append(f)

    def ring(v):
        return {w for f in star[v] for w in F[f] if w != v}

    def elen(a, b):
        return float(np.sum((V[b] - V[a]) ** 2))

    short = np.full(nv, np.inf)
    for f, tri in enumerate(F):
        if alive[f]:
            for k in range(3):
                a, b = tri[k], tri[(k + 1) % 3]
                short[a] = min(short[a], elen(a, b))
                short[b] = min(short[b], elen(a, b))
    valence = {v: len(star[v]) for v in range(nv)}
    order = np.argsort(short, kind="mergesort")
    locked = set()
    done = 0
    for v in order.tolist():
        if done >= max_collapses:
            break
        if short[v] > max_sq:
            break
        if v in locked or frozen[v] or not np.isfinite(short[v]) or len(star[v]) > 64:
            continue
        nbv = ring(v)
        if len(nbv) < 3:
            continue
        # neighbours by distance, ties in the order the kernel meets them (stable)
        seen = []
        for f in star[v]:
            for w in F[f]:
                if w != v and w not in seen:
                    seen.append(w)
        cands = sorted(seen, key=lambda w: elen(v, w))
        for u in cands:
            if u in locked or len(star[u]) > 64:
                continue
            nbu = ring(u)
            common = sorted(nbv & nbu)
            if len(common) != 2:
                continue
            if frozen[u] and any(frozen[w] and w != u and w not in common for w in nbv):
                continue
            if len(nbu) + len(nbv) - 4 > max_valence:
                continue
            if any(valence[o] - 1 < 3 for o in common):
                continue
            ok = True
            for f in star[v]:
                tri = F[f]
                if u in tri:
                    continue
                new = [u if w == v else w for w in tri]
                no, nn = _normal(V, tri), _normal(V, new)
                if np.linalg.norm(nn) <= 0 or np.linalg.norm(no) <= 0:
                    ok = False
                    break
                if float(no @ nn) < min_cos * np.linalg.norm(no) * np.linalg.norm(nn):
                    ok = False
                    break
                q = _quality(V, new)
                if q < min_quality and q < _quality(V, tri):
                    ok = False
                    break
            if not ok:
                continue
            for f in star[v]:
                if u in F[f]:
                    alive[f] = False
                else:
                    F[f] = [u if w == v else w for w in F[f]]
            for o in common:
                valence[o] -= 1
            valence[u] = len(nbu) + len(nbv) - 4
            valence[v] = 0
            locked |= {v, u} | nbv
            done += 1
            break
    return np.asarray(F, dtype=np.int64), np.asarray(alive, dtype=bool), done


def compact(V, F, alive, kept):
    """The alive faces and the vertices they use, in their order (numpy indexing)."""
    F = F[alive]
    used = np.unique(F.reshape(-1))
    remap = np.full(len(V), -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    return V[used], remap[F], kept[used]


def face_cells(V, F, lo, scale, bits):
    """Morton codes of the faces' centroid cells, with numpy: centroids, cells, bits."""
    c = V[F.reshape(-1)].reshape(-1, 3, 3).mean(axis=1)
    q = np.clip(((c - lo) * scale).astype(np.int64), 0, (1 << bits) - 1)
    code = np.zeros(len(F), dtype=np.int64)
    for k in range(bits):
        for axis in range(3):
            code |= ((q[:, axis] >> k) & 1) << (3 * k + axis)
    return code


def survey_bricks(V, bricks, n_vertices):
    """Per brick in turn: vertices used by an earlier brick are shared; each brick's area."""
    first = np.full(n_vertices, -1)
    shared = np.zeros(n_vertices, dtype=bool)
    areas = []
    for b, faces in enumerate(bricks):
        used = np.unique(faces)
        seen = first[used] >= 0
        shared[used[seen]] = True
        first[used[~seen]] = b
        x = V[faces]
        areas.append(
            0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1).sum()
        )
    return shared, np.array(areas)
