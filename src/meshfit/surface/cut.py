"""Cutting a mesh along a curve of face points, so the curve becomes a path of mesh edges.

The fit pipeline cuts the mesh along the painted patch boundaries so that every patch is a
submesh of its own and no walk on a patch can leave it: the "polygonal patches" bounded by the
painted curves (Krishnamurthy 2000, sec. 1.3 and fig. 1.2; curves painted as in sec. 3.2) that
the spring mesh of sec. 5 resamples.

Method
------
1. Every input point is snapped (within ``tol.CUT_SNAP`` mean edge lengths) onto a vertex or an
   edge of its face. Between consecutive points on edge-adjacent faces the crossing with the
   shared edge is inserted (the second face unfolded into the plane of the first); points whose
   faces share only a vertex are routed through that vertex. After this every consecutive pair
   lies in one original face, so the segment joining them is straight in that face's plane.
2. Each point is inserted into a dynamic triangulation: 1-to-3 split of the triangle holding an
   interior point, 2-to-4 split of the edge holding an edge point.
3. Consecutive points ``u -> w`` are joined by walking from ``u``: the triangle around ``u``
   (inside their common original face) whose wedge holds the direction to ``w`` has its opposite
   edge split at the crossing point (or the walk steps onto a corner lying on the segment), so
   every step adds one mesh edge along the segment.
4. With ``split=True`` the vertices of the cut path are duplicated per fan of faces that the
   cut separates (:func:`meshfit.mesh.topology.corner_fans` with the cut edges marked).

All arithmetic on new points is done in barycentric coordinates of the original faces, so a
point on an original edge keeps an exact zero coordinate and every new vertex has an exact
source point on the original mesh.
"""

from __future__ import annotations

import contextlib
import gc
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

from meshfit import tol
from meshfit._kernels import cut as _k
from meshfit._validate import as_surface_points
from meshfit.errors import CutError, InputError
from meshfit.mesh import Mesh
from meshfit.surface.paths import vertex_points
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = ["CutResult", "NetworkCutResult", "cut_mesh", "cut_mesh_network", "network_meetings"]


@dataclass(frozen=True)
class CutResult:
    """Result of :func:`cut_mesh`.

    Attributes
    ----------
    mesh : Mesh
        The cut mesh (validated). Original vertices keep their indices (the first
        ``nv`` rows); original faces keep their index for one of their pieces.
    path : (k,) int64
        Vertices of the new mesh along the curve, in curve order. For a closed curve the last
        vertex joins back to the first (the first is not repeated). With ``split=True`` these
        are the copies on the left of the curve (the side of the faces whose winding runs along
        the curve's direction).
    path_other_side : (k,) int64
        The copies on the right of the curve; equal to ``path`` where nothing was split
        (``split=False``, the ends of an open cut, the mesh boundary).
    face_parent : (nf_new,) int64
        Original face each new face lies in.
    vertex_parent : (nv_new,) int64
        Original vertex each new vertex copies, -1 for vertices created by the cut.
    vertex_source : SurfacePoints
        Every new vertex as a face point of the original mesh (original vertices get one-hot
        barycentrics): ``original.xyz(vertex_source)`` equals ``mesh.vertices``.
    closed : bool
        Whether the curve was cut as a closed loop.

    Notes
    -----
    Where the curve passes through a vertex of the mesh boundary, the faces on one side of it
    are no longer connected around that vertex; ``path`` then takes the copy on the left of the
    edge leaving the vertex.
    """

    mesh: Mesh
    path: NDArray[np.int64]
    path_other_side: NDArray[np.int64]
    face_parent: NDArray[np.int64]
    vertex_parent: NDArray[np.int64]
    vertex_source: SurfacePoints
    closed: bool


# ----------------------------------------------------------------------- small vector helpers
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _norm(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


def _lerp(a, b, s):
    return (a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), a[2] + s * (b[2] - a[2]))


@contextlib.contextmanager
def _no_gc():
    """Pause the cyclic garbage collector while the cut builds its many small containers
    (they hold no cycles; repeated full collections over them dominate the run time)."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


@dataclass
class _CutPoint:
    """A curve point after snapping: on original vertex ``vertex`` (or -1), else at ``bary`` in
    ``face``; ``faces`` are all original faces containing it."""

    face: int
    bary: tuple[float, float, float]
    vertex: int
    faces: frozenset[int]
    xyz: tuple[float, float, float]
    index: int  # input index, for messages


class _Cutter:
    """Dynamic triangulation of the original faces a cut touches.

    The triangulation lives in the arrays of :mod:`meshfit._kernels.cut` (``state``); points
    are inserted and joined there. Original faces are loaded lazily: making face ``g``
    editable loads it and its neighbours.
    """

    def __init__(self, mesh: Mesh, n_points: int = 0, scale: tuple[float, float] | None = None):
        self.mesh = mesh
        self.V0 = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
        self.F0 = np.ascontiguousarray(mesh.faces, dtype=np.int64)
        self.FN = np.ascontiguousarray(mesh.face_neighbors, dtype=np.int64)
        self.nv0 = mesh.n_vertices
        self.nf0 = mesh.n_faces
        edge, diag = (mesh.mean_edge_length, mesh.bbox_diagonal) if scale is None else scale
        self.snap = tol.CUT_SNAP * edge
        self.min_area = tol.CUT_MIN_AREA * diag**2
        self.vf_indptr, self.vf_faces = mesh.vertex_faces
        self.VFI = np.ascontiguousarray(self.vf_indptr, dtype=np.int64)
        self.VFF = np.ascontiguousarray(self.vf_faces, dtype=np.int64)
        self._face_cache: dict[int, tuple[int, int, int]] = {}
        self._xyz_cache: dict[int, tuple[float, float, float]] = {}
        cap = max(1024, 4 * n_points)
        self.state = _k.new_state(self.F0, self.nv0, cap, cap)
        # the cut edges of the finished paths, (m, 2) sorted rows a < b (set before splitting)
        self.cut = np.zeros((0, 2), dtype=np.int64)
        # join points on faces sharing only a vertex across the fan (else through the vertex)
        self.route_fans = False

    # ------------------------------------------------------------------ lookups
    def face(self, f: int) -> tuple[int, int, int]:
        t = self._face_cache.get(f)
        if t is None:
            t = tuple(int(v) for v in self.F0[f])
            self._face_cache[f] = t
        return t

    def xyz(self, v: int) -> tuple[float, float, float]:
        if v >= self.nv0:
            x = self.state[3][v - self.nv0]
            return (float(x[0]), float(x[1]), float(x[2]))
        p = self._xyz_cache.get(v)
        if p is None:
            p = tuple(float(x) for x in self.V0[v])
            self._xyz_cache[v] = p
        return p

    def faces_around(self, v: int) -> frozenset[int]:
        return frozenset(self.vf_faces[self.vf_indptr[v] : self.vf_indptr[v + 1]].tolist())

    def bary_in(self, v: int, g: int) -> tuple[float, float, float]:
        """Barycentric coordinates of original vertex ``v`` in original face ``g``."""
        fg = self.face(g)
        return (float(fg[0] == v), float(fg[1] == v), float(fg[2] == v))

    @property
    def n_new(self) -> int:
        """Number of vertices the cut made."""
        return int(self.state[0][_k.N_NEW])

    @property
    def n_tri(self) -> int:
        """Number of triangles (original faces first, loaded or not)."""
        return int(self.state[0][_k.N_TRI])

    def mark_on_path(self, v: int) -> None:
        _, _, _, _, NI, OP0, _, _ = self.state
        _k.set_on_path(self.V0, NI, OP0, v)

    def _raise(self) -> None:
        """Raise the error that a kernel left in the state, if any."""
        S = self.state[0]
        code, a, b, c, d = (int(x) for x in S[_k.ERR : _k.ERR + 5])
        if code == 0:
            return
        S[_k.ERR : _k.ERR + 5] = 0
        if code == _k.ERR_BRIDGE:
            raise CutError(
                f"curve points {a} and {b} lie on faces {c} and {d}, which are not "
                "the same, edge-adjacent or sharing a vertex: sample the curve more densely "
                "(consecutive points on the same or adjacent faces)"
            )
        if code == _k.ERR_COLLAPSE:
            raise CutError(
                f"the curve's {a} points collapse to {b} distinct point(s): nothing to cut"
            )
        if code == _k.ERR_NOT_JOINED:
            raise CutError(f"internal: edge pieces {a}, {b} of face {c} are not joined")
        if code == _k.ERR_WALK:  # pragma: no cover - guarded by construction
            raise CutError(f"internal: walk from vertex {a} to vertex {b} in face {c} did not end")
        if code == _k.ERR_NO_TRIANGLE:  # pragma: no cover - guarded by construction
            raise CutError(f"internal: no triangle of original face {a} around vertex {b}")
        if code == _k.ERR_NOT_ON_FACE:  # pragma: no cover - guarded by construction
            raise CutError(f"internal: vertex {a} is not on original face {b}")
        if code == _k.ERR_POOL:  # pragma: no cover - guarded by construction
            raise CutError("internal: no room for a face's triangle table")
        raise CutError(f"internal: edge ({a}, {b}) has more than two faces")  # pragma: no cover

    # --------------------------------------------------------------- insertion
    def insert(self, cp: _CutPoint, g: int) -> int:
        """Insert a snapped curve point into original face ``g`` (which contains it)."""
        if cp.vertex >= 0:
            return cp.vertex
        path, *state = _k.insert_curve(
            self.V0,
            self.F0,
            self.FN,
            self.snap,
            self.min_area,
            *self.state,
            np.array([cp.face], dtype=np.int64),
            np.array([cp.bary], dtype=np.float64),
            np.array([cp.vertex], dtype=np.int64),
            np.array([cp.xyz], dtype=np.float64),
            np.array([g], dtype=np.int64),
            False,
        )
        self.state = tuple(state)
        self._raise()
        return int(path[0])

    def cut_curve(self, CI: NDArray[np.int64], CF: NDArray[np.float64], closed: bool) -> list[int]:
        """Cut along one curve's points (as from :func:`_classify_all`): method steps 1-3 of
        the module docstring. Returns the curve's vertices in order (before :func:`_expand`);
        the joining edges are marked as cut, so that later splits of them are known to
        :func:`_expand`. A point whose ``vertex`` is set (an original vertex, or a corner
        inserted earlier) is used as that vertex."""
        S = self.state[0]
        QI, QF, faces = _k.bridge_curve(
            self.V0,
            self.F0,
            self.FN,
            self.VFI,
            self.VFF,
            self.snap,
            self.route_fans,
            np.ascontiguousarray(CI, dtype=np.int64),
            np.ascontiguousarray(CF, dtype=np.float64),
            closed,
            S,
        )
        self._raise()
        path, *state = _k.insert_curve(
            self.V0,
            self.F0,
            self.FN,
            self.snap,
            self.min_area,
            *self.state,
            np.ascontiguousarray(QI[:, 2]),
            np.ascontiguousarray(QF[:, :3]),
            np.ascontiguousarray(QI[:, 1]),
            np.ascontiguousarray(QF[:, 3:]),
            faces,
            closed,
        )
        self.state = tuple(state)
        self._raise()
        return path.tolist()


def _classify(
    cutter: _Cutter,
    face: int,
    bary: NDArray,
    index: int,
    within: tuple[float, float] | None = None,
) -> _CutPoint:
    """Snap a face point onto a vertex or an edge of its face when within ``within``
    (distances to a vertex and to an edge; default the cutter's ``CUT_SNAP`` for both)."""
    snap, edge_snap = (
        (cutter.snap,) * 2 if within is None else (max(w, cutter.snap) for w in within)
    )
    fv = cutter.face(face)
    b = np.clip(bary, 0.0, None)
    b = b / b.sum()
    pos = [cutter.xyz(v) for v in fv]
    p = tuple(float(x) for x in b @ np.asarray(pos))
    dv = [_norm(_sub(p, q)) for q in pos]
    k = int(np.argmin(dv))
    if dv[k] < snap:
        return _vertex_point(cutter, fv[k], index)
    for k in range(3):
        qa, qb = pos[k], pos[(k + 1) % 3]
        e = _sub(qb, qa)
        s = _dot(_sub(p, qa), e) / _dot(e, e)
        if 0.0 < s < 1.0 and _norm(_sub(p, _lerp(qa, qb, s))) < edge_snap:
            return _edge_point(cutter, face, k, s, index)
    return _CutPoint(
        face, (float(b[0]), float(b[1]), float(b[2])), -1, frozenset((face,)), p, index
    )


def _classify_all(
    cutter: _Cutter, face: NDArray[np.int64], bary: NDArray[np.float64]
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """:func:`_classify` of many points at once (the same arithmetic, elementwise), as arrays
    ``(n, 4) int64`` (kind, vertex, face, other face) and ``(n, 6) float64`` (barycentrics,
    position); see :mod:`meshfit._kernels.cut` for the point layout."""
    return _k.classify(
        cutter.V0,
        cutter.F0,
        cutter.FN,
        cutter.VFI,
        cutter.VFF,
        cutter.snap,
        np.ascontiguousarray(face, dtype=np.int64),
        np.ascontiguousarray(bary, dtype=np.float64).reshape(-1, 3),
    )


def _record(cutter: _Cutter, cp: _CutPoint) -> tuple[list[int], list[float]]:
    """A snapped point as a row of the arrays of :func:`_classify_all`."""
    if 0 <= cp.vertex < cutter.nv0:
        kind, other = _k.KIND_VERTEX, -1
    else:
        kind = _k.KIND_FACES
        rest = sorted(cp.faces - {cp.face})
        other = rest[0] if rest else -1
    return [kind, cp.vertex, cp.face, other], [*cp.bary, *cp.xyz]


def _vertex_point(cutter: _Cutter, v: int, index: int) -> _CutPoint:
    faces = cutter.faces_around(v)
    f = min(faces)
    return _CutPoint(f, cutter.bary_in(v, f), v, faces, cutter.xyz(v), index)


def _edge_point(cutter: _Cutter, face: int, k: int, s: float, index: int) -> _CutPoint:
    """The point at parameter s along edge k of ``face`` (snapped to an end when close)."""
    fv = cutter.face(face)
    qa, qb = cutter.xyz(fv[k]), cutter.xyz(fv[(k + 1) % 3])
    length = _norm(_sub(qb, qa))
    if s * length < cutter.snap:
        return _vertex_point(cutter, fv[k], index)
    if (1.0 - s) * length < cutter.snap:
        return _vertex_point(cutter, fv[(k + 1) % 3], index)
    bary = [0.0, 0.0, 0.0]
    bary[k] = 1.0 - s
    bary[(k + 1) % 3] = s
    other = int(cutter.FN[face, k])
    faces = frozenset((face, other)) if other >= 0 else frozenset((face,))
    return _CutPoint(face, (bary[0], bary[1], bary[2]), -1, faces, _lerp(qa, qb, s), index)


def cut_mesh(
    mesh: Mesh, curve: SurfacePoints | SurfaceCurve, *, closed: bool = False, split: bool = True
) -> CutResult:
    """Cut a mesh along a polyline of face points so that it runs along mesh edges.

    Parameters
    ----------
    mesh : Mesh
    curve : SurfacePoints or SurfaceCurve
        ``n >= 2`` face points (``face (n,) int64``, ``bary (n, 3) float64``). Consecutive points
        lie on the same or edge-adjacent faces (the thesis' sampling rule); points whose faces
        share only a vertex are joined through that vertex. Between points on adjacent faces the
        cut follows the straight line unfolded across the shared edge.
    closed : bool
        Also cut from the last point back to the first. A :class:`SurfaceCurve` that is closed
        is cut closed whatever this says.
    split : bool
        Duplicate the vertices of the cut so that faces on the two sides are no longer
        connected (the cut becomes boundary). When False only the triangulation is refined.

    Returns
    -------
    CutResult
        ``mesh``, ``path (k,) int64`` and ``path_other_side (k,) int64`` (the curve's vertices in
        the new mesh on each side), ``face_parent (nf_new,) int64``, ``vertex_parent (nv_new,)
        int64`` and ``vertex_source`` (each new vertex as a point of the original mesh). New
        vertices get vertex colours interpolated barycentrically.

    Raises
    ------
    CutError
        When two consecutive points are on faces that are neither the same, adjacent nor
        sharing a vertex (the message names the pair of point indices).
    InputError
        When the points are not valid face points of ``mesh`` or fewer than two.

    Notes
    -----
    Points within ``tol.CUT_SNAP`` mean edge lengths of a vertex or an edge snap onto it, and a
    split that would leave a triangle under ``tol.CUT_MIN_AREA * bbox_diagonal**2`` snaps to the
    nearest vertex instead, so the cut mesh always validates. The curve should not cross itself.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.1-3.2 (face-point curves on the same or adjacent faces)
       and sec. 1.3, fig. 1.2 (boundary curves bound the polygonal patches).
    """
    if isinstance(curve, SurfaceCurve):
        closed = closed or curve.closed
        points = curve.points
    else:
        points = curve
    points = as_surface_points(mesh, points, name="curve")
    n = len(points)
    if n < 2:
        raise InputError(f"a cut needs at least 2 curve points, got {n}")
    with _no_gc():
        cutter = _Cutter(mesh, n)
        CI, CF = _classify_all(cutter, points.face, points.bary)
        path = cutter.cut_curve(CI, CF, closed)
        path = _drop_spikes(_expand(cutter, path, closed), closed)
        if len(path) < 2:
            raise CutError(f"the curve's {n} points collapse to a single vertex: nothing to cut")
        cutter.cut = _cut_edges([path], closed)
        return _assemble(cutter, mesh, path, closed, split)


def _expand(cutter: _Cutter, path: list[int], closed: bool) -> list[int]:
    """Re-insert the vertices that later splits put on earlier cut edges; drop repeats."""
    H = cutter.state[6]
    return _k.expand_path(H, np.asarray(path, dtype=np.int64), closed).tolist()


def _drop_spikes(path: list[int], closed: bool) -> list[int]:
    """Remove immediate back-and-forth steps ``a, b, a`` (a cut of zero width)."""
    return _k.drop_spikes(np.asarray(path, dtype=np.int64), closed).tolist()


def _cut_edges(paths: list[list[int]], closed: bool) -> NDArray[np.int64]:
    """The edges joining consecutive vertices of the paths (and each path's last vertex to its
    first when ``closed``): ``(m, 2) int64`` rows ``a < b``, unique and sorted."""
    pairs = []
    for path in paths:
        p = np.asarray(path, dtype=np.int64)
        pairs.append(np.stack([p[:-1], p[1:]], axis=1))
        if closed:
            pairs.append(np.array([[p[-1], p[0]]], dtype=np.int64))
    e = np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=np.int64)
    e = np.sort(e, axis=1)
    n = np.int64(max(int(e.max(initial=0)) + 1, 1))
    keys = np.unique(e[:, 0] * n + e[:, 1])
    return np.stack([keys // n, keys % n], axis=1)


def _refined(cutter: _Cutter, mesh: Mesh, base: SurfacePoints | None = None):
    """Arrays of the refined (not yet split) triangulation: vertices, faces, face parents,
    vertex sources, vertex parents and colours (``base``: the mesh's vertices as face points,
    when already made)."""
    nv0 = cutter.nv0
    n_new, n_tri = cutter.n_new, cutter.n_tri
    nf0 = cutter.nf0
    _, TR, FL, NV, NI, _, _, _ = cutter.state
    vertices = np.concatenate([mesh.vertices, NV[:n_new, :3]])
    faces = np.concatenate([mesh.faces, TR[nf0:n_tri, :3]])
    loaded = np.flatnonzero(FL[:, 2] & _k.LOADED)
    faces[loaded] = TR[loaded, :3]
    face_parent = np.concatenate([np.arange(nf0, dtype=np.int64), TR[nf0:n_tri, 3]])
    src = SurfacePoints.concatenate(
        [
            vertex_points(mesh, np.arange(nv0)) if base is None else base,
            SurfacePoints(NI[:n_new, 0].copy(), NV[:n_new, 3:6].copy()),
        ]
    )
    parent = np.concatenate([np.arange(nv0, dtype=np.int64), np.full(n_new, -1, np.int64)])
    colors = None
    if mesh.vertex_colors is not None:
        c0 = mesh.vertex_colors.astype(np.float64)
        new_c = np.einsum("ij,ijk->ik", src.bary[nv0:], c0[mesh.faces[src.face[nv0:]]])
        colors = np.concatenate(
            [mesh.vertex_colors, np.clip(np.round(new_c), 0, 255).astype(np.uint8)]
        )
    return vertices, faces, face_parent, src, parent, colors


def _assemble(cutter: _Cutter, mesh: Mesh, path: list[int], closed: bool, split: bool) -> CutResult:
    vertices, faces, face_parent, src, parent, colors = _refined(cutter, mesh)
    path_arr = np.asarray(path, dtype=np.int64)
    other = path_arr.copy()
    if split:
        faces, copy_of, left, right = _split_along(cutter, faces, vertices.shape[0], path, closed)
        vertices = vertices[copy_of]
        parent = parent[copy_of]
        src = src[copy_of]
        colors = None if colors is None else colors[copy_of]
        path_arr, other = left, right
    new_mesh = Mesh(vertices, faces, colors, name=mesh.name)
    return CutResult(new_mesh, path_arr, other, face_parent, parent, src, closed)


# ------------------------------------------------------------------------- network of curves
@dataclass(frozen=True, kw_only=True)
class _NetworkCutMaps:
    """What a network cut knows of its pieces besides the cut mesh itself (the fields
    :class:`NetworkCutResult` and :class:`NetworkCutArrays` share, documented there)."""

    curve_vertices: tuple[NDArray[np.int64], ...]
    corners: NDArray[np.int64]
    copy_of: NDArray[np.int64]
    face_parent: NDArray[np.int64]
    vertex_parent: NDArray[np.int64]
    vertex_source: SurfacePoints

    def maps(self) -> dict[str, object]:
        """These fields by name (to build the other kind of result)."""
        return {f.name: getattr(self, f.name) for f in fields(_NetworkCutMaps)}


@dataclass(frozen=True)
class NetworkCutResult(_NetworkCutMaps):
    """Result of :func:`cut_mesh_network`.

    Attributes
    ----------
    mesh : Mesh
        The cut mesh (validated). Its first ``n_refined`` vertices are the vertices of the
        refined, unsplit triangulation (original vertices first, then the ones the cut made);
        with ``split=True`` the copies made by splitting follow.
    curve_vertices : tuple of (k_i,) int64
        Each curve's vertices in the refined triangulation, from its first corner to its last.
    corners : (nc,) int64
        Vertex of the refined triangulation at each corner.
    copy_of : (nv_new,) int64
        Refined-triangulation vertex each vertex of ``mesh`` copies (identity without split).
    face_parent : (nf_new,) int64
        Original face each new face lies in.
    vertex_parent : (nv_new,) int64
        Original vertex each new vertex copies, -1 for vertices created by the cut.
    vertex_source : SurfacePoints
        Every vertex of ``mesh`` as a face point of the original mesh.

    The fields after ``mesh`` are keyword-only.
    """

    mesh: Mesh


@dataclass(frozen=True)
class NetworkCutArrays(_NetworkCutMaps):
    """Result of :func:`network_cut_arrays`: the fields of :class:`NetworkCutResult`, with
    the cut mesh as unchecked arrays instead of ``mesh``.

    Attributes
    ----------
    vertices : (nv_new, 3) float64
    faces : (nf_new, 3) int64
    colors : (nv_new, 3) uint8 or None
        The cut mesh's vertices, faces and vertex colours.
    curve_vertices, corners, copy_of, face_parent, vertex_parent, vertex_source
        As in :class:`NetworkCutResult` (keyword-only).
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    colors: NDArray[np.uint8] | None


def cut_mesh_network(
    mesh: Mesh,
    curves: list[SurfacePoints | SurfaceCurve],
    corners: SurfacePoints,
    ends: NDArray[np.int64],
    *,
    split: bool = True,
) -> NetworkCutResult:
    """Cut a mesh along a network of open curves that meet only at shared corners.

    All curves are inserted into one dynamic triangulation: each corner is inserted once, so
    the curves that end at it share one vertex, and the mesh is then split along the union of
    the cut edges (the polygonal patches of Krishnamurthy 2000, sec. 1.3, fig. 1.2).

    Parameters
    ----------
    mesh : Mesh
    curves : list of SurfacePoints or SurfaceCurve
        ``nk`` open curves of face points (sampled as for :func:`cut_mesh`). The first and last
        point of curve ``i`` are replaced by corners ``ends[i, 0]`` and ``ends[i, 1]``.
    corners : SurfacePoints
        ``nc`` corner points. A corner within ``tol.CUT_CORNER_MERGE`` mean edge lengths of a
        mesh vertex is moved onto it (one nearer an edge than the side of the cut's least
        triangle, onto the edge), and curve points that close to their end corners are
        dropped (painted curves pass through the vertex nearest a corner pick).
    ends : (nk, 2) int64
        Corner index at the start and end of each curve.
    split : bool, keyword-only
        Duplicate the vertices of the cut so that the regions between the curves become
        separate pieces (default). When False only the triangulation is refined.

    Returns
    -------
    NetworkCutResult

    Raises
    ------
    CutError
        Two curves meet away from their shared corners (the message names both curves and
        the point), a curve collapses to one point, or consecutive points are too far apart.
    InputError
        Bad face points, corner indices out of range.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3, fig. 1.2 (patch boundaries) and sec. 8.1.3 (patches
       sharing boundary curves and corners).
    """
    a = network_cut_arrays(mesh, curves, corners, ends, split=split)
    return NetworkCutResult(Mesh(a.vertices, a.faces, a.colors, name=mesh.name), **a.maps())


def network_cut_arrays(
    mesh: Mesh,
    curves: list[SurfacePoints | SurfaceCurve],
    corners: SurfacePoints,
    ends: NDArray[np.int64],
    *,
    split: bool = True,
    scale: tuple[float, float] | None = None,
) -> NetworkCutArrays:
    """:func:`cut_mesh_network` without building the cut mesh: its arrays, unchecked.

    For callers that check the cut piece by piece: :func:`meshfit.layout.extract_patches`
    validates each region's submesh on its own, on threads, instead of the whole mesh.

    Parameters
    ----------
    mesh : Mesh
    curves : list of SurfacePoints or SurfaceCurve
    corners : SurfacePoints
    ends : (nk, 2) int64
    split : bool, keyword-only
        As for :func:`cut_mesh_network`.
    scale : (float, float), keyword-only, optional
        The mean edge length and the bounding-box diagonal the tolerances are relative to
        (default the mesh's own): pieces of one surface cut with the whole surface's
        scale snap alike.

    Returns
    -------
    NetworkCutArrays

    Raises
    ------
    CutError, InputError
        As :func:`cut_mesh_network`; the arrays are not checked as one mesh.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3, fig. 1.2 (patch boundaries) and sec. 8.1.3 (patches
       sharing boundary curves and corners).
    """
    # the mesh's own vertices as face points, made on a thread while the curves go in
    with _no_gc(), ThreadPoolExecutor(max_workers=1) as pool:
        base = pool.submit(vertex_points, mesh, np.arange(mesh.n_vertices))
        cutter, corner_v, paths, _ = _network_paths(
            mesh, curves, corners, ends, strict=True, scale=scale
        )
        _check_meetings(paths, corner_v)
        cutter.cut = _cut_edges(paths, False)
        vertices, faces, face_parent, src, parent, colors = _refined(cutter, mesh, base.result())
        copy_of = np.arange(vertices.shape[0], dtype=np.int64)
        if split:
            faces, copy_of = _split_faces(cutter, faces, vertices.shape[0])
            vertices = vertices[copy_of]
            parent = parent[copy_of]
            src = src[copy_of]
            colors = None if colors is None else colors[copy_of]
        return NetworkCutArrays(
            vertices,
            faces,
            colors,
            curve_vertices=tuple(np.asarray(p, dtype=np.int64) for p in paths),
            corners=corner_v,
            copy_of=copy_of,
            face_parent=face_parent,
            vertex_parent=parent,
            vertex_source=src,
        )


def _insert_corners(cutter: _Cutter, corners: SurfacePoints, merge: float):
    """Insert the corners into ``cutter`` (one within ``merge`` of a mesh vertex is that
    vertex, one very near an edge is on the edge); their cutter vertices and cut points."""
    nc = len(corners)
    corner_cp: list[_CutPoint] = []
    corner_v = np.empty(nc, dtype=np.int64)
    # a corner within ``merge`` of a vertex is that vertex; one nearer an edge than the side
    # of the cut's least triangle is on the edge (curves leaving it across the edge would
    # cross the edge next to each other and split off triangles below the least area,
    # which snap one crossing onto the other: the curves would touch), but never farther
    # than ``merge`` (the least area is a share of the diagonal, not of the edges)
    near = (merge, min(merge, float(np.sqrt(2.0 * cutter.min_area))))
    for c in range(nc):
        cp = _classify(cutter, int(corners.face[c]), corners.bary[c], c, within=near)
        v = cutter.insert(cp, cp.face)
        if v < cutter.nv0:
            cp = _vertex_point(cutter, v, c)
        else:
            cp = _CutPoint(cp.face, cp.bary, v, cp.faces, cutter.xyz(v), c)
        corner_v[c] = v
        corner_cp.append(cp)
        cutter.mark_on_path(v)
    if len(set(corner_v.tolist())) < nc:
        a, b = _first_repeat(corner_v)
        raise CutError(f"corners {a} and {b} fall on the same point")
    return corner_v, corner_cp


def _network_paths(mesh: Mesh, curves, corners, ends, *, strict: bool, scale=None):
    """The corners inserted into a cutter and every curve cut in as a vertex path (the
    tolerances scaled by ``scale``, as in :func:`network_cut_arrays`).

    Returns ``(cutter, corner_v, paths, failed)``: ``failed`` holds the curves that could
    not be cut in (their paths are placeholders); with ``strict`` the first such curve
    raises a CutError instead.
    """
    corners = as_surface_points(mesh, corners, name="corners")
    ends = np.asarray(ends, dtype=np.int64).reshape(-1, 2)
    if ends.shape[0] != len(curves):
        raise InputError(f"ends has {ends.shape[0]} rows for {len(curves)} curves")
    nc = len(corners)
    if ends.size and (ends.min() < 0 or ends.max() >= nc):
        i = int(np.flatnonzero((ends < 0).any(axis=1) | (ends >= nc).any(axis=1))[0])
        raise InputError(f"curve {i}: corner index out of range 0..{nc - 1}: {ends[i].tolist()}")
    failed: set[int] = set()
    n_points = sum(len(c.points if isinstance(c, SurfaceCurve) else c) for c in curves)
    cutter = _Cutter(mesh, n_points, scale)
    cutter.route_fans = True
    merge = tol.CUT_CORNER_MERGE * (mesh.mean_edge_length if scale is None else scale[0])
    corner_v, corner_cp = _insert_corners(cutter, corners, merge)
    raw: list[list[int]] = []
    for i, curve in enumerate(curves):
        pts = curve.points if isinstance(curve, SurfaceCurve) else curve
        pts = as_surface_points(mesh, pts, name=f"curve {i}")
        if len(pts) < 2:
            raise InputError(f"curve {i}: needs at least 2 points, got {len(pts)}")
        # points at (within CUT_CORNER_MERGE of) an end corner are that corner
        xyz = mesh.xyz(pts)
        first, last = corner_cp[ends[i, 0]], corner_cp[ends[i, 1]]
        d0 = np.linalg.norm(xyz - np.asarray(first.xyz), axis=1)
        d1 = np.linalg.norm(xyz - np.asarray(last.xyz), axis=1)
        inner = np.flatnonzero((d0 > merge) & (d1 > merge))
        inner = inner[(inner > 0) & (inner < len(pts) - 1)]
        CI, CF = _classify_all(cutter, pts.face[inner], pts.bary[inner])
        (i0, f0), (i1, f1) = _record(cutter, first), _record(cutter, last)
        CI = np.concatenate([[i0], CI, [i1]]).astype(np.int64)
        CF = np.concatenate([[f0], CF, [f1]])
        try:
            raw.append(cutter.cut_curve(CI, CF, False))
        except CutError as exc:
            if strict:
                raise CutError(f"curve {i}: {exc}") from None
            failed.add(i)
            raw.append([])
    paths: list[list[int]] = []
    for i, path in enumerate(raw):
        if i not in failed:
            path = _drop_loops(_drop_spikes(_expand(cutter, path, False), False))
            if len(path) < 2:
                if strict:
                    raise CutError(f"curve {i} collapses to a single vertex: nothing to cut")
                failed.add(i)
                path = []
        paths.append(path)
    return cutter, corner_v, paths, failed


def _drop_loops(path: list[int]) -> list[int]:
    """Cut out closed detours ``v ... v`` of an open path (left where a walk curled round and
    came back to a vertex it had passed), so each vertex appears once."""
    return _k.drop_loops(np.asarray(path, dtype=np.int64)).tolist()


def _first_repeat(a: NDArray[np.int64]) -> tuple[int, int]:
    seen: dict[int, int] = {}
    for i, v in enumerate(a.tolist()):
        if v in seen:
            return seen[v], i
        seen[v] = i
    return -1, -1  # pragma: no cover


def network_meetings(
    mesh: Mesh,
    curves: list[SurfacePoints | SurfaceCurve],
    corners: SurfacePoints,
    ends: NDArray[np.int64],
) -> set[int]:
    """The curves of a network that :func:`cut_mesh_network` would refuse, all at once.

    A curve is named when it touches itself or another curve away from its end corners
    (both curves are named), passes through a corner, or cannot be cut in at all. An empty
    set: every curve goes in and they meet only at their end corners (whether the pieces
    are the patches a layout wants is checked by
    :func:`meshfit.layout.check_layout_topology`). For callers that repair a network curve
    by curve instead of stopping at the first fault.

    Parameters
    ----------
    mesh : Mesh
    curves : list of SurfacePoints or SurfaceCurve
        ``nk`` open curves, as for :func:`cut_mesh_network`.
    corners : SurfacePoints
        ``nc`` corner points.
    ends : (nk, 2) int64
        Corner index at the start and end of each curve.

    Returns
    -------
    set of int
        Indices into ``curves``.

    Raises
    ------
    CutError, InputError
        Corners that fall on one point; bad face points or corner indices.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3, fig. 1.2 (curves meet only at patch corners).
    """
    with _no_gc():
        _, corner_v, paths, failed = _network_paths(mesh, curves, corners, ends, strict=False)
    out = set(failed)
    for i, _, _, _, j in _meetings(paths, corner_v):
        out.update((i,) if j is None else (i, j))
    return out


def _meetings(paths: list[list[int]], corner_v: NDArray[np.int64]):
    """Every place a path meets a corner or a path (itself included) away from its own
    ends, in path order: ``(curve, point, vertex, corner or None, other curve or None)``."""
    owner: dict[int, int] = {}
    corner_of = {int(v): c for c, v in enumerate(corner_v.tolist())}
    for i, path in enumerate(paths):
        for k in range(1, len(path) - 1):
            v = path[k]
            if v in corner_of:
                yield i, k, v, corner_of[v], None
                continue
            j = owner.get(v)
            if j is None:
                owner[v] = i
            else:  # (j == i: the curve touches itself)
                yield i, k, v, None, j


def _check_meetings(paths: list[list[int]], corner_v: NDArray[np.int64]) -> None:
    """Raise at the first place a curve touches itself or another curve away from its own
    end corners."""
    for i, k, v, c, j in _meetings(paths, corner_v):
        if c is not None:
            raise CutError(
                f"curve {i} passes through corner {c} (point {k} of its path): "
                "curves may meet only at their end corners"
            )
        what = "touches itself" if j == i else f"crosses or touches curve {j}"
        raise CutError(
            f"curve {i} {what} away from the corners, at cut vertex {v} (point {k} of its path)"
        )


def _split_along(cutter: _Cutter, faces: NDArray[np.int64], nv: int, path: list[int], closed: bool):
    """Give each fan of faces around a vertex that the cut separates its own vertex copy."""
    new_faces, copy_of = _split_faces(cutter, faces, nv)
    left, right = _path_sides(cutter, new_faces, path, closed)
    return new_faces, copy_of, left, right


def _split_faces(cutter: _Cutter, faces: NDArray[np.int64], nv: int):
    """Faces with each fan separated by ``cutter.cut`` on its own vertex copy, and the vertex
    each new vertex copies (the first ``nv`` keep their index)."""
    return _k.split_faces(np.ascontiguousarray(faces, dtype=np.int64), nv, cutter.cut)


def _path_sides(cutter: _Cutter, new_faces: NDArray[np.int64], path: list[int], closed: bool):
    """The copies of each path vertex on the left and right of the curve after splitting."""
    _, TR, _, _, _, _, H, _ = cutter.state
    return _k.path_sides(TR, H, new_faces, np.asarray(path, dtype=np.int64), closed)
