"""Painting surface curves through picked points, CurveAttract, and extending to a curve.

- :func:`paint_curve`: greedy graph path between each pair of picks, sampled into face
  points and straightened toward the chord between the picks by CurveAttract (sec. 3.2);
- :func:`attract_curve`: slide each face point of a curve to the surface point closest to
  its sample of a space curve (CurveAttract, sec. 3.3.1);
- :func:`extend_to_curve`: extend a curve from one end to the closest point of another
  curve (sec. 5.10.1).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit import tol
from meshfit._kernels import curves as _curves
from meshfit._validate import as_points, as_surface_points
from meshfit.curves.base import (
    _as_curve,
    _resample,
    _topology,
    curve_length,
    resample_curve,
)
from meshfit.curves.snake import SnakeOptions, relax_snake
from meshfit.errors import InputError, PathError
from meshfit.mesh import Mesh
from meshfit.surface.paths import greedy_path, path_to_surface_points, vertex_points
from meshfit.surface.walk import _i8, attract_points
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = ["attract_curve", "extend_to_curve", "paint_curve"]

#: a painted segment's spacing is even to this coefficient of variation (one resampling pass
#: in most cases; :func:`resample_curve` evens a curve to 1 %)
PAINT_SPACING_CV = 0.05
#: membrane steps that smooth a painted segment longer than its graph path
TAUT_ITERATIONS = 10
#: attraction steps per point when straightening (as :func:`meshfit.surface.attract_points`)
_ATTRACT_MAX_ITER = 200


def _as_picks(mesh: Mesh, picks: ArrayLike | SurfacePoints) -> tuple[SurfacePoints, NDArray]:
    """Picks as face points plus the vertex each one snaps to for graph paths."""
    if isinstance(picks, SurfacePoints):
        pts = as_surface_points(mesh, picks, name="picks")
        V, F = mesh.vertices, mesh.faces
        x = mesh.xyz(pts)
        corners = F[pts.face]  # (n, 3)
        d = np.linalg.norm(V[corners] - x[:, None, :], axis=2)
        snap = corners[np.arange(len(pts)), np.argmin(d, axis=1)]
        return pts, snap.astype(np.int64)
    try:
        a = np.asarray(picks)
    except (TypeError, ValueError):
        raise InputError("picks must be vertex indices or SurfacePoints") from None
    if a.ndim != 1 or not (
        a.size == 0 or np.issubdtype(a.dtype, np.integer) or np.issubdtype(a.dtype, np.floating)
    ):
        raise InputError(f"picks must be a 1-d array of vertex indices, got shape {a.shape}")
    if np.issubdtype(a.dtype, np.floating):
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise InputError(f"picks[{bad[0]}] is {a[bad[0]]}, not a vertex index")
        if (a != np.round(a)).any():
            i = int(np.flatnonzero(a != np.round(a))[0])
            raise InputError(f"picks[{i}] = {a[i]} is not an integer vertex index")
    v = a.astype(np.int64)
    bad = np.flatnonzero((v < 0) | (v >= mesh.n_vertices))
    if bad.size:
        raise InputError(
            f"picks[{bad[0]}] = {v[bad[0]]} is not a vertex index in [0, {mesh.n_vertices})"
        )
    return vertex_points(mesh, v), v


def _segment(
    mesh: Mesh, a: SurfacePoints, b: SurfacePoints, va: int, vb: int, spacing: float
) -> SurfacePoints:
    """One painted segment from pick a to pick b (both included), well sampled."""
    if a.face[0] == b.face[0]:
        raw = SurfacePoints.concatenate([a, b])
    else:
        path = greedy_path(mesh, va, vb).vertices
        # pick -> its snap vertex (same face) -> path samples -> snap vertex -> pick
        # (edge midpoints too: samples about half an edge apart, as dense as the result)
        per_edge = max(0, int(np.ceil(mesh.mean_edge_length / spacing)) - 1)
        samples = path_to_surface_points(mesh, path, per_edge=per_edge)
        raw = SurfacePoints.concatenate([a, samples, b])
    pts = raw
    m = len(pts)
    if m <= 2:
        return resample_curve(mesh, SurfaceCurve(pts), spacing=spacing).points
    # CurveAttract toward the chord: each graph sample's target is the chord point at the
    # same fraction of the length (the samples keep their order and rough spacing)
    targets = _curves.chord_targets(mesh.vertices, _i8(mesh.faces), pts.face, pts.bary)
    # by continuation: each point may start where its predecessor settled (a short walk
    # each); where attraction pulled neighbours apart (sharp bends, thin parts of the model:
    # faces sharing no vertex, or a gap over three spacings) the graph-path samples are kept,
    # each reverted stretch growing until no pair jumps; a pair merely passing a vertex
    # through a fan of faces is filled in by densifying when resampling
    face, bary = _curves.straighten_chain(
        mesh.vertices,
        *_topology(mesh),
        pts.face,
        pts.bary,
        targets,
        _ATTRACT_MAX_ITER,
        10_000,
        tol.length(mesh, tol.ATTRACT_EPS),
        tol.BARY_EPS,
        3.0 * max(spacing, mesh.mean_edge_length),
    )
    straight = SurfacePoints(face, bary)
    out, _ = _resample(
        mesh, SurfaceCurve(straight), spacing=spacing, n=None, cv=PAINT_SPACING_CV, checked=True
    )
    # attraction by continuation can settle unevenly, in a zigzag of the samples that the
    # graph path's length betrays (the resampled curve comes out longer than the path; a
    # minority of segments do this): such a segment is smoothed by a few membrane steps at
    # its own resolution (each sample moves under three spacings, the course stays)
    if curve_length(mesh, out) <= curve_length(mesh, SurfaceCurve(raw)):
        return out.points
    taut_options = SnakeOptions(w_arc=0.0, levels=1, max_iter=TAUT_ITERATIONS)
    taut = relax_snake(mesh, out, taut_options).curve
    taut, _ = _resample(mesh, taut, spacing=spacing, n=None, cv=PAINT_SPACING_CV, checked=True)
    return taut.points


def paint_curve(
    mesh: Mesh,
    picks: ArrayLike | SurfacePoints,
    *,
    closed: bool = False,
    kind: Literal["boundary", "feature"] = "boundary",
    spacing: float | None = None,
) -> SurfaceCurve:
    """Paint a surface curve through picked points (the thesis' curve painting).

    Each pair of consecutive picks is joined in two steps: a greedy graph path between the
    mesh vertices nearest the picks, sampled into face points, is straightened toward the
    3-D chord between the picks by CurveAttract (targets evenly spaced on the chord). The
    attracted points only slide on the surface; where attraction pulls neighbours onto
    faces that are neither the same nor adjacent (sharp bends, thin parts of the model) the
    stretch falls back to the graph-path samples, so the curve never jumps. Attraction runs
    by continuation: each point may start where its predecessor settled. Each segment is
    then resampled evenly by arc length (spacing CV at most :data:`PAINT_SPACING_CV`). A
    segment that comes out longer than its graph path (attraction settled in a zigzag) is
    smoothed by :data:`TAUT_ITERATIONS` membrane steps of
    :func:`meshfit.curves.relax_snake` at its own resolution and resampled again.

    Parameters
    ----------
    mesh : Mesh
    picks : (n,) int64 vertex indices or SurfacePoints
        n >= 2 picked points (n >= 3 for a closed curve), all on one component. A face-point
        pick is kept exactly; only its graph path starts at its nearest face corner.
    closed : bool, keyword-only
        Join the last pick back to the first.
    kind : {"boundary", "feature"}, keyword-only
        Stored on the result.
    spacing : float, keyword-only, optional
        Arc length between samples, model units; default half the mean edge length.

    Returns
    -------
    SurfaceCurve
        Face points through every pick in order (each pick exactly once), consecutive
        points on the same or adjacent faces (``check_sampling`` is empty).

    Raises
    ------
    meshfit.errors.InputError
        Fewer than two picks (three for a closed curve), a non-finite or out-of-range pick,
        a bad ``spacing``.
    meshfit.errors.PathError
        Two picks lie on different components of the mesh.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD
       thesis, Stanford 2000, sec. 3.2 (curve painting, fig. 3.3) and sec. 3.3.1
       (CurveAttract).
    """
    pts, snap = _as_picks(mesh, picks)
    need = 3 if closed else 2
    if len(pts) < need:
        what = "a closed curve needs" if closed else "a curve needs"
        raise InputError(f"{what} at least {need} picks, got {len(pts)}")
    if kind not in ("boundary", "feature"):
        raise InputError(f"kind must be 'boundary' or 'feature', got {kind!r}")
    if spacing is None:
        spacing = 0.5 * mesh.mean_edge_length
    spacing = float(spacing)
    if not np.isfinite(spacing) or spacing <= 0:
        raise InputError(f"spacing must be a positive length, got {spacing!r}")
    comp = mesh.vertex_components[snap]
    other = np.flatnonzero(comp != comp[0])
    if other.size:
        j = int(other[0])
        raise PathError(
            f"picks 0 and {j} lie on different components ({int(comp[0])} and "
            f"{int(comp[j])}) of {mesh.name or 'the mesh'}: no curve can join them"
        )
    n = len(pts)
    parts = []
    for i in range(n if closed else n - 1):
        j = (i + 1) % n
        seg = _segment(mesh, pts[i], pts[j], int(snap[i]), int(snap[j]), spacing)
        parts.append(seg if i == 0 else seg[1:])
    curve = SurfacePoints.concatenate(parts)
    if closed:
        curve = curve[: len(curve) - 1]  # the last point is pick 0 again
    return SurfaceCurve(curve, closed=closed, kind=kind)


def _uniform_polyline(xyz: NDArray, n: int, closed: bool) -> NDArray:
    """n points evenly spaced by arc length along a 3-D polyline (closed: around the loop)."""
    if closed:
        xyz = np.concatenate([xyz, xyz[:1]])
    seg = np.linalg.norm(np.diff(xyz, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = s[-1]
    if total == 0.0 or xyz.shape[0] == 1:
        return np.repeat(xyz[:1], n, axis=0)
    q = np.arange(n) * (total / n) if closed else np.linspace(0.0, total, n)
    j = np.clip(np.searchsorted(s, q, side="right") - 1, 0, seg.size - 1)
    t = np.divide(q - s[j], seg[j], out=np.zeros_like(q), where=seg[j] > 0)
    return xyz[j] + t[:, None] * (xyz[j + 1] - xyz[j])


def attract_curve(
    mesh: Mesh,
    curve: SurfaceCurve,
    space_curve: ArrayLike | Callable[[NDArray], ArrayLike],
    *,
    samples_per_point: int = 16,
) -> SurfaceCurve:
    """Slide a face-point curve onto the surface projection of a space curve (CurveAttract).

    The space curve is sampled uniformly by arc length into one 3-D point per face point of
    ``curve``; each face point then walks on the surface to the locally closest point to its
    target (:func:`meshfit.surface.attract_points`). Face points move independently and
    never leave the surface; no global projection is made.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfaceCurve
        m face points, the starting positions.
    space_curve : (k, 3) float64 or callable
        The space curve: a 3-D polyline (k >= 2), or a function mapping parameters
        ``t (j,) float64`` in [0, 1] to positions ``(j, 3) float64`` (e.g.
        ``SpaceCurve.evaluate``). For a closed ``curve`` the polyline is closed back to its
        first point; a callable is sampled on [0, 1) then.
    samples_per_point : int, keyword-only
        A callable is evaluated at ``samples_per_point * m + 1`` parameters before the
        arc-length sampling.

    Returns
    -------
    SurfaceCurve
        m attracted face points, same ``closed`` and ``kind``. Consecutive points may break
        the sampling rule where the space curve has no plausible projection; check with
        :func:`meshfit.curves.check_sampling` and repair with
        :func:`meshfit.curves.densify_curve`.

    Raises
    ------
    meshfit.errors.InputError
        Bad ``curve``, a space curve with the wrong shape or a non-finite value.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD
       thesis, Stanford 2000, sec. 3.3.1 (CurveAttract, fig. 3.4) and appendix A.
    """
    curve = _as_curve(mesh, curve)
    m = len(curve)
    if callable(space_curve):
        k = max(int(samples_per_point), 1) * m + 1
        t = np.linspace(0.0, 1.0, k)
        xyz = as_points(space_curve(t), name="space_curve(t)")
        if xyz.shape[0] != k:
            raise InputError(f"space_curve(t) returned {xyz.shape[0]} points for {k} parameters")
        if curve.closed:
            xyz = xyz[:-1]
    else:
        xyz = as_points(space_curve, name="space_curve")
        if xyz.shape[0] < 2:
            raise InputError(f"space_curve needs at least 2 points, got {xyz.shape[0]}")
    targets = _uniform_polyline(xyz, m, curve.closed)
    end = attract_points(mesh, curve.points, targets).end
    return SurfaceCurve(end, closed=curve.closed, kind=curve.kind)


def extend_to_curve(
    mesh: Mesh,
    curve: SurfaceCurve,
    target_curve: SurfaceCurve,
    *,
    at: Literal["start", "end"] = "end",
    spacing: float | None = None,
) -> SurfaceCurve:
    """Extend an open curve from one end to the closest point of another curve.

    The face point of ``target_curve`` closest (Euclidean, brute force) to the chosen end is
    found and joined to that end with the painting procedure of :func:`paint_curve`; the
    result ends (or starts) exactly at that face point of ``target_curve``.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfaceCurve
        Open curve to extend.
    target_curve : SurfaceCurve
        The curve to reach (e.g. a patch boundary).
    at : {"start", "end"}, keyword-only
        Which end of ``curve`` to extend.
    spacing : float, keyword-only, optional
        Sample spacing of the new stretch, as in :func:`paint_curve`.

    Returns
    -------
    SurfaceCurve
        ``curve`` with the new stretch added at ``at``; same ``kind``; well sampled where
        ``curve`` was.

    Raises
    ------
    meshfit.errors.InputError
        ``curve`` is closed, either curve is not on ``mesh``, or ``at`` is not "start" or
        "end".
    meshfit.errors.PathError
        The end of ``curve`` and ``target_curve`` lie on different components.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.10.1 (a feature curve starts at the closest point of
       a boundary curve, joined with the procedure of sec. 3.2).
    """
    curve = _as_curve(mesh, curve)
    target_curve = _as_curve(mesh, target_curve, "target_curve")
    if curve.closed:
        raise InputError("extend_to_curve needs an open curve; curve is closed")
    if at not in ("start", "end"):
        raise InputError(f"at must be 'start' or 'end', got {at!r}")
    p = curve.points[-1] if at == "end" else curve.points[0]
    x = mesh.xyz(p)[0]
    d = np.linalg.norm(mesh.xyz(target_curve.points) - x, axis=1)
    q = target_curve.points[int(np.argmin(d))]
    try:
        bridge = paint_curve(
            mesh, SurfacePoints.concatenate([p, q]), kind=curve.kind, spacing=spacing
        ).points
    except PathError as exc:
        raise PathError(f"cannot extend the curve's {at} to target_curve: {exc}") from None
    if at == "end":
        pts = SurfacePoints.concatenate([curve.points, bridge[1:]])
    else:
        pts = SurfacePoints.concatenate([bridge[::-1][:-1], curve.points])
    return SurfaceCurve(pts, closed=False, kind=curve.kind)
