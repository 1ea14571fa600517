"""Slow oracles of the batched snake kernels (``_kernels.snakes``): one curve at a time
through the public single-curve functions."""

from __future__ import annotations

import numpy as np

from . import snake as single


def forces_many(x, start, levels, w_fair, w_curv, w_arc):
    out = np.zeros_like(x)
    for c in range(len(start) - 1):
        a, b = start[c], start[c + 1]
        out[a:b] = single.snake_forces(
            x[a:b], closed=False, w_fair=w_fair, w_curv=w_curv, w_arc=w_arc, levels=levels[c]
        )
    return out


def moves_many(x, force, nrm, fixed, start, gain, step, floor):
    """Tangent part of ``gain * force`` per point, capped at ``step`` times the mean of its
    adjacent segment lengths (at least the curve's ``floor``)."""
    out = np.zeros_like(x)
    for c in range(len(start) - 1):
        a, b = start[c], start[c + 1]
        for i in range(a, b):
            if fixed[i]:
                continue
            g = gain * force[i]
            t = g - (g @ nrm[i]) * nrm[i]
            segs = [np.linalg.norm(x[j] - x[i]) for j in (i - 1, i + 1) if a <= j < b]
            cap = step * max(np.mean(segs), floor[c])
            ln = np.linalg.norm(t)
            out[i] = t * (cap / ln) if ln > cap else t
    return out


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
    """The batched relaxation of `_kernels.snakes.relax_many` as one loop over all curves at
    once, each step a call of the vectorised kernels (forces, moves, walks, pair tests).

    Returns ``face``, ``bary`` and ``stats (k, 3)``: iterations the curve was active in,
    halved walks, reverted points.
    """
    from meshfit._kernels import snake as _ks
    from meshfit._kernels import snakes as _kb
    from meshfit._kernels import walk as _walk

    sizes = np.diff(start)
    k = len(sizes)
    owner = np.repeat(np.arange(k), sizes)
    face = np.array(face, dtype=np.int64)
    bary = np.array(bary, dtype=np.float64, order="C")
    ends = np.zeros(face.size, dtype=bool)
    ends[start[:-1]] = True
    ends[start[1:] - 1] = True
    inner_seg = np.ones(max(face.size - 1, 0), dtype=bool)
    inner_seg[start[1:-1] - 1] = False
    stats = np.zeros((k, 3), dtype=np.int64)

    def pairs(fc):
        return _ks.pairs_ok(F, fc, False) & inner_seg

    def walk(fc, bc, mv):
        f, b, ln, _, _ = _walk.walk_points(
            V, F, FN, fc, bc, np.ascontiguousarray(mv), max_faces, eps_len, bary_eps
        )
        return f, b, ln

    def step_all(fc, bc, mv):
        n = fc.shape[0]
        ok0 = pairs(fc)
        nf, nb, ln = walk(fc, bc, mv)
        mv = mv.copy()
        for _attempt in range(_kb.HALVINGS):
            bad = ok0 & ~pairs(nf)
            if not bad.any():
                return nf, nb, ln
            seg = np.flatnonzero(bad)
            pts = np.unique(np.concatenate([seg, seg + 1]))
            pts = pts[np.linalg.norm(mv[pts], axis=1) > 0]
            if pts.size == 0:
                break
            np.add.at(stats[:, 1], owner[pts], 1)
            mv[pts] *= 0.5
            f2, b2, l2 = walk(fc[pts], np.ascontiguousarray(bc[pts]), mv[pts])
            nf[pts], nb[pts], ln[pts] = f2, b2, l2
        while True:
            bad = ok0 & ~pairs(nf)
            if not bad.any():
                return nf, nb, ln
            seg = np.flatnonzero(bad)
            pts = np.unique(np.concatenate([seg, seg + 1]))
            pts = pts[pts < n]
            np.add.at(stats[:, 2], owner[pts], 1)
            nf[pts], nb[pts], ln[pts] = fc[pts], bc[pts], 0.0

    x = _ks.positions(V, F, face, bary)
    active = np.ones(k, dtype=bool)
    x_prev2 = None
    x_prev = x
    for _ in range(int(iterations)):
        stats[:, 0] += active
        fixed = ends | ~active[owner]
        force = _kb.forces_many(x, start, levels, 1.0, 0.0, 1.0)
        nrm = np.einsum("ij,ijk->ik", bary, VN[F[face]])
        nrm /= np.linalg.norm(nrm, axis=1)[:, None]
        move = _kb.moves_many(x, force, nrm, fixed, start, gain, step, floor)
        nf, nb, length = step_all(face, bary, move)
        free = ~fixed
        face = np.where(free, nf, face)
        bary = np.where(free[:, None], nb, bary)
        mm = _kb.curve_max(np.where(free, length, 0.0), start)
        has_free = np.bincount(owner, weights=free, minlength=k) > 0
        active &= has_free & (mm >= stop)
        x = _ks.positions(V, F, face, bary)
        if x_prev2 is not None:
            net = _kb.curve_max(np.linalg.norm(x - x_prev2, axis=1), start)
            active &= net >= stop
        if not active.any():
            break
        x_prev2, x_prev = x_prev, x
    return face, bary, stats
