"""Slow oracle for `meshfit.surface.cut`: the cut written plainly, one curve point at a time.

This is the per-point implementation (dictionaries of triangles, tuples for vectors, no
batching) that the fast module must reproduce exactly: same vertices, faces, face and vertex
parents, vertex sources and paths. The method is the one described in
:mod:`meshfit.surface.cut`.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from meshfit import tol
from meshfit._validate import as_surface_points
from meshfit.errors import CutError, InputError
from meshfit.mesh import Mesh, topology
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = ["CutResult", "NetworkCutResult", "cut_mesh", "cut_mesh_network"]

#: a walk between two consecutive curve points never takes more steps than this
_MAX_WALK_STEPS = 100_000


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


def _hypot(x, y):
    """The C library's hypot, as the kernels' ``math.hypot`` (CPython's own algorithm
    differs from it in the last bit for about one pair in 200 on some machines)."""
    return float(np.hypot(x, y))


def _area(p, q, r):
    u = _sub(q, p)
    v = _sub(r, p)
    c = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
    return 0.5 * _norm(c)


def _lerp(a, b, s):
    return (a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), a[2] + s * (b[2] - a[2]))


def _cross2(a, b):
    return a[0] * b[1] - a[1] * b[0]


def _key(a: int, b: int) -> tuple[int, int]:
    return (a, b) if a < b else (b, a)


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
    """Dynamic triangulation of the original faces a cut touches."""

    def __init__(self, mesh: Mesh):
        self.mesh = mesh
        self.V0 = mesh.vertices
        self.F0 = mesh.faces
        self.FN = mesh.face_neighbors
        self.nv0 = mesh.n_vertices
        self.nf0 = mesh.n_faces
        self.snap = tol.length(mesh, tol.CUT_SNAP)
        self.min_area = tol.CUT_MIN_AREA * mesh.bbox_diagonal**2
        self.vf_indptr, self.vf_faces = mesh.vertex_faces
        self._face_cache: dict[int, tuple[int, int, int]] = {}
        self._xyz_cache: dict[int, tuple[float, float, float]] = {}
        # new vertices
        self.new_xyz: list[tuple[float, float, float]] = []
        self.new_face: list[int] = []
        self.new_bary: list[tuple[float, float, float]] = []
        # triangles (ids < nf0 are original faces, loaded lazily)
        self.tri: dict[int, tuple[int, int, int]] = {}
        self.parent: dict[int, int] = {}
        self.n_tri = self.nf0
        self.edge_map: dict[tuple[int, int], list[int]] = {}
        self.vtris: dict[int, set[int]] = {}
        self.face_tris: dict[int, set[int]] = {}
        self.loaded: set[int] = set()
        self.active: set[int] = set()
        self._uv: dict[tuple[int, int], tuple[float, float]] = {}
        # cut edges and the vertex that split a cut edge later
        self.cut: set[tuple[int, int]] = set()
        self.split_of: dict[tuple[int, int], int] = {}
        self.on_path: set[int] = set()
        self.snap_ok: tuple[int, ...] = ()
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
            return self.new_xyz[v - self.nv0]
        p = self._xyz_cache.get(v)
        if p is None:
            p = tuple(float(x) for x in self.V0[v])
            self._xyz_cache[v] = p
        return p

    def faces_around(self, v: int) -> frozenset[int]:
        return frozenset(self.vf_faces[self.vf_indptr[v] : self.vf_indptr[v + 1]].tolist())

    def bary_in(self, v: int, g: int) -> tuple[float, float, float]:
        """Barycentric coordinates of vertex ``v`` in original face ``g`` (exact mapping)."""
        fg = self.face(g)
        if v < self.nv0:
            return (float(fg[0] == v), float(fg[1] == v), float(fg[2] == v))
        sf = self.new_face[v - self.nv0]
        sb = self.new_bary[v - self.nv0]
        if sf == g:
            return sb
        out = [0.0, 0.0, 0.0]
        fs = self.face(sf)
        for k in range(3):
            if sb[k] == 0.0:
                continue
            ov = fs[k]
            if ov not in fg:  # pragma: no cover - guarded by construction
                raise CutError(f"internal: vertex {v} is not on original face {g}")
            out[fg.index(ov)] += sb[k]
        return (out[0], out[1], out[2])

    def uv(self, v: int, g: int) -> tuple[float, float]:
        key = (v, g)
        r = self._uv.get(key)
        if r is None:
            b = self.bary_in(v, g)
            r = (b[1], b[2])
            self._uv[key] = r
        return r

    # ---------------------------------------------------------- triangulation
    def _register(self, t: int, abc: tuple[int, int, int], parent: int) -> None:
        self.tri[t] = abc
        self.parent[t] = parent
        for k in range(3):
            self.edge_map.setdefault(_key(abc[k], abc[(k + 1) % 3]), []).append(t)
            self.vtris.setdefault(abc[k], set()).add(t)
        self.face_tris.setdefault(parent, set()).add(t)

    def _unregister(self, t: int) -> None:
        abc = self.tri.pop(t)
        parent = self.parent[t]
        for k in range(3):
            self.edge_map[_key(abc[k], abc[(k + 1) % 3])].remove(t)
            self.vtris[abc[k]].discard(t)
        self.face_tris[parent].discard(t)

    def _load(self, f: int) -> None:
        if f >= 0 and f not in self.loaded:
            self.loaded.add(f)
            self._register(f, self.face(f), f)

    def ensure(self, g: int) -> None:
        """Make original face ``g`` and its neighbours editable."""
        if g in self.active:
            return
        self.active.add(g)
        self._load(g)
        for h in self.FN[g].tolist():
            self._load(h)

    def _new_tri(self, abc: tuple[int, int, int], parent: int) -> int:
        t = self.n_tri
        self.n_tri += 1
        self._register(t, abc, parent)
        return t

    def new_vertex(self, xyz, g: int, bary) -> int:
        self.new_xyz.append((float(xyz[0]), float(xyz[1]), float(xyz[2])))
        self.new_face.append(int(g))
        self.new_bary.append((float(bary[0]), float(bary[1]), float(bary[2])))
        return self.nv0 + len(self.new_xyz) - 1

    def tri_area(self, t: int) -> float:
        a, b, c = self.tri[t]
        return _area(self.xyz(a), self.xyz(b), self.xyz(c))

    def split_face(self, t: int, x: int) -> None:
        a, b, c = self.tri[t]
        parent = self.parent[t]
        self._unregister(t)
        self._register(t, (a, b, x), parent)
        self._new_tri((b, c, x), parent)
        self._new_tri((c, a, x), parent)

    def split_edge(self, a: int, b: int, x: int) -> None:
        key = _key(a, b)
        for t in list(self.edge_map.get(key, ())):
            abc = self.tri[t]
            parent = self.parent[t]
            for k in range(3):
                p, q = abc[k], abc[(k + 1) % 3]
                if _key(p, q) == key:
                    r = abc[(k + 2) % 3]
                    break
            self._unregister(t)
            self._register(t, (p, x, r), parent)
            self._new_tri((x, q, r), parent)
        if key in self.cut:
            self.cut.discard(key)
            self.cut.add(_key(a, x))
            self.cut.add(_key(x, b))
            self.split_of[key] = x

    def may_snap(self, v: int) -> bool:
        """Whether a point may snap onto vertex ``v``: not when ``v`` is already on the cut
        path (other than the path's current end or the walk's target), so the cut does not
        touch itself where a split is possible instead."""
        return v not in self.on_path or v in self.snap_ok

    def edge_split_ok(self, a: int, b: int, s: float) -> bool:
        """Whether splitting edge (a, b) at parameter s keeps every piece above min_area."""
        m = min(s, 1.0 - s)
        return all(self.tri_area(t) * m >= self.min_area for t in self.edge_map[_key(a, b)])

    def split_edge_at(self, a: int, b: int, s: float, g: int) -> int:
        """Split edge (a, b) at parameter s, or snap to its nearer end when that is within
        ``CUT_SNAP`` or a piece would be too small; returns the vertex. An end already on the
        cut path is snapped to only when the split is impossible (no self-touching cut)."""
        pa, pb = self.xyz(a), self.xyz(b)
        length = _norm(_sub(pb, pa))
        near = a if s < 0.5 else b
        if not 0.0 < s < 1.0 or not self.edge_split_ok(a, b, s):
            return near
        if (s * length < self.snap or (1.0 - s) * length < self.snap) and self.may_snap(near):
            return near
        ba, bb = self.bary_in(a, g), self.bary_in(b, g)
        bary = tuple(ba[k] + s * (bb[k] - ba[k]) for k in range(3))
        x = self.new_vertex(_lerp(pa, pb, s), g, bary)
        self.split_edge(a, b, x)
        return x

    # --------------------------------------------------------------- insertion
    def insert(self, cp: _CutPoint, g: int) -> int:
        """Insert a snapped curve point into original face ``g`` (which contains it)."""
        if cp.vertex >= 0:
            return cp.vertex
        self.ensure(g)
        bary = cp.bary if cp.face == g else self._map_bary(cp, g)
        if 0.0 in bary:
            return self._insert_on_edge(cp.xyz, bary, g)
        p = cp.xyz
        pu = (bary[1], bary[2])
        # locate: the sub-triangle of g with the largest smallest barycentric coordinate
        best_t, best_min, best_lam = -1, -math.inf, (0.0, 0.0, 0.0)
        for t in self.face_tris[g]:
            a, b, c = self.tri[t]
            ua, ub, uc = self.uv(a, g), self.uv(b, g), self.uv(c, g)
            e1 = (ub[0] - ua[0], ub[1] - ua[1])
            e2 = (uc[0] - ua[0], uc[1] - ua[1])
            d = (pu[0] - ua[0], pu[1] - ua[1])
            det = _cross2(e1, e2)
            l1 = _cross2(d, e2) / det
            l2 = _cross2(e1, d) / det
            lam = (1.0 - l1 - l2, l1, l2)
            m = min(lam)
            if m > best_min:
                best_t, best_min, best_lam = t, m, lam
        abc = self.tri[best_t]
        pos = [self.xyz(v) for v in abc]
        # an existing vertex
        dv = [_norm(_sub(p, q)) for q in pos]
        k = int(np.argmin(dv))
        if dv[k] < self.snap and self.may_snap(abc[k]):
            return abc[k]
        # an existing edge
        edge_d, edge_s = [], []
        for k in range(3):
            qa, qb = pos[k], pos[(k + 1) % 3]
            e = _sub(qb, qa)
            ee = _dot(e, e)
            s = min(max(_dot(_sub(p, qa), e) / ee, 0.0), 1.0)
            edge_s.append(s)
            edge_d.append(_norm(_sub(p, _lerp(qa, qb, s))))
        area = self.tri_area(best_t)
        k = int(np.argmin(edge_d))
        if edge_d[k] >= self.snap and min(best_lam) * area >= self.min_area:
            x = self.new_vertex(p, g, bary)
            self.split_face(best_t, x)
            return x
        if edge_d[k] >= self.snap:  # too thin to split the face: use the nearest edge
            k = (int(np.argmin(best_lam)) + 1) % 3
        return self.split_edge_at(abc[k], abc[(k + 1) % 3], edge_s[k], g)

    def _insert_on_edge(self, p, bary: tuple[float, float, float], g: int) -> int:
        """Insert a point of an original edge of ``g`` (exact zero coordinate in ``bary``) on
        the pieces of that edge, so that it stays a vertex of both faces sharing the edge."""
        z = bary.index(0.0)
        j = (z + 2) % 3  # parameter along the edge: the coordinate of its second vertex
        t = bary[j]
        lo, hi, t_lo, t_hi = -1, -1, -math.inf, math.inf
        seen: set[int] = set()
        for tri in self.face_tris[g]:
            for v in self.tri[tri]:
                if v in seen:
                    continue
                seen.add(v)
                bv = self.bary_in(v, g)
                if bv[z] != 0.0:
                    continue
                if t_lo < bv[j] <= t:
                    lo, t_lo = v, bv[j]
                if t <= bv[j] < t_hi:
                    hi, t_hi = v, bv[j]
        if lo == hi:
            return lo
        d_lo = _norm(_sub(p, self.xyz(lo)))
        d_hi = _norm(_sub(p, self.xyz(hi)))
        near = lo if d_lo <= d_hi else hi
        if min(d_lo, d_hi) < self.snap and self.may_snap(near):
            return near
        s = (t - t_lo) / (t_hi - t_lo)
        if _key(lo, hi) not in self.edge_map or not self.edge_map[_key(lo, hi)]:
            raise CutError(f"internal: edge pieces {lo}, {hi} of face {g} are not joined")
        if not 0.0 < s < 1.0 or not self.edge_split_ok(lo, hi, s):
            return near
        x = self.new_vertex(p, g, bary)
        self.split_edge(lo, hi, x)
        return x

    def _map_bary(self, cp: _CutPoint, g: int) -> tuple[float, float, float]:
        fs, fg = self.face(cp.face), self.face(g)
        out = [0.0, 0.0, 0.0]
        for k in range(3):
            if cp.bary[k] != 0.0:
                out[fg.index(fs[k])] += cp.bary[k]
        return (out[0], out[1], out[2])

    # ------------------------------------------------------------------- walk
    def connect(self, u: int, w: int, g: int) -> list[int]:
        """Vertices after ``u`` up to ``w`` along the straight segment u -> w in face ``g``."""
        out: list[int] = []
        cur = u
        self.snap_ok = (w,)
        W = self.xyz(w)
        uw = self.uv(w, g)
        for _ in range(_MAX_WALK_STEPS):
            if cur == w:
                return out
            if _key(cur, w) in self.edge_map and self.edge_map[_key(cur, w)]:
                out.append(w)
                return out
            P = self.xyz(cur)
            D = _sub(W, P)
            L = _norm(D)
            uc = self.uv(cur, g)
            dw = (uw[0] - uc[0], uw[1] - uc[1])
            nw = _hypot(dw[0], dw[1])
            best, best_score = None, -math.inf
            for t in self.vtris.get(cur, ()):
                if self.parent[t] != g:
                    continue
                abc = self.tri[t]
                i = abc.index(cur)
                b, c = abc[(i + 1) % 3], abc[(i + 2) % 3]
                ub, uc2 = self.uv(b, g), self.uv(c, g)
                db = (ub[0] - uc[0], ub[1] - uc[1])
                dc = (uc2[0] - uc[0], uc2[1] - uc[1])
                s1 = _cross2(db, dw) / (_hypot(*db) * nw)
                s2 = _cross2(dw, dc) / (_hypot(*dc) * nw)
                score = min(s1, s2)
                if score > best_score:
                    best, best_score = (b, c, ub, uc2), score
            if best is None:  # pragma: no cover - guarded by construction
                raise CutError(f"internal: no triangle of original face {g} around vertex {cur}")
            b, c, ub, uc2 = best
            nxt = -1
            nxt_proj = math.inf
            for v in (b, c):
                X = _sub(self.xyz(v), P)
                proj = _dot(X, D) / L
                perp = _norm(_sub(X, tuple(proj * D[i] / L for i in range(3))))
                if (
                    perp < self.snap
                    and 0.0 < proj < L + self.snap
                    and proj < nxt_proj
                    and (v == w or v not in self.on_path)
                ):
                    nxt, nxt_proj = v, proj
            if nxt < 0:
                denom = _cross2(dw, (uc2[0] - ub[0], uc2[1] - ub[1]))
                s = _cross2(dw, (uc[0] - ub[0], uc[1] - ub[1])) / denom if denom != 0 else 0.5
                s = min(max(s, 0.0), 1.0)
                nxt = self.split_edge_at(b, c, s, g)
            out.append(nxt)
            self.on_path.add(nxt)
            cur = nxt
        raise CutError(f"internal: walk from vertex {u} to vertex {w} in face {g} did not end")


def _classify(
    cutter: _Cutter,
    face: int,
    bary: NDArray,
    index: int,
    matmul: bool = False,
    within: tuple[float, float] | None = None,
) -> _CutPoint:
    """Snap a face point onto a vertex or an edge of its face when within ``within``
    (distances to a vertex and to an edge; default ``CUT_SNAP`` for both).

    The point is ``b0 p0 + b1 p1 + b2 p2`` summed left to right, as the kernel classifying
    curve points does; ``matmul`` takes numpy's ``b @ pos`` instead, as the library does for
    corners (on some CPUs numpy fuses its multiply-adds, so the two differ in the last bit).
    """
    snap, edge_snap = (
        (cutter.snap,) * 2 if within is None else (max(w, cutter.snap) for w in within)
    )
    fv = cutter.face(face)
    b = np.clip(bary, 0.0, None)
    b = b / b.sum()
    pos = [cutter.xyz(v) for v in fv]
    if matmul:
        p = tuple(float(x) for x in b @ np.asarray(pos))
    else:
        p = tuple(float(b[0] * pos[0][d] + b[1] * pos[1][d] + b[2] * pos[2][d]) for d in range(3))
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


def _same_point(cutter: _Cutter, p: _CutPoint, q: _CutPoint) -> bool:
    """Whether two points are one: the same vertex, or within ``CUT_SNAP`` on the same faces
    (points on different faces are kept apart; insertion snaps them where it is safe)."""
    if p.vertex >= 0 or q.vertex >= 0:
        return p.vertex == q.vertex
    return p.faces == q.faces and _norm(_sub(p.xyz, q.xyz)) < cutter.snap


def _crossing(cutter: _Cutter, p: _CutPoint, f: int, k: int, q: _CutPoint) -> _CutPoint:
    """Where the straight segment p -> q, unfolded about edge k of face f, crosses that edge."""
    fv = cutter.face(f)
    vi, vj = cutter.xyz(fv[k]), cutter.xyz(fv[(k + 1) % 3])
    e = _sub(vj, vi)
    length = _norm(e)
    eh = (e[0] / length, e[1] / length, e[2] / length)
    rp, rq = _sub(p.xyz, vi), _sub(q.xyz, vi)
    pa, qa = _dot(rp, eh), _dot(rq, eh)
    ph = _norm(_sub(rp, tuple(pa * x for x in eh)))
    qh = _norm(_sub(rq, tuple(qa * x for x in eh)))
    a = pa + (qa - pa) * ph / (ph + qh) if ph + qh > 0 else 0.5 * (pa + qa)
    s = min(max(a / length, 0.0), 1.0)
    return _edge_point(cutter, f, k, s, p.index)


def _bridge(cutter: _Cutter, p: _CutPoint, q: _CutPoint, i: int, j: int) -> list[_CutPoint]:
    """Points to insert between p and q so each consecutive pair shares an original face."""
    if p.faces & q.faces:
        return []
    # edge-adjacent faces: the crossing point on the shared edge
    best, best_len = None, math.inf
    for f in sorted(p.faces):
        for k in range(3):
            h = int(cutter.FN[f, k])
            if h >= 0 and h in q.faces:
                x = _crossing(cutter, p, f, k, q)
                d = _norm(_sub(x.xyz, p.xyz)) + _norm(_sub(q.xyz, x.xyz))
                if d < best_len:
                    best, best_len = x, d
    if best is not None:
        return [best]
    # faces sharing a vertex only: route through it (or across the fan of faces around it)
    vp = {v for f in p.faces for v in cutter.face(f)}
    vq = {v for f in q.faces for v in cutter.face(f)}
    shared = sorted(vp & vq)
    if shared:
        v = min(
            shared,
            key=lambda v: _norm(_sub(cutter.xyz(v), p.xyz)) + _norm(_sub(q.xyz, cutter.xyz(v))),
        )
        if cutter.route_fans:
            fan = _fan_crossings(cutter, p, q, v)
            if fan:
                return fan
        return [_vertex_point(cutter, v, p.index)]
    raise CutError(
        f"curve points {i} and {j} lie on faces {p.face} and {q.face}, which are not "
        "the same, edge-adjacent or sharing a vertex: sample the curve more densely "
        "(consecutive points on the same or adjacent faces)"
    )


def _fan_crossings(cutter: _Cutter, p: _CutPoint, q: _CutPoint, v: int) -> list[_CutPoint]:
    """Crossings of the segment p -> q with the edges around vertex ``v`` between a face of p
    and a face of q, going round ``v`` the way that passes fewer faces (empty when none)."""
    around = cutter.faces_around(v)
    starts = sorted(f for f in p.faces if f in around)
    best: list[tuple[int, int]] | None = None
    for f0 in starts:
        for first in range(3):
            fv = cutter.face(f0)
            if v not in (fv[first], fv[(first + 1) % 3]):
                continue  # only the two edges of f0 at v lead round the fan
            steps: list[tuple[int, int]] = []
            f, k = f0, first
            for _ in range(len(around)):
                h = int(cutter.FN[f, k])
                if h < 0 or h not in around or h == f0:
                    steps = []
                    break
                steps.append((f, k))
                if h in q.faces:
                    break
                hv = cutter.face(h)
                # leave h by its other edge at v
                k = next(
                    kk
                    for kk in range(3)
                    if v in (hv[kk], hv[(kk + 1) % 3]) and int(cutter.FN[h, kk]) != f
                )
                f = h
            else:
                steps = []
            if steps and (best is None or len(steps) < len(best)):
                best = steps
    if not best:
        return []
    out: list[_CutPoint] = []
    prev = p
    for f, k in best:
        x = _crossing(cutter, prev, f, k, q)
        out.append(x)
        prev = x
    return out


def _common_face(p: _CutPoint, q: _CutPoint) -> int:
    common = p.faces & q.faces
    if p.face in common:
        return p.face
    if q.face in common:
        return q.face
    return min(common)


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
    cutter = _Cutter(mesh)
    cps = [_classify(cutter, int(points.face[i]), points.bary[i], i) for i in range(n)]
    path = _insert_curve(cutter, cps, closed)
    path = _drop_spikes(_expand(cutter, path, closed), closed)
    if len(path) < 2:
        raise CutError(f"the curve's {n} points collapse to a single vertex: nothing to cut")
    edges = list(itertools.pairwise(path)) + ([(path[-1], path[0])] if closed else [])
    cutter.cut = {_key(a, b) for a, b in edges}
    return _assemble(cutter, mesh, path, closed, split)


def _insert_curve(cutter: _Cutter, cps: list[_CutPoint], closed: bool) -> list[int]:
    """Insert one curve's snapped points into the triangulation and join them by edges.

    Returns the curve's vertices in order (before :func:`_expand`); the joining edges are added
    to ``cutter.cut``. A point whose ``vertex`` is set (an original vertex, or a corner inserted
    earlier) is used as that vertex.
    """
    n = len(cps)
    # 1. a sequence in which consecutive points share an original face
    seq: list[_CutPoint] = []
    pairs = [(i, i + 1) for i in range(n - 1)] + ([(n - 1, 0)] if closed else [])
    seq.append(cps[0])
    for i, j in pairs:
        q = cps[j]
        if _same_point(cutter, seq[-1], q):
            continue
        for x in _bridge(cutter, seq[-1], q, i, j):
            if not _same_point(cutter, seq[-1], x):
                seq.append(x)
        if not _same_point(cutter, seq[-1], q):
            seq.append(q)
    if closed and len(seq) > 1 and _same_point(cutter, seq[-1], seq[0]):
        seq.pop()
    if len(seq) < 2 or (closed and len(seq) < 3):
        raise CutError(
            f"the curve's {n} points collapse to {len(seq)} distinct point(s): nothing to cut"
        )

    # 2-3. insert the points and join consecutive ones by edges
    segs = list(itertools.pairwise(seq))
    if closed:
        segs.append((seq[-1], seq[0]))
    first = cutter.insert(seq[0], _common_face(seq[0], seq[1]))
    path = [first]
    cutter.on_path.add(first)
    prev = first
    for k, (p, q) in enumerate(segs):
        g = _common_face(p, q)
        cutter.ensure(g)
        cutter.snap_ok = (prev,)
        nxt = first if (closed and k == len(segs) - 1) else cutter.insert(q, g)
        step = cutter.connect(prev, nxt, g)
        chain = [prev, *step]
        for a, b in itertools.pairwise(chain):
            cutter.cut.add(_key(a, b))
        path.extend(step)
        cutter.on_path.add(nxt)
        prev = nxt
    if closed and len(path) > 1 and path[-1] == path[0]:
        path.pop()  # the walk ended back at the first vertex
    return path


def _expand(cutter: _Cutter, path: list[int], closed: bool) -> list[int]:
    """Re-insert the vertices that later splits put on earlier cut edges; drop repeats."""

    def between(a: int, b: int) -> list[int]:
        x = cutter.split_of.get(_key(a, b))
        if x is None:
            return [b]
        return between(a, x) + between(x, b)

    out = [path[0]]
    ends = path[1:] + ([path[0]] if closed else [])
    for b in ends:
        for v in between(out[-1], b):
            if v != out[-1]:
                out.append(v)
    if closed and len(out) > 1 and out[-1] == out[0]:
        out.pop()
    return out


def _drop_spikes(path: list[int], closed: bool) -> list[int]:
    """Remove immediate back-and-forth steps ``a, b, a`` (a cut of zero width)."""
    stack: list[int] = []
    for v in path + ([path[0]] if closed else []):
        if len(stack) >= 2 and stack[-2] == v:
            stack.pop()
        else:
            stack.append(v)
    if closed:
        while len(stack) >= 3 and stack[1] == stack[-2]:
            stack = stack[1:-1]
        stack.pop()
    return stack


def _refined(cutter: _Cutter, mesh: Mesh):
    """Arrays of the refined (not yet split) triangulation: vertices, faces, face parents,
    vertex sources, vertex parents and colours."""
    nv0, nf0 = cutter.nv0, cutter.nf0
    n_new = len(cutter.new_xyz)
    vertices = np.concatenate([mesh.vertices, np.asarray(cutter.new_xyz).reshape(-1, 3)])
    faces = np.concatenate([mesh.faces, np.zeros((cutter.n_tri - nf0, 3), dtype=np.int64)])
    face_parent = np.concatenate(
        [np.arange(nf0, dtype=np.int64), np.zeros(cutter.n_tri - nf0, dtype=np.int64)]
    )
    for t, abc in cutter.tri.items():
        faces[t] = abc
        face_parent[t] = cutter.parent[t]
    src = SurfacePoints.concatenate(
        [
            SurfacePoints.at_vertices(mesh.faces, np.arange(nv0)),
            SurfacePoints(
                np.asarray(cutter.new_face, dtype=np.int64),
                np.asarray(cutter.new_bary, dtype=np.float64).reshape(-1, 3),
            ),
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
@dataclass(frozen=True)
class NetworkCutResult:
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
    """

    mesh: Mesh
    curve_vertices: tuple[NDArray[np.int64], ...]
    corners: NDArray[np.int64]
    copy_of: NDArray[np.int64]
    face_parent: NDArray[np.int64]
    vertex_parent: NDArray[np.int64]
    vertex_source: SurfacePoints


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
        mesh vertex is moved onto it (one nearer an edge than the side of the least
        triangle, onto the edge), and curve points that
        close to their end corners are dropped (painted curves pass through the vertex
        nearest a corner pick).
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
    corners = as_surface_points(mesh, corners, name="corners")
    ends = np.asarray(ends, dtype=np.int64).reshape(-1, 2)
    if ends.shape[0] != len(curves):
        raise InputError(f"ends has {ends.shape[0]} rows for {len(curves)} curves")
    nc = len(corners)
    if ends.size and (ends.min() < 0 or ends.max() >= nc):
        i = int(np.flatnonzero((ends < 0).any(axis=1) | (ends >= nc).any(axis=1))[0])
        raise InputError(f"curve {i}: corner index out of range 0..{nc - 1}: {ends[i].tolist()}")
    cutter = _Cutter(mesh)
    cutter.route_fans = True
    merge = tol.length(mesh, tol.CUT_CORNER_MERGE)
    corner_cp: list[_CutPoint] = []
    corner_v = np.empty(nc, dtype=np.int64)
    for c in range(nc):
        # a corner within CUT_CORNER_MERGE of a vertex is that vertex; one nearer an edge than
        # the side of the least triangle (at most that), on the edge
        near = (merge, min(merge, float(np.sqrt(2.0 * cutter.min_area))))
        cp = _classify(cutter, int(corners.face[c]), corners.bary[c], c, matmul=True, within=near)
        v = cutter.insert(cp, cp.face)
        if v < cutter.nv0:
            cp = _vertex_point(cutter, v, c)
        else:
            cp = _CutPoint(cp.face, cp.bary, v, cp.faces, cutter.xyz(v), c)
        corner_v[c] = v
        corner_cp.append(cp)
        cutter.on_path.add(v)
    if len(set(corner_v.tolist())) < nc:
        a, b = _first_repeat(corner_v)
        raise CutError(f"corners {a} and {b} fall on the same point")
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
        cps = [first]
        cps += [_classify(cutter, int(pts.face[k]), pts.bary[k], int(k)) for k in inner]
        cps.append(last)
        try:
            raw.append(_insert_curve(cutter, cps, False))
        except CutError as exc:
            raise CutError(f"curve {i}: {exc}") from None
    paths = []
    for i, path in enumerate(raw):
        path = _drop_loops(_drop_spikes(_expand(cutter, path, False), False))
        if len(path) < 2:
            raise CutError(f"curve {i} collapses to a single vertex: nothing to cut")
        paths.append(path)
    _check_meetings(paths, corner_v, ends)
    cutter.cut = {_key(a, b) for path in paths for a, b in itertools.pairwise(path)}
    vertices, faces, face_parent, src, parent, colors = _refined(cutter, mesh)
    copy_of = np.arange(vertices.shape[0], dtype=np.int64)
    if split:
        faces, copy_of = _split_faces(cutter, faces, vertices.shape[0])
        vertices = vertices[copy_of]
        parent = parent[copy_of]
        src = src[copy_of]
        colors = None if colors is None else colors[copy_of]
    new_mesh = Mesh(vertices, faces, colors, name=mesh.name)
    return NetworkCutResult(
        new_mesh,
        tuple(np.asarray(p, dtype=np.int64) for p in paths),
        corner_v,
        copy_of,
        face_parent,
        parent,
        src,
    )


def _drop_loops(path: list[int]) -> list[int]:
    """Cut out closed detours ``v ... v`` of an open path (left where a walk curled round and
    came back to a vertex it had passed), so each vertex appears once."""
    out: list[int] = []
    where: dict[int, int] = {}
    for v in path:
        k = where.get(v)
        if k is not None:
            for u in out[k + 1 :]:
                del where[u]
            del out[k + 1 :]
            continue
        where[v] = len(out)
        out.append(v)
    return out


def _first_repeat(a: NDArray[np.int64]) -> tuple[int, int]:
    seen: dict[int, int] = {}
    for i, v in enumerate(a.tolist()):
        if v in seen:
            return seen[v], i
        seen[v] = i
    return -1, -1  # pragma: no cover


def _check_meetings(paths: list[list[int]], corner_v: NDArray[np.int64], ends: NDArray) -> None:
    """Raise when a curve touches itself or another curve away from its own end corners."""
    owner: dict[int, int] = {}
    corner_of = {int(v): c for c, v in enumerate(corner_v.tolist())}
    for i, path in enumerate(paths):
        own_ends = {path[0], path[-1]}
        for k, v in enumerate(path):
            if v in own_ends and k in (0, len(path) - 1):
                continue
            if v in corner_of:
                raise CutError(
                    f"curve {i} passes through corner {corner_of[v]} (point {k} of its path): "
                    "curves may meet only at their end corners"
                )
            j = owner.get(v)
            if j is not None:
                what = "touches itself" if j == i else f"crosses or touches curve {j}"
                raise CutError(
                    f"curve {i} {what} away from the corners, at cut vertex {v} "
                    f"(point {k} of its path)"
                )
            owner[v] = i


def _split_along(cutter: _Cutter, faces: NDArray[np.int64], nv: int, path: list[int], closed: bool):
    """Give each fan of faces around a vertex that the cut separates its own vertex copy."""
    new_faces, copy_of = _split_faces(cutter, faces, nv)
    left, right = _path_sides(cutter, new_faces, path, closed)
    return new_faces, copy_of, left, right


def _split_faces(cutter: _Cutter, faces: NDArray[np.int64], nv: int):
    """Faces with each fan separated by ``cutter.cut`` on its own vertex copy, and the vertex
    each new vertex copies (the first ``nv`` keep their index)."""
    table = topology.edge_table(faces, nv)
    n = np.int64(max(nv, 1))
    keys = table.edges[:, 0] * n + table.edges[:, 1]
    cut = np.asarray(sorted(cutter.cut), dtype=np.int64).reshape(-1, 2)
    cut_mask = np.zeros(keys.size, dtype=bool)
    if cut.size:
        cut_mask[np.searchsorted(keys, cut[:, 0] * n + cut[:, 1])] = True
    fan, n_fans = topology.corner_fans(faces, nv, table, cut_mask)
    corner_vertex = faces.reshape(-1)
    fan_vertex = np.empty(n_fans, dtype=np.int64)
    fan_vertex[fan] = corner_vertex
    fan_first = np.full(n_fans, corner_vertex.size, dtype=np.int64)
    np.minimum.at(fan_first, fan, np.arange(corner_vertex.size))
    order = np.lexsort((fan_first, fan_vertex))
    primary = np.ones(n_fans, dtype=bool)
    primary[order[1:]] = fan_vertex[order[1:]] != fan_vertex[order[:-1]]
    new_id = np.empty(n_fans, dtype=np.int64)
    new_id[primary] = fan_vertex[primary]
    extra = order[~primary[order]]
    new_id[extra] = nv + np.arange(extra.size)
    copy_of = np.concatenate([np.arange(nv), fan_vertex[extra]])
    new_faces = new_id[fan].reshape(-1, 3)

    return new_faces, copy_of


def _path_sides(cutter: _Cutter, new_faces: NDArray[np.int64], path: list[int], closed: bool):
    """The copies of each path vertex on the left and right of the curve after splitting."""
    k = len(path)
    left = np.full(k, -1, dtype=np.int64)
    right = np.full(k, -1, dtype=np.int64)
    n_edges = k if closed else k - 1
    for i in range(k):
        e = i if i < n_edges else i - 1  # the edge leaving vertex i (entering, at an open end)
        a, b = path[e], path[(e + 1) % k]
        for t in cutter.edge_map[_key(a, b)]:
            abc = cutter.tri[t]
            v = int(new_faces[t, abc.index(path[i])])
            if abc[(abc.index(a) + 1) % 3] == b:  # half-edge a -> b: the face on the left
                left[i] = v
            else:
                right[i] = v
    left = np.where(left < 0, right, left)
    right = np.where(right < 0, left, right)
    return left, right
