"""A quick level-0 spring mesh of a large patch, its planar map made on a coarse copy (private).

The exact level 0 of :func:`meshfit.springs.resample_patch` starts from the images of a
regular parameter grid under the mean-value map of the whole patch onto the unit square;
on a large patch that map's solve is most of the time of a cold level-0 preview.
:func:`coarse_level0` makes the map on a coarse copy of the patch
instead: every boundary vertex kept (at the same side parameters as in the exact map), the
interior vertices merged into graph aggregates of about one vertex ring (each represented
by one of its own vertices, so the copy's vertices are a subset of the patch's). The grid's
parameters are located in the coarse map, carried to the closest points of the full patch
and relaxed on the full patch exactly as level 0 of ``resample_patch`` is (its fold repair
re-places points through the coarse map). Every point is a face point of the full patch.

How close it is (measured against ``resample_patch(patch, level=0)``; distances over the
mean spacing of the exact level-0 grid). On the patches a session previews this way (over
:data:`PREVIEW_MIN_VERTICES`) every point stays within a fraction of a grid spacing of the
exact one, and most far closer. On small patches the copy is coarse next to the grid and
single points settle further away, up to a spacing or two, which is one reason for the
threshold. The largest offsets are single points of bulging patches where relaxation from
a slightly different start settles elsewhere. Bounds with margin for the large patches:
:data:`PREVIEW_MAX_OFFSET`, :data:`PREVIEW_MEDIAN_OFFSET`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from meshfit import tol
from meshfit._kernels import planar as _kp
from meshfit.springs.grid import FREE, SpringMesh
from meshfit.springs.planar import PlanarMap, _square_map
from meshfit.springs.relax import Sweeps, relax, repair_folds, unfold_in_map, untangle
from meshfit.springs.resample import (
    COARSE_EPS,
    COARSE_OMEGA,
    COARSE_SWEEPS,
    _level0_sections,
    _sides,
    grid_parameters,
)
from meshfit.springs.state import State
from meshfit.types import SurfacePoints

__all__ = [
    "AGGREGATE_ROUNDS",
    "PREVIEW_MAX_OFFSET",
    "PREVIEW_MEDIAN_OFFSET",
    "PREVIEW_MIN_VERTICES",
    "coarse_level0",
]

#: a level-0 preview of a patch with more vertices than this is made on a coarse copy
#: (:func:`coarse_level0`); below it the exact map is quick enough for an interactive preview
PREVIEW_MIN_VERTICES = 10_000
#: rounds of aggregation of the interior vertices (one round merges about a vertex ring into
#: one vertex; a second round saves a little more time but lets the points settle further away)
AGGREGATE_ROUNDS = 1
#: bound on the largest distance of a coarse level-0 point from the exact level 0, in mean
#: exact grid spacings, for patches over the threshold and for bulging ones a few times
#: smaller (a bound with a margin, not a measured figure; benchmarks/ui_latency.py reports
#: the preview's offsets)
PREVIEW_MAX_OFFSET = 1.0
#: bound on the median distance, in mean exact grid spacings (with the same margin)
PREVIEW_MEDIAN_OFFSET = 0.05


@dataclass(frozen=True, eq=False)
class _Coarse:
    """The coarse copy: enough of a mesh for the mean-value system and point location
    (vertices a subset of the patch's; it need not be manifold)."""

    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    mean_edge_length: float

    @property
    def n_vertices(self) -> int:
        return self.vertices.shape[0]

    @property
    def n_faces(self) -> int:
        return self.faces.shape[0]


def _coarse_copy(mesh, boundary: NDArray[np.int64], rounds: int):
    """Coarse copy of ``mesh``: boundary vertices kept, interior vertices merged by rounds of
    graph aggregation (each aggregate represented by its member closest to its centroid);
    faces whose corners merge are dropped, the others keep their corners' representatives.

    Returns the coarse mesh and ``keep`` (k,) int64, the patch vertex of each coarse vertex.
    """
    n = mesh.n_vertices
    V = mesh.vertices
    fixed = np.zeros(n, dtype=bool)
    fixed[boundary] = True
    rep = np.arange(n, dtype=np.int64)  # patch vertex -> representative patch vertex
    inner = np.flatnonzero(~fixed)
    indptr, indices = mesh.vertex_adjacency
    row = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr))
    col = indices
    for _ in range(rounds):
        if inner.size < 2:
            break
        at = np.full(n, -1, dtype=np.int64)
        at[inner] = np.arange(inner.size)
        r, c = at[row], at[col]
        ok = (r >= 0) & (c >= 0) & (r != c)
        r, c = r[ok], c[ok]
        o = np.lexsort((c, r))
        r, c = r[o], c[o]
        if r.size:  # drop repeated edges (after a merge)
            first = np.r_[True, (r[1:] != r[:-1]) | (c[1:] != c[:-1])]
            r, c = r[first], c[first]
        m = inner.size
        ip = np.zeros(m + 1, dtype=np.int64)
        np.cumsum(np.bincount(r, minlength=m), out=ip[1:])
        # theta 0: every edge is strong (no diagonal needed)
        agg, na = _kp.aggregate(ip, np.ascontiguousarray(c), np.ones(c.size), 0.0)
        P = V[inner]
        cnt = np.bincount(agg, minlength=na).astype(np.float64)
        cen = np.stack([np.bincount(agg, P[:, k], na) for k in range(3)], axis=1) / cnt[:, None]
        d = np.einsum("ij,ij->i", P - cen[agg], P - cen[agg])
        order = np.lexsort((d, agg))
        lead = order[np.r_[True, agg[order][1:] != agg[order][:-1]]]
        new_rep = np.arange(n, dtype=np.int64)
        new_rep[inner] = inner[lead[agg]]
        rep = new_rep[rep]
        row, col = new_rep[row], new_rep[col]
        inner = inner[lead]
    keep = np.flatnonzero(rep == np.arange(n))
    idx = np.full(n, -1, dtype=np.int64)
    idx[keep] = np.arange(keep.size)
    G = idx[rep[mesh.faces]]
    G = G[(G[:, 0] != G[:, 1]) & (G[:, 1] != G[:, 2]) & (G[:, 2] != G[:, 0])]
    used = np.bincount(G.ravel(), minlength=keep.size) > 0
    used[idx[boundary]] = True
    if not used.all():  # a representative left in no face: no equation of its own
        keep = keep[used]
        idx[:] = -1
        idx[keep] = np.arange(keep.size)
        G = idx[rep[mesh.faces]]
        G = G[(G[:, 0] != G[:, 1]) & (G[:, 1] != G[:, 2]) & (G[:, 2] != G[:, 0])]
    G = np.ascontiguousarray(G)
    Vc = np.ascontiguousarray(V[keep])
    e = Vc[G[:, [1, 2, 0]]] - Vc[G]
    return _Coarse(Vc, G, float(np.sqrt(np.einsum("ijk,ijk->ij", e, e)).mean())), keep


class _ProxyMap:
    """The coarse copy's map seen from the patch: ``uv_of`` and ``locate`` of
    :class:`meshfit.springs.planar.PlanarMap` for face points of the patch (through the
    closest points of the coarse copy, and of the patch to the coarse copy's points)."""

    def __init__(self, mesh, coarse: _Coarse, cmap: PlanarMap):
        self.mesh, self.coarse, self.cmap = mesh, coarse, cmap
        self._tree = None

    def uv_of(self, face: NDArray[np.int64], bary: NDArray[np.float64]) -> NDArray[np.float64]:
        import igl

        from meshfit.mesh.locate import barycentric

        c = self.coarse
        if self._tree is None:
            self._tree = igl.AABB()
            self._tree.init(c.vertices, c.faces)
        xyz = self.mesh.xyz(SurfacePoints(face, bary))
        _, cf, near = self._tree.squared_distance(c.vertices, c.faces, xyz)
        cf = np.asarray(cf, dtype=np.int64)
        b = np.nan_to_num(barycentric(c, cf, np.asarray(near)), nan=1.0 / 3.0)
        b = np.clip(b, 0.0, None)
        b /= b.sum(axis=1, keepdims=True)
        return self.cmap.uv_of(cf, b)

    def locate(self, q: NDArray[np.float64]) -> SurfacePoints:
        pts = self.cmap.locate(q)
        c = self.coarse
        xyz = np.einsum("ij,ijk->ik", pts.bary, c.vertices[c.faces[pts.face]])
        lost = pts.face < 0  # in no face's bucket: the coarse vertex nearest in the square
        if lost.any():
            from scipy.spatial import cKDTree

            _, v = cKDTree(self.cmap.uv).query(np.clip(q[lost], 0.0, 1.0))
            xyz[lost] = c.vertices[v]
        return self.mesh.closest_points(xyz).points


def coarse_level0(
    patch,
    *,
    init_intervals: int = 8,
    fairness: float = 0.5,
    max_iter: int = 10,
    ramp: int = 8,
    rounds: int = AGGREGATE_ROUNDS,
) -> SpringMesh | None:
    """Level-0 spring mesh of ``patch`` close to ``resample_patch(patch, level=0).final``
    (default options), its planar map made on a coarse copy of the patch.

    The free points start at the closest points of the patch to the images of the regular
    parameter grid under the coarse copy's mean-value map; then the grid is relaxed on the
    patch itself with the sweeps, weights, untangling and fold repair of level 0 of
    ``resample_patch`` (the harmonic re-placement of folded points goes through the coarse
    map). With ``rounds=0`` the copy is the patch and the result is the exact level 0 up to
    round-off. How close it is otherwise: see the module docstring; on patches over
    :data:`PREVIEW_MIN_VERTICES` the offsets from the exact level 0 stay within
    :data:`PREVIEW_MAX_OFFSET` (largest) and :data:`PREVIEW_MEDIAN_OFFSET` (median).

    Parameters
    ----------
    patch : meshfit.layout.Patch
    init_intervals, fairness, max_iter, ramp : keyword-only
        As in :func:`meshfit.springs.resample_patch`.
    rounds : int, keyword-only
        Rounds of aggregation of the interior vertices (default :data:`AGGREGATE_ROUNDS`).

    Returns
    -------
    meshfit.springs.SpringMesh or None
        Level 0; every point is a face point of ``patch.mesh``. None when the patch has
        feature curves in both directions (its level 0 starts from Dijkstra paths, not from
        the map) or the coarse map could not be solved: use ``resample_patch`` then.

    References
    ----------
    .. [1] Krishnamurthy, "Fitting Smooth Surfaces to Dense Polygon Meshes", PhD thesis,
       Stanford 2000, sec. 5.4 (level-0 spring mesh), sec. 5.13 (coarse previews);
       Floater, "Mean value coordinates", CAGD 20 (2003).
    """
    mesh = patch.mesh
    sides = _sides(patch)
    us, vs, breaks, counts_u, counts_v = _level0_sections(patch, sides, init_intervals)
    if us and vs:
        return None
    state = State(mesh, patch.index, sides, us, vs, breaks, counts_u, counts_v)
    state.chords = True

    boundary = np.unique(np.concatenate([sides.chains[k] for k in sides.chains]))
    coarse, keep = _coarse_copy(mesh, boundary, int(rounds))
    index = np.full(mesh.n_vertices, -1, dtype=np.int64)
    index[keep] = np.arange(keep.size)
    try:
        cmap = _square_map(coarse, sides, index)  # the boundary where the exact map puts it
    except RuntimeError:  # singular coarse system (SuperLU): no preview from this copy
        return None
    if not np.isfinite(cmap.uv).all():
        return None

    nu, nv = state.nu, state.nv
    state.face = np.zeros(nu * nv, dtype=np.int64)
    state.bary = np.zeros((nu * nv, 3))
    uv = grid_parameters(state).reshape(-1, 2)
    free = (state.kind() == FREE).ravel()
    pmap = _ProxyMap(mesh, coarse, cmap)
    near = pmap.locate(uv[free])
    state.face[free] = near.face
    state.bary[free] = near.bary
    state.set_boundary()
    state.s_u = [np.linspace(0.0, ln.total, nv) for ln in state.u_feat]
    state.s_v = [np.linspace(0.0, ln.total, nu) for ln in state.v_feat]
    state.set_feature_points()

    schedule = Sweeps(
        max_iter=max_iter * COARSE_SWEEPS,
        ramp=ramp,
        fairness=fairness,
        omega=min(1.9, COARSE_OMEGA),
        start=ramp,
        eps=tol.SPRING_CONVERGED * COARSE_EPS,
    )
    relax(state, schedule, tangent=True, guard=True)
    untangle(state, rounds=3, sweeps=max_iter, reach=2, tangent=True, guard=True)
    unfold_in_map(state, pmap)
    repair_folds(state)
    return state.snapshot()
