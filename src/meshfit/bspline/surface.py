"""The tensor-product cubic B-spline surface: evaluation with derivatives, normals, frames."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit import tol
from meshfit._kernels import bspline as _k
from meshfit._kernels import frozen
from meshfit.bspline.basis import DEGREE, basis_local, clamped_knots
from meshfit.errors import InputError

__all__ = ["BSplineSurface"]


def _as_knots(knots: ArrayLike | None, n_control: int, name: str) -> NDArray[np.float64]:
    if knots is None:
        return clamped_knots(n_control)
    U = np.asarray(knots, dtype=np.float64)
    if U.shape != (n_control + DEGREE + 1,):
        raise InputError(
            f"{name} must have {n_control + DEGREE + 1} values for {n_control} control points, "
            f"got shape {U.shape}"
        )
    if not np.isfinite(U).all() or (np.diff(U) < 0).any():
        raise InputError(f"{name} must be finite and non-decreasing")
    if (U[: DEGREE + 1] != U[0]).any() or (U[-DEGREE - 1 :] != U[-1]).any() or U[-1] <= U[0]:
        raise InputError(f"{name} must be clamped: {DEGREE + 1} equal knots at each end")
    return U


@dataclass(frozen=True, eq=False)
class BSplineSurface:
    """A clamped cubic tensor-product B-spline surface over the unit square.

    ``S(u, v) = sum_i sum_j P[i, j] N_i(u) N_j(v)`` (Krishnamurthy 2000, eq. 4.1), degree 3 in
    both directions, end-point interpolating: the corner control points are corner points of
    the surface and each boundary row of control points alone defines that boundary curve.

    Attributes
    ----------
    control_points : (mu, mv, 3) float64
        Control points, model units; ``mu, mv >= 4``. ``P[i, j]`` is the i-th along u and the
        j-th along v; ``P[0, 0]`` is the corner at (u, v) = (0, 0).
    knots_u : (mu + 4,) float64
        Clamped knots along u; clamped uniform on [0, 1] unless given.
    knots_v : (mv + 4,) float64
        Clamped knots along v.

    References
    ----------
    .. [1] Krishnamurthy, "Developing Geometric Models from Dense Polygon Meshes", PhD
       thesis, Stanford 2000, sec. 4.3, eq. 4.1; sec. 6.2.
    """

    control_points: NDArray[np.float64]
    knots_u: NDArray[np.float64] | None = None
    knots_v: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        try:
            cp = np.array(self.control_points, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError("control_points must be numeric with shape (mu, mv, 3)") from None
        if cp.ndim != 3 or cp.shape[2] != 3:
            raise InputError(f"control_points must have shape (mu, mv, 3), got {cp.shape}")
        if cp.shape[0] < DEGREE + 1 or cp.shape[1] < DEGREE + 1:
            raise InputError(
                f"a cubic B-spline surface needs at least 4 x 4 control points, got "
                f"{cp.shape[0]} x {cp.shape[1]}"
            )
        if not np.isfinite(cp).all():
            i, j = np.argwhere(~np.isfinite(cp).all(axis=2))[0]
            raise InputError(f"control_points[{i}, {j}] is not finite")
        ku = _as_knots(self.knots_u, cp.shape[0], "knots_u")
        kv = _as_knots(self.knots_v, cp.shape[1], "knots_v")
        for a in (cp, ku, kv):
            a.flags.writeable = False
        object.__setattr__(self, "control_points", cp)
        object.__setattr__(self, "knots_u", ku)
        object.__setattr__(self, "knots_v", kv)

    @property
    def degree(self) -> int:
        """Polynomial degree in both directions (3)."""
        return DEGREE

    @property
    def shape(self) -> tuple[int, int]:
        """Control resolution ``(mu, mv)``."""
        return int(self.control_points.shape[0]), int(self.control_points.shape[1])

    @property
    def is_uniform(self) -> bool:
        """True when both knot vectors are the clamped uniform knots on [0, 1]."""
        mu, mv = self.shape
        return bool(
            np.array_equal(self.knots_u, clamped_knots(mu))
            and np.array_equal(self.knots_v, clamped_knots(mv))
        )

    def with_control_points(self, control_points: ArrayLike) -> BSplineSurface:
        """The same knots with new control points of the same shape."""
        cp = np.asarray(control_points, dtype=np.float64)
        if cp.shape != self.control_points.shape:
            raise InputError(
                f"control_points must keep the shape {self.control_points.shape}, got {cp.shape}"
            )
        return BSplineSurface(cp, self.knots_u, self.knots_v)

    # ------------------------------------------------------------------ evaluation
    def evaluate(
        self, u: ArrayLike, v: ArrayLike, derivatives: int = 0
    ) -> NDArray[np.float64] | tuple[NDArray[np.float64], ...]:
        """Points (and partial derivatives) at parameter pairs.

        Parameters
        ----------
        u, v : array_like float64
            Parameters in [0, 1] (clipped), broadcast against each other to a shape ``s``.
        derivatives : {0, 1, 2}
            0: points only; 1: also ``S_u, S_v``; 2: also ``S_uu, S_uv, S_vv``.

        Returns
        -------
        (*s, 3) float64 or tuple of them
            ``S`` for ``derivatives=0``; ``(S, S_u, S_v)`` for 1;
            ``(S, S_u, S_v, S_uu, S_uv, S_vv)`` for 2. Model units per unit parameter.
        """
        if derivatives not in (0, 1, 2):
            raise InputError(f"derivatives must be 0, 1 or 2, got {derivatives!r}")
        uu, vv = np.broadcast_arrays(
            np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
        )
        shape = uu.shape
        uf, vf = uu.ravel(), vv.ravel()
        fu, Nu = basis_local(uf, self.knots_u, DEGREE, derivatives)
        fv, Nv = basis_local(vf, self.knots_v, DEGREE, derivatives)
        a = np.arange(DEGREE + 1)
        # (n, 4, 4, 3) block of control points around each parameter pair
        block = self.control_points[
            fu[:, None, None] + a[None, :, None], fv[:, None, None] + a[None, None, :]
        ]
        pairs = [(0, 0)]
        if derivatives >= 1:
            pairs += [(1, 0), (0, 1)]
        if derivatives == 2:
            pairs += [(2, 0), (1, 1), (0, 2)]
        out = tuple(
            np.einsum("na,nb,nabc->nc", Nu[:, du, :], Nv[:, dv, :], block).reshape(*shape, 3)
            for du, dv in pairs
        )
        return out[0] if derivatives == 0 else out

    def evaluate_grid(
        self, u: ArrayLike, v: ArrayLike, derivatives: int = 0
    ) -> NDArray[np.float64] | tuple[NDArray[np.float64], ...]:
        """Like :meth:`evaluate` on the tensor grid ``u (nu,) x v (nv,)``: arrays ``(nu, nv, 3)``.

        Two banded products per output (``B_u P B_v^T``), the fast path for images.
        """
        if derivatives not in (0, 1, 2):
            raise InputError(f"derivatives must be 0, 1 or 2, got {derivatives!r}")
        u = np.atleast_1d(np.asarray(u, dtype=np.float64))
        v = np.atleast_1d(np.asarray(v, dtype=np.float64))
        fu, Nu = basis_local(u, self.knots_u, DEGREE, derivatives)
        fv, Nv = basis_local(v, self.knots_v, DEGREE, derivatives)
        pairs = [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2)][: (1, 3, 6)[derivatives]]
        P = self.control_points
        out = tuple(
            _k.grid_eval(
                *frozen(
                    fu,
                    np.ascontiguousarray(Nu[:, du, :]),
                    fv,
                    np.ascontiguousarray(Nv[:, dv, :]),
                    P,
                )
            )
            for du, dv in pairs
        )
        return out[0] if derivatives == 0 else out

    def normals(self, u: ArrayLike, v: ArrayLike) -> NDArray[np.float64]:
        """Unit normals ``S_u x S_v / |S_u x S_v|`` at parameter pairs: ``(*s, 3) float64``.

        Where the partials are parallel or vanish (a collapsed boundary row), the normal is
        taken a small step (``tol.BSPLINE_NORMAL_STEP`` of the parameter range) towards the
        middle of the patch.
        """
        uu, vv = np.broadcast_arrays(
            np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
        )
        _, Su, Sv = self.evaluate(uu, vv, derivatives=1)
        return _unit_normals(self, uu, vv, Su, Sv)

    def frames(
        self, u: ArrayLike, v: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Orthonormal local frame ``(T, B, N)`` at parameter pairs, each ``(*s, 3) float64``.

        ``T = S_u / |S_u|``, ``N`` the unit normal, ``B = N x T`` (so ``T, B, N`` is right
        handed and ``B`` leans towards ``S_v``). This is the frame of the displacement and
        bump maps (Krishnamurthy 2000, sec. 7.2, eq. 7.1 made orthonormal).
        """
        uu, vv = np.broadcast_arrays(
            np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
        )
        _, Su, Sv = self.evaluate(uu, vv, derivatives=1)
        return _frames_from_partials(self, uu, vv, Su, Sv)

    def points_and_frames(
        self, u: ArrayLike, v: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Points and orthonormal frames at parameter pairs from one evaluation.

        Parameters
        ----------
        u, v : array_like float64
            Parameters in [0, 1] (clipped), broadcast against each other to a shape ``s``.

        Returns
        -------
        S, T, B, N : (*s, 3) float64
            :meth:`evaluate` and :meth:`frames` at the same parameters.
        """
        uu, vv = np.broadcast_arrays(
            np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
        )
        S, Su, Sv = self.evaluate(uu, vv, derivatives=1)
        return (S, *_frames_from_partials(self, uu, vv, Su, Sv))


def _unit_normals(surface, uu, vv, Su, Sv):
    n = np.cross(Su, Sv)
    ln = np.linalg.norm(n, axis=-1)
    scale = np.linalg.norm(Su, axis=-1) * np.linalg.norm(Sv, axis=-1)
    bad = ln <= tol.BSPLINE_DEGENERATE * np.maximum(scale, np.finfo(float).tiny)
    if bad.any():
        h = tol.BSPLINE_NORMAL_STEP
        ub = uu[bad] + h * np.sign(0.5 - uu[bad])
        vb = vv[bad] + h * np.sign(0.5 - vv[bad])
        _, su, sv = surface.evaluate(ub, vb, derivatives=1)
        n[bad] = np.cross(su, sv)
        ln = np.linalg.norm(n, axis=-1)
    return n / np.maximum(ln, np.finfo(float).tiny)[..., None]


def _frames_from_partials(surface, uu, vv, Su, Sv):
    N = _unit_normals(surface, uu, vv, Su, Sv)
    # T: S_u projected on the tangent plane (it already is, unless the normal came from a
    # neighbouring parameter at a degenerate point)
    T = Su - (Su * N).sum(axis=-1)[..., None] * N
    lt = np.linalg.norm(T, axis=-1)
    bad = lt <= tol.BSPLINE_DEGENERATE * np.maximum(np.linalg.norm(Su, axis=-1), 1e-300)
    if bad.any():  # S_u vanishes: use S_v to orient the frame
        Tb = np.cross(Sv[bad] - (Sv[bad] * N[bad]).sum(-1)[..., None] * N[bad], N[bad])
        T[bad] = Tb
        lt = np.linalg.norm(T, axis=-1)
    T = T / np.maximum(lt, np.finfo(float).tiny)[..., None]
    B = np.cross(N, T)
    return T, B, N
