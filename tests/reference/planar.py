"""Slow, obviously-correct oracles of the planar-map kernels (`meshfit._kernels.planar`)."""

from __future__ import annotations

import numpy as np


def mean_value_system(V, F, at, uv, floor, eps, scale=None):
    """The interior mean-value system as a dense matrix (m, m) and right-hand side (m, 2),
    face corner by face corner; ``scale`` (n,) multiplies each weight ``w_ij`` by
    ``scale[j]`` (default 1)."""
    scale = np.ones(len(V)) if scale is None else scale
    m = int((at >= 0).sum())
    A = np.zeros((m, m))
    rhs = np.zeros((m, 2))
    for f in range(len(F)):
        for c in range(3):
            i, j, k = F[f, c], F[f, (c + 1) % 3], F[f, (c + 2) % 3]
            if at[i] < 0:
                continue
            eij, eik = V[j] - V[i], V[k] - V[i]
            lij = max(np.linalg.norm(eij), floor)
            lik = max(np.linalg.norm(eik), floor)
            theta = np.arccos(np.clip(eij @ eik / (lij * lik), -1.0, 1.0))
            half = max(np.tan(theta / 2), eps)
            for q, length in ((j, lij), (k, lik)):
                w = half / length * scale[q]
                A[at[i], at[i]] += w
                if at[q] >= 0:
                    A[at[i], at[q]] -= w
                else:
                    rhs[at[i]] += w * uv[q]
    return A, rhs


def gauss_seidel(A, x, b, sweeps, backward):
    """Gauss-Seidel sweeps on a dense ``A`` (m, m); returns the new x (m, 2)."""
    x = x.copy()
    m = len(A)
    order = range(m - 1, -1, -1) if backward else range(m)
    for _ in range(sweeps):
        for i in order:
            x[i] = (b[i] - A[i] @ x + A[i, i] * x[i]) / A[i, i]
    return x
