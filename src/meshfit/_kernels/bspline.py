"""Numba kernels of meshfit.bspline: banded tensor-product products, single-threaded.

The products are tiny (a 100 x 100 grid, 30 x 30 controls); serial loops over the four
non-zero basis functions per parameter avoid BLAS thread start-up, which costs tens of
milliseconds on a busy machine.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def gram_sandwich(fu, Nu, fv, Nv, X, mu, mv):
    """``B_u^T X B_v`` from banded bases; kernel of `bspline.fit_bspline`.

    fu (nu,) i8, Nu (nu, 4) f8; fv (nv,) i8, Nv (nv, 4) f8; X (nu, nv, 3) f8 -> (mu, mv, 3).
    """
    nu, nv = X.shape[0], X.shape[1]
    p1 = Nu.shape[1]
    # first along v: T[i, b] = sum_j X[i, j] Nv[j, b - fv[j]]
    T = np.zeros((nu, mv, 3))
    for i in range(nu):
        for j in range(nv):
            for b in range(p1):
                w = Nv[j, b]
                col = fv[j] + b
                for c in range(3):
                    T[i, col, c] += w * X[i, j, c]
    G = np.zeros((mu, mv, 3))
    for i in range(nu):
        for a in range(p1):
            w = Nu[i, a]
            row = fu[i] + a
            for b in range(mv):
                for c in range(3):
                    G[row, b, c] += w * T[i, b, c]
    return G


@njit(cache=True, nogil=True)
def grid_eval(fu, Nu, fv, Nv, P):
    """``B_u P B_v^T`` from banded bases; kernel of `BSplineSurface.evaluate_grid`.

    fu (nu,) i8, Nu (nu, 4) f8; fv (nv,) i8, Nv (nv, 4) f8; P (mu, mv, 3) f8 -> (nu, nv, 3).
    """
    nu, nv = fu.shape[0], fv.shape[0]
    mv = P.shape[1]
    p1 = Nu.shape[1]
    T = np.zeros((nu, mv, 3))
    for i in range(nu):
        for a in range(p1):
            w = Nu[i, a]
            row = fu[i] + a
            for b in range(mv):
                for c in range(3):
                    T[i, b, c] += w * P[row, b, c]
    out = np.zeros((nu, nv, 3))
    for i in range(nu):
        for j in range(nv):
            for b in range(p1):
                w = Nv[j, b]
                col = fv[j] + b
                for c in range(3):
                    out[i, j, c] += w * T[i, col, c]
    return out


@njit(cache=True, nogil=True)
def dense_sandwich(A, X, B):
    """``A X B^T`` per channel; kernel of `bspline.fit_bspline` and map resampling.

    A (a, n) f8; X (n, m, c) f8; B (b, m) f8 -> (a, b, c). Zero weights are skipped.
    """
    na, n = A.shape
    nb, m = B.shape
    nc = X.shape[2]
    T = np.zeros((na, m, nc))
    for r in range(na):
        for i in range(n):
            w = A[r, i]
            if w != 0.0:
                for j in range(m):
                    for c in range(nc):
                        T[r, j, c] += w * X[i, j, c]
    out = np.zeros((na, nb, nc))
    for r in range(na):
        for s in range(nb):
            for j in range(m):
                w = B[s, j]
                if w != 0.0:
                    for c in range(nc):
                        out[r, s, c] += w * T[r, j, c]
    return out


@njit(cache=True, nogil=True)
def qr_pinv(B):
    """Pseudo-inverse ``(m, n)`` of a full-rank ``B (n, m)``, n >= m, and ``(B^T B)^-1``.

    Gram-Schmidt QR with a second orthogonalisation pass (orthogonal to round-off), then
    ``R^-1 Q^T`` by back substitution; kernel of `bspline.fit_bspline`. No LAPACK call:
    LAPACK's thread start-up costs tens of ms on a busy machine.
    """
    n, m = B.shape
    Q = np.zeros((n, m))
    R = np.zeros((m, m))
    v = np.zeros(n)
    for k in range(m):
        for i in range(n):
            v[i] = B[i, k]
        for _pass in range(2):
            for j in range(k):
                r = 0.0
                for i in range(n):
                    r += Q[i, j] * v[i]
                R[j, k] += r
                for i in range(n):
                    v[i] -= r * Q[i, j]
        nv = 0.0
        for i in range(n):
            nv += v[i] * v[i]
        nv = np.sqrt(nv)
        R[k, k] = nv
        for i in range(n):
            Q[i, k] = v[i] / nv
    pinv = np.zeros((m, n))
    for col in range(n):
        for k in range(m - 1, -1, -1):
            s = Q[col, k]
            for j in range(k + 1, m):
                s -= R[k, j] * pinv[j, col]
            pinv[k, col] = s / R[k, k]
    gram_inv = np.zeros((m, m))
    for a in range(m):
        for b in range(a, m):
            s = 0.0
            for i in range(n):
                s += pinv[a, i] * pinv[b, i]
            gram_inv[a, b] = s
            gram_inv[b, a] = s
    return pinv, gram_inv
