"""Connectivity tables computed from face arrays alone (no geometry, no validation).

All functions take ``faces (nf, 3) int64`` with indices in ``[0, nv)``. Half-edge ``3 f + k``
of face ``f`` runs from ``faces[f, k]`` to ``faces[f, (k + 1) % 3]``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from meshfit._kernels import frozen
from meshfit._kernels import topology as _k
from meshfit.errors import InputError

__all__ = ["EdgeTable", "corner_fans", "edge_table", "vertex_adjacency", "vertex_faces"]


@dataclass(frozen=True)
class EdgeTable:
    """Undirected edges and how half-edges map onto them.

    Attributes
    ----------
    edges : (ne, 2) int64
        Unique undirected edges, ``edges[:, 0] < edges[:, 1]``.
    halfedge_edge : (3 nf,) int64
        Edge id of each half-edge.
    edge_count : (ne,) int64
        Number of faces using each edge (1: boundary, 2: interior, >2: non-manifold).
    order : (3 nf,) int64
        Half-edges sorted by edge id (stable), so the half-edges of edge e are
        ``order[start[e]:start[e] + edge_count[e]]``.
    start : (ne,) int64
        Offsets into ``order``.
    """

    edges: NDArray[np.int64]
    halfedge_edge: NDArray[np.int64]
    edge_count: NDArray[np.int64]
    order: NDArray[np.int64]
    start: NDArray[np.int64]

    def halfedges_of(self, edge: int) -> NDArray[np.int64]:
        s = self.start[edge]
        return self.order[s : s + self.edge_count[edge]]


def halfedges(faces: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Tail and head vertex of every half-edge, each ``(3 nf,) int64``."""
    tail = faces.reshape(-1)
    head = np.roll(faces, -1, axis=1).reshape(-1)
    return tail, head


def edge_table(faces: NDArray[np.int64], n_vertices: int) -> EdgeTable:
    """Build the undirected edge table of a triangle list (a linear-time kernel: a counting
    sort of the half-edges by their smaller vertex).

    Parameters
    ----------
    faces : (nf, 3) int64
        Triangles with indices in ``[0, n_vertices)``.
    n_vertices : int
        Number of vertices.
    """
    (f,) = frozen(np.ascontiguousarray(faces, dtype=np.int64))  # (one signature)
    edges, inverse, counts, order, start = _k.edge_table(f, int(n_vertices))
    # numpy-owned copies of the arrays a mesh hands out (``edges``, ``face_edges``,
    # ``edge_face_count``): a mesh can seal those in place instead of keeping a read-only
    # copy of each beside the table (memory a kernel's result owns stays writeable)
    edges, inverse, counts = (np.array(a) for a in (edges, inverse, counts))
    return EdgeTable(edges, inverse, counts, order, start)


def vertex_faces(
    faces: NDArray[np.int64], n_vertices: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Faces around each vertex as CSR ``(indptr (nv + 1,), faces (3 nf,))`` int64, each
    vertex's faces ascending (a linear-time counting sort).

    Raises
    ------
    meshfit.errors.InputError
        ``faces`` not ``(nf, 3)``, or an index outside ``[0, n_vertices)``.
    """
    (f,) = frozen(_indices(faces, n_vertices, "faces"))
    return _k.vertex_faces(f, int(n_vertices))


def vertex_adjacency(
    edges: NDArray[np.int64], n_vertices: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Neighbours of each vertex as CSR ``(indptr (nv + 1,), indices (2 ne,))`` int64, each
    row ascending, from unique undirected edges (rows of :attr:`EdgeTable.edges`).

    Raises
    ------
    meshfit.errors.InputError
        ``edges`` not ``(ne, 2)``, or an index outside ``[0, n_vertices)``.
    """
    (e,) = frozen(_indices(edges, n_vertices, "edges"))
    return _k.vertex_adjacency(e, int(n_vertices))


def _indices(a, n_vertices: int, name: str) -> NDArray[np.int64]:
    """``a`` as contiguous int64 rows of vertex indices (3 for faces, 2 for edges), checked
    to lie in ``[0, n_vertices)``: the kernels index with them unchecked."""
    out = np.ascontiguousarray(a, dtype=np.int64)
    width = 3 if name == "faces" else 2
    if out.ndim != 2 or out.shape[1] != width:
        raise InputError(f"{name} must have shape (n, {width}), got {out.shape}")
    if out.size and (out.min() < 0 or out.max() >= int(n_vertices)):
        raise InputError(f"{name}: an index is outside 0..{int(n_vertices) - 1}")
    return out


def face_neighbors(faces: NDArray[np.int64], table: EdgeTable) -> NDArray[np.int64]:
    """Neighbour across each face edge, ``(nf, 3) int64``, -1 where the edge is a boundary or
    non-manifold edge. Edge k of face f joins ``faces[f, k]`` and ``faces[f, (k + 1) % 3]``."""
    nf = faces.shape[0]
    out = np.full(3 * nf, -1, dtype=np.int64)
    two = np.flatnonzero(table.edge_count == 2)
    a = table.order[table.start[two]]
    b = table.order[table.start[two] + 1]
    out[a] = b // 3
    out[b] = a // 3
    return out.reshape(nf, 3)


def corner_fans(
    faces: NDArray[np.int64],
    n_vertices: int,
    table: EdgeTable,
    cut_edges: NDArray[np.bool_] | None = None,
) -> tuple[NDArray[np.int64], int]:
    """Group the corners around each vertex into fans of faces joined across shared edges.

    Two corners of the same vertex belong to one fan when their faces share a manifold edge
    incident to that vertex (and the edge is not marked in ``cut_edges``). A vertex whose
    corners form more than one fan is non-manifold (a bow-tie), or lies on a cut.

    Parameters
    ----------
    faces : (nf, 3) int64
    n_vertices : int
    table : EdgeTable
        From :func:`edge_table` on the same faces.
    cut_edges : (ne,) bool, optional
        Edges across which corners are not joined.

    Returns
    -------
    fan : (3 nf,) int64
        Fan label of each corner (``3 f + k`` is the corner of ``faces[f, k]``), labels
        global over the mesh.
    n_fans : int
        Number of distinct fans.
    """
    nc = faces.size
    join = table.edge_count == 2
    if cut_edges is not None:
        join = join & ~cut_edges
    two = np.flatnonzero(join)
    ha = table.order[table.start[two]]
    hb = table.order[table.start[two] + 1]

    # half-edge h = 3f+k has corners (3f+k) at its tail and (3f+(k+1)%3) at its head
    def tail_corner(h):
        return h

    def head_corner(h):
        return 3 * (h // 3) + (h % 3 + 1) % 3

    corner_vertex = faces.reshape(-1)
    # the two half-edges may run in opposite or (badly oriented) equal directions: match by vertex
    a_tail, a_head = tail_corner(ha), head_corner(ha)
    b_tail, b_head = tail_corner(hb), head_corner(hb)
    same = corner_vertex[a_tail] == corner_vertex[b_tail]
    r1 = np.concatenate([a_tail, a_head])
    c1 = np.concatenate([np.where(same, b_tail, b_head), np.where(same, b_head, b_tail)])
    n, labels = _k.components(nc, r1, c1)
    return labels, int(n)


def face_components(n_faces: int, neighbors: NDArray[np.int64]) -> tuple[int, NDArray[np.int64]]:
    """Connected components of faces joined across manifold edges."""
    g = np.ascontiguousarray(neighbors, dtype=np.int64).reshape(int(n_faces), -1)
    n, labels = _k.neighbor_components(g)
    return int(n), labels


def boundary_loops(faces: NDArray[np.int64], table: EdgeTable) -> list[NDArray[np.int64]]:
    """Boundary loops as vertex index arrays, each in the order of its half-edges.

    A boundary vertex met by more than one loop (a pinch) ends the trace of the loop it
    closes; every boundary half-edge is used exactly once.
    """
    bnd = np.flatnonzero(table.edge_count == 1)
    if bnd.size == 0:
        return []
    he = table.order[table.start[bnd]]
    tail, head = halfedges(faces)
    t, h = tail[he], head[he]
    # successor: the unused boundary half-edge of lowest index leaving the head vertex
    nv = int(max(t.max(), h.max())) + 1
    out, starts = _k.trace_loops(np.ascontiguousarray(t), np.ascontiguousarray(h), nv)
    return [out[a:b].copy() for a, b in itertools.pairwise(starts)]
