"""Surface snakes: minimum-energy face-point curves relaxed on the mesh (thesis sec. 3.5-3.8.1).

A surface snake is a :class:`~meshfit.types.SurfaceCurve` whose face points are moved by
variational Euler forces computed from the 3-D positions of their neighbours along the
curve: a membrane (fairness) force, a thin-plate (curvature) force and an arc-length force
that keeps the samples evenly spaced, plus an optional external force (e.g. colour
attraction, :mod:`meshfit.curves.color`). Only the component of the resultant in the tangent
plane of the point's face is used; points slide over the surface by walking
(:func:`meshfit.surface.walk_points`) and are never re-projected. Forces are evaluated on a
hierarchy of resolutions of the curve (neighbours at distance ``2**l``, weights halving per
level) so an impulse at one end propagates along the whole snake in one iteration.

- :func:`relax_snake` relaxes a whole snake (some points fixed);
- :func:`edit_snake` pulls one edit point and relaxes only a symmetric edit section around it.

Both take their relaxation settings (weights, levels, step, iteration cap, tolerance) as one
:class:`SnakeOptions`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit import tol
from meshfit._kernels import snake as _ks
from meshfit._kernels import walk as _walk
from meshfit._validate import as_surface_points
from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = ["SnakeOptions", "SnakeResult", "edit_snake", "relax_snake", "snake_forces"]

#: default stopping tolerance of :func:`relax_snake`: largest move, times the mean edge length
SNAKE_MOVE_TOL = 1e-4
#: edge crossings allowed per point per relaxation step (a step is at most a fraction of the
#: curve spacing, so a few faces at most)
_MAX_FACES = 64

ExternalForce = Callable[[SurfaceCurve], ArrayLike]


@dataclass(frozen=True, eq=False)
class SnakeResult:
    """Result of :func:`relax_snake` and :func:`edit_snake`.

    Attributes
    ----------
    curve : SurfaceCurve
        The relaxed curve (same number of points, same ``closed`` and ``kind``).
    iterations : int
        Relaxation iterations run.
    max_move : (iterations,) float64
        Largest distance any point walked in each iteration, model units.
    converged : bool
        The last iteration's largest move was below the stopping tolerance.
    """

    curve: SurfaceCurve
    iterations: int
    max_move: NDArray[np.float64]
    converged: bool


@dataclass(frozen=True)
class SnakeOptions:
    """Relaxation settings of :func:`relax_snake` and :func:`edit_snake` (all have defaults;
    frozen, so one value can be shared by many calls). The values are checked, and the
    numbers converted to ``float`` / ``int``, when the options are made.

    Attributes
    ----------
    w_fair : float
        Membrane (fairness) weight, >= 0: the curve behaves like a tight elastic band
        (default 1).
    w_curv : float
        Thin-plate (curvature) weight, >= 0: the curve behaves like a stiff wire (default 0).
    w_arc : float
        Arc-length weight, >= 0: evens out the sample spacing (default 1).
    levels : int, optional
        Resolutions of the coarse-to-fine force evaluation (eq. 3.16), >= 1; 1 evaluates
        forces at the curve's own resolution only. Default ``None``: as many as the relaxed
        curve's (or edit section's) length allows (strides up to about half its samples).
    step : float
        Largest move per iteration as a fraction of the local sample spacing, in (0, 1]
        (default 0.25).
    max_iter : int
        Iteration cap, >= 0 (default 5000; 0 moves no point).
    tol_move : float
        Stopping tolerance, >= 0, relative to the mean edge length (default
        `SNAKE_MOVE_TOL`).

    Raises
    ------
    meshfit.errors.InputError
        A weight, ``step`` or ``tol_move`` is not a finite number in range, or ``levels`` /
        ``max_iter`` is not an integer in range (the message names the field).
    """

    w_fair: float = 1.0
    w_curv: float = 0.0
    w_arc: float = 1.0
    levels: int | None = None
    step: float = 0.25
    max_iter: int = 5000
    tol_move: float = SNAKE_MOVE_TOL

    def __post_init__(self) -> None:
        for name in ("w_fair", "w_curv", "w_arc", "step", "tol_move"):
            object.__setattr__(self, name, _as_weight(getattr(self, name), name))
        if not 0.0 < self.step <= 1.0:
            raise InputError(f"step must be in (0, 1], got {self.step!r}")
        object.__setattr__(self, "max_iter", _as_count(self.max_iter, "max_iter", minimum=0))
        if self.levels is not None:
            object.__setattr__(self, "levels", _as_count(self.levels, "levels"))


def _as_options(options: SnakeOptions | None) -> SnakeOptions:
    """``options``, or the defaults for None; anything else raises InputError."""
    if options is None:
        return SnakeOptions()
    if not isinstance(options, SnakeOptions):
        raise InputError(f"options must be SnakeOptions, got {type(options).__name__}")
    return options


# ------------------------------------------------------------------------------------ forces
def _auto_levels(n: int, closed: bool) -> int:
    """Number of resolutions such that the coarsest stride still has neighbours both sides."""
    reach = (n - 1) // 2
    return 1 if reach < 1 else int(np.floor(np.log2(reach))) + 1


def snake_forces(
    xyz: ArrayLike,
    *,
    closed: bool,
    w_fair: float = 1.0,
    w_curv: float = 0.0,
    w_arc: float = 1.0,
    levels: int = 1,
) -> NDArray[np.float64]:
    """Variational Euler forces on each curve sample, coarse to fine (3-D, not yet projected).

    At resolution ``l`` the neighbours of sample ``i`` are ``i +- k`` with ``k = 2**l``; a level
    contributes to a sample only where its stencil fits inside an open curve (a closed curve
    wraps). Per sample the level forces are averaged with weights ``2**-l`` (normalised over
    the levels that contribute), so the equilibrium of an evenly spaced straight or circular
    curve is the same at every level.

    Parameters
    ----------
    xyz : (n, 3) float64
        Positions of the curve samples, model units.
    closed : bool, keyword-only
        Whether sample ``n - 1`` connects back to sample 0.
    w_fair, w_curv, w_arc : float, keyword-only
        Weights of the membrane, thin-plate and arc-length forces.
    levels : int, keyword-only
        Number of resolutions (1: the curve's own resolution only).

    Returns
    -------
    (n, 3) float64
        Resultant force per sample: a displacement, model units. Membrane:
        ``(x[i-k] + x[i+k]) / 2 - x[i]``; thin plate: ``-(x[i-2k] - 4x[i-k] + 6x[i] - 4x[i+k]
        + x[i+2k]) / 8`` (both move a sample at most to its equilibrium per unit weight);
        arc length: half the difference of the distances to the two neighbours, toward the
        more distant one.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD thesis,
       Stanford 2000, sec. 3.6.1 (eq. 3.11-3.12), sec. 3.6.3 (eq. 3.15), sec. 3.7 (eq. 3.16).
    """
    x = np.ascontiguousarray(xyz, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3:
        raise InputError(f"xyz must have shape (n, 3), got {x.shape}")
    if not np.isfinite(x).all():
        raise InputError(
            f"xyz is not finite at sample {int(np.flatnonzero(~np.isfinite(x).all(1))[0])}"
        )
    return _ks.snake_forces(
        x,
        bool(closed),
        _as_weight(w_fair, "w_fair"),
        _as_weight(w_curv, "w_curv"),
        _as_weight(w_arc, "w_arc"),
        _as_count(levels, "levels"),
    )


# ------------------------------------------------------------------------------- validation
def _as_weight(value: float, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}") from None
    if not np.isfinite(v) or v < 0.0:
        raise InputError(f"{name} must be a finite number >= 0, got {value!r}")
    return v


def _as_count(value, name: str, *, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _as_curve(mesh: Mesh, curve: SurfaceCurve, name: str = "curve") -> SurfaceCurve:
    if not isinstance(curve, SurfaceCurve):
        raise InputError(f"{name} must be a SurfaceCurve, got {type(curve).__name__}")
    as_surface_points(mesh, curve.points, name=f"{name}.points")
    if len(curve) < 2:
        raise InputError(f"{name} has {len(curve)} points; a snake needs at least 2")
    return curve


def _fixed_mask(fixed, n: int, closed: bool) -> NDArray[np.bool_]:
    mask = np.zeros(n, dtype=bool)
    if fixed is None:
        if not closed:
            mask[[0, n - 1]] = True
        return mask
    f = np.asarray(fixed).reshape(-1)
    if f.size == 0:
        return mask
    if f.dtype == bool:
        if f.shape[0] != n:
            raise InputError(f"fixed as a mask must have {n} entries, got {f.shape[0]}")
        return f.copy()
    if not np.issubdtype(f.dtype, np.integer):
        raise InputError(f"fixed must hold integer point indices, got dtype {f.dtype}")
    bad = f[(f < -n) | (f >= n)]
    if bad.size:
        raise InputError(f"fixed index {int(bad[0])} is out of range for a {n}-point curve")
    mask[f % n] = True
    return mask


def _external(external, curve: SurfaceCurve, n: int) -> NDArray[np.float64]:
    f = external(curve) if callable(external) else external
    a = np.asarray(f, dtype=np.float64)
    if a.shape != (n, 3):
        raise InputError(f"external force must have shape ({n}, 3), got {a.shape}")
    bad = np.flatnonzero(~np.isfinite(a).all(axis=1))
    if bad.size:
        raise InputError(f"external force is not finite at curve point {int(bad[0])}")
    return a


# ----------------------------------------------------------------------------------- moving
def _pairs_ok(faces: NDArray[np.int64], face: NDArray[np.int64], closed: bool) -> NDArray[np.bool_]:
    """Sampling rule per segment: its two points lie on faces that touch.

    Same face, edge-adjacent faces, or faces sharing a vertex (which
    :func:`meshfit.surface.cut_mesh` joins through that vertex).
    """
    return _ks.pairs_ok(faces, np.ascontiguousarray(face, dtype=np.int64), bool(closed))


def _share_pairs(
    mesh: Mesh,
    face: NDArray[np.int64],
    bary: NDArray[np.float64],
    closed: bool,
    fixed: NDArray[np.bool_] | None = None,
) -> NDArray[np.int64]:
    """``face`` with curve points that lie on a mesh vertex or edge written in another face
    there, where that makes a segment's two faces share a vertex (the pair rule the moves
    keep). A painted curve passes through vertices; written in any one face around the
    vertex, its segments may pass the layout's check (which looks at every face holding the
    point) but not the face-based test of `_pairs_ok`, and a segment that fails that test at
    the start is not protected during the relaxation. Barycentrics are permuted with the
    face, so the points do not move; ``fixed`` points keep their faces. ``bary`` is
    permuted in place."""
    ok = _pairs_ok(mesh.faces, face, closed)
    if ok.all():
        return face
    F = mesh.faces
    ptr, around = mesh.vertex_faces
    n = face.shape[0]
    face = face.copy()

    def shares(a: int, b: int) -> bool:
        return bool(np.isin(F[a], F[b]).any())

    def fits(p: int, g: int) -> bool:
        ends = [q % n for q in (p - 1, p + 1) if closed or 0 <= q < n]
        return all(shares(g, int(face[q])) for q in ends)

    for seg in np.flatnonzero(~ok):
        for p in (int(seg + 1) % n, int(seg)):
            if fixed is not None and fixed[p]:
                continue
            f = int(face[p])
            on = np.flatnonzero(bary[p] > tol.BARY_EPS)
            if on.size == 3:
                continue  # inside its face: one way to write it
            held = F[f, on]  # the vertex (or edge's two vertices) the point lies on
            cands = around[ptr[held[0]] : ptr[held[0] + 1]]
            cands = [int(g) for g in cands if g != f and np.isin(held, F[g]).all()]
            best = next((g for g in cands if fits(p, g)), None)
            if best is not None:
                w = np.zeros(3)
                for k, v in zip(on, held, strict=True):
                    w[int(np.flatnonzero(F[best] == v)[0])] = bary[p, k]
                bary[p] = w
                face[p] = best
                break
    return face


class _Stepper:
    """Walk curve points by capped tangent moves without breaking the sampling rule."""

    def __init__(self, mesh: Mesh, closed: bool):
        self.mesh = mesh
        self.closed = closed
        self.V = mesh.vertices
        self.F = mesh.faces
        self.FN = mesh.face_neighbors
        self.N = mesh.face_normals
        self.VN = mesh.vertex_normals
        self.eps = tol.length(mesh, tol.WALK_EPS)

    def walk(self, face, bary, move):
        f, b, length, _, _ = _walk.walk_points(
            self.V, self.F, self.FN, face, bary, move, _MAX_FACES, self.eps, tol.BARY_EPS
        )
        return f, b, length

    def step(self, face, bary, move):
        """Walk every point by ``move`` (n, 3); shorten moves that break the sampling rule."""
        n = face.shape[0]
        closed = self.closed
        ok0 = _pairs_ok(self.F, face, closed)
        nf, nb, length = self.walk(face, bary, move)
        move = move.copy()
        for _attempt in range(6):
            bad = ok0 & ~_pairs_ok(self.F, nf, closed)
            if not bad.any():
                return nf, nb, length
            seg = np.flatnonzero(bad)
            pts = np.unique(np.concatenate([seg, (seg + 1) % n]))
            pts = pts[np.linalg.norm(move[pts], axis=1) > 0]
            if pts.size == 0:
                break
            move[pts] *= 0.5
            f2, b2, l2 = self.walk(face[pts], np.ascontiguousarray(bary[pts]), move[pts])
            nf[pts], nb[pts], length[pts] = f2, b2, l2
        # still broken: put the offending points back until every segment that obeyed the
        # rule before obeys it again (terminates: all points back is the starting state)
        while True:
            bad = ok0 & ~_pairs_ok(self.F, nf, closed)
            if not bad.any():
                return nf, nb, length
            seg = np.flatnonzero(bad)
            pts = np.unique(np.concatenate([seg, (seg + 1) % n]))
            nf[pts], nb[pts], length[pts] = face[pts], bary[pts], 0.0


def _spacing(x: NDArray[np.float64], closed: bool) -> NDArray[np.float64]:
    """Mean length of the (one or two) segments at each sample."""
    seg = np.linalg.norm(np.diff(x, axis=0, append=x[:1]) if closed else np.diff(x, axis=0), axis=1)
    n = x.shape[0]
    if closed:
        return 0.5 * (seg + np.roll(seg, 1))
    h = np.empty(n)
    h[0], h[-1] = seg[0], seg[-1]
    h[1:-1] = 0.5 * (seg[:-1] + seg[1:])
    return h


def _relax(
    mesh: Mesh,
    face: NDArray[np.int64],
    bary: NDArray[np.float64],
    options: SnakeOptions,
    *,
    closed: bool,
    kind: str,
    fixed: NDArray[np.bool_],
    levels: int,
    max_iter: int,
    external,
):
    """Relax the face points ``face``, ``bary`` with the weights, ``step`` and ``tol_move``
    of ``options``; ``levels`` and ``max_iter`` are given apart (resolved by the caller)."""
    w_fair, w_curv, w_arc = options.w_fair, options.w_curv, options.w_arc
    step, tol_move = options.step, options.tol_move
    stepper = _Stepper(mesh, closed)
    n = face.shape[0]
    ids = np.arange(n, dtype=np.int64)
    gain = 1.0 / max(1.0, w_fair + w_curv + w_arc)
    stop = tol_move * mesh.mean_edge_length
    x0 = _ks.positions(mesh.vertices, mesh.faces, face, bary)
    seg = np.linalg.norm(np.diff(x0, axis=0), axis=1)
    floor = 0.1 * float(seg.mean()) if seg.size else 0.0  # duplicate samples still separate
    history = []
    converged = False
    free = ~fixed
    x_prev2 = None  # positions two iterations back, for the net-move test
    x_prev = x = x0
    for _ in range(max_iter):
        force = _ks.snake_forces(x, closed, w_fair, w_curv, w_arc, levels)
        if external is not None:
            ext = external
            if callable(external):
                ext = _external(external, SurfaceCurve(SurfacePoints(face, bary), closed, kind), n)
            force += ext
        # tangent plane of the interpolated vertex normal: continuous across edges, so a point
        # on a crease is not pushed back and forth between the planes of its two faces
        nrm = np.einsum("ij,ijk->ik", bary, stepper.VN[mesh.faces[face]])
        nrm /= np.linalg.norm(nrm, axis=1)[:, None]
        move = _ks.capped_moves(x, force, ids, nrm, fixed, closed, gain, step, floor)
        if not np.isfinite(move).all():
            bad = int(np.flatnonzero(~np.isfinite(move).all(axis=1))[0])
            raise InputError(f"snake force is not finite at curve point {bad}")
        nf, nb, length = stepper.step(face, bary, np.ascontiguousarray(move))
        face = np.where(free, nf, face)
        bary = np.where(free[:, None], nb, bary)
        mm = float(length[free].max()) if free.any() else 0.0
        history.append(mm)
        if mm < stop:
            converged = True
            break
        # a point flipping between two faces at a sharp fold moves every iteration but goes
        # nowhere: a net move over two iterations below the tolerance also stops
        x = _ks.positions(mesh.vertices, mesh.faces, face, bary)
        if x_prev2 is not None and float(np.linalg.norm(x - x_prev2, axis=1).max()) < stop:
            converged = True
            break
        x_prev2, x_prev = x_prev, x
    return face, bary, np.asarray(history, dtype=np.float64), converged


def relax_snake(
    mesh: Mesh,
    curve: SurfaceCurve,
    options: SnakeOptions | None = None,
    *,
    fixed: ArrayLike | None = None,
    external: ExternalForce | ArrayLike | None = None,
) -> SnakeResult:
    """Relax a surface snake toward its minimum-energy shape without leaving the surface.

    Each iteration computes per sample the membrane, thin-plate and arc-length forces of
    :func:`snake_forces` from the 3-D positions of its neighbours (coarse to fine), adds the
    external force, keeps the component in the tangent plane of the sample's face (only the
    tangential part of the curvature is penalised, eq. 3.6), scales it by ``1 / max(1,
    w_fair + w_curv + w_arc)`` (explicit Euler step, stable for these forces), caps its length
    at ``step`` times the local sample spacing and walks the face point by it. A move that
    would put two consecutive samples on faces that are neither equal nor edge-adjacent (when
    they were before) is halved, and dropped if halving does not help, so the curve keeps
    the sampling rule. Fixed samples never move. Iteration stops when the largest move, or
    the largest net move over the last two iterations (a point flipping between two faces at
    a sharp fold), is below ``tol_move * mesh.mean_edge_length``. The weights, ``levels``,
    ``step``, ``max_iter`` and ``tol_move`` are the fields of ``options``: grouped in one
    value because :func:`edit_snake` takes the same settings.

    Parameters
    ----------
    mesh : Mesh
        Manifold triangle mesh.
    curve : SurfaceCurve
        The snake: n >= 2 face points, open or closed.
    options : SnakeOptions, optional
        Weights, levels, step, iteration cap and stopping tolerance (default
        ``SnakeOptions()``); ``levels=None`` uses as many as the curve's length allows.
    fixed : (k,) int64 or (n,) bool, optional, keyword-only
        Samples that never move. Default: both ends of an open curve, none of a closed one;
        ``[]`` frees the ends (a free end feels only the external force).
    external : callable or (n, 3) float64, optional, keyword-only
        Extra force per sample, model units (a displacement, already weighted against the
        internal forces, eq. 3.18), or a function ``external(curve) -> (n, 3)`` evaluated
        every iteration (e.g. a closure over :func:`meshfit.curves.color.color_force`).

    Returns
    -------
    SnakeResult
        The relaxed curve, iterations run, the largest move per iteration and whether the
        stopping tolerance was reached.

    Raises
    ------
    meshfit.errors.InputError
        The curve is not on ``mesh``, has fewer than 2 points, ``options`` is not
        SnakeOptions, ``fixed`` is out of range, or the external force has the wrong shape
        or a non-finite row (the message names the sample).

    Notes
    -----
    Coarse levels compare a sample with neighbours ``2**l`` samples away; on a curved
    surface their chord midpoints are not exactly in the sample's tangent plane, so a
    coarse-to-fine equilibrium may differ slightly from the single-resolution one where the
    curve's curvature changes (not on spheres or planes). Run again with
    ``SnakeOptions(levels=1)`` to finish at the curve's own resolution.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD thesis,
       Stanford 2000, sec. 3.5.3 (eq. 3.6), sec. 3.6.1 (eq. 3.11-3.12), sec. 3.6.3
       (eq. 3.15), sec. 3.7 (eq. 3.16), sec. 3.8.2 (eq. 3.18).
    """
    curve = _as_curve(mesh, curve)
    opt = _as_options(options)
    n = len(curve)
    levels = _auto_levels(n, curve.closed) if opt.levels is None else opt.levels
    mask = _fixed_mask(fixed, n, curve.closed)
    if external is not None and not callable(external):
        external = _external(external, curve, n)
    face = np.ascontiguousarray(curve.points.face, dtype=np.int64)
    bary = np.array(curve.points.bary, dtype=np.float64, order="C")
    neg = (bary < 0).any(axis=1)
    if neg.any():
        c = np.clip(bary[neg], 0.0, None)
        bary[neg] = c / c.sum(axis=1, keepdims=True)
    face = _share_pairs(mesh, face, bary, curve.closed, mask)
    face, bary, history, converged = _relax(
        mesh,
        face,
        bary,
        opt,
        closed=curve.closed,
        kind=curve.kind,
        fixed=mask,
        levels=levels,
        max_iter=opt.max_iter,
        external=external,
    )
    # fixed points are returned bitwise unchanged
    face = np.where(mask, curve.points.face, face)
    bary = np.where(mask[:, None], curve.points.bary, bary)
    out = SurfaceCurve(SurfacePoints(face, bary), curve.closed, curve.kind)
    return SnakeResult(out, int(history.size), history, bool(converged))


def edit_snake(
    mesh: Mesh,
    curve: SurfaceCurve,
    options: SnakeOptions | None = None,
    *,
    edit_index: int,
    section: int,
    force: ArrayLike | None = None,
    target: ArrayLike | None = None,
) -> SnakeResult:
    """Pull one edit point of a snake and relax only the symmetric edit section around it.

    The edit point is moved by the user's force alone (walked along its tangent part in
    sub-steps of at most half the local spacing, the section relaxing a little after each so
    it follows), or walked toward a 3-D ``target`` until it gets no closer. Then the edit
    section, samples ``edit_index - section .. edit_index + section``, is relaxed with its
    two ends and the edit point fixed. Samples outside the section are returned bitwise
    unchanged.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfaceCurve
        The snake.
    options : SnakeOptions, optional
        As in :func:`relax_snake`, for the relaxation of the section (default
        ``SnakeOptions()``); ``levels=None`` uses as many as the section's length allows.
    edit_index : int, keyword-only
        The edit point (negative indices count from the end).
    section : int, keyword-only
        Half-length of the edit section in samples (>= 2); clipped at the ends of an open
        curve, at most ``(n - 1) // 2`` for a closed one.
    force : (3,) float64, optional, keyword-only
        The user's pull on the edit point, model units (its part tangent to the surface is
        walked). Give exactly one of ``force`` and ``target``.
    target : (3,) float64, optional, keyword-only
        A 3-D position the edit point is walked toward.

    Returns
    -------
    SnakeResult
        The edited curve; ``iterations``, ``max_move`` and ``converged`` describe the final
        relaxation of the section.

    Raises
    ------
    meshfit.errors.InputError
        Bad curve, options, index or section, neither or both of ``force`` / ``target``, or
        a non-finite force or target.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD thesis,
       Stanford 2000, sec. 3.8.1 ("Curve editing with surface snakes").
    """
    curve = _as_curve(mesh, curve)
    opt = _as_options(options)
    n = len(curve)
    if (
        isinstance(edit_index, bool)
        or not isinstance(edit_index, (int, np.integer))
        or not (-n <= edit_index < n)
    ):
        raise InputError(f"edit_index must be an integer in [-{n}, {n}), got {edit_index!r}")
    e = int(edit_index) % n
    section = _as_count(section, "section", minimum=2)
    if (force is None) == (target is None):
        raise InputError("give exactly one of force and target")
    pull = np.asarray(force if force is not None else target, dtype=np.float64)
    name = "force" if force is not None else "target"
    if pull.shape != (3,):
        raise InputError(f"{name} must have shape (3,), got {pull.shape}")
    if not np.isfinite(pull).all():
        raise InputError(f"{name} is not finite: {pull.tolist()}")
    if curve.closed:
        if 2 * section + 1 > n:
            raise InputError(
                f"section {section} is too long for a closed {n}-point curve "
                f"(at most {(n - 1) // 2})"
            )
        ids = (np.arange(e - section, e + section + 1)) % n
    else:
        ids = np.arange(max(0, e - section), min(n - 1, e + section) + 1)
    local = int(np.flatnonzero(ids == e)[0])
    if local == 0 or local == ids.size - 1:
        raise InputError(f"edit point {e} is an end of the curve: it has no section to edit")
    m = ids.size
    lv = _auto_levels(m, False) if opt.levels is None else opt.levels
    fixed = np.zeros(m, dtype=bool)
    fixed[[0, local, m - 1]] = True
    face = np.array(curve.points.face[ids], dtype=np.int64)
    bary = np.array(curve.points.bary[ids], dtype=np.float64, order="C")
    face = _share_pairs(mesh, face, bary, False, fixed)
    stepper = _Stepper(mesh, False)
    h = mesh.mean_edge_length
    # pull the edit point in sub-steps, letting the section follow
    for _ in range(10_000):
        x = np.einsum("ij,ijk->ik", bary, mesh.vertices[mesh.faces[face]])
        xe = x[local]
        if force is not None:
            remaining = pull
        else:
            nrm = mesh.face_normals[face[local]]
            d = pull - xe
            remaining = d - np.dot(d, nrm) * nrm
        size = float(np.linalg.norm(remaining))
        if size < tol.length(mesh, tol.ATTRACT_EPS) + opt.tol_move * h * 0.01:
            break
        sp = 0.5 * float(_spacing(x, False)[local])
        sub = remaining * min(1.0, sp / size)
        f1, b1, _ = stepper.walk(
            face[local : local + 1],
            bary[local : local + 1].copy(),
            np.ascontiguousarray(sub[None, :]),
        )
        if target is not None:
            xn = np.einsum("j,jk->k", b1[0], mesh.vertices[mesh.faces[f1[0]]])
            if np.linalg.norm(pull - xn) >= np.linalg.norm(pull - xe):
                break
        face[local], bary[local] = f1[0], b1[0]
        if force is not None:
            pull = pull - sub
        face, bary, _, _ = _relax(
            mesh,
            face,
            bary,
            opt,
            closed=False,
            kind=curve.kind,
            fixed=fixed,
            levels=lv,
            max_iter=10,
            external=None,
        )
    face, bary, history, converged = _relax(
        mesh,
        face,
        bary,
        opt,
        closed=False,
        kind=curve.kind,
        fixed=fixed,
        levels=lv,
        max_iter=opt.max_iter,
        external=None,
    )
    out_face = np.array(curve.points.face)
    out_bary = np.array(curve.points.bary)
    inner = ids[1:-1]
    out_face[inner] = face[1:-1]
    out_bary[inner] = bary[1:-1]
    out = SurfaceCurve(SurfacePoints(out_face, out_bary), curve.closed, curve.kind)
    return SnakeResult(out, int(history.size), history, bool(converged))
