"""Clamped B-spline basis functions and their derivatives, vectorised over parameters.

The surfaces of :mod:`meshfit.bspline` are uniform cubic tensor-product B-splines with
end-point interpolating (clamped) knots (Krishnamurthy 2000, sec. 4.3, eq. 4.1). The basis
here accepts any clamped, non-decreasing knot vector so that surfaces fitted by other tools
(non-uniform knots) can be evaluated and measured with the same code.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit._kernels import bspline as _k
from meshfit._kernels import frozen

__all__ = ["DEGREE", "basis_local", "basis_matrix", "clamped_knots"]

#: polynomial degree of every surface in meshfit.bspline (order 4)
DEGREE = 3


def clamped_knots(n_control: int, degree: int = DEGREE) -> NDArray[np.float64]:
    """Clamped uniform knot vector on [0, 1].

    Parameters
    ----------
    n_control : int
        Number of control points along the direction, ``>= degree + 1``.
    degree : int
        Polynomial degree.

    Returns
    -------
    (n_control + degree + 1,) float64
        ``degree + 1`` zeros, evenly spaced interior knots, ``degree + 1`` ones.
    """
    inner = np.linspace(0.0, 1.0, n_control - degree + 1)
    return np.concatenate([np.zeros(degree), inner, np.ones(degree)])


def basis_local(
    t: ArrayLike, knots: NDArray[np.float64], degree: int = DEGREE, derivatives: int = 0
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Non-zero basis functions and their derivatives at parameters ``t``.

    Parameters
    ----------
    t : (n,) float64
        Parameters; clipped to the knot domain ``[knots[degree], knots[-degree-1]]``.
    knots : (k + degree + 1,) float64
        Clamped, non-decreasing knot vector of k control points.
    degree : int
        Polynomial degree p.
    derivatives : int
        Highest derivative order d returned (0 <= d <= p).

    Returns
    -------
    first : (n,) int64
        Index of the first of the ``p + 1`` non-zero functions at each parameter.
    values : (n, d + 1, p + 1) float64
        ``values[i, r, a]`` is the r-th derivative of basis function ``first[i] + a``.

    Notes
    -----
    Vectorised form of algorithm A2.3 of Piegl & Tiller, *The NURBS Book* (1997). The right
    end of the domain belongs to the last non-empty span.
    """
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    U = np.ascontiguousarray(knots, dtype=np.float64)
    p = int(degree)
    k = U.size - p - 1
    tc = np.ascontiguousarray(np.clip(t.ravel(), U[p], U[k]))
    return _k.basis_local(*frozen(tc, U), p, min(int(derivatives), p))


def basis_matrix(
    t: ArrayLike, knots: NDArray[np.float64], degree: int = DEGREE, derivative: int = 0
) -> NDArray[np.float64]:
    """Dense basis (or derivative) matrix: ``(n, k) float64`` with k control points.

    Row i holds the ``derivative``-th derivative of every basis function at ``t[i]``; the
    collocation matrix ``B`` of eq. 4.4 (Krishnamurthy 2000, sec. 4.3.2) for ``derivative=0``.
    """
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    k = np.asarray(knots).size - degree - 1
    first, vals = basis_local(t, knots, degree, derivative)
    out = np.zeros((t.size, k))
    cols = first[:, None] + np.arange(degree + 1)[None, :]
    out[np.arange(t.size)[:, None], cols] = vals[:, derivative, :]
    return out
