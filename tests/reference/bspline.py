"""Slow, obviously-correct B-spline oracles: Cox-de Boor recursion and its derivative formula."""

from __future__ import annotations

import numpy as np


def basis(i: int, p: int, t: float, U: np.ndarray) -> float:
    """N_{i,p}(t) by the Cox-de Boor recursion; the right domain end closes the last span."""
    if p == 0:
        last = U[-1]
        if U[i] <= t < U[i + 1]:
            return 1.0
        # t at the right end belongs to the last non-empty span
        if t == last and U[i] < U[i + 1] == last:
            return 1.0
        return 0.0
    a = 0.0
    if U[i + p] > U[i]:
        a = (t - U[i]) / (U[i + p] - U[i]) * basis(i, p - 1, t, U)
    b = 0.0
    if U[i + p + 1] > U[i + 1]:
        b = (U[i + p + 1] - t) / (U[i + p + 1] - U[i + 1]) * basis(i + 1, p - 1, t, U)
    return a + b


def basis_derivative(i: int, p: int, t: float, U: np.ndarray, r: int) -> float:
    """r-th derivative of N_{i,p} by N' = p/(U[i+p]-U[i]) N_{i,p-1} - p/(...) N_{i+1,p-1}."""
    if r == 0:
        return basis(i, p, t, U)
    a = 0.0
    if U[i + p] > U[i]:
        a = p / (U[i + p] - U[i]) * basis_derivative(i, p - 1, t, U, r - 1)
    b = 0.0
    if U[i + p + 1] > U[i + 1]:
        b = p / (U[i + p + 1] - U[i + 1]) * basis_derivative(i + 1, p - 1, t, U, r - 1)
    return a - b


def surface_point(
    P: np.ndarray, Uu: np.ndarray, Uv: np.ndarray, u: float, v: float, du: int = 0, dv: int = 0
) -> np.ndarray:
    """(du, dv) partial derivative of the tensor-product cubic surface: a double loop."""
    out = np.zeros(3)
    for i in range(P.shape[0]):
        bi = basis_derivative(i, 3, u, Uu, du)
        if bi == 0.0:
            continue
        for j in range(P.shape[1]):
            out += bi * basis_derivative(j, 3, v, Uv, dv) * P[i, j]
    return out


def dense_fit(X: np.ndarray, mu: int, mv: int, Uu: np.ndarray, Uv: np.ndarray) -> np.ndarray:
    """The gridded fit as one dense (nu nv) x (mu mv) least-squares system (small grids only)."""
    nu, nv = X.shape[:2]
    u = np.linspace(0, 1, nu)
    v = np.linspace(0, 1, nv)
    A = np.zeros((nu * nv, mu * mv))
    for a in range(nu):
        for b in range(nv):
            for i in range(mu):
                bi = basis(i, 3, u[a], Uu)
                for j in range(mv):
                    A[a * nv + b, i * mv + j] = bi * basis(j, 3, v[b], Uv)
    sol = np.linalg.lstsq(A, X.reshape(-1, 3), rcond=None)[0]
    return sol.reshape(mu, mv, 3)
