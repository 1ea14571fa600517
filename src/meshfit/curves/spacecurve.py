"""Uniform cubic B-spline space curves fitted to face-point curves, and editing with them.

The thesis edits surface curves indirectly: a B-spline space curve is least-squares fitted
to the face points with chord-length parameters (sec. 3.3.2); the user moves a control
vertex or an edit point, and the surface curve follows by CurveAttract (sec. 3.3.3).

The B-spline basis here is small and self-contained (:func:`_bspline_basis`); the later
``meshfit.bspline`` module generalises it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit._validate import as_points
from meshfit.curves.base import _as_curve, check_sampling, densify_curve
from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.surface.walk import attract_points
from meshfit.types import SurfaceCurve

__all__ = [
    "SpaceCurve",
    "fit_bspline_curve",
    "fit_space_curve",
    "move_control_point",
    "move_edit_point",
]

DEGREE = 3


def _clamped_knots(n_control: int, degree: int = DEGREE) -> NDArray[np.float64]:
    """Clamped uniform knot vector on [0, 1]: ``n_control + degree + 1`` knots."""
    inner = np.linspace(0.0, 1.0, n_control - degree + 1)
    return np.concatenate([np.zeros(degree), inner, np.ones(degree)])


def _bspline_basis(t: ArrayLike, knots: ArrayLike, degree: int = DEGREE) -> NDArray[np.float64]:
    """B-spline basis functions at parameters: ``(n, k) float64`` with k = len(knots) - degree - 1.

    Uses the triangular scheme of Piegl & Tiller (The NURBS Book, algorithm A2.2) on the
    knot span of each parameter; the right end of the domain belongs to the last span.
    """
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    U = np.asarray(knots, dtype=np.float64)
    k = U.size - degree - 1
    lo, hi = U[degree], U[k]
    tc = np.clip(t, lo, hi)
    span = np.searchsorted(U, tc, side="right") - 1
    span = np.clip(span, degree, k - 1)
    n = t.size
    N = np.zeros((n, degree + 1))
    N[:, 0] = 1.0
    left = np.zeros((n, degree + 1))
    right = np.zeros((n, degree + 1))
    for j in range(1, degree + 1):
        left[:, j] = tc - U[span + 1 - j]
        right[:, j] = U[span + j] - tc
        saved = np.zeros(n)
        for r in range(j):
            den = right[:, r + 1] + left[:, j - r]
            temp = np.divide(N[:, r], den, out=np.zeros(n), where=den != 0)
            N[:, r] = saved + right[:, r + 1] * temp
            saved = left[:, j - r] * temp
        N[:, j] = saved
    out = np.zeros((n, k))
    cols = span[:, None] - degree + np.arange(degree + 1)[None, :]
    out[np.arange(n)[:, None], cols] = N
    return out


@dataclass(frozen=True, eq=False)
class SpaceCurve:
    """A clamped uniform cubic B-spline curve in 3-D, parameter domain [0, 1].

    Attributes
    ----------
    control_points : (k, 3) float64
        Control vertices, model units; k >= 4.
    knots : (k + 4,) float64
        Clamped uniform knots: four zeros, evenly spaced interior knots, four ones.
    """

    control_points: NDArray[np.float64]
    knots: NDArray[np.float64]

    def __post_init__(self) -> None:
        cp = as_points(self.control_points, name="control_points")
        if cp.shape[0] < DEGREE + 1:
            raise InputError(f"a cubic B-spline needs at least 4 control points, got {cp.shape[0]}")
        knots = np.asarray(self.knots, dtype=np.float64)
        if knots.shape != (cp.shape[0] + DEGREE + 1,) or (np.diff(knots) < 0).any():
            raise InputError(
                f"knots must be a non-decreasing vector of {cp.shape[0] + DEGREE + 1} values, "
                f"got shape {knots.shape}"
            )
        cp, knots = cp.copy(), knots.copy()
        cp.flags.writeable = False
        knots.flags.writeable = False
        object.__setattr__(self, "control_points", cp)
        object.__setattr__(self, "knots", knots)

    @classmethod
    def uniform(cls, control_points: ArrayLike) -> SpaceCurve:
        """A curve with clamped uniform knots for the given control points."""
        cp = as_points(control_points, name="control_points")
        return cls(cp, _clamped_knots(cp.shape[0]))

    @property
    def n_control(self) -> int:
        return int(self.control_points.shape[0])

    def basis(self, t: ArrayLike) -> NDArray[np.float64]:
        """``(n, k) float64`` basis matrix at parameters ``t (n,)``."""
        return _bspline_basis(t, self.knots)

    def evaluate(self, t: ArrayLike) -> NDArray[np.float64]:
        """Positions ``(n, 3) float64`` at parameters ``t (n,) float64`` in [0, 1]."""
        return self.basis(t) @ self.control_points

    @property
    def edit_parameters(self) -> NDArray[np.float64]:
        """``(k,) float64`` parameters of the edit points: the Greville abscissae."""
        U = self.knots
        return np.array([U[i + 1 : i + DEGREE + 1].mean() for i in range(self.n_control)])

    @property
    def edit_points(self) -> NDArray[np.float64]:
        """``(k, 3) float64`` edit points: the curve at the Greville abscissae, one per
        control vertex (Forsey & Bartels 1988)."""
        return self.evaluate(self.edit_parameters)


def fit_bspline_curve(
    points: ArrayLike,
    params: ArrayLike,
    *,
    n_control: int,
    fix_ends: bool = True,
) -> SpaceCurve:
    """Least-squares clamped uniform cubic B-spline through 3-D data at given parameters.

    Parameters
    ----------
    points : (m, 3) float64
        Data positions, model units.
    params : (m,) float64
        Parameter of each datum in [0, 1], non-decreasing.
    n_control : int, keyword-only
        Number of control vertices k, 4 <= k <= m.
    fix_ends : bool, keyword-only
        Constrain the curve to interpolate the first and last data points exactly (the
        clamped end control points equal them); the others are fitted in the least-squares
        sense.

    Returns
    -------
    SpaceCurve

    Raises
    ------
    meshfit.errors.InputError
        Bad shapes, non-finite values, parameters outside [0, 1] or decreasing, or
        ``n_control`` out of range.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.3.2, eq. 3.1-3.2 (over-constrained linear system;
       fixed control vertices as linear constraints).
    """
    x = as_points(points, name="points")
    m = x.shape[0]
    t = np.asarray(params, dtype=np.float64).reshape(-1)
    if t.shape != (m,):
        raise InputError(f"params must have shape ({m},), got {t.shape}")
    if not np.isfinite(t).all() or t.min() < 0 or t.max() > 1 or (np.diff(t) < 0).any():
        raise InputError("params must be finite, non-decreasing and within [0, 1]")
    if isinstance(n_control, bool) or not isinstance(n_control, (int, np.integer)):
        raise InputError(f"n_control must be an integer, got {n_control!r}")
    k = int(n_control)
    if not DEGREE + 1 <= k <= m:
        raise InputError(f"n_control must be in [4, {m}] for {m} data points, got {k}")
    knots = _clamped_knots(k)
    A = _bspline_basis(t, knots)
    if fix_ends:
        P = np.zeros((k, 3))
        P[0], P[-1] = x[0], x[-1]
        rhs = x - A[:, [0]] * P[0] - A[:, [-1]] * P[-1]
        P[1:-1] = np.linalg.lstsq(A[:, 1:-1], rhs, rcond=None)[0]
    else:
        P = np.linalg.lstsq(A, x, rcond=None)[0]
    return SpaceCurve(P, knots)


def _chord_params(xyz: NDArray) -> NDArray[np.float64]:
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xyz, axis=0), axis=1))])
    return s / s[-1] if s[-1] > 0 else np.linspace(0.0, 1.0, xyz.shape[0])


def _curve_xyz(mesh: Mesh, curve: SurfaceCurve) -> NDArray[np.float64]:
    xyz = mesh.xyz(curve.points)
    return np.concatenate([xyz, xyz[:1]]) if curve.closed else xyz


def fit_space_curve(
    mesh: Mesh, curve: SurfaceCurve, *, n_control: int, fix_ends: bool = True
) -> SpaceCurve:
    """Fit a uniform cubic B-spline space curve to a face-point curve.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfaceCurve
        m face points; a closed curve is fitted as the open curve from point 0 around back
        to point 0.
    n_control : int, keyword-only
        Control vertices k, 4 <= k <= number of data points: fewer smooth more.
    fix_ends : bool, keyword-only
        Keep the curve's end points exactly.

    Returns
    -------
    SpaceCurve
        Least-squares fit with chord-length parameters (each face point's parameter is the
        polyline length up to it over the total length).

    Raises
    ------
    meshfit.errors.InputError
        Bad ``curve`` or ``n_control``.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD
       thesis, Stanford 2000, sec. 3.3.2 (least-squares fit, arc-length parameters).
    """
    curve = _as_curve(mesh, curve)
    xyz = _curve_xyz(mesh, curve)
    return fit_bspline_curve(xyz, _chord_params(xyz), n_control=n_control, fix_ends=fix_ends)


def _follow(mesh: Mesh, curve: SurfaceCurve, old: SpaceCurve, new: SpaceCurve) -> SurfaceCurve:
    """Move the surface curve by the spline's change and re-attract it to the surface."""
    xyz = _curve_xyz(mesh, curve)
    t = _chord_params(xyz)[: len(curve)]
    delta = new.evaluate(t) - old.evaluate(t)
    moved = np.flatnonzero(np.linalg.norm(delta, axis=1) > 0)
    if moved.size == 0:
        return curve
    pts = curve.points
    sub = pts[moved]
    end = attract_points(mesh, sub, mesh.xyz(sub) + delta[moved]).end
    face = pts.face.copy()
    bary = pts.bary.copy()
    face[moved] = end.face
    bary[moved] = end.bary
    return SurfaceCurve(type(pts)(face, bary), closed=curve.closed, kind=curve.kind)


def _repair(mesh: Mesh, curve: SurfaceCurve) -> SurfaceCurve:
    return densify_curve(mesh, curve) if check_sampling(mesh, curve).size else curve


def _as_index(index: int, k: int) -> int:
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not -k <= index < k:
        raise InputError(f"index must be an integer in [0, {k}), got {index!r}")
    return int(index) % k


def move_control_point(
    mesh: Mesh, curve: SurfaceCurve, space_curve: SpaceCurve, index: int, new_xyz: ArrayLike
) -> tuple[SurfaceCurve, SpaceCurve]:
    """Move one control vertex of a fitted space curve; the surface curve follows.

    Each face point gets its chord-length parameter t (as in :func:`fit_space_curve`) and
    is attracted (CurveAttract) to its current position displaced by the spline's change at
    t. Only the face points whose parameters lie in the moved vertex's support (at most four
    knot spans) move; the rest are kept exactly. Inserted points repair the sampling rule
    where the moved stretch pulls apart.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfaceCurve
        The surface curve ``space_curve`` was fitted to.
    space_curve : SpaceCurve
    index : int
        Control vertex to move.
    new_xyz : (3,) float64
        Its new position, model units.

    Returns
    -------
    (SurfaceCurve, SpaceCurve)
        The updated surface curve and space curve.

    Raises
    ------
    meshfit.errors.InputError
        Bad index, position or curve.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.3.3 (control-vertex editing updates the surface curve
       through CurveAttract).
    """
    curve = _as_curve(mesh, curve)
    i = _as_index(index, space_curve.n_control)
    x = as_points(new_xyz, name="new_xyz")
    if x.shape[0] != 1:
        raise InputError(f"new_xyz must be one position (3,), got shape {x.shape}")
    cp = space_curve.control_points.copy()
    cp[i] = x[0]
    new = SpaceCurve(cp, space_curve.knots)
    return _repair(mesh, _follow(mesh, curve, space_curve, new)), new


def move_edit_point(
    mesh: Mesh, curve: SurfaceCurve, space_curve: SpaceCurve, index: int, new_xyz: ArrayLike
) -> tuple[SurfaceCurve, SpaceCurve]:
    """Move one edit point of a fitted space curve; the surface curve follows.

    The edit point at Greville parameter ``t_j`` is moved to ``new_xyz`` with the smallest
    change of the control vertices (least norm): control vertex ``i`` moves by
    ``N_i(t_j) d / sum N(t_j)^2``, where d is the requested displacement, so the curve
    passes exactly through ``new_xyz`` at ``t_j``. The surface curve follows as in
    :func:`move_control_point`.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfaceCurve
    space_curve : SpaceCurve
    index : int
        Edit point to move (one per control vertex, see ``SpaceCurve.edit_points``).
    new_xyz : (3,) float64

    Returns
    -------
    (SurfaceCurve, SpaceCurve)

    Raises
    ------
    meshfit.errors.InputError
        Bad index, position or curve.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.3.3 (edit points).
    .. [2] Forsey & Bartels, "Hierarchical B-spline refinement", SIGGRAPH 1988.
    """
    curve = _as_curve(mesh, curve)
    j = _as_index(index, space_curve.n_control)
    x = as_points(new_xyz, name="new_xyz")
    if x.shape[0] != 1:
        raise InputError(f"new_xyz must be one position (3,), got shape {x.shape}")
    tj = space_curve.edit_parameters[j]
    N = space_curve.basis([tj])[0]
    d = x[0] - space_curve.evaluate([tj])[0]
    cp = space_curve.control_points + np.outer(N / (N @ N), d)
    new = SpaceCurve(cp, space_curve.knots)
    return _repair(mesh, _follow(mesh, curve, space_curve, new)), new
