"""A starting layout for closed genus-0 meshes: a subdivided cube projected onto the surface."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit.curves.base import check_sampling, densify_curve
from meshfit.curves.paint import paint_curve
from meshfit.errors import InputError, LayoutError
from meshfit.layout.layout import Layout, layout_from_curves
from meshfit.mesh import Mesh
from meshfit.mesh.locate import RayHits
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = ["AxisRays", "FeatureCurves", "cube_layout", "principal_frame"]

#: ray origins tried again (on the copy of bbox diagonal 10) where a ray slips between faces
_NUDGES = 1e-6 * np.array([[1.0, 0.7, 0.3], [-0.4, 1.0, -0.8], [0.9, -0.6, 1.0]])


def _cube_network(n: int, rows: int | None = None):
    """Lattice corners, edges and CCW squares of the subdivided box [-1, 1]^3: ``rows``
    intervals along the first axis (default ``n``), ``n`` along the other two."""
    dims = (n if rows is None else rows, n, n)
    grids = [np.linspace(-1.0, 1.0, d + 1) for d in dims]
    idx: dict[tuple[int, int, int], int] = {}
    pts = []
    for i in range(dims[0] + 1):
        for j in range(dims[1] + 1):
            for k in range(dims[2] + 1):
                if 0 in (i, j, k) or i == dims[0] or j == dims[1] or k == dims[2]:
                    idx[(i, j, k)] = len(pts)
                    pts.append((grids[0][i], grids[1][j], grids[2][k]))
    edges: dict[tuple[int, int], int] = {}
    ends = []
    patches = []
    squares = []
    for a in range(3):
        for side in (0, dims[a]):
            b, c = (a + 1) % 3, (a + 2) % 3
            if side == 0:
                b, c = c, b  # outward normal -e_a: (e_b x e_c) must point outwards
            for u in range(dims[b]):
                for v in range(dims[c]):
                    lat = []
                    for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        key = [0, 0, 0]
                        key[a] = side
                        key[b] = u + du
                        key[c] = v + dv
                        lat.append(idx[tuple(key)])
                    sides = []
                    for s in range(4):
                        p, q = lat[s], lat[(s + 1) % 4]
                        k = (min(p, q), max(p, q))
                        if k not in edges:
                            edges[k] = len(ends)
                            ends.append(k)
                        sides.append((edges[k], p > q))
                    patches.append(sides)
                    squares.append(lat)
    return np.asarray(pts), np.asarray(ends, dtype=np.int64), patches, squares


def principal_frame(mesh: Mesh) -> NDArray[np.float64]:
    """Principal axes of a mesh's vertices about their centroid, as a rotation.

    :func:`cube_layout`'s default ``frame``, and the frame in which its ``axis`` points can
    be given (see ``examples/paint_layouts.py``).

    Parameters
    ----------
    mesh : Mesh
        Any mesh; only its vertices (n, 3) float64 are used.

    Returns
    -------
    (3, 3) float64
        Right-handed rotation whose columns are the axes by decreasing variance. Each of the
        first two columns has the sign the symmetric eigensolver returns; the third is their
        cross product.

    References
    ----------
    .. [1] Jolliffe, "Principal Component Analysis", Springer 2002, ch. 1 (the cube frame
       is not from the thesis, whose layouts are painted by hand, sec. 1.3).
    """
    x = mesh.vertices - mesh.vertices.mean(axis=0)
    _, vecs = np.linalg.eigh(x.T @ x)
    r = vecs[:, ::-1]
    if np.linalg.det(r) < 0:
        r[:, 2] = -r[:, 2]
    return r


@dataclass(frozen=True, eq=False)
class AxisRays:
    """Where :func:`cube_layout` casts its rays from when no single point sees the whole
    model: an axis polyline inside it.

    Attributes
    ----------
    points : (k, 3) float64
        Polyline inside the closed mesh (``k >= 2`` points, model units) along which the
        ray origins move. The box's first axis ``e0`` is the first column of the layout's
        ``frame``, turned to point from the first point to the last; ``e1``, ``e2`` are the
        other two columns (made square to ``e0``).
    levels : (rows + 1,) float64, optional
        Increasing fractions of the axis's length where the ray origins of each row boundary
        sit (default evenly spread from 0 to 1).
    cap_tilt : (float, float)
        Tilt of the rays towards ``-e0`` at the first end and ``+e0`` at the last end
        (default 1.0: 45 degrees at the middle of a cap's sides); larger values make
        smaller caps.
    """

    points: ArrayLike
    levels: ArrayLike | None = None
    cap_tilt: tuple[float, float] = (1.0, 1.0)


@dataclass(frozen=True)
class FeatureCurves:
    """Feature curves :func:`cube_layout` paints inside one patch (thesis sec. 5.10.1).

    Attributes
    ----------
    patch : int
        The patch that gets them.
    fractions : tuple of float
        For each fraction one iso-curve in each direction at that parameter, painted from a
        sample of one side's curve to a sample of the opposite side's curve (default
        ``(1/3, 2/3)``).
    """

    patch: int
    fractions: tuple[float, ...] = (1 / 3, 2 / 3)


def cube_layout(
    mesh: Mesh,
    *,
    n: int = 2,
    rows: int | None = None,
    center: ArrayLike | None = None,
    frame: ArrayLike | None = None,
    axis: AxisRays | ArrayLike | None = None,
    picks_per_curve: int = 8,
    spacing: float | None = None,
    features: FeatureCurves | None = None,
) -> Layout:
    """Project an ``n x n`` subdivided cube from a centre onto a closed mesh (``6 n^2``
    patches), or a box from an axis, and paint its edges as boundary curves.

    Each cube lattice point is projected along the ray from ``center`` through it (first hit);
    each cube edge is painted with :func:`meshfit.curves.paint_curve` through the projections of
    ``picks_per_curve`` points along it. This gives a valid layout where the surface is
    star-shaped from the centre; elsewhere projected curves may cross (check with
    :func:`meshfit.layout.check_layout_topology`).

    A model that no single point sees all of, such as a bust (a head on a neck on the
    shoulders), is laid out from an ``axis`` instead: a polyline inside the model from the
    middle of one end to the middle of the other. The box then has ``rows`` rows of ``4 n``
    patches around the axis and an ``n x n`` cap at each end (``4 n rows + 2 n^2``
    patches). The lattice points of row boundary ``j`` are projected from the axis point at
    ``axis.levels[j]`` (a fraction of the axis length), along rays square to the axis; towards
    the caps the rays tilt to the axis direction by ``axis.cap_tilt`` (the cap lattice is
    projected from the axis ends along ``a e1 + b e2 -+ cap_tilt e0``, ``a, b`` in
    ``[-1, 1]``). Where the model is star-shaped from every axis point along the rays square
    to it (each cross-section seen from its axis point), the curves do not cross.

    Parameters
    ----------
    mesh : Mesh
        Closed mesh containing ``center``.
    n : int, keyword-only
        Patches per cube face along each direction (default 2: 24 patches).
    rows : int, keyword-only, optional
        Patches along the box's first axis (default ``n``: a cube). Without ``axis`` that is
        the first column of ``frame``.
    center : (3,) float64, keyword-only, optional
        Ray origin; default the vertex centroid.
    frame : (3, 3) float64, keyword-only, optional
        Rotation whose columns are the cube axes; default the principal axes of the vertices.
    axis : AxisRays or (k, 3) float64, keyword-only, optional
        Cast the rays from this axis instead of from ``center`` (a bare polyline is
        ``AxisRays(points)``).
    picks_per_curve : int, keyword-only
        Projected picks painted through on each cube edge, ends excluded (default 8).
    spacing : float, keyword-only, optional
        Sample spacing of the painted curves, model units; default the mean edge length.
    features : FeatureCurves, keyword-only, optional
        Feature curves painted inside one patch.

    Returns
    -------
    Layout

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.2 (painting curves through picked points), sec. 1.3
       (patch layouts), sec. 5.10.1 (feature curves painted from side to opposite side).
    """
    if int(n) < 1:
        raise InputError(f"n must be >= 1, got {n}")
    n = int(n)
    if rows is not None and int(rows) < 1:
        raise InputError(f"rows must be >= 1, got {rows}")
    rows = n if rows is None else int(rows)
    center = mesh.vertices.mean(axis=0) if center is None else np.asarray(center, float)
    frame = principal_frame(mesh) if frame is None else np.asarray(frame, float)
    if spacing is None:
        spacing = mesh.mean_edge_length
    if axis is not None and not isinstance(axis, AxisRays):
        axis = AxisRays(axis)
    from_axis = None if axis is None else _Axis(axis, frame, rows)
    pts, ends, patches, squares = _cube_network(n, rows)
    # rays are cast on a copy centred at the origin with bbox diagonal 10: libigl's ray query
    # misses every hit on finely tessellated models a few centimetres across; faces and
    # barycentrics are the same on the copy
    scale = 10.0 / mesh.bbox_diagonal
    unit = Mesh((mesh.vertices - center) * scale, mesh.faces)

    def project(q: NDArray[np.float64]) -> SurfacePoints:
        if from_axis is None:
            d = q @ frame.T
            o = np.zeros_like(d)
        else:
            o, d = from_axis.rays(q)
            o = (o - center) * scale
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        hits = unit.ray_first_hit(o, d)
        face, bary = hits.face.copy(), hits.bary.copy()
        for nudge in _NUDGES:  # a ray through an edge or vertex may slip between the faces
            miss = np.flatnonzero(face < 0)
            if miss.size == 0:
                break
            again = unit.ray_first_hit(o[miss] + nudge[None], d[miss])
            face[miss], bary[miss] = again.face, again.bary
        hits = RayHits(face >= 0, hits.t, face, bary)
        if not hits.hit.all():
            k = int(np.flatnonzero(~hits.hit)[0])
            where = "the centre" if from_axis is None else "the axis"
            raise LayoutError(
                f"the ray from {where} towards box point {q[k].tolist()} misses the mesh: "
                f"is {where} inside the closed mesh?"
            )
        return SurfacePoints(hits.face, hits.bary)

    corners = project(pts)
    curves = []
    t = np.linspace(0.0, 1.0, picks_per_curve + 2)[1:-1]
    for a, b in ends.tolist():
        q = pts[a][None] + t[:, None] * (pts[b] - pts[a])[None]
        mid = project(q) if len(t) else SurfacePoints(np.zeros(0, np.int64), np.zeros((0, 3)))
        picks = SurfacePoints.concatenate([corners[a], mid, corners[b]])
        curves.append(_tidy(mesh, paint_curve(mesh, picks, spacing=spacing), spacing))
    inside: list[list[SurfaceCurve]] = [[] for _ in patches]
    if features is not None:
        k = features.patch
        if not 0 <= int(k) < len(patches):
            raise InputError(f"features.patch must be in [0, {len(patches)}), got {k}")
        inside[k] = _feature_curves(
            mesh, project, pts, curves, patches[k], squares[k],
            features.fractions, picks_per_curve, spacing,
        )  # fmt: skip
    return layout_from_curves(mesh, corners, curves, ends, patches, inside)


def _feature_curves(
    mesh: Mesh,
    project: Callable[[NDArray[np.float64]], SurfacePoints],
    pts: NDArray[np.float64],
    curves: list[SurfaceCurve],
    sides: Sequence,
    lat: Sequence,
    fractions: Sequence[float],
    picks_per_curve: int,
    spacing: float,
) -> list[SurfaceCurve]:
    """The feature curves of `cube_layout`'s ``features`` patch (its four ``sides`` and box
    points ``lat``): for each fraction one iso-curve in each direction, painted from a
    sample of one side's curve to a sample of the opposite side's curve."""
    out = []
    p0, p1, p3 = pts[lat[0]], pts[lat[1]], pts[lat[3]]
    eu, ev = p1 - p0, p3 - p0
    for along in ("u", "v"):
        for frac in fractions:
            if along == "u":  # constant v, from side 3 (u = 0) to side 1 (u = 1)
                q = [p0 + s * eu + frac * ev for s in np.linspace(0, 1, picks_per_curve + 2)]
                s_from, s_to = 3, 1
            else:  # constant u, from side 0 (v = 0) to side 2 (v = 1)
                q = [p0 + frac * eu + s * ev for s in np.linspace(0, 1, picks_per_curve + 2)]
                s_from, s_to = 0, 2
            q = np.asarray(q)
            mid = project(q[1:-1])
            start = _nearest_sample(mesh, curves, sides[s_from], project(q[:1]))
            end = _nearest_sample(mesh, curves, sides[s_to], project(q[-1:]))
            picks = SurfacePoints.concatenate([start, mid, end])
            out.append(
                _tidy(mesh, paint_curve(mesh, picks, kind="feature", spacing=spacing), spacing)
            )
    return out


class _Axis:
    """Ray origins and directions of box points projected from an axis polyline (see
    `cube_layout`)."""

    def __init__(self, axis: AxisRays, frame, rows: int) -> None:
        levels, cap_tilt = axis.levels, axis.cap_tilt
        P = np.asarray(axis.points, dtype=np.float64)
        if P.ndim != 2 or P.shape[0] < 2 or P.shape[1] != 3 or not np.isfinite(P).all():
            raise InputError(f"axis must be a (k >= 2, 3) array of finite points, got {P.shape}")
        seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
        if not (seg > 0.0).all():
            raise InputError("axis points must differ from their neighbours")
        self.points = P
        self.arc = np.concatenate([[0.0], np.cumsum(seg)]) / seg.sum()
        lv = np.linspace(0.0, 1.0, rows + 1) if levels is None else np.asarray(levels, float)
        if lv.shape != (rows + 1,) or not (np.diff(lv) > 0).all() or lv[0] < 0 or lv[-1] > 1:
            raise InputError(
                f"levels must be {rows + 1} increasing fractions in [0, 1] (one per row "
                f"boundary), got {lv.tolist()}"
            )
        self.levels = lv
        tilt = np.asarray(cap_tilt, dtype=np.float64)
        if tilt.shape != (2,) or not (tilt > 0).all() or not np.isfinite(tilt).all():
            raise InputError(f"cap_tilt must be two positive numbers, got {cap_tilt}")
        self.tilt = tilt
        self.rows = rows
        f = np.asarray(frame, dtype=np.float64)
        e0 = f[:, 0] / np.linalg.norm(f[:, 0])
        run = float((P[-1] - P[0]) @ e0)
        if abs(run) <= 1e-9 * np.linalg.norm(P[-1] - P[0]):
            raise InputError("the axis must run along the frame's first axis (end to end)")
        e0 = e0 if run > 0 else -e0
        e1 = f[:, 1] - (f[:, 1] @ e0) * e0
        e1 = e1 / np.linalg.norm(e1)
        self.basis = np.column_stack([e0, e1, np.cross(e0, e1)])

    def rays(self, q: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """Origins and directions (model units) of box points ``q (k, 3)`` in [-1, 1]^3."""
        q = np.atleast_2d(np.asarray(q, dtype=np.float64))
        level = 0.5 * (q[:, 0] + 1.0) * self.rows  # row-boundary index, fractional between
        frac = np.interp(level, np.arange(self.rows + 1), self.levels)
        origin = np.column_stack([np.interp(frac, self.arc, self.points[:, c]) for c in range(3)])
        # the tilt fades out over the first and last rows (one row: from one end's to the other's)
        t = np.interp(level, [0.0, 1.0], [-self.tilt[0], 0.0]) + np.interp(
            level, [self.rows - 1.0, self.rows], [0.0, self.tilt[1]]
        )
        local = np.column_stack([t, q[:, 1], q[:, 2]])
        return origin, local @ self.basis.T


def _nearest_sample(
    mesh: Mesh, curves: list[SurfaceCurve], side: tuple[int, bool], target: SurfacePoints
) -> SurfacePoints:
    """The sample of the side's curve nearest ``target`` (ends excluded)."""
    c = curves[side[0]]
    x = mesh.xyz(c.points)
    d = np.linalg.norm(x - mesh.xyz(target)[0], axis=1)
    d[[0, -1]] = np.inf
    return c.points[int(np.argmin(d))]


def _tidy(mesh: Mesh, curve: SurfaceCurve, spacing: float) -> SurfaceCurve:
    """Drop painted samples that stall or step back (closer than ``spacing / 4`` to the last
    kept sample, or closer to the sample two back than to the last), keeping both ends; the
    sampling rule is restored with :func:`meshfit.curves.densify_curve` where needed."""
    x = mesh.xyz(curve.points)
    n = len(x)
    keep = [0]
    for i in range(1, n - 1):
        while True:
            if np.linalg.norm(x[i] - x[keep[-1]]) < 0.25 * spacing:
                break  # a stall: drop sample i
            if len(keep) >= 2 and np.linalg.norm(x[i] - x[keep[-2]]) <= np.linalg.norm(
                x[keep[-1]] - x[keep[-2]]
            ):
                keep.pop()  # a step back towards the sample two back: a zig-zag
                continue
            keep.append(i)
            break
    while len(keep) >= 2 and np.linalg.norm(x[n - 1] - x[keep[-1]]) < 0.25 * spacing:
        keep.pop()
    keep.append(n - 1)
    out = SurfaceCurve(curve.points[np.asarray(keep)], kind=curve.kind)
    if len(check_sampling(mesh, out)):
        out = densify_curve(mesh, out)
    return out
