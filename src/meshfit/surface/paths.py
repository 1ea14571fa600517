"""Graph paths on the mesh's vertex/edge graph: greedy, A* and (restricted) Dijkstra.

The greedy graph path is how the thesis turns two picked vertices into a first curve
(Krishnamurthy 2000, sec. 3.2) and how FindMidPoint starts (sec. 5.6). Greedy descent can stall
in a concave region; :func:`greedy_path` then finishes with weighted A*, so it always connects
two vertices of the same component.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import sparse
from scipy.sparse.csgraph import dijkstra

from meshfit._kernels import paths as _paths
from meshfit._validate import as_vertex_index
from meshfit.errors import InputError, PathError
from meshfit.mesh import Mesh
from meshfit.types import SurfacePoints

#: heuristic weight of the A* that finishes a stalled greedy path: the finish is at most this
#: many times longer than the shortest path from the stall, and searches far fewer vertices
#: (a long segment stalling in a concave fold: the weight trades a path a little longer
#: than the shortest for a search an order of magnitude smaller)
GREEDY_ASTAR_WEIGHT = 1.5

__all__ = [
    "GREEDY_ASTAR_WEIGHT",
    "GraphPath",
    "ShortestPaths",
    "astar_path",
    "greedy_path",
    "path_to_surface_points",
    "shortest_path",
]


@dataclass(frozen=True)
class GraphPath:
    """A path of mesh edges.

    Attributes
    ----------
    vertices : (k,) int64
        Vertex indices from the source to the target; consecutive ones are joined by an edge,
        no vertex repeats.
    length : float
        Sum of the edge lengths, model units.
    used_fallback : bool
        True when greedy descent stalled and A* finished the path.
    """

    vertices: NDArray[np.int64]
    length: float
    used_fallback: bool = False


@dataclass(frozen=True)
class ShortestPaths:
    """Result of :func:`shortest_path`.

    Attributes
    ----------
    distance : (nv,) float64
        Graph distance from the nearest source, model units; ``inf`` where unreachable or
        outside the allowed subset.
    predecessor : (nv,) int64
        Previous vertex on a shortest path from the nearest source; -1 at the sources and where
        unreachable.
    nearest_source : (nv,) int64
        The source each vertex is nearest to; -1 where unreachable.
    targets : (t,) int64
        The requested targets (empty when none were given).
    paths : list of (k,) int64
        One vertex path per target, from its nearest source to the target.
    lengths : (t,) float64
        ``distance[targets]``.
    """

    distance: NDArray[np.float64]
    predecessor: NDArray[np.int64]
    nearest_source: NDArray[np.int64]
    targets: NDArray[np.int64]
    paths: list[NDArray[np.int64]]
    lengths: NDArray[np.float64]

    def path_to(self, vertex: int) -> NDArray[np.int64]:
        """(k,) int64: a shortest path from the nearest source to ``vertex``.

        Raises
        ------
        PathError
            When ``vertex`` is unreachable.
        """
        v = int(vertex)
        if not np.isfinite(self.distance[v]):
            raise PathError(f"vertex {v} is not reachable from the sources")
        return _walk_back(self.predecessor, v)


def _walk_back(predecessor: NDArray[np.int64], v: int) -> NDArray[np.int64]:
    out = [v]
    while predecessor[v] >= 0:
        v = int(predecessor[v])
        out.append(v)
    return np.asarray(out[::-1], dtype=np.int64)


def _path_length(mesh: Mesh, vertices: NDArray[np.int64]) -> float:
    if vertices.size < 2:
        return 0.0
    p = mesh.vertices[vertices]
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def _check_same_component(mesh: Mesh, source: int, target: int) -> None:
    comp = mesh.vertex_components
    if comp[source] != comp[target]:
        raise PathError(
            f"no path from vertex {source} to vertex {target}: they lie on different "
            f"components ({int(comp[source])} and {int(comp[target])}) of "
            f"{mesh.name or 'the mesh'}"
        )


def greedy_path(mesh: Mesh, source: int, target: int, *, fallback: bool = True) -> GraphPath:
    """Greedy graph path between two vertices, finished by A* where greedy descent stalls.

    From the current vertex the path steps to the neighbour closest (Euclidean distance) to the
    target. When no neighbour is strictly closer than the current vertex (a local minimum, e.g.
    across a cavity) the rest of the path is found from that stall vertex by A* with the
    Euclidean heuristic weighted by :data:`GREEDY_ASTAR_WEIGHT` (a finish at most that many
    times the shortest, found in a small fraction of the search), and loops formed by the join
    are erased. :func:`astar_path` gives shortest paths.

    Parameters
    ----------
    mesh : Mesh
    source, target : int
        Vertex indices.
    fallback : bool
        Finish a stalled path with A*; when False a stall raises :class:`PathError`.

    Returns
    -------
    GraphPath
        ``vertices (k,) int64`` from ``source`` to ``target``, ``length`` in model units,
        ``used_fallback``.

    Raises
    ------
    PathError
        When the vertices lie on different components, or greedy descent stalls and
        ``fallback`` is False.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.2 (curve painting: greedy graph path, fig. 3.3) and
       sec. 5.6 (FindMidPoint, step 2).
    """
    s = as_vertex_index(mesh, source, name="source")
    t = as_vertex_index(mesh, target, name="target")
    _check_same_component(mesh, s, t)
    indptr, indices = mesh.vertex_adjacency
    path, used, stall = _paths.greedy_path(
        mesh.vertices,
        indptr,
        indices,
        np.int64(s),
        np.int64(t),
        bool(fallback),
        float(GREEDY_ASTAR_WEIGHT),
    )
    if path.size == 0:
        raise PathError(
            f"greedy path from vertex {s} to vertex {t} stalls at vertex "
            f"{int(stall)} (no neighbour is closer to the target)"
        )
    return GraphPath(path, _path_length(mesh, path), bool(used))


def _allowed_mask(mesh: Mesh, allowed_vertices: ArrayLike | None, name: str) -> NDArray[np.bool_]:
    if allowed_vertices is None:
        return np.zeros(0, dtype=bool)
    a = np.asarray(allowed_vertices)
    if a.dtype == bool:
        if a.shape != (mesh.n_vertices,):
            raise InputError(
                f"{name} as a mask must have shape ({mesh.n_vertices},), got {a.shape}"
            )
        return np.ascontiguousarray(a)
    idx = _as_index_array(a, mesh.n_vertices, name)
    mask = np.zeros(mesh.n_vertices, dtype=bool)
    mask[idx] = True
    return mask


def _as_index_array(a: ArrayLike, n: int, name: str) -> NDArray[np.int64]:
    a = np.asarray(a)
    if a.size and not np.issubdtype(a.dtype, np.integer):
        raise InputError(f"{name} must hold integer indices, got dtype {a.dtype}")
    a = a.astype(np.int64).reshape(-1)
    bad = np.flatnonzero((a < 0) | (a >= n))
    if bad.size:
        raise InputError(f"{name}[{int(bad[0])}] = {int(a[bad[0]])} is not an index in [0, {n})")
    return a


def astar_path(
    mesh: Mesh, source: int, target: int, *, allowed_vertices: ArrayLike | None = None
) -> GraphPath:
    """Shortest graph path between two vertices by A* with the Euclidean heuristic.

    The heuristic (straight-line distance to the target) never overestimates a path of edges,
    so the result is a shortest path of the edge graph.

    Parameters
    ----------
    mesh : Mesh
    source, target : int
        Vertex indices.
    allowed_vertices : (k,) int64 or (nv,) bool, optional
        Only these vertices may be used (indices or a mask).

    Returns
    -------
    GraphPath
        ``vertices (k,) int64``, ``length`` (model units), ``used_fallback`` False.

    Raises
    ------
    PathError
        When no path exists (different components, a vertex outside ``allowed_vertices``, or
        the allowed subset disconnects them).

    References
    ----------
    .. [1] Hart, Nilsson & Raphael, "A formal basis for the heuristic determination of minimum
       cost paths", IEEE Trans. SSC 4(2), 1968.
    .. [2] Krishnamurthy 2000, sec. 3.2 (the graph path that seeds a painted curve).
    """
    s = as_vertex_index(mesh, source, name="source")
    t = as_vertex_index(mesh, target, name="target")
    mask = _allowed_mask(mesh, allowed_vertices, "allowed_vertices")
    if mask.size:
        for v, label in ((s, "source"), (t, "target")):
            if not mask[v]:
                raise PathError(f"{label} vertex {v} is not in allowed_vertices")
    _check_same_component(mesh, s, t)
    indptr, indices = mesh.vertex_adjacency
    path = _paths.astar(mesh.vertices, indptr, indices, np.int64(s), np.int64(t), mask, 1.0)
    if path.size == 0:
        raise PathError(f"no path from vertex {s} to vertex {t} inside allowed_vertices")
    return GraphPath(path, _path_length(mesh, path), False)


def _restricted_graph(
    mesh: Mesh, vertices: ArrayLike | None, faces: ArrayLike | None
) -> tuple[sparse.csr_matrix, NDArray[np.bool_]]:
    """Edge graph keeping only allowed edges, and the mask of allowed vertices."""
    if vertices is not None and faces is not None:
        raise InputError("give vertices or faces, not both")
    if vertices is None and faces is None:
        return mesh.edge_graph, np.ones(mesh.n_vertices, dtype=bool)
    if vertices is not None:
        mask = _allowed_mask(mesh, vertices, "vertices")
        e = mesh.edges
        keep = np.flatnonzero(mask[e[:, 0]] & mask[e[:, 1]])
    else:
        f = _as_index_array(faces, mesh.n_faces, "faces")
        keep = np.unique(mesh.face_edges[f])
        mask = np.zeros(mesh.n_vertices, dtype=bool)
        mask[mesh.faces[f].reshape(-1)] = True
    e = mesh.edges[keep]
    w = mesh.edge_lengths[keep]
    n = mesh.n_vertices
    graph = sparse.csr_matrix(
        (
            np.concatenate([w, w]),
            (np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]])),
        ),
        shape=(n, n),
    )
    return graph, mask


def shortest_path(
    mesh: Mesh,
    sources: int | ArrayLike,
    targets: int | ArrayLike | None = None,
    *,
    vertices: ArrayLike | None = None,
    faces: ArrayLike | None = None,
) -> ShortestPaths:
    """Dijkstra distances and shortest edge paths from a set of sources, optionally restricted.

    Parameters
    ----------
    mesh : Mesh
    sources : int or (s,) int64
        Source vertices; distances are to the nearest of them.
    targets : int or (t,) int64, optional
        Vertices to return paths to.
    vertices : (k,) int64 or (nv,) bool, optional
        Use only these vertices (and the edges joining two of them).
    faces : (m,) int64, optional
        Use only the edges of these faces (and their vertices).

    Returns
    -------
    ShortestPaths
        ``distance (nv,)``, ``predecessor (nv,)``, ``nearest_source (nv,)``, and one path per
        target (``paths``, ``lengths``).

    Raises
    ------
    PathError
        When a source or target lies outside the allowed subset, or a target is unreachable.

    References
    ----------
    .. [1] Dijkstra, "A note on two problems in connexion with graphs", Numer. Math. 1, 1959.
    .. [2] Krishnamurthy 2000, sec. 3.2 (graph paths on the mesh that seed surface curves).
    """
    graph, mask = _restricted_graph(mesh, vertices, faces)
    src = _as_index_array(np.atleast_1d(sources), mesh.n_vertices, "sources")
    if src.size == 0:
        raise InputError("sources must name at least one vertex")
    tgt = (
        np.zeros(0, dtype=np.int64)
        if targets is None
        else _as_index_array(np.atleast_1d(targets), mesh.n_vertices, "targets")
    )
    for arr, label in ((src, "source"), (tgt, "target")):
        bad = arr[~mask[arr]]
        if bad.size:
            raise PathError(f"{label} vertex {int(bad[0])} is outside the allowed subset")
    dist, pred, near = dijkstra(
        graph, directed=True, indices=np.unique(src), return_predecessors=True, min_only=True
    )
    pred = pred.astype(np.int64)
    pred[pred < 0] = -1
    near = near.astype(np.int64)
    near[near < 0] = -1
    paths = []
    for t in tgt.tolist():
        if not np.isfinite(dist[t]):
            shown = ", ".join(str(int(v)) for v in src[:5]) + (", ..." if src.size > 5 else "")
            raise PathError(
                f"target vertex {t} is not reachable from source vertex(es) {shown}"
                + (
                    " inside the allowed subset"
                    if vertices is not None or faces is not None
                    else ""
                )
            )
        paths.append(_walk_back(pred, t))
    return ShortestPaths(dist, pred, near, tgt, paths, dist[tgt].copy())


def _edge_ids(mesh: Mesh, a: NDArray[np.int64], b: NDArray[np.int64]) -> NDArray[np.int64]:
    """Edge id of each vertex pair, -1 where the pair is not an edge."""
    n = np.int64(max(mesh.n_vertices, 1))
    keys = mesh.edge_keys
    q = np.minimum(a, b) * n + np.maximum(a, b)
    i = np.minimum(np.searchsorted(keys, q), keys.size - 1)
    return np.where(keys[i] == q, i, -1)


def vertex_points(mesh: Mesh, vertices: NDArray[np.int64]) -> SurfacePoints:
    """``SurfacePoints.at_vertices(mesh.faces, vertices)`` (the lowest-index face around each
    vertex) from the mesh's vertex-face table, without a pass over all faces.

    Parameters
    ----------
    mesh : Mesh
    vertices : (n,) int64
        Vertex indices in range.
    """
    v = np.asarray(vertices, dtype=np.int64).reshape(-1)
    if v.size == 0:
        return SurfacePoints(np.zeros(0, np.int64), np.zeros((0, 3)))
    indptr, vf = mesh.vertex_faces
    if v.size == mesh.n_vertices and (v == np.arange(v.size)).all():
        # every vertex in order (each is on a face): the table's segments as they lie
        face = np.minimum.reduceat(vf, indptr[:-1])
    else:
        lo, hi = indptr[v], indptr[v + 1]
        if (hi <= lo).any():  # a vertex on no face: at_vertices raises its error
            return SurfacePoints.at_vertices(mesh.faces, v)
        face = _segment_min(vf, lo, hi)
    bary = (mesh.faces[face] == v[:, None]).astype(np.float64)
    return SurfacePoints(face, bary)


def _segment_min(values: NDArray[np.int64], lo: NDArray, hi: NDArray) -> NDArray[np.int64]:
    """Smallest of ``values[lo[i]:hi[i]]`` for each (non-empty) segment, in any order."""
    n = hi - lo
    first = np.concatenate([[0], np.cumsum(n)[:-1]])  # each segment's start once gathered
    idx = np.repeat(lo - first, n) + np.arange(int(n.sum()))
    return np.minimum.reduceat(values[idx], first)


def path_to_surface_points(mesh: Mesh, vertices: ArrayLike, *, per_edge: int = 0) -> SurfacePoints:
    """Sample a vertex path into face points, the form curves are kept in.

    Parameters
    ----------
    mesh : Mesh
    vertices : (k,) int64
        A path: consecutive vertices joined by an edge.
    per_edge : int
        Interior samples per edge, evenly spaced.

    Returns
    -------
    SurfacePoints
        ``k + (k - 1) * per_edge`` points: each path vertex, then the interior samples of the
        edge leaving it. The samples of an edge and the vertex it leaves lie on one face
        containing that edge; the point at a path vertex is that vertex exactly, so the face of
        the previous edge's samples also contains it. Consecutive points therefore always share a
        face (counting a point at a vertex as lying on every face around it).

    Raises
    ------
    InputError
        When two consecutive vertices are not joined by an edge.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.2: the greedy path "is then sampled into a face-point
       curve" before it is smoothed.
    """
    v = _as_index_array(vertices, mesh.n_vertices, "vertices")
    if per_edge < 0 or int(per_edge) != per_edge:
        raise InputError(f"per_edge must be a non-negative integer, got {per_edge!r}")
    per_edge = int(per_edge)
    if v.size == 0:
        return SurfacePoints(np.zeros(0, np.int64), np.zeros((0, 3)))
    if v.size == 1:
        return vertex_points(mesh, v)
    a, b = v[:-1], v[1:]
    eid = _edge_ids(mesh, a, b)
    bad = np.flatnonzero(eid < 0)
    if bad.size:
        i = int(bad[0])
        raise InputError(
            f"vertices[{i}] = {int(a[i])} and vertices[{i + 1}] = {int(b[i])} are "
            "not joined by an edge"
        )
    face = mesh.edge_face[eid]
    tri = mesh.faces[face]
    sa = np.argmax(tri == a[:, None], axis=1)
    sb = np.argmax(tri == b[:, None], axis=1)
    m = a.size
    t = np.arange(per_edge + 1) / (per_edge + 1)  # 0 is the vertex the edge leaves
    bary = np.zeros((m, per_edge + 1, 3))
    rows = np.arange(m)[:, None]
    bary[rows, np.arange(per_edge + 1)[None, :], sa[:, None]] = 1.0 - t[None, :]
    bary[rows, np.arange(per_edge + 1)[None, :], sb[:, None]] += t[None, :]
    last = np.zeros((1, 3))
    last[0, sb[-1]] = 1.0
    faces_out = np.concatenate([np.repeat(face, per_edge + 1), face[-1:]])
    return SurfacePoints(faces_out, np.concatenate([bary.reshape(-1, 3), last]))
