"""Face-point curves: length, the sampling rule, densifying and uniform resampling.

A surface curve is an ordered sequence of face points (Krishnamurthy 2000, sec. 3.1). The
thesis samples curves densely enough that consecutive face points lie on the same face or on
edge-adjacent faces; :func:`check_sampling` finds the pairs that break this rule,
:func:`densify_curve` repairs them by walking on the surface, and :func:`resample_curve`
spaces the points evenly by arc length along the surface polyline (sec. 3.6.3).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numpy.typing import NDArray

from meshfit import tol
from meshfit._kernels import curves as _curves
from meshfit._kernels import walk as _walk
from meshfit._validate import as_surface_points
from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.surface.paths import greedy_path, path_to_surface_points
from meshfit.surface.walk import (
    _clean_bary,
    _curve_pieces,
    _curve_positions,
    _i8,
    _Pieces,
    _place_on_pieces,
    curve_arc_lengths,
)
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = [
    "check_sampling",
    "curve_length",
    "densify_curve",
    "densify_curves",
    "resample_curve",
]

#: bisection depth before a pair that will not come together is joined by a graph path
_MAX_BISECT = 12
#: attraction steps of a bisection midpoint
_MID_MAX_ITER = 50
#: extra resampling passes that even out the spacing of a jagged input
_MAX_PASSES = 3
#: the passes stop once the spacing's coefficient of variation is at most this
_RESAMPLE_CV = 0.01
#: a step breaking the sampling rule is split evenly into the fewest k in this range that works
_K_MIN, _K_MAX = 2, 32
#: point count from which attraction runs on all cores
_PARALLEL_MIN = 64


def _as_curve(mesh: Mesh, curve: SurfaceCurve, name: str = "curve") -> SurfaceCurve:
    if not isinstance(curve, SurfaceCurve):
        raise InputError(f"{name} must be a SurfaceCurve, got {type(curve).__name__}")
    as_surface_points(mesh, curve.points, name=f"{name}.points")
    if len(curve) == 0:
        raise InputError(f"{name} has no points")
    return curve


def _attract_few(
    mesh: Mesh,
    face: NDArray,
    bary: NDArray,
    targets: NDArray,
    *,
    max_iter: int = 200,
    chain: bool = False,
) -> SurfacePoints:
    """:func:`meshfit.surface.attract_points` (default face cap) for trusted inputs.

    A few points run serially, without the cost of starting threads, which dominates for the
    few hundred or thousand points of one painted segment. With ``chain`` (an ordered curve
    toward close-spaced ordered targets) each point walks from the nearer, to its target, of
    its own position and the previous point's result, so a curve far from its targets gets
    there by continuation, a short walk per point (serial by nature).
    """
    args = (
        mesh.vertices,
        *_topology(mesh),
        _i8(face),
        _clean_bary(bary),
        np.ascontiguousarray(targets, dtype=np.float64),
        int(max_iter),
        10_000,
        tol.length(mesh, tol.ATTRACT_EPS),
        tol.BARY_EPS,
    )
    # many independent points: the parallel kernel (threads sleep between kernels, so
    # starting them costs microseconds); a few, or a chain: the serial one
    if chain or len(face) < _PARALLEL_MIN:
        f, b, _, _, _, _ = _curves.attract_points_serial(*args, chain)
    else:
        f, b, _, _, _, _ = _walk.attract_points(*args)
    return SurfacePoints(f, b)


def check_sampling(mesh: Mesh, curve: SurfaceCurve) -> NDArray[np.int64]:
    """Consecutive pairs of a curve that break the sampling rule.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfaceCurve
        m face points.

    Returns
    -------
    (k,) int64
        Indices ``i`` such that points ``i`` and ``i + 1`` (``0`` after ``m - 1`` for a
        closed curve) lie on faces that are neither the same nor edge-adjacent. An edge point
        counts as lying on both faces of its edge, a vertex point on every face around it.
        Empty when the curve is well sampled.

    Raises
    ------
    meshfit.errors.InputError
        ``curve`` is not a SurfaceCurve on ``mesh``.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD
       thesis, Stanford 2000, sec. 3.1 (successive face points on the same or adjacent
       faces).
    """
    return _broken_pairs(mesh, _as_curve(mesh, curve))


def _topology(mesh: Mesh) -> tuple[NDArray[np.int64], ...]:
    """The curve kernels' view of a mesh's connectivity, as contiguous int64: faces, face
    neighbours and the vertex-face table ``(indptr, faces)``."""
    indptr, vf = mesh.vertex_faces
    return _i8(mesh.faces), _i8(mesh.face_neighbors), _i8(indptr), _i8(vf)


def _broken_pairs(mesh: Mesh, curve: SurfaceCurve) -> NDArray[np.int64]:
    """:func:`check_sampling` for a curve already checked to be on ``mesh``."""
    p = curve.points
    return _curves.broken_pairs(
        *_topology(mesh),
        _i8(p.face),
        np.ascontiguousarray(p.bary, dtype=np.float64),
        bool(curve.closed),
        tol.BARY_EPS,
    )


def curve_length(mesh: Mesh, curve: SurfaceCurve) -> float:
    """Length of a face-point curve measured along the surface.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfaceCurve
        Well-sampled curve (see :func:`check_sampling`); a closed curve includes its closing
        segment.

    Returns
    -------
    float
        Length in model units: each segment is the shortest path inside its one or two faces.

    Raises
    ------
    meshfit.errors.InputError
        A pair of consecutive points breaks the sampling rule (use :func:`densify_curve`).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.3.2 (chord length of face-point curves).
    """
    curve = _as_curve(mesh, curve)
    return float(curve_arc_lengths(mesh, curve)[-1])


def _graph_bridge(mesh: Mesh, fa: int, ba: NDArray, fb: int, bb: NDArray) -> SurfacePoints:
    """Face points strictly between two face points, along a greedy graph path.

    The path runs from the corner of a's face nearest to b to the corner of b's face
    nearest to a; its vertex points lie on every face around them, so every consecutive
    pair including a and b shares a face.
    """
    V, F = mesh.vertices, mesh.faces
    xa = ba @ V[F[fa]]
    xb = bb @ V[F[fb]]
    va = int(F[fa][np.argmin(np.linalg.norm(V[F[fa]] - xb, axis=1))])
    vb = int(F[fb][np.argmin(np.linalg.norm(V[F[fb]] - xa, axis=1))])
    path = greedy_path(mesh, va, vb).vertices
    return path_to_surface_points(mesh, path, per_edge=1)


def densify_curve(mesh: Mesh, curve: SurfaceCurve) -> SurfaceCurve:
    """Insert face points so that every consecutive pair lies on the same or adjacent faces.

    Between two points that break the rule the curve is bisected on the surface: a point
    walks halfway towards the other (MovePointOnSurface) and is attracted to the 3-D
    midpoint of the pair, recursively. A pair that does not come closer, or is still apart
    after a dozen bisections, is joined by a greedy graph path instead. Points never leave
    the surface, so no segment jumps across a thin part of the model.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfaceCurve
        Any face-point sequence on ``mesh``, all points on one component.

    Returns
    -------
    SurfaceCurve
        The original points, in order and unchanged, with points inserted where needed;
        same ``closed`` and ``kind``. ``check_sampling`` of the result is empty.

    Raises
    ------
    meshfit.errors.InputError
        ``curve`` is not a SurfaceCurve on ``mesh``.
    meshfit.errors.PathError
        Two consecutive points lie on different components of the mesh.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.1 (sampling rule), sec. 3.2 (graph paths) and
       appendix A (MovePointOnSurface).
    """
    return _densify(mesh, _as_curve(mesh, curve))


def densify_curves(mesh: Mesh, curves: list[SurfaceCurve]) -> list[SurfaceCurve]:
    """:func:`densify_curve` of every curve, the open ones in one pass.

    The open curves' points are taken as one sequence, whose pairs across two curves are not
    pairs of a curve; their broken pairs are bridged by one kernel call. Each result is
    what :func:`densify_curve` gives (a curve without broken pairs is returned as it is).

    Parameters
    ----------
    mesh : Mesh
    curves : list of SurfaceCurve

    Returns
    -------
    list of SurfaceCurve

    Raises
    ------
    meshfit.errors.InputError
        A curve that is not a SurfaceCurve on ``mesh``.
    meshfit.errors.PathError
        Two consecutive points lie on different components of the mesh.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.1 (the sampling rule) and appendix A
       (MovePointOnSurface).
    """
    checked = [_as_curve(mesh, c, name=f"curves[{i}]") for i, c in enumerate(curves)]
    out: list[SurfaceCurve | None] = [_densify(mesh, c) if c.closed else None for c in checked]
    open_ = [i for i, c in enumerate(checked) if not c.closed]
    if not open_:
        return out  # type: ignore[return-value]
    sizes = np.array([len(checked[i]) for i in open_], dtype=np.int64)
    ends = np.cumsum(sizes)
    allp = SurfacePoints.concatenate([checked[i].points for i in open_])
    bad = _broken_pairs(mesh, SurfaceCurve(allp))
    bad = bad[~np.isin(bad, ends - 1)]  # a curve's last point and the next one's first
    face, bary, inserted = _bridge(mesh, allp, bad)
    # each curve's share of the inserted points: those after its own points
    owner = np.searchsorted(ends, bad, side="right")
    grow = np.bincount(owner, weights=inserted, minlength=len(open_)).astype(np.int64)
    stop = np.cumsum(sizes + grow)
    for k, i in enumerate(open_):
        if grow[k] == 0:
            out[i] = checked[i]
            continue
        a = int(stop[k] - sizes[k] - grow[k])
        pts = SurfacePoints(face[a : stop[k]], bary[a : stop[k]])
        out[i] = SurfaceCurve(pts, closed=False, kind=checked[i].kind)
    return out  # type: ignore[return-value]


def _densify(mesh: Mesh, curve: SurfaceCurve) -> SurfaceCurve:
    """:func:`densify_curve` for a curve already checked to be on ``mesh``."""
    bad = _broken_pairs(mesh, curve)
    if bad.size == 0:
        return curve
    face, bary, _ = _bridge(mesh, curve.points, bad)
    return SurfaceCurve(SurfacePoints(face, bary), closed=curve.closed, kind=curve.kind)


def _bridge(
    mesh: Mesh, p: SurfacePoints, bad: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.int64]]:
    """The points ``p`` with the points bridging each broken pair ``(bad[e], bad[e] + 1)``
    (modulo the count) spliced in: ``(face, bary, inserted)``, ``inserted[e]`` the number
    of points pair ``e`` got."""
    m = len(p)
    if bad.size == 0:
        return p.face, p.bary, np.zeros(0, dtype=np.int64)
    nxt = (bad + 1) % m
    pair, new_face, new_bary, g_face, g_bary = _bridge_pairs(
        mesh,
        _i8(p.face[bad]),
        np.ascontiguousarray(p.bary[bad], dtype=np.float64),
        _i8(p.face[nxt]),
        np.ascontiguousarray(p.bary[nxt], dtype=np.float64),
    )
    graph = np.flatnonzero(new_face < 0)
    if graph.size:  # a pair that would not come together: a greedy graph path instead
        parts_f = np.split(new_face, graph)
        parts_b = np.split(new_bary, graph)
        parts_p = np.split(pair, graph)
        fs, bs, ps = [parts_f[0]], [parts_b[0]], [parts_p[0]]
        for j, e in enumerate(graph.tolist()):
            r = -1 - int(new_face[e])
            g = _graph_bridge(
                mesh, int(g_face[r, 0]), g_bary[r, 0], int(g_face[r, 1]), g_bary[r, 1]
            )
            fs += [np.asarray(g.face, dtype=np.int64), parts_f[j + 1][1:]]
            bs += [np.asarray(g.bary, dtype=np.float64), parts_b[j + 1][1:]]
            ps += [np.full(len(g), pair[e], dtype=np.int64), parts_p[j + 1][1:]]
        new_face, new_bary, pair = np.concatenate(fs), np.concatenate(bs), np.concatenate(ps)
    inserted = np.bincount(pair, minlength=bad.size)
    if new_face.size == 0:
        return p.face, p.bary, inserted
    # the points bridging pair i go right after point i, in order
    face, bary = _curves.splice(
        _i8(p.face),
        np.ascontiguousarray(p.bary, dtype=np.float64),
        _i8(bad[pair]),
        _i8(new_face),
        np.ascontiguousarray(new_bary, dtype=np.float64),
    )
    return face, bary, inserted


#: broken pairs per thread at least before the pairs are bridged on several threads
_BRIDGE_CHUNK = 64


def _bridge_pairs(mesh: Mesh, fa, ba, fb, bb):
    """The `bridge_pairs` kernel's outputs for the pairs ``(fa, ba) -> (fb, bb)``.

    The pairs are bridged independently, so many are split into runs bridged on threads
    (the kernel releases the GIL), and the runs' outputs are joined as one call would give
    them: pair indices and graph-path entries offset by the runs before.
    """
    mesh_args = (mesh.vertices, *_topology(mesh))
    consts = (
        _MAX_BISECT,
        _MID_MAX_ITER,
        10_000,
        tol.length(mesh, tol.WALK_EPS),
        tol.length(mesh, tol.ATTRACT_EPS),
        tol.BARY_EPS,
    )
    n = fa.size
    runs = min(os.cpu_count() or 1, n // _BRIDGE_CHUNK)
    if runs < 2:
        return _curves.bridge_pairs(*mesh_args, fa, ba, fb, bb, *consts)
    cuts = np.linspace(0, n, runs + 1).astype(np.int64)

    def run(k: int):
        a, b = cuts[k], cuts[k + 1]
        return _curves.bridge_pairs(*mesh_args, fa[a:b], ba[a:b], fb[a:b], bb[a:b], *consts)

    with ThreadPoolExecutor(max_workers=runs) as pool:
        parts = list(pool.map(run, range(runs)))
    g_base = np.cumsum([0] + [len(part[3]) for part in parts])
    pair = np.concatenate([part[0] + cuts[k] for k, part in enumerate(parts)])
    # a graph-path entry -1 - j of run k is entry j + g_base[k] of the joined list
    face = np.concatenate(
        [np.where(part[1] < 0, part[1] - g_base[k], part[1]) for k, part in enumerate(parts)]
    )
    bary = np.concatenate([part[2] for part in parts])
    g_face = np.concatenate([part[3] for part in parts])
    g_bary = np.concatenate([part[4] for part in parts])
    return pair, face, bary, g_face, g_bary


def _positions(total: float, closed: bool, spacing: float | None, n: int | None) -> NDArray:
    if n is None:
        count = int(np.ceil(total / spacing - 1e-9)) if spacing > 0 else 0
        n = max(count, 3) if closed else max(count, 1) + 1
    if closed:
        return np.arange(n) * (total / n)
    pos = np.linspace(0.0, total, n)
    pos[-1] = total
    return pos


def resample_curve(
    mesh: Mesh, curve: SurfaceCurve, *, spacing: float | None = None, n: int | None = None
) -> SurfaceCurve:
    """Uniformly resample a face-point curve by arc length along the surface.

    The curve is first densified (:func:`densify_curve`), then new points are placed at
    equal arc-length steps along its surface polyline (MovePointOnCurve). An open curve
    keeps its two end points exactly; a closed curve keeps its first point. Because the new
    polyline cuts the corners of a jagged input, the resampling is repeated on its own
    result (same count, at most three more passes) until its steps agree to 1 %.

    The sampling rule takes precedence over even spacing: where a step would join points on
    faces that are neither the same nor adjacent (a curve passing close to a vertex crosses a
    fan of faces in a short distance, or ``spacing`` is wider than the faces), that step
    alone is subdivided evenly into the fewest parts that keep the rule. The evenly spaced
    points are all present; the inserted ones lie between them on the same polyline.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfaceCurve
        m >= 1 face points (m >= 2 for an open curve to have a length).
    spacing : float, keyword-only, optional
        Target arc length between consecutive points, model units; the actual step is
        ``length / ceil(length / spacing)``. Default: half the mean edge length.
    n : int, keyword-only, optional
        Number of points instead of a spacing (>= 2 open, >= 3 closed). Give at most one of
        ``spacing`` and ``n``.

    Returns
    -------
    SurfaceCurve
        Evenly spaced face points, same ``closed`` and ``kind``.

    Raises
    ------
    meshfit.errors.InputError
        Bad ``curve``, both or invalid ``spacing`` / ``n``.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.1 (sampling density) and sec. 3.6.3 (uniformly
       sampled curves); sec. 5.11.1 (MovePointOnCurve).
    """
    return _resample(mesh, curve, spacing=spacing, n=n)[0]


def _resample(
    mesh: Mesh,
    curve: SurfaceCurve,
    *,
    spacing: float | None,
    n: int | None,
    cv: float = _RESAMPLE_CV,
    checked: bool = False,
) -> tuple[SurfaceCurve, NDArray[np.bool_]]:
    """:func:`resample_curve` plus a mask of the evenly spaced points (False: inserted);
    passes repeat until the spacing's coefficient of variation is at most ``cv``. With
    ``checked`` the curve is known to be a SurfaceCurve on ``mesh`` (not validated again)."""
    if not checked:
        curve = _as_curve(mesh, curve)
    if spacing is not None and n is not None:
        raise InputError("give spacing or n, not both")
    need = 3 if curve.closed else 2
    if n is not None:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < need:
            raise InputError(f"n must be an integer >= {need} for this curve, got {n!r}")
        n = int(n)
    if spacing is None:
        spacing = 0.5 * mesh.mean_edge_length
    try:
        spacing = float(spacing)
    except (TypeError, ValueError):
        raise InputError(f"spacing must be a positive length, got {spacing!r}") from None
    if not np.isfinite(spacing) or spacing <= 0:
        raise InputError(f"spacing must be a positive length, got {spacing!r}")
    out, regular = _resample_once(mesh, curve, spacing, n)
    # the new polyline cuts the corners of a jagged input, so its own spacing is less even
    # than the arc-length steps taken on the input: repeat on the result (same count) until
    # its steps agree to 1 %; the result's pieces give its arc lengths and serve the next pass
    for _ in range(_MAX_PASSES):
        pieces = _curve_pieces(mesh, out.points, out.closed, "curve")
        arc = np.append(pieces.start[0::2], pieces.total)
        if _arc_spacing_cv(arc, regular, out.closed) <= cv:
            break
        out, regular = _resample_once(mesh, out, spacing, int(regular.sum()), pieces)
    return out, regular


def _spacing_cv(mesh: Mesh, curve: SurfaceCurve, regular: NDArray[np.bool_]) -> float:
    """Coefficient of variation of the arc length between consecutive regular points."""
    return _arc_spacing_cv(curve_arc_lengths(mesh, curve), regular, curve.closed)


def _arc_spacing_cv(arc: NDArray, regular: NDArray[np.bool_], closed: bool) -> float:
    """:func:`_spacing_cv` from the curve's arc lengths (closed: with the total appended)."""
    idx = np.flatnonzero(regular)
    if closed:
        idx = np.append(idx, regular.size)
    d = np.diff(arc[idx])
    return float(d.std() / d.mean()) if d.size and d.mean() > 0 else 0.0


def _points_at(curve: SurfaceCurve, pieces: _Pieces, pos: NDArray) -> SurfacePoints:
    """``move_along_curve(mesh, curve, pos, 0.0).points`` on the curve's precomputed pieces."""
    s = _curve_positions(pieces, curve.closed, np.ascontiguousarray(pos, dtype=np.float64))
    face, bary, _ = _place_on_pieces(curve.points, curve.closed, pieces, s)
    return SurfacePoints(face, bary)


def _resample_once(
    mesh: Mesh, curve: SurfaceCurve, spacing: float, n: int | None, pieces: _Pieces | None = None
) -> tuple[SurfaceCurve, NDArray[np.bool_]]:
    """One resampling pass; ``pieces`` are the curve's own when already known."""
    dense = _densify(mesh, curve)
    # the curve's pieces once, for its arc lengths and every placement below
    if pieces is None or dense is not curve:
        pieces = _curve_pieces(mesh, dense.points, dense.closed, "curve")
    curve = dense
    arc = np.append(pieces.start[0::2], pieces.total)
    total = float(arc[-1])
    if total == 0.0:
        return curve, np.ones(len(curve), dtype=bool)
    pos = _positions(total, curve.closed, spacing, n)
    res = _points_at(curve, pieces, pos)
    out = SurfaceCurve(res, closed=curve.closed, kind=curve.kind)
    bad = _broken_pairs(mesh, out)
    if bad.size == 0:
        return out, np.ones(pos.size, dtype=bool)
    # a step still breaking the rule (it passes a vertex through a fan of small faces) is
    # subdivided evenly into the fewest parts that keep the rule, that step alone (searched
    # in a numba kernel)
    ends = np.append(pos, total)
    # the fewest parts first: a step leaves the search at the first k that keeps the rule
    a, b = pos[bad], ends[bad + 1]
    pts = curve.points
    kbest = _curves.subdivide_steps(
        *_topology(mesh),
        np.ascontiguousarray(a, dtype=np.float64),
        np.ascontiguousarray(b, dtype=np.float64),
        _K_MIN,
        _K_MAX,
        bool(curve.closed),
        total,
        _i8(pieces.face),
        np.ascontiguousarray(pieces.b0),
        np.ascontiguousarray(pieces.b1),
        np.ascontiguousarray(pieces.start),
        np.ascontiguousarray(pieces.length),
        np.ascontiguousarray(arc),
        _i8(pts.face),
        np.ascontiguousarray(pts.bary, dtype=np.float64),
        tol.BARY_EPS,
    )
    # the inserted positions of every broken step, in curve order: k - 1 evenly spaced ones
    # for a step split into k parts, or the curve's own points strictly inside a step no
    # split fixes (they always do)
    inside = arc[:-1] if curve.closed else arc
    pos2, regular = _curves.split_steps(
        pos,
        _i8(bad),
        np.ascontiguousarray(a, dtype=np.float64),
        np.ascontiguousarray(b, dtype=np.float64),
        kbest,
        np.ascontiguousarray(inside),
    )
    res = _points_at(curve, pieces, pos2)
    return SurfaceCurve(res, closed=curve.closed, kind=curve.kind), regular
