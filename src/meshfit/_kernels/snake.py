"""Numba kernels of surface-snake relaxation (`meshfit.curves.snake`).

No validation here: the public wrappers check every input and pass contiguous arrays.
Conventions: ``V (nv, 3) f8`` vertices, ``F (nf, 3) i8`` faces, ``FNRM (nf, 3) f8`` unit face
normals; curve samples as ``face (n,) i8``, ``bary (n, 3) f8``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from meshfit._kernels import inner


@njit(cache=True, nogil=True, fastmath=False)
def positions(V, F, face, bary):
    """(n, 3) f8 positions of face points; kernel of `meshfit.curves.snake.relax_snake`."""
    n = face.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        f = face[i]
        for d in range(3):
            out[i, d] = (
                bary[i, 0] * V[F[f, 0], d] + bary[i, 1] * V[F[f, 1], d] + bary[i, 2] * V[F[f, 2], d]
            )
    return out


@inner
def _index(i, k, n, closed):
    j = i + k
    if closed:
        return j % n
    return j


@njit(cache=True, nogil=True, fastmath=False)
def snake_forces(x, closed, w_fair, w_curv, w_arc, levels):
    """Coarse-to-fine membrane + thin-plate + arc-length forces; x (n, 3) f8 -> (n, 3) f8.

    Kernel of `meshfit.curves.snake.snake_forces` (same definitions, per-sample loop).
    """
    n = x.shape[0]
    out = np.zeros((n, 3))
    if n < 3:
        return out
    fair = np.empty(3)
    arc = np.empty(3)
    curv = np.empty(3)
    for i in range(n):
        for c in range(3):
            fair[c] = 0.0
            arc[c] = 0.0
            curv[c] = 0.0
        wf = 0.0
        wc = 0.0
        w = 1.0
        k = 1
        for _lev in range(levels):
            if closed:
                ok1 = 2 * k < n
                ok2 = 4 * k < n
            else:
                ok1 = i - k >= 0 and i + k <= n - 1
                ok2 = i - 2 * k >= 0 and i + 2 * k <= n - 1
            if not ok1:  # coarser strides do not fit either
                break
            im = _index(i, -k, n, closed)
            ip = _index(i, k, n, closed)
            la = 0.0
            lb = 0.0
            for d in range(3):
                a = x[im, d] - x[i, d]
                b = x[ip, d] - x[i, d]
                la += a * a
                lb += b * b
                fair[d] += w * 0.5 * (a + b)
            la = np.sqrt(la)
            lb = np.sqrt(lb)
            if la > lb:
                s = 0.5 * (la - lb) / la
                for d in range(3):
                    arc[d] += w * s * (x[im, d] - x[i, d])
            elif lb > la:
                s = 0.5 * (lb - la) / lb
                for d in range(3):
                    arc[d] += w * s * (x[ip, d] - x[i, d])
            wf += w
            if w_curv != 0.0 and ok2:
                im2 = _index(i, -2 * k, n, closed)
                ip2 = _index(i, 2 * k, n, closed)
                for d in range(3):
                    curv[d] -= (
                        w
                        * (x[im2, d] - 4.0 * x[im, d] + 6.0 * x[i, d] - 4.0 * x[ip, d] + x[ip2, d])
                        / 8.0
                    )
                wc += w
            k *= 2
            w *= 0.5
        if wf > 0.0:
            for d in range(3):
                out[i, d] = (w_fair * fair[d] + w_arc * arc[d]) / wf
        if wc > 0.0:
            for d in range(3):
                out[i, d] += w_curv * curv[d] / wc
    return out


@njit(cache=True, nogil=True, fastmath=False)
def capped_moves(x, force, face, FNRM, fixed, closed, gain, step, floor):
    """Tangent part of ``gain * force``, capped at ``step`` times the local spacing.

    x, force (n, 3) f8; face (n,) i8; FNRM (nf, 3) f8; fixed (n,) bool -> (n, 3) f8.
    Kernel of `meshfit.curves.snake.relax_snake`.
    """
    n = x.shape[0]
    out = np.zeros((n, 3))
    for i in range(n):
        if fixed[i]:
            continue
        f = face[i]
        dn = 0.0
        for d in range(3):
            dn += gain * force[i, d] * FNRM[f, d]
        ln = 0.0
        for d in range(3):
            out[i, d] = gain * force[i, d] - dn * FNRM[f, d]
            ln += out[i, d] * out[i, d]
        ln = np.sqrt(ln)
        # local spacing: mean of the adjacent segments
        h = 0.0
        c = 0
        if closed or i > 0:
            j = (i - 1) % n
            h += np.sqrt(np.sum((x[j] - x[i]) ** 2))
            c += 1
        if closed or i < n - 1:
            j = (i + 1) % n
            h += np.sqrt(np.sum((x[j] - x[i]) ** 2))
            c += 1
        h = max(h / max(c, 1), floor)
        cap = step * h
        if ln > cap:
            for d in range(3):
                out[i, d] *= cap / ln
    return out


@njit(cache=True, nogil=True, fastmath=False)
def pairs_ok(F, face, closed):
    """Per segment: its two samples' faces share a vertex; face (n,) i8 -> (n or n-1,) bool."""
    n = face.shape[0]
    m = n if closed else n - 1
    out = np.zeros(max(m, 0), dtype=np.bool_)
    for s in range(m):
        a = face[s]
        b = face[(s + 1) % n]
        ok = False
        for p in range(3):
            for q in range(3):
                if F[a, p] == F[b, q]:
                    ok = True
        out[s] = ok
    return out
