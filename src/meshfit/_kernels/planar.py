"""Numba kernels of the planar (mean-value) map: the interior system and its multigrid solve.

No validation here: :mod:`meshfit.springs.planar` passes contiguous arrays. Sparse matrices are
CSR triples ``indptr (m + 1,) i8, indices (nnz,) i8, data (nnz,) f8`` with sorted, unique
columns in each row. Right-hand sides and solutions carry both map coordinates: ``(m, 2) f8``.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def mean_value_system(V, F, at, uv, floor, eps, scale):
    """Interior mean-value system of `springs.planar.square_map`.

    V (n, 3) f8; F (nf, 3) i8; at (n,) i8 (row of a free vertex, -1 for a fixed one);
    uv (n, 2) f8 (fixed vertices' parameters); floor (shortest edge length used), eps
    (smallest ``tan(theta / 2)``); scale (n,) f8 (each weight ``w_ij`` is multiplied by
    ``scale[j]``) -> indptr, indices, data (CSR, m x m), rhs (m, 2) f8.
    Row ``at[i]``: ``sum_j w_ij (x_i - x_j) = 0`` with ``w_ij`` the mean-value weights summed
    over the faces at edge ``ij``, fixed ``x_j`` moved to the right-hand side.
    """
    n = V.shape[0]
    nf = F.shape[0]
    m = 0
    for i in range(n):
        if at[i] >= 0:
            m += 1
    # weights per face corner: (i, j) and (i, k)
    er = np.empty(6 * nf, dtype=np.int64)
    ec = np.empty(6 * nf, dtype=np.int64)
    ew = np.empty(6 * nf)
    deg = np.zeros(n)
    t = 0
    for f in range(nf):
        for c in range(3):
            i = F[f, c]
            j = F[f, (c + 1) % 3]
            k = F[f, (c + 2) % 3]
            ax = V[j, 0] - V[i, 0]
            ay = V[j, 1] - V[i, 1]
            az = V[j, 2] - V[i, 2]
            bx = V[k, 0] - V[i, 0]
            by = V[k, 1] - V[i, 1]
            bz = V[k, 2] - V[i, 2]
            la = max(np.sqrt(ax * ax + ay * ay + az * az), floor)
            lb = max(np.sqrt(bx * bx + by * by + bz * bz), floor)
            cs = (ax * bx + ay * by + az * bz) / (la * lb)
            cs = min(max(cs, -1.0), 1.0)
            half = np.sqrt(max(1.0 - cs, 0.0) / max(1.0 + cs, 1e-12))
            half = max(half, eps)
            wa = half / la * scale[j]
            wb = half / lb * scale[k]
            deg[i] += wa + wb
            er[t] = i
            ec[t] = j
            ew[t] = wa
            t += 1
            er[t] = i
            ec[t] = k
            ew[t] = wb
            t += 1
    rhs = np.zeros((m, 2))
    # free-free entries (with repeats) bucketed by row, the diagonal first in each row
    count = np.ones(m + 1, dtype=np.int64)
    count[m] = 0
    for e in range(t):
        r = at[er[e]]
        if r < 0:
            continue
        cc = at[ec[e]]
        if cc >= 0:
            count[r] += 1
        else:
            rhs[r, 0] += ew[e] * uv[ec[e], 0]
            rhs[r, 1] += ew[e] * uv[ec[e], 1]
    start = np.zeros(m + 1, dtype=np.int64)
    for r in range(m):
        start[r + 1] = start[r] + count[r]
    fill = start[:m].copy()
    cols = np.empty(start[m], dtype=np.int64)
    vals = np.empty(start[m])
    for i in range(n):
        r = at[i]
        if r >= 0:
            cols[fill[r]] = r
            vals[fill[r]] = deg[i]
            fill[r] += 1
    for e in range(t):
        r = at[er[e]]
        if r < 0:
            continue
        cc = at[ec[e]]
        if cc >= 0:
            cols[fill[r]] = cc
            vals[fill[r]] = -ew[e]
            fill[r] += 1
    # sort each (short) row by column and sum repeats
    indptr = np.zeros(m + 1, dtype=np.int64)
    indices = np.empty(start[m], dtype=np.int64)
    data = np.empty(start[m])
    out = 0
    for r in range(m):
        a, b = start[r], start[r + 1]
        for p in range(a + 1, b):  # insertion sort
            c0 = cols[p]
            v0 = vals[p]
            q = p - 1
            while q >= a and cols[q] > c0:
                cols[q + 1] = cols[q]
                vals[q + 1] = vals[q]
                q -= 1
            cols[q + 1] = c0
            vals[q + 1] = v0
        p = a
        while p < b:
            c0 = cols[p]
            v0 = 0.0
            while p < b and cols[p] == c0:
                v0 += vals[p]
                p += 1
            indices[out] = c0
            data[out] = v0
            out += 1
        indptr[r + 1] = out
    return indptr, indices[:out].copy(), data[:out].copy(), rhs


@njit(cache=True, nogil=True)
def aggregate(indptr, indices, data, theta):
    """Aggregates of the strong matrix graph for smoothed-aggregation multigrid of
    `springs.planar.square_map`; CSR (m x m) with its diagonal, theta (strength threshold)
    -> (agg (m,) i8, count).

    ``j`` is a strong neighbour of ``i`` when ``|a_ij| >= theta sqrt(|a_ii a_jj|)``. A node
    whose strong neighbours are all free founds an aggregate of itself and them; the nodes
    left join a strongly connected aggregate, or found one with their free strong neighbours.
    """
    m = indptr.shape[0] - 1
    diag = np.zeros(m)
    for i in range(m):
        for p in range(indptr[i], indptr[i + 1]):
            if indices[p] == i:
                diag[i] = abs(data[p])
    nnz = indptr[m]
    strong = np.zeros(nnz, dtype=np.bool_)
    for i in range(m):
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            strong[p] = j != i and abs(data[p]) >= theta * np.sqrt(diag[i] * diag[j])
    agg = np.full(m, -1, dtype=np.int64)
    na = 0
    for i in range(m):
        if agg[i] >= 0:
            continue
        ok = True
        for p in range(indptr[i], indptr[i + 1]):
            if strong[p] and agg[indices[p]] >= 0:
                ok = False
                break
        if ok:
            agg[i] = na
            for p in range(indptr[i], indptr[i + 1]):
                if strong[p]:
                    agg[indices[p]] = na
            na += 1
    first = agg.copy()
    for i in range(m):
        if first[i] >= 0:
            continue
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            if strong[p] and first[j] >= 0:
                agg[i] = first[j]
                break
    for i in range(m):
        if agg[i] >= 0:
            continue
        agg[i] = na
        for p in range(indptr[i], indptr[i + 1]):
            if strong[p] and agg[indices[p]] < 0:
                agg[indices[p]] = na
        na += 1
    return agg, na


@njit(cache=True, nogil=True)
def gauss_seidel(indptr, indices, data, x, b, sweeps, backward):
    """Gauss-Seidel sweeps on ``A x = b`` in place (forward, or backward when ``backward``);
    the smoother of `springs.planar.square_map`'s multigrid. x, b (m, 2) f8."""
    m = x.shape[0]
    for _ in range(sweeps):
        for s in range(m):
            i = m - 1 - s if backward else s
            d = 0.0
            r0 = b[i, 0]
            r1 = b[i, 1]
            for p in range(indptr[i], indptr[i + 1]):
                j = indices[p]
                if j == i:
                    d = data[p]
                else:
                    r0 -= data[p] * x[j, 0]
                    r1 -= data[p] * x[j, 1]
            x[i, 0] = r0 / d
            x[i, 1] = r1 / d


@njit(cache=True, nogil=True)
def scaled_residual(indptr, indices, data, x, b, r):
    """Residual ``r = b - A x`` (written to r, (m, 2) f8) and its largest entry over the
    row's diagonal (the Jacobi-scaled residual, in the units of x)."""
    m = x.shape[0]
    worst = 0.0
    for i in range(m):
        r0 = b[i, 0]
        r1 = b[i, 1]
        d = 1.0
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            if j == i:
                d = data[p]
            r0 -= data[p] * x[j, 0]
            r1 -= data[p] * x[j, 1]
        r[i, 0] = r0
        r[i, 1] = r1
        worst = max(worst, abs(r0 / d), abs(r1 / d))
    return worst


@njit(cache=True, nogil=True)
def dense_lu(a):
    """LU factors with partial pivoting of a small dense matrix (the coarsest multigrid level
    of `springs.planar.square_map`); a (k, k) f8 -> (lu (k, k) f8, piv (k,) i8)."""
    k = a.shape[0]
    lu = a.copy()
    piv = np.arange(k)
    for c in range(k):
        p = c
        for r in range(c + 1, k):
            if abs(lu[r, c]) > abs(lu[p, c]):
                p = r
        if p != c:
            for q in range(k):
                t = lu[c, q]
                lu[c, q] = lu[p, q]
                lu[p, q] = t
            t2 = piv[c]
            piv[c] = piv[p]
            piv[p] = t2
        d = lu[c, c]
        if d == 0.0:
            continue
        for r in range(c + 1, k):
            f = lu[r, c] / d
            lu[r, c] = f
            if f != 0.0:
                for q in range(c + 1, k):
                    lu[r, q] -= f * lu[c, q]
    return lu, piv


@njit(cache=True, nogil=True)
def dense_lu_solve(lu, piv, b):
    """Solve with the factors of `dense_lu`; b (k, 2) f8 -> (k, 2) f8."""
    k = lu.shape[0]
    x = np.empty((k, 2))
    for i in range(k):
        x[i, 0] = b[piv[i], 0]
        x[i, 1] = b[piv[i], 1]
    for i in range(k):
        for q in range(i):
            x[i, 0] -= lu[i, q] * x[q, 0]
            x[i, 1] -= lu[i, q] * x[q, 1]
    for i in range(k - 1, -1, -1):
        for q in range(i + 1, k):
            x[i, 0] -= lu[i, q] * x[q, 0]
            x[i, 1] -= lu[i, q] * x[q, 1]
        x[i, 0] /= lu[i, i]
        x[i, 1] /= lu[i, i]
    return x


@njit(cache=True, nogil=True)
def arnoldi(Q, k, w, H):
    """One modified Gram-Schmidt step of `springs.planar.square_map`'s GMRES: orthogonalise
    w (m, 2) f8 in place against Q[0..k] (Q (r + 1, m, 2) f8), writing the projections to
    H[0..k, k]; returns the norm left, and stores ``w / norm`` in Q[k + 1] when it is
    positive and there is room."""
    m = w.shape[0]
    for i in range(k + 1):
        h = 0.0
        for p in range(m):
            h += Q[i, p, 0] * w[p, 0] + Q[i, p, 1] * w[p, 1]
        H[i, k] = h
        for p in range(m):
            w[p, 0] -= h * Q[i, p, 0]
            w[p, 1] -= h * Q[i, p, 1]
    s = 0.0
    for p in range(m):
        s += w[p, 0] * w[p, 0] + w[p, 1] * w[p, 1]
    nrm = np.sqrt(s)
    if nrm > 0.0 and k + 1 < Q.shape[0]:
        for p in range(m):
            Q[k + 1, p, 0] = w[p, 0] / nrm
            Q[k + 1, p, 1] = w[p, 1] / nrm
    return nrm


@njit(cache=True, nogil=True)
def gmres_update(x, Z, H, g, k):
    """``x += sum_i y_i Z[i]`` over i <= k, with ``y`` the solution of the upper triangle
    ``H[:k+1, :k+1] y = g[:k+1]`` (the GMRES update of `springs.planar.square_map`).
    x (m, 2) f8; Z (r, m, 2) f8; H (r + 1, r) f8; g (r + 1,) f8."""
    y = np.empty(k + 1)
    for i in range(k, -1, -1):
        s = g[i]
        for q in range(i + 1, k + 1):
            s -= H[i, q] * y[q]
        y[i] = s / H[i, i]
    m = x.shape[0]
    for i in range(k + 1):
        for p in range(m):
            x[p, 0] += y[i] * Z[i, p, 0]
            x[p, 1] += y[i] * Z[i, p, 1]


@njit(cache=True, nogil=True)
def norm2(x):
    """2-norm of x (m, 2) f8 taken as one vector (no BLAS call: tiny kernels, shared cores)."""
    t = 0.0
    for p in range(x.shape[0]):
        t += x[p, 0] * x[p, 0] + x[p, 1] * x[p, 1]
    return np.sqrt(t)
