"""Moving face points over the surface without leaving it.

Three verbs, all built on one walking kernel that slides a point across triangles and unfolds
its direction about every edge it crosses (the thesis' MovePointOnSurface, Krishnamurthy
2000, appendix A):

- :func:`walk_points` slides points by tangent displacements;
- :func:`attract_points` walks points downhill to the locally closest surface point to a 3-D
  target (the core of CurveAttract, sec. 3.3.1);
- :func:`move_along_curve` slides points along a face-point polyline by signed arc length
  (MovePointOnCurve, sec. 5.11.1); :func:`curve_arc_lengths` gives the polyline's
  cumulative lengths.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit import tol
from meshfit._kernels import curves as _curves
from meshfit._kernels import walk as _walk
from meshfit._validate import as_surface_points, as_vectors
from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = [
    "AttractResult",
    "CurveMoveResult",
    "WalkResult",
    "attract_points",
    "curve_arc_lengths",
    "move_along_curve",
    "walk_points",
]


@dataclass(frozen=True, eq=False)
class WalkResult:
    """Result of :func:`walk_points`.

    Attributes
    ----------
    end : SurfacePoints
        Where each point stopped.
    length : (n,) float64
        Distance travelled along the surface, model units. Equal to the length of the step
        projected onto the start face unless the walk hit the boundary or the face cap.
    hit_boundary : (n,) bool
        The walk stopped on a boundary edge (``end`` lies exactly on that edge).
    capped : (n,) bool
        The walk stopped after crossing ``max_faces`` edges.
    """

    end: SurfacePoints
    length: NDArray[np.float64]
    hit_boundary: NDArray[np.bool_]
    capped: NDArray[np.bool_]


@dataclass(frozen=True, eq=False)
class AttractResult:
    """Result of :func:`attract_points`.

    Attributes
    ----------
    end : SurfacePoints
        The attracted points.
    distance : (n,) float64
        Distance from each end point to its target, model units.
    iterations : (n,) int64
        Iterations used: walking steps tried (accepted or halved), each possibly followed
        by an exact descent move.
    hit_boundary : (n,) bool
        The end point lies on a boundary edge (within ``tol.BARY_EPS``): its minimum is
        constrained by the boundary.
    converged : (n,) bool
        The end point is a certified local minimum (no face touching it holds a point
        closer to the target); False when ``max_iter`` ran out first.
    """

    end: SurfacePoints
    distance: NDArray[np.float64]
    iterations: NDArray[np.int64]
    hit_boundary: NDArray[np.bool_]
    converged: NDArray[np.bool_]


@dataclass(frozen=True, eq=False)
class CurveMoveResult:
    """Result of :func:`move_along_curve`.

    Attributes
    ----------
    position : (n,) float64
        New arc-length parameter of each point, model units, in ``[0, total]`` (open curve)
        or ``[0, total)`` (closed curve).
    points : SurfacePoints
        The same positions as face points, exactly on the curve's surface segments; a
        position equal to a curve vertex's arc length returns that vertex's face point.
    segment : (n,) int64
        Curve segment holding each point: segment ``i`` runs from curve point ``i`` to
        ``i + 1`` (to point 0 for the closing segment of a closed curve).
    clamped : (n,) bool
        The move ran past an end of an open curve and was stopped there.
    """

    position: NDArray[np.float64]
    points: SurfacePoints
    segment: NDArray[np.int64]
    clamped: NDArray[np.bool_]


def _clean_bary(bary: NDArray[np.float64]) -> NDArray[np.float64]:
    """Contiguous copy with tiny negatives (accepted by validation) clamped and renormalised."""
    b = np.array(bary, dtype=np.float64, order="C")
    bad = (b < 0.0).any(axis=1)
    if bad.any():
        c = np.clip(b[bad], 0.0, None)
        b[bad] = c / c.sum(axis=1, keepdims=True)
    return b


def _as_cap(value: int, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise InputError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def walk_points(
    mesh: Mesh, start: SurfacePoints, step: ArrayLike, *, max_faces: int = 10_000
) -> WalkResult:
    """Slide face points over the surface by tangent displacements (MovePointOnSurface).

    Each step is projected onto the plane of its start face and followed in a straight line
    inside the face; where it crosses an edge into a neighbouring face, the rest of the
    displacement is rotated about that edge into the neighbour's plane (its component along
    the edge and the magnitude of its in-plane perpendicular part are kept), so the path is
    straight in the unfolding of the faces it crosses. Points never leave the surface and are
    never re-projected. A walk through a vertex continues across one of the vertex's edges
    and turns through the fan of faces until the unfolded direction enters one.

    Parameters
    ----------
    mesh : Mesh
        Manifold triangle mesh, closed or with boundary.
    start : SurfacePoints
        n points: ``face (n,) int64``, ``bary (n, 3) float64``.
    step : (n, 3) float64
        Displacement per point, model units; its component along the start face's normal is
        dropped. A single (3,) vector is used for every point.
    max_faces : int, keyword-only
        Edge crossings allowed per point before the walk stops with ``capped`` set.

    Returns
    -------
    WalkResult
        ``end`` SurfacePoints (barycentrics >= 0 summing to 1), ``length (n,) float64``,
        ``hit_boundary (n,) bool`` (stopped on a boundary edge), ``capped (n,) bool``.

    Raises
    ------
    meshfit.errors.InputError
        ``start`` is not on ``mesh``, ``step`` has the wrong number of rows or a non-finite
        row, or ``max_faces`` is not a positive integer.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD
       thesis, Stanford 2000, appendix A ("Face-point motion", MovePointOnSurface).
    .. [2] Polthier & Schmies, "Straightest geodesics on polyhedral surfaces",
       Mathematical Visualization, 1998.
    """
    start = as_surface_points(mesh, start, name="start")
    step = as_vectors(step, n=len(start), name="step")
    max_faces = _as_cap(max_faces, "max_faces")
    face, bary, length, hit, capped = _walk.walk_points(
        mesh.vertices,
        mesh.faces,
        mesh.face_neighbors,
        np.ascontiguousarray(start.face),
        _clean_bary(start.bary),
        step,
        max_faces,
        tol.length(mesh, tol.WALK_EPS),
        tol.BARY_EPS,
    )
    return WalkResult(SurfacePoints(face, bary), length, hit, capped)


def attract_points(
    mesh: Mesh,
    start: SurfacePoints,
    targets: ArrayLike,
    *,
    max_iter: int = 200,
    max_faces: int = 10_000,
) -> AttractResult:
    """Walk face points to the locally closest surface point to 3-D targets (CurveAttract).

    Each iteration moves a point by its target's orthogonal projection onto the current
    face's plane minus the point, with the walking of :func:`walk_points`; a step that does
    not bring the point closer to its target is halved for the next iteration (a step that
    does doubles it again, up to the full projection step). At a boundary edge the outward
    part of a step is dropped, so points slide along the boundary.

    When a step is rejected, or is shorter than ``tol.ATTRACT_EPS * mesh.mean_edge_length``,
    the point also makes one exact descent move without leaving the surface: to the closest
    point of its face, or from there (on an edge or at a vertex) to the closest point of the
    neighbouring face or of the best face around the vertex. This finishes minima on ridges
    and at vertices, where projected steps keep overshooting. A point stops when no such
    move gets closer: then no face touching it holds a closer point, which certifies a
    local minimum. There is no global closest-point query: the result is the *local*
    minimum of distance reached from ``start``.

    Parameters
    ----------
    mesh : Mesh
    start : SurfacePoints
        n starting face points.
    targets : (n, 3) float64
        Attractor positions, model units (a single (3,) position is used for every point).
    max_iter : int, keyword-only
        Walking steps allowed per point.
    max_faces : int, keyword-only
        Edge crossings allowed per walking step.

    Returns
    -------
    AttractResult
        ``end`` SurfacePoints, ``distance (n,) float64`` to the target, ``iterations (n,)
        int64``, ``hit_boundary (n,) bool``, ``converged (n,) bool``.

    Raises
    ------
    meshfit.errors.InputError
        ``start`` is not on ``mesh``, ``targets`` has the wrong number of rows or a
        non-finite row, or a cap is not a positive integer.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD
       thesis, Stanford 2000, sec. 3.3.1 (CurveAttract, fig. 3.4) and appendix A.
    """
    start = as_surface_points(mesh, start, name="start")
    targets = as_vectors(targets, n=len(start), name="targets")
    max_iter = _as_cap(max_iter, "max_iter")
    max_faces = _as_cap(max_faces, "max_faces")
    vf_indptr, vf = mesh.vertex_faces
    face, bary, dist, iters, hit, conv = _walk.attract_points(
        mesh.vertices,
        mesh.faces,
        mesh.face_neighbors,
        vf_indptr,
        vf,
        np.ascontiguousarray(start.face),
        _clean_bary(start.bary),
        targets,
        max_iter,
        max_faces,
        tol.length(mesh, tol.ATTRACT_EPS),
        tol.BARY_EPS,
    )
    return AttractResult(SurfacePoints(face, bary), dist, iters, hit, conv)


# ---------------------------------------------------------------------------- curves


@dataclass(frozen=True)
class _Pieces:
    """A face-point polyline as straight pieces, two per segment, each inside one face.

    Piece ``2 i`` runs in the face of point i from the point to where the segment crosses
    the shared edge, piece ``2 i + 1`` on in the next point's face to point ``i + 1``
    (zero length when both points share a face).
    """

    face: NDArray[np.int64]  # (p,)
    b0: NDArray[np.float64]  # (p, 3)
    b1: NDArray[np.float64]  # (p, 3)
    start: NDArray[np.float64]  # (p,) arc length at the piece start
    length: NDArray[np.float64]  # (p,)
    total: float


def _curve_points(
    curve: SurfaceCurve | SurfacePoints, closed: bool | None
) -> tuple[SurfacePoints, bool]:
    if isinstance(curve, SurfaceCurve):
        if closed is not None and bool(closed) != curve.closed:
            raise InputError(
                f"closed={closed} contradicts the SurfaceCurve's closed={curve.closed}"
            )
        return curve.points, curve.closed
    if not isinstance(curve, SurfacePoints):
        raise InputError(
            f"curve must be a SurfaceCurve or SurfacePoints, got {type(curve).__name__}"
        )
    return curve, bool(closed)


def _representations(
    mesh: Mesh, face: int, bary: NDArray[np.float64]
) -> list[tuple[int, NDArray[np.float64]]]:
    """The same surface point written in every face that holds it (edge and vertex points)."""
    out = [(face, bary)]
    zero = bary <= tol.BARY_EPS
    if zero.sum() == 1:
        k = (int(np.flatnonzero(zero)[0]) + 1) % 3  # edge on which the point lies
        g = int(mesh.face_neighbors[face, k])
        if g >= 0:
            va, vc = mesh.faces[face, k], mesh.faces[face, (k + 1) % 3]
            b = np.zeros(3)
            b[np.flatnonzero(mesh.faces[g] == va)[0]] = bary[k]
            b[np.flatnonzero(mesh.faces[g] == vc)[0]] = bary[(k + 1) % 3]
            out.append((g, b / b.sum()))
    elif zero.sum() == 2:
        v = mesh.faces[face, int(np.flatnonzero(~zero)[0])]
        indptr, vf = mesh.vertex_faces
        for g in vf[indptr[v] : indptr[v + 1]]:
            if g != face:
                b = (mesh.faces[g] == v).astype(np.float64)
                out.append((int(g), b))
    return out


def _i8(a: NDArray) -> NDArray[np.int64]:
    """``a`` as a C-contiguous int64 array (no copy when it already is one)."""
    return np.ascontiguousarray(a, dtype=np.int64)


def _curve_pieces(mesh: Mesh, points: SurfacePoints, closed: bool, name: str) -> _Pieces:
    m = len(points)
    if m == 0:
        raise InputError(f"{name} has no points")
    # segment i joins point i to point i + 1 (to point 0 for a closed curve's last); the
    # kernel rewrites both ends of a segment in place, so each gets its own copy
    face = np.asarray(points.face, dtype=np.int64)
    bary = _clean_bary(points.bary)
    if closed:
        pf, qf = face.copy(), np.roll(face, -1)
        pb, qb = bary, np.roll(bary, -1, axis=0)
    else:
        pf, qf = face[:-1].copy(), face[1:].copy()
        pb, qb = bary[:-1].copy(), bary[1:].copy()
    # faces neither equal nor adjacent: the other faces through an edge or vertex point are
    # tried (a shared face first, in the order of `_representations`); faces that still share
    # only a vertex are joined through that vertex
    indptr, vf = mesh.vertex_faces
    bad, pface, b0, b1, start, length = _curves.curve_pieces(
        mesh.vertices,
        _i8(mesh.faces),
        _i8(mesh.face_neighbors),
        _i8(indptr),
        _i8(vf),
        pf,
        pb,
        qf,
        qb,
        tol.BARY_EPS,
    )
    if bad >= 0:
        P = bad
        Q = (bad + 1) % m
        raise InputError(
            f"{name} points {P} and {Q} are on faces {pf[bad]} and "
            f"{qf[bad]}, which are neither the same, adjacent nor sharing a vertex"
        )
    return _Pieces(pface, b0, b1, start[:-1], length, float(start[-1]))


def curve_arc_lengths(
    mesh: Mesh, curve: SurfaceCurve | SurfacePoints, *, closed: bool | None = None
) -> NDArray[np.float64]:
    """Cumulative arc length of a face-point polyline at each of its points.

    Consecutive points must lie on the same or on edge-adjacent faces (or be edge / vertex
    points that some such pair of faces holds). A segment between adjacent faces is the
    straight line in the two faces unfolded about their shared edge; where that line would
    leave the two faces (a reflex unfolding) it bends at the shared edge's end vertex, so a
    segment is always the shortest path inside its two faces. Points on faces that share
    only a vertex (which a relaxed snake may leave, and :func:`meshfit.surface.cut_mesh`
    accepts) are joined through that vertex.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfaceCurve or SurfacePoints
        m >= 1 ordered face points.
    closed : bool, keyword-only, optional
        Whether the last point joins the first; taken from a ``SurfaceCurve`` (a
        contradicting value raises), False for plain ``SurfacePoints`` when omitted.

    Returns
    -------
    (m,) float64 for an open curve, (m + 1,) float64 for a closed one
        Arc length at each point, starting at 0, model units; a closed curve's last entry is
        the total length (back at point 0).

    Raises
    ------
    meshfit.errors.InputError
        A point is not on ``mesh``, or two consecutive points are on faces that are neither
        the same nor adjacent.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD
       thesis, Stanford 2000, sec. 3.1 (face-point curves) and sec. 5.11.1 (MovePointOnCurve).
    """
    points, closed = _curve_points(curve, closed)
    points = as_surface_points(mesh, points, name="curve")
    pieces = _curve_pieces(mesh, points, closed, "curve")
    return np.append(pieces.start[0::2], pieces.total)


def move_along_curve(
    mesh: Mesh,
    curve: SurfaceCurve | SurfacePoints,
    position: ArrayLike,
    distance: ArrayLike,
    *,
    closed: bool | None = None,
) -> CurveMoveResult:
    """Slide points along a face-point polyline by signed arc length (MovePointOnCurve).

    Positions are arc-length parameters along the polyline (see :func:`curve_arc_lengths`).
    An open curve stops points at its ends; a closed curve wraps them around. The returned
    face points lie exactly on the polyline's surface segments: inside a face they are the
    linear blend of the segment piece's end barycentrics (a straight line in the face), and a
    position equal to a curve point's arc length returns that curve point unchanged. Use
    ``distance=0`` to evaluate face points at given positions.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfaceCurve or SurfacePoints
        m >= 1 ordered face points, consecutive ones on the same or adjacent faces (or
        faces sharing a vertex, joined through it).
    position : (n,) float64
        Current arc-length parameters, model units; within ``[0, total]`` for an open curve,
        any value (taken modulo the length) for a closed one.
    distance : (n,) float64
        Signed distance to move along the curve, model units (a scalar applies to all).
    closed : bool, keyword-only, optional
        As in :func:`curve_arc_lengths`.

    Returns
    -------
    CurveMoveResult
        ``position (n,) float64``, ``points`` SurfacePoints, ``segment (n,) int64``,
        ``clamped (n,) bool``.

    Raises
    ------
    meshfit.errors.InputError
        Bad curve (as in :func:`curve_arc_lengths`), non-finite or mismatched
        ``position`` / ``distance``, or a position outside an open curve.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD
       thesis, Stanford 2000, sec. 5.11.1 (curve points, MovePointOnCurve) and appendix A.
    """
    points, closed = _curve_points(curve, closed)
    points = as_surface_points(mesh, points, name="curve")
    pos = _as_scalars(position, None, "position")
    dist = _as_scalars(distance, pos.size, "distance")
    pieces = _curve_pieces(mesh, points, closed, "curve")
    total = pieces.total
    slack = tol.length(mesh, tol.ON_SURFACE, scale="bbox_diagonal")
    if closed:
        s = np.mod(pos + dist, total) if total > 0 else np.zeros_like(pos)
        s[s >= total] = 0.0
        clamped = np.zeros(pos.size, dtype=bool)
    else:
        bad = np.flatnonzero((pos < -slack) | (pos > total + slack))
        if bad.size:
            raise InputError(
                f"position[{bad[0]}] = {pos[bad[0]]} is outside the curve's "
                f"arc-length range [0, {total}]"
            )
        raw = np.clip(pos, 0.0, total) + dist
        clamped = (raw < 0.0) | (raw > total)
        s = np.clip(raw, 0.0, total)
    face, bary, segment = _place_on_pieces(points, closed, pieces, s)
    if pieces.face.size == 0:  # a single-point open curve
        return CurveMoveResult(np.zeros(pos.size), SurfacePoints(face, bary), segment, dist != 0.0)
    return CurveMoveResult(s, SurfacePoints(face, bary), segment, clamped)


def _curve_positions(pieces: _Pieces, closed: bool, pos: NDArray[np.float64]) -> NDArray:
    """Arc-length positions already on the curve (open: within [0, total]) as used by
    :func:`move_along_curve` with ``distance=0``."""
    total = pieces.total
    if closed:
        s = np.mod(pos + 0.0, total) if total > 0 else np.zeros_like(pos)
        s[s >= total] = 0.0
        return s
    return np.clip(np.clip(pos, 0.0, total) + 0.0, 0.0, total)


def _place_on_pieces(
    points: SurfacePoints, closed: bool, pieces: _Pieces, s: NDArray[np.float64]
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.int64]]:
    """Face, barycentrics and segment of the curve points at arc lengths ``s`` (in range)."""
    if pieces.face.size == 0:  # a single-point open curve
        return (
            np.repeat(points.face, s.size),
            np.repeat(points.bary, s.size, axis=0),
            np.zeros(s.size, dtype=np.int64),
        )
    arc = np.append(pieces.start[0::2], pieces.total)
    face, bary, segment = _curves.place_on_pieces(
        pieces.face,
        pieces.b0,
        pieces.b1,
        np.ascontiguousarray(pieces.start),
        pieces.length,
        arc,
        _i8(points.face),
        np.ascontiguousarray(points.bary, dtype=np.float64),
        bool(closed),
        np.ascontiguousarray(s, dtype=np.float64),
    )
    return face, bary, segment


def _as_scalars(value: ArrayLike, n: int | None, name: str) -> NDArray[np.float64]:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be numeric") from None
    if a.ndim == 0:
        a = np.full(1 if n is None else n, float(a))
    if a.ndim != 1 or (n is not None and a.shape[0] != n):
        want = "(n,)" if n is None else f"({n},)"
        raise InputError(f"{name} must have shape {want}, got {a.shape}")
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        raise InputError(f"{name}[{bad[0]}] is not finite")
    return np.ascontiguousarray(a)
