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


@njit(cache=True, nogil=True)
def basis_local(tc, U, p, d):
    """Non-zero basis functions and derivatives (Piegl & Tiller A2.3) at clipped parameters.

    tc (n,) f8 inside the knot domain; U (k + p + 1,) f8 clamped knots; d <= p. Returns the
    first non-zero function (n,) i8 and values (n, d + 1, p + 1) f8; kernel of
    `bspline.basis.basis_local`, whose docstring has the conventions.
    """
    n = tc.shape[0]
    k = U.shape[0] - p - 1
    first = np.empty(n, dtype=np.int64)
    ders = np.zeros((n, d + 1, p + 1))
    ndu = np.zeros((p + 1, p + 1))
    left = np.zeros(p + 1)
    right = np.zeros(p + 1)
    a = np.zeros((2, p + 1))
    for i in range(n):
        t = tc[i]
        # the last knot <= t (searchsorted side="right" - 1), kept in [p, k - 1]
        lo, hi = 0, U.shape[0]
        while lo < hi:
            mid = (lo + hi) // 2
            if U[mid] <= t:
                lo = mid + 1
            else:
                hi = mid
        span = min(max(lo - 1, p), k - 1)
        first[i] = span - p
        ndu[:, :] = 0.0
        ndu[0, 0] = 1.0
        left[:] = 0.0
        right[:] = 0.0
        for j in range(1, p + 1):
            left[j] = t - U[span + 1 - j]
            right[j] = U[span + j] - t
            saved = 0.0
            for r in range(j):
                ndu[j, r] = right[r + 1] + left[j - r]
                temp = ndu[r, j - 1] / ndu[j, r]
                ndu[r, j] = saved + right[r + 1] * temp
                saved = left[j - r] * temp
            ndu[j, j] = saved
        for r in range(p + 1):
            ders[i, 0, r] = ndu[r, p]
        for r in range(p + 1):
            s1, s2 = 0, 1
            a[:, :] = 0.0
            a[0, 0] = 1.0
            for kk in range(1, d + 1):
                acc = 0.0
                rk, pk = r - kk, p - kk
                if r >= kk:
                    a[s2, 0] = a[s1, 0] / ndu[pk + 1, rk]
                    acc += a[s2, 0] * ndu[rk, pk]
                j1 = 1 if rk >= -1 else -rk
                j2 = kk - 1 if r - 1 <= pk else p - r
                for j in range(j1, j2 + 1):
                    a[s2, j] = (a[s1, j] - a[s1, j - 1]) / ndu[pk + 1, rk + j]
                    acc += a[s2, j] * ndu[rk + j, pk]
                if r <= pk:
                    a[s2, kk] = -a[s1, kk - 1] / ndu[pk + 1, r]
                    acc += a[s2, kk] * ndu[r, pk]
                ders[i, kk, r] = acc
                s1, s2 = s2, s1
        fac = float(p)
        for kk in range(1, d + 1):
            for r in range(p + 1):
                ders[i, kk, r] *= fac
            fac *= p - kk
    return first, ders
