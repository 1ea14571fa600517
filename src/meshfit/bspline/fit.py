"""Gridded least-squares fitting of a cubic B-spline surface, and its error measures."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit import tol
from meshfit._kernels import bspline as _k
from meshfit._kernels import frozen
from meshfit.bspline.basis import DEGREE, basis_local, basis_matrix, clamped_knots
from meshfit.bspline.surface import BSplineSurface
from meshfit.errors import InputError
from meshfit.types import Side

__all__ = ["FitErrors", "closest_parameters", "fit_bspline", "fit_errors", "grid_parameters"]

#: names of the boundary rows of control points that can be pinned (:class:`Side`)
SIDES = tuple(Side)
#: reach of `fit_bspline`'s smoothing Gaussian in standard deviations: terms below
#: exp(-REACH^2 / 2) of its peak are dropped (in its Fourier series too)
_GAUSS_REACH = 8.0


def grid_parameters(n: int) -> NDArray[np.float64]:
    """Uniform parameters of a grid line of ``n`` points: ``(n,) float64``, ``i / (n - 1)``."""
    return np.linspace(0.0, 1.0, n)


@lru_cache(maxsize=64)
def _solver(n: int, m: int):
    """Banded basis of n uniform samples for m controls, and how to invert it.

    Returns ``first (n,)``, ``values (n, 4)`` (the non-zero basis functions per sample), the
    dense collocation matrix ``B (n, m)``, ``(B^T B)^-1 (m, m)``, and the pseudo-inverse
    ``B^+ (m, n)`` (from a QR factorisation) when ``n < tol.BSPLINE_GRAM_RATIO * m``, else None.

    The normal equations square the condition number of ``B``: fine while m is well below
    n (cond(B) ~ 5 for 30 controls on 100 samples, 7 for 48 on 60), not when m approaches n
    (cond(B) ~ 2e4 for 60 on 60), where the QR pseudo-inverse is applied to the grid instead.
    Cached, so re-fitting a grid of a seen size costs only the products.
    """
    t = grid_parameters(n)
    U = clamped_knots(m)
    first, vals = basis_local(t, U, DEGREE, 0)
    first = np.ascontiguousarray(first)
    vals = np.ascontiguousarray(vals[:, 0, :])
    B = basis_matrix(t, U, DEGREE, 0)
    pinv, inv = _k.qr_pinv(B)
    if n >= tol.BSPLINE_GRAM_RATIO * m:
        pinv = None
    for a in (first, vals, B, inv, pinv):
        if a is not None:
            a.flags.writeable = False
    return first, vals, B, inv, pinv


def _periodic_gaussian(sigma: float, period: int) -> NDArray[np.float64]:
    """Sampled Gaussian of ``sigma`` samples wrapped onto ``period`` samples, summing to 1.

    Summed directly over the periods it reaches while it is narrow, and as its Fourier
    series (Poisson summation) once it spans a quarter period, so that any width costs
    ``O(period)``.
    """
    d = np.arange(period, dtype=np.float64)
    g = np.zeros(period)
    if sigma < period / 4:
        reach = int(np.ceil(_GAUSS_REACH * sigma / period)) + 1
        for q in range(-reach, reach + 1):
            g += np.exp(-0.5 * ((d + q * period) / sigma) ** 2)
    else:
        tail = np.exp(-0.5 * _GAUSS_REACH**2)
        g += 1.0
        k = 1
        while (a := np.exp(-2.0 * (np.pi * sigma * k / period) ** 2)) > tail:
            g += 2.0 * a * np.cos(2.0 * np.pi * k * d / period)
            k += 1
    return g / g.sum()


@lru_cache(maxsize=64)
def lowpass_matrix(n: int, m: int, smoothing: float) -> NDArray[np.float64]:
    """Low-pass ``L (n, n)`` of one grid direction of n samples for m controls (the filter
    of :func:`fit_bspline`'s ``smoothing``; boundary curves fitted on their own take it too,
    so that patches and their pinned boundaries keep the same detail out).

    ``L = C + W (I - C)``: ``C`` is the least-squares projection onto cubic polynomials
    (a single clamped span), ``W`` a Gaussian of ``smoothing`` knot spacings, i.e.
    ``smoothing * (n - 1) / (m - 3)`` samples, applied to the line's odd reflection about
    its end samples (``W = Lam + W_odd (I - Lam)``, ``Lam`` the line through the two end
    samples, ``W_odd`` the Gaussian on the odd, ``2 (n - 1)``-periodic extension of what
    is left). Rows sum to 1; cubics and both end samples pass unchanged. Cached, read-only.
    """
    N = n - 1
    sigma = smoothing * N / (m - DEGREE)
    g = _periodic_gaussian(sigma, 2 * N)
    i = np.arange(n)
    W_odd = g[(i[:, None] - i[None, :]) % (2 * N)] - g[(i[:, None] + i[None, :]) % (2 * N)]
    Lam = np.zeros((n, n))
    Lam[:, 0] = 1.0 - i / N
    Lam[:, -1] = i / N
    W = Lam + W_odd @ (np.eye(n) - Lam)
    _, _, B4, inv4, _ = _solver(n, DEGREE + 1)
    C = B4 @ inv4 @ B4.T
    L = C + W @ (np.eye(n) - C)
    L.flags.writeable = False
    return L


def _as_grid(grid_xyz: ArrayLike) -> NDArray[np.float64]:
    try:
        X = np.asarray(grid_xyz, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("grid_xyz must be numeric with shape (nu, nv, 3)") from None
    if X.ndim != 3 or X.shape[2] != 3:
        raise InputError(f"grid_xyz must have shape (nu, nv, 3), got {X.shape}")
    if not np.isfinite(X).all():
        i, j = np.argwhere(~np.isfinite(X).all(axis=2))[0]
        raise InputError(f"grid_xyz[{i}, {j}] is not finite")
    return X


def fit_bspline(
    grid_xyz: ArrayLike,
    *,
    controls: tuple[int, int],
    pin_boundary: Mapping[str, ArrayLike] | None = None,
    smoothing: float = 0.0,
) -> BSplineSurface:
    """Least-squares cubic B-spline surface through a gridded set of points.

    Solves eq. 4.4 of the thesis, ``X = B_u P B_v^T`` in the least-squares sense, as two small
    solves, ``P = (B_u^T B_u)^-1 B_u^T X B_v (B_v^T B_v)^-1``: an ``(mu, nu)`` and an
    ``(mv, nv)`` pseudo-inverse, never the ``(nu nv) x (mu mv)`` system.

    Parameters
    ----------
    grid_xyz : (nu, nv, 3) float64
        Grid points, model units; ``grid_xyz[i, j]`` is sampled at ``(u_i, v_j) =
        (i / (nu - 1), j / (nv - 1))``.
    controls : (int, int)
        Control resolution ``(mu, mv)``, with ``4 <= mu <= nu`` and ``4 <= mv <= nv``.
    pin_boundary : mapping of str to (m, 3) float64, optional
        Boundary rows of control points held fixed, by side: ``"u0"`` is ``P[0, :]``,
        ``"u1"`` ``P[-1, :]`` (each ``(mv, 3)``), ``"v0"`` ``P[:, 0]``, ``"v1"`` ``P[:, -1]``
        (each ``(mu, 3)``), in increasing parameter order. Pinned sides meeting at a corner
        must agree on the corner point. The remaining control points are the least-squares
        solution given the pinned ones; the problem stays separable because the free
        control points form the product of the free rows and free columns. Default: none.
    smoothing : float
        Standard deviation, in knot spacings, of the Gaussian low-pass that keeps fine
        detail out of the spline and leaves it to the displacement map (sec. 7.5). ``0``
        (default): plain least squares. Otherwise the spline is the least-squares fit (pins
        included) of a low-passed grid: along each grid direction, the deviation from the
        line's least-squares cubic is smoothed by the Gaussian, the line extended by odd
        reflection about its end samples. Cubics along either direction and the grid's
        corners pass unchanged; boundary rows are smoothed only along themselves. The
        result does not depend on the grid's resolution, position, orientation or scale.

    Returns
    -------
    BSplineSurface
        Clamped uniform knots, ``control_points (mu, mv, 3)``.

    Raises
    ------
    InputError
        Bad shapes, a control resolution out of range, non-finite values, an unknown side,
        pinned sides that disagree at a corner, or a negative or non-finite smoothing.

    Notes
    -----
    Least squares cannot tell fine detail from coarse shape (sec. 7.5): it splits a bump
    narrower than the knot spacing between spline and map and rings around it. A Gaussian
    separates by scale without ringing (its kernel is positive): the spline takes no dents
    and the map most of the detail, though the detail's volume, spread thinly over the
    spline, leaves a shallow, wide trough around it in the map (as any linear split that
    keeps planes in the spline does). Filtering the deviation from the cubic trend keeps
    the Gaussian from shrinking curved patches (by about ``k s^2`` at curvature ``k``).
    Spline plus map is still the grid.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 4.3.2, eq. 4.4; sec. 6.2; sec. 8.1.3 (boundary
       constraints at the fitting step); sec. 7.5 and sec. 9.2.2 (fine detail in the
       spline, and a frequency split as the remedy).
    """
    X = _as_grid(grid_xyz)
    nu, nv = X.shape[:2]
    try:
        mu, mv = (int(c) for c in controls)
    except (TypeError, ValueError):
        raise InputError(f"controls must be a pair of integers, got {controls!r}") from None
    if not (DEGREE + 1 <= mu <= nu and DEGREE + 1 <= mv <= nv):
        raise InputError(
            f"controls {(mu, mv)} out of range for a {nu} x {nv} grid: need 4 <= mu <= {nu} "
            f"and 4 <= mv <= {nv}"
        )
    try:
        smoothing = float(smoothing)
    except (TypeError, ValueError):
        raise InputError(f"smoothing must be a number, got {smoothing!r}") from None
    if not (np.isfinite(smoothing) and smoothing >= 0.0):
        raise InputError(f"smoothing must be finite and >= 0 (knot spacings), got {smoothing}")
    fu, Nu, Bu, Mu, Pu = _solver(nu, mu)
    fv, Nv, Bv, Mv, Pv = _solver(nv, mv)
    X = np.ascontiguousarray(X)
    if smoothing > 0.0:
        X = _k.dense_sandwich(
            lowpass_matrix(nu, mu, smoothing), X, lowpass_matrix(nv, mv, smoothing)
        )
    if not pin_boundary:
        if Pu is None and Pv is None:
            G = _k.gram_sandwich(fu, Nu, fv, Nv, X, mu, mv)  # B_u^T X B_v
            return BSplineSurface(_k.dense_sandwich(Mu, G, Mv))
        Pu = _k.qr_pinv(Bu)[0] if Pu is None else Pu
        Pv = _k.qr_pinv(Bv)[0] if Pv is None else Pv
        return BSplineSurface(_k.dense_sandwich(Pu, X, Pv))

    P = np.zeros((mu, mv, 3))
    fixed = np.zeros((mu, mv), dtype=bool)
    rows_free = np.ones(mu, dtype=bool)
    cols_free = np.ones(mv, dtype=bool)
    for side, values in pin_boundary.items():
        if side not in SIDES:
            raise InputError(f"pin_boundary side must be one of {', '.join(SIDES)}, got {side!r}")
        n = mv if side[0] == "u" else mu
        vals = np.asarray(values, dtype=np.float64)
        if vals.shape != (n, 3) or not np.isfinite(vals).all():
            raise InputError(
                f"pin_boundary[{side!r}] must be finite with shape ({n}, 3), got {vals.shape}"
            )
        row = Side(side)
        overlap = row.row(fixed)
        if overlap.any() and not np.array_equal(row.row(P)[overlap], vals[overlap]):
            raise InputError(f"pin_boundary[{side!r}] disagrees with another side at a corner")
        row.row(P)[...] = vals
        row.row(fixed)[...] = True
        if side[0] == "u":
            rows_free[0 if side == "u0" else -1] = False
        else:
            cols_free[0 if side == "v0" else -1] = False
    # residual of the pinned part, then least squares over free rows x free columns
    R = X - _k.grid_eval(*frozen(fu, Nu, fv, Nv, P))
    G = _k.gram_sandwich(fu, Nu, fv, Nv, R, mu, mv)[np.ix_(rows_free, cols_free)]
    Bu_f, Bv_f = Bu[:, rows_free], Bv[:, cols_free]
    Pu_f, Mu_f = _k.qr_pinv(np.ascontiguousarray(Bu_f))
    Pv_f, Mv_f = _k.qr_pinv(np.ascontiguousarray(Bv_f))
    if Pu is None and Pv is None:
        P[np.ix_(rows_free, cols_free)] = _k.dense_sandwich(Mu_f, np.ascontiguousarray(G), Mv_f)
    else:
        P[np.ix_(rows_free, cols_free)] = _k.dense_sandwich(Pu_f, R, Pv_f)
    return BSplineSurface(P)


@dataclass(frozen=True)
class FitErrors:
    """Error of a surface against grid points, model units.

    Attributes
    ----------
    parametric_rms, parametric_max : float
        ``|X_ij - S(u_i, v_j)|`` over the grid (eq. 6.1): RMS and maximum.
    normal_rms, normal_max : float
        Distance of each grid point to its closest point on the surface (eq. 6.2): RMS and
        maximum. Never above the parametric figures.
    """

    parametric_rms: float
    parametric_max: float
    normal_rms: float
    normal_max: float

    def as_dict(self) -> dict[str, float]:
        return {
            "parametric_rms": self.parametric_rms,
            "parametric_max": self.parametric_max,
            "normal_rms": self.normal_rms,
            "normal_max": self.normal_max,
        }


def closest_parameters(
    surface: BSplineSurface,
    points: ArrayLike,
    u0: ArrayLike,
    v0: ArrayLike,
    *,
    max_iter: int = tol.BSPLINE_CLOSEST_MAX_ITER,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Closest points on a surface by Newton iteration from starting parameters.

    Parameters
    ----------
    surface : BSplineSurface
    points : (n, 3) float64
        Query points, model units.
    u0, v0 : (n,) float64
        Starting parameters (for grid data, the grid parameters: the closest point is near).
    max_iter : int
        Iteration cap (default ``tol.BSPLINE_CLOSEST_MAX_ITER``).

    Returns
    -------
    u, v : (n,) float64
        Parameters of the closest points found, in [0, 1] (steps are clipped to the domain).
    distance : (n,) float64
        Distances, model units; never above the distance at the start parameters.

    Notes
    -----
    Newton on ``f(u, v) = |S(u, v) - X|^2 / 2`` with the full Hessian ``J^T J + r . S''``,
    falling back to Gauss-Newton where that is not positive definite, and halving any step
    that does not decrease the distance (point inversion, Piegl & Tiller sec. 6.1).
    """
    X = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    u = np.clip(np.asarray(u0, dtype=np.float64).ravel().copy(), 0.0, 1.0)
    v = np.clip(np.asarray(v0, dtype=np.float64).ravel().copy(), 0.0, 1.0)
    S = surface.evaluate(u, v)
    d2 = ((S - X) ** 2).sum(axis=1)
    active = np.ones(u.size, dtype=bool)
    for _ in range(max_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        S, Su, Sv, Suu, Suv, Svv = surface.evaluate(u[idx], v[idx], derivatives=2)
        r = S - X[idx]
        g = np.stack([(r * Su).sum(1), (r * Sv).sum(1)], axis=1)
        a = (Su * Su).sum(1) + (r * Suu).sum(1)
        b = (Su * Sv).sum(1) + (r * Suv).sum(1)
        c = (Sv * Sv).sum(1) + (r * Svv).sum(1)
        det = a * c - b * b
        gn = (a <= 0) | (det <= 0)
        a = np.where(gn, (Su * Su).sum(1), a)
        b = np.where(gn, (Su * Sv).sum(1), b)
        c = np.where(gn, (Sv * Sv).sum(1), c)
        det = a * c - b * b
        ok = det > 0
        det = np.where(ok, det, 1.0)
        du = np.where(ok, -(c * g[:, 0] - b * g[:, 1]) / det, 0.0)
        dv = np.where(ok, -(a * g[:, 1] - b * g[:, 0]) / det, 0.0)
        step = np.ones(idx.size)
        done = ~ok.copy()
        for _half in range(30):
            todo = ~done
            if not todo.any():
                break
            un = np.clip(u[idx] + step * du, 0.0, 1.0)
            vn = np.clip(v[idx] + step * dv, 0.0, 1.0)
            dn = ((surface.evaluate(un[todo], vn[todo]) - X[idx[todo]]) ** 2).sum(1)
            better = dn <= d2[idx[todo]]
            t_idx = np.flatnonzero(todo)
            acc = t_idx[better]
            u[idx[acc]], v[idx[acc]], d2[idx[acc]] = un[acc], vn[acc], dn[better]
            done[acc] = True
            step[t_idx[~better]] *= 0.5
        moved = np.abs(step * du) + np.abs(step * dv)
        still = ok & (moved > tol.BSPLINE_CLOSEST_STEP) & (step > 2.0**-29)
        active[idx[~still]] = False
    return u, v, np.sqrt(d2)


def fit_errors(surface: BSplineSurface, grid_xyz: ArrayLike) -> FitErrors:
    """Parametric (eq. 6.1) and normal (eq. 6.2) distance errors of a surface to grid points.

    Parameters
    ----------
    surface : BSplineSurface
    grid_xyz : (nu, nv, 3) float64
        Grid points at the uniform grid parameters (see :func:`fit_bspline`).

    Returns
    -------
    FitErrors
        RMS and max of both measures, model units.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 6.2, eqs. 6.1 and 6.2.
    """
    X = _as_grid(grid_xyz)
    nu, nv = X.shape[:2]
    gu, gv = grid_parameters(nu), grid_parameters(nv)
    S = surface.evaluate_grid(gu, gv)
    par = np.linalg.norm(X - S, axis=2).ravel()
    U, V = np.meshgrid(gu, gv, indexing="ij")
    _, _, nd = closest_parameters(surface, X.reshape(-1, 3), U.ravel(), V.ravel())
    nd = np.minimum(nd, par)
    return FitErrors(
        parametric_rms=float(np.sqrt(np.mean(par**2))),
        parametric_max=float(par.max()),
        normal_rms=float(np.sqrt(np.mean(nd**2))),
        normal_max=float(nd.max()),
    )
