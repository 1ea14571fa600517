"""A fold-free planar map of a patch onto the unit square (convex-combination map, private).

The spring mesh's starting points and subdivision mid-points can be taken as the images of
regular parameter points under this map: a mean-value (Floater) map with the boundary fixed
by arc length along the four sides is a bijection onto the square (Tutte's theorem: positive
weights and a convex boundary), so a grid located in it never starts folded.
"""

from __future__ import annotations

import hashlib
import threading
import weakref

import numpy as np
from numpy.typing import NDArray

from meshfit import tol
from meshfit._kernels import planar as _kp
from meshfit._kernels import springs as _k
from meshfit._kernels import springs_aux as _aux
from meshfit.mesh import Mesh
from meshfit.springs.features import Sides
from meshfit.types import SurfacePoints

__all__ = ["PlanarMap", "clear_map_cache", "square_map"]


class PlanarMap:
    """Vertex positions of a patch mesh in the unit square and point location in it.

    Attributes
    ----------
    uv : (n_vertices, 2) float64
        Parameter of each vertex; the sides lie on ``v = 0`` (bottom), ``u = 1`` (right),
        ``v = 1`` (top) and ``u = 0`` (left).
    """

    def __init__(self, mesh: Mesh, uv: NDArray[np.float64], _buckets=None):
        self.mesh = mesh
        uv = np.ascontiguousarray(uv, dtype=np.float64)
        uv.flags.writeable = False  # shared by every caller of square_map on this patch
        self.uv = uv
        # about two faces per bucket
        self._g = max(1, int(np.sqrt(mesh.n_faces / 2.0)))
        self._buckets = _k.uv_buckets(uv, mesh.faces, self._g) if _buckets is None else _buckets

    def uv_of(self, face: NDArray[np.int64], bary: NDArray[np.float64]) -> NDArray[np.float64]:
        """(m, 2) parameters of face points (``face`` (m,), ``bary`` (m, 3))."""
        face = np.ascontiguousarray(face, dtype=np.int64).reshape(-1)
        bary = np.ascontiguousarray(bary, dtype=np.float64)
        if bary.shape != (face.size, 3):
            raise ValueError(f"uv_of needs bary of shape ({face.size}, 3), got {bary.shape}")
        self._check_faces(face)
        return _aux.face_point_sums(self.uv, self.mesh.faces, face, bary)

    def mid_uv(
        self,
        face: NDArray[np.int64],
        bary: NDArray[np.float64],
        a: NDArray[np.int64],
        b: NDArray[np.int64],
    ) -> NDArray[np.float64]:
        """(m, 2) mean parameters of the face points ``a`` and ``b`` ((m,) indices into the
        points ``face`` (g,), ``bary`` (g, 3)): ``0.5 * (uv_of(a) + uv_of(b))``."""
        face = np.ascontiguousarray(face, dtype=np.int64).reshape(-1)
        bary = np.ascontiguousarray(bary, dtype=np.float64)
        a = np.ascontiguousarray(a, dtype=np.int64).reshape(-1)
        b = np.ascontiguousarray(b, dtype=np.int64).reshape(-1)
        g = face.size
        if bary.shape != (g, 3) or a.size != b.size:
            raise ValueError("mid_uv needs bary (g, 3) for face (g,) and as many a as b")
        if a.size and (min(a.min(), b.min()) < 0 or max(a.max(), b.max()) >= g):
            raise IndexError("mid_uv: point index out of range")
        self._check_faces(face)
        return _aux.mid_parameters(self.uv, self.mesh.faces, face, bary, a, b)

    def _check_faces(self, face: NDArray[np.int64]) -> None:
        """Raise IndexError unless every entry of ``face`` is a face of the patch mesh."""
        if face.size and (face.min() < 0 or face.max() >= self.mesh.n_faces):
            raise IndexError("face index out of range of the patch mesh")

    def locate(self, q: NDArray[np.float64]) -> SurfacePoints:
        """Face points of the patch mesh whose parameters are ``q`` (m, 2), clamped into the
        square (a point on an edge goes to either face)."""
        q = np.ascontiguousarray(q, dtype=np.float64)
        face, bary = _k.locate_uv(self.uv, self.mesh.faces, *self._buckets, self._g, q)
        return SurfacePoints.owned(face, bary)


def _interior_system(
    mesh: Mesh, uv: NDArray, fixed: NDArray, free: NDArray, scale: NDArray | None = None
):
    """The mean-value equations of the interior vertices: ``A`` (m, m) CSR over ``free`` and
    the right-hand side (m, 2) from the fixed boundary parameters ``uv[fixed]``.

    Row ``i``: ``sum_j w_ij (x_i - x_j) = 0``, the fixed ``x_j`` moved to the right; with
    ``scale`` (n,) each weight ``w_ij`` is multiplied by ``scale[j]``.
    """
    import scipy.sparse as sp

    n, m = mesh.n_vertices, free.size
    at = np.full(n, -1, dtype=np.int64)
    at[free] = np.arange(m)
    # the floor only keeps zero-length edges finite: the mean over the faces' three edges
    # sets its scale without the unique-edge table that Mesh.mean_edge_length builds
    floor = tol.BARY_EPS * _aux.mean_face_edge(
        np.ascontiguousarray(mesh.vertices, dtype=np.float64),
        np.ascontiguousarray(mesh.faces, dtype=np.int64),
    )
    indptr, indices, data, rhs = _kp.mean_value_system(
        np.ascontiguousarray(mesh.vertices, dtype=np.float64),
        np.ascontiguousarray(mesh.faces, dtype=np.int64),
        at,
        np.ascontiguousarray(uv, dtype=np.float64),
        floor,
        tol.BARY_EPS,
        np.ones(n) if scale is None else np.ascontiguousarray(scale, dtype=np.float64),
    )
    A = sp.csr_matrix((data, indices, indptr), shape=(m, m))
    A.has_sorted_indices = True
    return A, rhs


#: the interior solve stops when every equation's residual over its diagonal (a length in
#: the unit square) is below this; the error is then below this times the largest expected
#: exit time of a random walk on the weights (which grows with the patch's vertex count)
_SOLVE_TOL = 1e-14
#: a restart that no longer halves the residual has met the arithmetic's floor (the
#: scaled residual of a large system can stall a few times above `_SOLVE_TOL`): the solve
#: stops there, keeping its answer when the residual is below this, else the direct solve
_FLOOR_TOL = 1e-12
#: multigrid levels stop coarsening at this many unknowns (solved densely)
_COARSEST = 300
#: strength threshold of the aggregation (``|a_ij| >= theta sqrt(a_ii a_jj)``)
_STRENGTH = 0.1
#: Jacobi damping of the prolongation smoother (4/3 over the bound 2 of rho(D^-1 A))
_OMEGA = 2.0 / 3.0
#: systems with at most this many unknowns are solved by the sparse LU factorization at once
#: (on small systems the factorization is faster than the iterative solve; the bound sits
#: with a margin below the size where the two cost the same)
_DIRECT_MAX = 30_000
#: GMRES restart length and cap on preconditioned iterations before the direct solve is used
_RESTART = 40
_MAX_ITER = 80
#: Gauss-Seidel sweeps before and after each coarse correction, on the finest level and on
#: the coarser ones (Galerkin coarse operators of the non-symmetric weights are not M-matrices:
#: more sweeps there slow the solve down)
_SWEEPS = (2, 1)


class _Multigrid:
    """Smoothed-aggregation V-cycle for ``A x = b`` with two right-hand-side columns:
    forward Gauss-Seidel sweeps before and backward sweeps after each coarse correction
    (:data:`_SWEEPS`)."""

    def __init__(self, A):
        import scipy.sparse as sp

        self.levels = []
        while A.shape[0] > _COARSEST:
            A = A.tocsr()
            A.sort_indices()
            ip = A.indptr.astype(np.int64)
            ix = A.indices.astype(np.int64)
            d = np.ascontiguousarray(A.data, dtype=np.float64)
            agg, na = _kp.aggregate(ip, ix, d, _STRENGTH)
            m = A.shape[0]
            if na >= m:  # nothing aggregates: stop here
                break
            T = sp.csr_matrix((np.ones(m), agg, np.arange(m + 1)), shape=(m, na))
            AT = A @ T
            P = (T - AT.multiply((_OMEGA / A.diagonal())[:, None])).tocsr()
            R = P.T.tocsr()
            self.levels.append((ip, ix, d, P, R))
            A = R @ (A @ P)
        self.lu, self.piv = _kp.dense_lu(np.ascontiguousarray(A.toarray()))

    def cycle(self, b: NDArray, k: int = 0) -> NDArray:
        """One V-cycle from a zero guess: an approximation of ``A^-1 b`` (linear in b)."""
        if k == len(self.levels):
            return _kp.dense_lu_solve(self.lu, self.piv, np.ascontiguousarray(b))
        ip, ix, d, P, R = self.levels[k]
        sweeps = _SWEEPS[0] if k == 0 else _SWEEPS[1]
        x = np.zeros_like(b)
        _kp.gauss_seidel(ip, ix, d, x, b, sweeps, False)
        r = np.empty_like(b)
        _kp.scaled_residual(ip, ix, d, x, b, r)
        x += P @ self.cycle(np.ascontiguousarray(R @ r), k + 1)
        _kp.gauss_seidel(ip, ix, d, x, b, sweeps, True)
        return x


def _gmres(A, b: NDArray, mg: _Multigrid, x0: NDArray | None = None) -> NDArray | None:
    """Right-preconditioned restarted GMRES on ``A x = b`` (both columns as one system) from
    ``x0`` (default zero); None when it does not reach :data:`_SOLVE_TOL` within
    :data:`_MAX_ITER` iterations, or stalls above :data:`_FLOOR_TOL` (an answer that stalls
    below it is kept)."""
    ip, ix, d = A.indptr, A.indices, A.data
    m = b.shape[0]
    x = np.zeros_like(b) if x0 is None else np.array(x0, dtype=np.float64, order="C")
    r = np.empty_like(b)
    zero = np.zeros_like(b)
    Q = np.empty((_RESTART + 1, m, 2))
    Z = np.empty((_RESTART, m, 2))
    H = np.zeros((_RESTART + 1, _RESTART))
    # the residual's 2-norm at which its scaled entries are likely below the target (checked)
    target = _SOLVE_TOL * float(A.diagonal().min()) * np.sqrt(m)
    done, last = 0, np.inf
    while True:
        worst = _kp.scaled_residual(ip, ix, d, x, b, r)
        if not np.isfinite(worst):
            return None
        if worst <= _SOLVE_TOL:
            return x
        if worst > 0.5 * last:  # stalled
            return x if worst <= _FLOOR_TOL else None
        if done >= _MAX_ITER:
            return None
        last = worst
        beta = _kp.norm2(r)
        np.divide(r, beta, out=Q[0])
        H[:] = 0.0
        g = np.zeros(_RESTART + 1)
        g[0] = beta
        cs = np.zeros(_RESTART)
        sn = np.zeros(_RESTART)
        k = 0
        for k in range(_RESTART):
            Z[k] = mg.cycle(Q[k])
            w = np.empty_like(b)
            _kp.scaled_residual(ip, ix, d, Z[k], zero, w)  # w = -A z
            np.negative(w, out=w)
            hk1 = _kp.arnoldi(Q, k, w, H)
            H[k + 1, k] = hk1
            for i in range(k):  # the earlier Givens rotations
                hi = cs[i] * H[i, k] + sn[i] * H[i + 1, k]
                H[i + 1, k] = -sn[i] * H[i, k] + cs[i] * H[i + 1, k]
                H[i, k] = hi
            den = float(np.hypot(H[k, k], H[k + 1, k]))
            cs[k], sn[k] = H[k, k] / den, H[k + 1, k] / den
            H[k, k], H[k + 1, k] = den, 0.0
            g[k + 1], g[k] = -sn[k] * g[k], cs[k] * g[k]
            done += 1
            if abs(g[k + 1]) <= target or hk1 == 0.0:
                break
        _kp.gmres_update(x, Z, H, g, k)


def _solve_interior(
    mesh: Mesh,
    uv: NDArray,
    fixed: NDArray,
    free: NDArray,
    scale: NDArray | None = None,
    guess: NDArray | None = None,
) -> NDArray:
    """Parameters (m, 2) of the interior vertices ``free``.

    A sparse LU solve up to :data:`_DIRECT_MAX` unknowns; above, multigrid-preconditioned
    GMRES to :data:`_SOLVE_TOL` (the map agrees with a direct solve to round-off times the
    system's conditioning), from ``guess`` (m, 2) when given (a map close to the solution:
    fewer iterations to the same tolerance), and the LU solve when that does not converge.
    ``scale`` reweights the equations (see `_interior_system`).
    """
    A, rhs = _interior_system(mesh, uv, fixed, free, scale)
    iterative = A.shape[0] > max(_COARSEST, _DIRECT_MAX)
    x = _gmres(A, rhs, _Multigrid(A), guess) if iterative else None
    if x is None:
        x = _direct_solve(A, rhs)
    return x


def _direct_solve(A, rhs: NDArray) -> NDArray:
    """``A^-1 rhs`` by a sparse LU factorization."""
    from scipy.sparse.linalg import splu

    # A is an M-matrix (positive diagonal, negative off-diagonal, weakly diagonally dominant
    # rows, strictly next to the boundary): the diagonal pivots are stable, and a symmetric
    # fill-reducing ordering of its (symmetric) pattern keeps the factors small
    lu = splu(A.tocsc(), **_LU_OPTIONS)
    return lu.solve(rhs)


#: SuperLU options of the direct solve (see :func:`_direct_solve`)
_LU_OPTIONS: dict = {
    "permc_spec": "MMD_AT_PLUS_A",
    "diag_pivot_thresh": 0.0,
    "options": {"SymmetricMode": True},
}


#: square maps already made, per patch mesh and sides: their arrays only (``uv``, buckets),
#: since a value that referred to its mesh would keep the weak key, and the mesh, alive
_MAPS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_MAPS_LOCK = threading.Lock()


def _sides_key(sides: Sides) -> bytes:
    h = hashlib.blake2b(digest_size=16)
    for name in ("bottom", "right", "top", "left"):
        h.update(np.ascontiguousarray(sides.chains[name], dtype=np.int64).tobytes())
        h.update(b"|")
        h.update(np.ascontiguousarray(sides.arcs[name], dtype=np.float64).tobytes())
        h.update(b"/")
    return h.digest()


def clear_map_cache() -> None:
    """Forget the square maps :func:`square_map` keeps (they also go with their meshes)."""
    with _MAPS_LOCK:
        _MAPS.clear()


def square_map(mesh: Mesh, sides: Sides, *, balanced: bool = False) -> PlanarMap:
    """Mean-value map of a four-sided disk patch onto the unit square.

    Boundary vertices go to the square's sides by arc length along each side; interior
    vertices are the mean-value convex combinations of their neighbours (one solve for both
    coordinates: a sparse LU factorization up to 30,000 interior vertices, above that
    smoothed-aggregation multigrid-preconditioned GMRES to a residual at round-off, the LU
    factorization if that does not converge). The map is kept while ``mesh`` lives: asking
    again for the same mesh object, sides and ``balanced`` (the next level of a
    coarse-to-fine preview) returns it at once.

    With ``balanced`` (keyword-only, default False) the weights are then reweighted by the
    vertices' stretch, solve after solve while the patch's overall stretch falls (at most
    ``STRETCH_ROUNDS`` = 6 solves): parts of the patch that the mean-value map squeezes
    into a sliver of the square (a pleat, a bulge, the wide end of a near-triangular patch)
    get their share of it. Still a bijection (positive weights).

    References
    ----------
    .. [1] Floater, "Mean value coordinates", CAGD 20 (2003); Tutte, "How to draw a graph"
       (1963). Used for the starting grid of Krishnamurthy 2000, sec. 5.4.
    .. [2] Vanek, Mandel & Brezina, "Algebraic multigrid by smoothed aggregation for second
       and fourth order elliptic problems", Computing 56 (1996); Saad & Schultz, "GMRES",
       SIAM J. Sci. Stat. Comput. 7 (1986).
    .. [3] Yoshizawa, Belyaev & Seidel, "A fast and simple stretch-minimizing mesh
       parameterization", Shape Modeling International 2004; Sander, Snyder, Gortler &
       Hoppe, "Texture mapping progressive meshes", SIGGRAPH 2001 (the L2 stretch).
    """
    key = _sides_key(sides) + (b"b" if balanced else b"m")
    with _MAPS_LOCK:
        hit = _MAPS.get(mesh, {}).get(key)
    if hit is not None:
        return PlanarMap(mesh, *hit)
    if balanced:  # reweighted from the plain map, itself solved once (and kept)
        plain = square_map(mesh, sides)
        _, fixed = _boundary(mesh.n_vertices, sides)
        free = np.flatnonzero(~fixed)
        uv = _balanced(mesh, plain.uv.copy(), fixed, free) if free.size else plain.uv
        pmap = PlanarMap(mesh, uv)
    else:
        pmap = _square_map(mesh, sides)
    with _MAPS_LOCK:
        _MAPS.setdefault(mesh, {})[key] = (pmap.uv, pmap._buckets)
    return pmap


def _square_map(mesh: Mesh, sides: Sides, index: NDArray[np.int64] | None = None) -> PlanarMap:
    """:func:`square_map` without the cache or the balance. ``index`` maps the sides'
    vertex numbers to ``mesh``'s (a coarse copy of the patch that keeps its boundary
    vertices)."""
    uv, fixed = _boundary(mesh.n_vertices, sides, index)
    free = np.flatnonzero(~fixed)
    if free.size:
        uv[free] = _solve_interior(mesh, uv, fixed, free)
    return PlanarMap(mesh, uv)


def _boundary(
    n: int, sides: Sides, index: NDArray[np.int64] | None = None
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Parameters ``(n, 2)`` with the sides' vertices on the square's sides by arc length
    (the others 0), and which vertices those are (``index``: see `_square_map`)."""
    uv = np.zeros((n, 2))
    fixed = np.zeros(n, dtype=bool)
    for name, (axis, const) in {
        "bottom": (0, 0.0),
        "top": (0, 1.0),
        "left": (1, 0.0),
        "right": (1, 1.0),
    }.items():
        chain = sides.chains[name] if index is None else index[sides.chains[name]]
        arc = sides.arcs[name]
        t = arc / arc[-1] if arc[-1] > 0 else np.linspace(0.0, 1.0, len(arc))
        uv[chain, axis] = t
        uv[chain, 1 - axis] = const
        fixed[chain] = True
    return uv, fixed


#: most reweighting rounds (each one solve)
STRETCH_ROUNDS = 6


def _vertex_stretch(mesh: Mesh, uv: NDArray) -> tuple[NDArray, float]:
    """Per vertex, the area-weighted root mean square of its faces' L2 stretch (Sander et
    al. 2001; the square scaled to the patch's area; 1 where no face has an area in the
    square); and the same over the whole patch."""
    F = mesh.faces
    X = mesh.vertices
    a3 = mesh.face_areas
    s, t = uv[:, 0], uv[:, 1]
    s1, s2, s3 = s[F[:, 0]], s[F[:, 1]], s[F[:, 2]]
    t1, t2, t3 = t[F[:, 0]], t[F[:, 1]], t[F[:, 2]]
    auv2 = (s2 - s1) * (t3 - t1) - (s3 - s1) * (t2 - t1)  # twice the signed area
    auv = 0.5 * np.abs(auv2)
    total3, total_uv = float(a3.sum()), float(auv.sum())
    ok = auv > tol.BARY_EPS * total_uv / max(len(F), 1)
    q1, q2, q3 = X[F[:, 0]], X[F[:, 1]], X[F[:, 2]]
    den = np.where(ok, auv2, 1.0)[:, None]
    Ss = (q1 * (t2 - t3)[:, None] + q2 * (t3 - t1)[:, None] + q3 * (t1 - t2)[:, None]) / den
    St = (q1 * (s3 - s2)[:, None] + q2 * (s1 - s3)[:, None] + q3 * (s2 - s1)[:, None]) / den
    # the square scaled to the patch's area: the partials shrink by sqrt(total3 / total_uv)
    gamma2 = np.where(ok, 0.5 * ((Ss * Ss).sum(axis=1) + (St * St).sum(axis=1)), 1.0)
    gamma2 *= total_uv / total3
    w = np.where(ok, a3, 0.0)
    num = np.zeros(mesh.n_vertices)
    den_v = np.zeros(mesh.n_vertices)
    for c in range(3):
        num += np.bincount(F[:, c], weights=w * gamma2, minlength=mesh.n_vertices)
        den_v += np.bincount(F[:, c], weights=w, minlength=mesh.n_vertices)
    sigma = np.sqrt(np.where(den_v > 0, num / np.where(den_v > 0, den_v, 1.0), 1.0))
    overall = float(np.sqrt((w * gamma2).sum() / max(w.sum(), 1e-300)))
    return sigma, overall


def _balanced(mesh: Mesh, uv: NDArray, fixed: NDArray, free: NDArray) -> NDArray:
    """The mean-value map ``uv`` reweighted where it squeezes part of the patch into a small
    part of the square (a bulge, a pleat): each neighbour's weight is divided by its vertex
    stretch, round after round, while the overall stretch falls (at most
    :data:`STRETCH_ROUNDS` solves). The weights stay positive, so every map is still a
    bijection onto the square.

    References
    ----------
    .. [1] Yoshizawa, Belyaev & Seidel, "A fast and simple stretch-minimizing mesh
       parameterization", Shape Modeling International 2004.
    """
    sigma, best = _vertex_stretch(mesh, uv)
    scale = np.ones(mesh.n_vertices)
    for _ in range(STRETCH_ROUNDS):
        scale = scale / sigma
        trial = uv.copy()
        trial[free] = _solve_interior(mesh, uv, fixed, free, scale, guess=uv[free])
        sigma, overall = _vertex_stretch(mesh, trial)
        if not overall < best:
            break
        uv, best = trial, overall
    return uv
