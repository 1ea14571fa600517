"""The validated, immutable triangle mesh every stage works on."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, fields
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import sparse

from meshfit import errors
from meshfit._kernels import geometry as _geometry
from meshfit.mesh import topology
from meshfit.mesh.validate import (
    RepairReport,
    clean_edge_table,
    find_problems,
    raise_first,
    repair_arrays,
)
from meshfit.types import SurfacePoints

if TYPE_CHECKING:
    from meshfit.mesh.locate import ClosestPoints, RayHits, TriangleTree

__all__ = ["Mesh"]

#: edges whose lengths `_lengths` gathers at a time (bounds its temporaries)
LENGTH_CHUNK = 1 << 20


def _frozen(a: NDArray) -> NDArray:
    a = np.array(a, copy=True, order="C")
    a.flags.writeable = False
    return a.view()  # a view of a read-only base cannot be made writeable again


def _sealed(a: NDArray) -> NDArray:
    """An array the mesh derived (held by it alone, or shared with its edge table) made
    read-only in place where numpy owns its memory: unlike `_frozen`, no copy, which over
    a dense scan would double each derived array for a moment."""
    a = np.ascontiguousarray(a)
    root = a
    while isinstance(root.base, np.ndarray):
        root = root.base
    if not root.flags.owndata:  # memory held by another object (e.g. a compiled kernel's
        return _frozen(a)  # result) stays writeable through it: a read-only copy
    root.flags.writeable = False  # (so no view of it can be made writeable again)
    a.flags.writeable = False
    return a.view()


def _as_vertices(vertices: ArrayLike) -> NDArray[np.float64]:
    try:
        v = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise errors.InputError(f"vertices must be numeric: {exc}") from None
    if v.ndim != 2 or v.shape[1] != 3:
        raise errors.InputError(f"vertices must have shape (nv, 3), got {v.shape}")
    return v


def _as_faces(faces: ArrayLike) -> NDArray[np.int64]:
    f = np.asarray(faces)
    if f.size == 0:
        return np.zeros((0, 3), dtype=np.int64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise errors.InputError(
            f"faces must have shape (nf, 3), got {f.shape} "
            "(triangulate polygons first, or load the file with load_mesh)"
        )
    if not np.issubdtype(f.dtype, np.integer):
        if (
            np.issubdtype(f.dtype, np.floating)
            and np.isfinite(f).all()
            and (f == np.round(f)).all()
        ):
            f = f.astype(np.int64)
        else:
            raise errors.InputError(f"faces must hold integer vertex indices, got dtype {f.dtype}")
    return f.astype(np.int64, copy=False)


def _as_colors(colors: ArrayLike | None, nv: int) -> NDArray[np.uint8] | None:
    if colors is None:
        return None
    c = np.asarray(colors)
    if c.ndim != 2 or c.shape[0] != nv or c.shape[1] not in (3, 4):
        raise errors.InputError(f"vertex_colors must have shape ({nv}, 3 or 4), got {c.shape}")
    if c.dtype != np.uint8:
        if np.issubdtype(c.dtype, np.floating) and c.size and c.max() <= 1.0:
            c = np.round(c * 255.0)
        c = np.clip(c, 0, 255).astype(np.uint8)
    return c


def _lengths(V: NDArray[np.float64], e: NDArray[np.int64]) -> NDArray[np.float64]:
    """Lengths of the segments ``V[e[:, 0]] V[e[:, 1]]``, `LENGTH_CHUNK` rows at a time: on a
    dense scan the end points of every edge gathered at once are over a gigabyte."""
    out = np.empty(e.shape[0])
    for a in range(0, e.shape[0], LENGTH_CHUNK):
        ee = e[a : a + LENGTH_CHUNK]
        d = V[ee[:, 1]] - V[ee[:, 0]]
        # the sum np.linalg.norm forms, without its temporaries
        out[a : a + LENGTH_CHUNK] = np.sqrt(
            d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
        )
    return out


@dataclass(frozen=True, eq=False)
class Mesh:
    """A validated manifold triangle mesh with read-only arrays and cached adjacency.

    Construct with ``Mesh(vertices, faces)`` (raises the first validation problem as a
    :class:`meshfit.errors.MeshValidationError`) or ``Mesh.from_arrays(..., repair=True)``.

    Parameters
    ----------
    vertices : (nv, 3) float64
        Vertex positions, model units.
    faces : (nf, 3) int64
        Counter-clockwise triangles (consistently oriented).
    vertex_colors : (nv, 3 | 4) uint8, optional
        Per-vertex RGB(A) colours.
    name : str
        A label (the file name when loaded).
    repairs : RepairReport, optional
        Set by ``repair=True``: index maps from the input arrays to this mesh.

    Notes
    -----
    Edge ``k`` of face ``f`` joins ``faces[f, k]`` and ``faces[f, (k + 1) % 3]``;
    ``face_neighbors[f, k]`` is the face across it, -1 on the boundary.
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    vertex_colors: NDArray[np.uint8] | None = None
    name: str = ""
    repairs: RepairReport | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        v = _as_vertices(self.vertices)
        f = _as_faces(self.faces)
        c = _as_colors(self.vertex_colors, v.shape[0])
        table = clean_edge_table(v, f)
        if table is None:
            raise_first(find_problems(v, f), where=self.name)
        object.__setattr__(self, "vertices", _frozen(v))
        object.__setattr__(self, "faces", _frozen(f))
        object.__setattr__(self, "vertex_colors", None if c is None else _frozen(c))
        if table is not None:  # the cached property's value, computed by the check
            object.__setattr__(self, "_edge_table", table)

    def with_name(self, name: str) -> Mesh:
        """The same mesh under another name, without checking it again.

        Parameters
        ----------
        name : str

        Returns
        -------
        Mesh
            Sharing this mesh's frozen arrays (``vertices (nv, 3) float64``, ``faces (nf, 3)
            int64``, colours) and everything already derived from them (edge table, search
            tree, ...); e.g. a region checked under a provisional name becomes a named patch
            (Krishnamurthy 2000, sec. 1.3) at no cost.
        """
        out = object.__new__(Mesh)
        out.__dict__.update(self.__dict__)
        object.__setattr__(out, "name", str(name))
        return out

    @classmethod
    def from_arrays(
        cls,
        vertices: ArrayLike,
        faces: ArrayLike,
        vertex_colors: ArrayLike | None = None,
        *,
        name: str = "",
        repair: bool = False,
    ) -> Mesh:
        """Build a mesh, optionally repairing what can be repaired first.

        Parameters
        ----------
        vertices : (nv, 3) float64
        faces : (nf, 3) int64
        vertex_colors : (nv, 3 | 4) uint8, optional
        name : str
        repair : bool
            Drop degenerate / duplicate / back-to-back faces and unreferenced vertices, split
            non-manifold edges and vertices apart, make the orientation consistent and turn
            inside-out closed components right side out
            (:func:`meshfit.mesh.validate.repair_arrays`); the index maps are in
            ``mesh.repairs``.
        """
        v = _as_vertices(vertices)
        f = _as_faces(faces)
        c = _as_colors(vertex_colors, v.shape[0])
        if not repair:
            return cls(v, f, c, name=name)
        try:
            v, f, c, report = repair_arrays(v, f, c)
        except errors.MeshValidationError as exc:
            raise type(exc)(
                f"{name}: {exc}" if name else str(exc), first=exc.first, count=exc.count
            ) from None
        return cls(v, f, c, name=name, repairs=report)

    # ------------------------------------------------------------------ sizes
    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    def __repr__(self) -> str:
        label = f"{self.name!r}, " if self.name else ""
        return f"Mesh({label}{self.n_vertices} vertices, {self.n_faces} faces)"

    def drop_caches(self, keep: Iterable[str] = ()) -> None:
        """Forget what was derived from the arrays (edge table, adjacency, normals, search
        trees, ...) except the names in ``keep`` and the bounding box; each is derived again
        on its next use. Over a dense scan these take several times the arrays' own memory,
        so a fit drops what its later stages do not read (meshes made by :meth:`with_name`
        keep their own references).

        Parameters
        ----------
        keep : iterable of str
            Names of cached values to keep, e.g. ``"triangle_tree"``, ``"face_normals"``.
        """
        kept = {*keep, "bbox", "bbox_diagonal", "mean_edge_length"}
        own = {f.name for f in fields(self)}
        for name in [k for k in self.__dict__ if k not in own and k not in kept]:
            self.__dict__.pop(name, None)

    # ------------------------------------------------------------- connectivity
    @cached_property
    def _edge_table(self) -> topology.EdgeTable:
        return topology.edge_table(self.faces, self.n_vertices)

    @cached_property
    def edges(self) -> NDArray[np.int64]:
        """(ne, 2) int64: unique undirected edges, smaller index first."""
        return _sealed(self._edge_table.edges)

    @cached_property
    def face_edges(self) -> NDArray[np.int64]:
        """(nf, 3) int64: edge id of edge k of each face (row of :attr:`edges`)."""
        return _sealed(self._edge_table.halfedge_edge.reshape(-1, 3))

    @cached_property
    def edge_keys(self) -> NDArray[np.int64]:
        """(ne,) int64: ``a * nv + b`` of each edge (a, b) of :attr:`edges`, ascending (edge
        ids of vertex pairs by ``searchsorted``)."""
        e = self.edges
        return _sealed(e[:, 0] * np.int64(max(self.n_vertices, 1)) + e[:, 1])

    @cached_property
    def edge_face(self) -> NDArray[np.int64]:
        """(ne,) int64: one face holding each edge (the highest-numbered one)."""
        out = np.empty(self.edges.shape[0], dtype=np.int64)
        out[self.face_edges.reshape(-1)] = np.repeat(np.arange(self.n_faces), 3)
        return _sealed(out)

    @cached_property
    def edge_face_count(self) -> NDArray[np.int64]:
        """(ne,) int64: 1 on the boundary, 2 inside."""
        return _sealed(self._edge_table.edge_count)

    @cached_property
    def face_neighbors(self) -> NDArray[np.int64]:
        """(nf, 3) int64: face across edge k = (F[f,k], F[f,(k+1)%3]); -1 on the boundary."""
        return _sealed(topology.face_neighbors(self.faces, self._edge_table))

    @cached_property
    def _vertex_adjacency(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        indptr, indices = topology.vertex_adjacency(self.edges, self.n_vertices)
        return _sealed(indptr), _sealed(indices)

    @property
    def vertex_adjacency(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """CSR ``(indptr (nv+1,), indices (2 ne,))`` int64: neighbours of vertex i are
        ``indices[indptr[i]:indptr[i+1]]``, sorted."""
        return self._vertex_adjacency

    def vertex_neighbors(self, vertex: int) -> NDArray[np.int64]:
        """(k,) int64: the vertices joined to ``vertex`` by an edge."""
        indptr, indices = self.vertex_adjacency
        return indices[indptr[vertex] : indptr[vertex + 1]]

    @cached_property
    def _vertex_faces(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        indptr, faces = topology.vertex_faces(self.faces, self.n_vertices)
        return _sealed(indptr), _sealed(faces)

    @property
    def vertex_faces(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """CSR ``(indptr (nv+1,), faces (3 nf,))`` int64: faces around each vertex."""
        return self._vertex_faces

    @cached_property
    def edge_graph(self) -> sparse.csr_matrix:
        """(nv, nv) sparse matrix of edge lengths (symmetric), for graph searches."""
        e = self.edges
        w = self.edge_lengths
        n = self.n_vertices
        return sparse.csr_matrix(
            (
                np.concatenate([w, w]),
                (np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]])),
            ),
            shape=(n, n),
        )

    def quantized_edge_graph(self) -> sparse.csr_matrix:
        """(nv, nv) sparse matrix of edge lengths in whole units of ``tol.GRAPH_QUANTUM``
        mean edge lengths (at least one), symmetric.

        Path lengths over it are sums of integers, exact: equal paths tie exactly, so every
        choice made from graph distances (a farthest vertex, an order of faces) is the same
        after any rotation, translation or scaling of the mesh, where rounding in the
        coordinates would otherwise break a symmetric mesh's ties one way or the other."""
        from meshfit import tol

        g = self.edge_graph.copy()
        g.data = np.maximum(np.round(g.data / tol.length(self, tol.GRAPH_QUANTUM)), 1.0)
        return g

    @cached_property
    def boundary_loops(self) -> list[NDArray[np.int64]]:
        """Boundary loops, each a ``(k,) int64`` vertex array in half-edge order."""
        return [_sealed(loop) for loop in topology.boundary_loops(self.faces, self._edge_table)]

    @cached_property
    def _components(self) -> tuple[int, NDArray[np.int64]]:
        n, labels = topology.face_components(self.n_faces, self.face_neighbors)
        return n, _sealed(labels)

    @property
    def n_components(self) -> int:
        """Number of edge-connected components."""
        return self._components[0]

    @property
    def face_components(self) -> NDArray[np.int64]:
        """(nf,) int64: component label of each face, in ``[0, n_components)``."""
        return self._components[1]

    @cached_property
    def vertex_components(self) -> NDArray[np.int64]:
        """(nv,) int64: component label of each vertex."""
        out = np.empty(self.n_vertices, dtype=np.int64)
        out[self.faces.reshape(-1)] = np.repeat(self.face_components, 3)
        return _sealed(out)

    @property
    def euler_characteristic(self) -> int:
        """V - E + F."""
        return self.n_vertices - int(self.edges.shape[0]) + self.n_faces

    @property
    def genus(self) -> int:
        """(2 c - chi - b) / 2 over all components (c components, b boundary loops)."""
        return (2 * self.n_components - self.euler_characteristic - len(self.boundary_loops)) // 2

    @property
    def is_closed(self) -> bool:
        """True when no edge is a boundary edge."""
        return not bool((self.edge_face_count == 1).any())

    # ---------------------------------------------------------------- geometry
    @cached_property
    def _face_cross(self) -> NDArray[np.float64]:
        return _geometry.face_cross(self.vertices, self.faces)

    @cached_property
    def face_areas(self) -> NDArray[np.float64]:
        """(nf,) float64: triangle areas, model units squared."""
        return _sealed(0.5 * np.linalg.norm(self._face_cross, axis=1))

    @cached_property
    def face_normals(self) -> NDArray[np.float64]:
        """(nf, 3) float64: unit normals (right-handed with the face winding)."""
        return _sealed(self._face_cross / (2.0 * self.face_areas[:, None]))

    @cached_property
    def vertex_normals(self) -> NDArray[np.float64]:
        """(nv, 3) float64: unit vertex normals, the area-weighted mean of the face normals
        around each vertex (a vertex on no face gets a zero row)."""
        # face normals times twice the face areas, summed around each vertex
        acc = _geometry.vertex_sums(self.faces, self._face_cross, self.n_vertices)
        ln = np.linalg.norm(acc, axis=1, keepdims=True)
        return _sealed(acc / np.where(ln > 0, ln, 1.0))

    @cached_property
    def edge_lengths(self) -> NDArray[np.float64]:
        """(ne,) float64: length of each row of :attr:`edges`."""
        return _sealed(_lengths(self.vertices, self.edges))

    def lengths_of(self, edges: NDArray[np.int64]) -> NDArray[np.float64]:
        """Lengths of some edges, without making :attr:`edge_lengths` for all of them (read
        from it when it is cached): on a dense scan a few sharp edges need not cost a
        length per edge.

        Parameters
        ----------
        edges : (k,) int64 or (ne,) bool
            Rows of :attr:`edges`.

        Returns
        -------
        (k,) float64
        """
        if "edge_lengths" in vars(self):
            return self.edge_lengths[edges]
        return _lengths(self.vertices, self.edges[edges])

    @cached_property
    def mean_edge_length(self) -> float:
        return float(self.edge_lengths.mean())

    @cached_property
    def bbox(self) -> NDArray[np.float64]:
        """(2, 3) float64: minimum and maximum corner."""
        return _sealed(np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)]))

    @cached_property
    def bbox_diagonal(self) -> float:
        return float(np.linalg.norm(self.bbox[1] - self.bbox[0]))

    @property
    def area(self) -> float:
        return float(self.face_areas.sum())

    def xyz(self, points: SurfacePoints) -> NDArray[np.float64]:
        """(n, 3) float64 positions of face points."""
        return np.einsum("ij,ijk->ik", points.bary, self.vertices[self.faces[points.face]])

    # ------------------------------------------------------------ tree queries
    @cached_property
    def triangle_tree(self) -> TriangleTree:
        """The bounding-volume hierarchy over the faces that :meth:`closest_points` searches,
        built on first use and kept, read-only (see :func:`meshfit.mesh.locate.build_tree`)."""
        from meshfit.mesh.locate import build_tree

        tree = build_tree(self.vertices, self.faces)
        for a in tree:
            a.flags.writeable = False
        return tree

    @cached_property
    def aabb(self):
        """The ``igl.AABB`` tree over the faces that :meth:`ray_first_hit` uses, built on first
        use and kept."""
        from meshfit.mesh.locate import build_aabb

        return build_aabb(self)

    def closest_points(self, xyz: ArrayLike) -> ClosestPoints:
        """Closest surface point to each query; see :func:`meshfit.mesh.locate.closest_points`."""
        from meshfit.mesh.locate import closest_points

        return closest_points(self, xyz)

    def ray_first_hit(self, origins: ArrayLike, directions: ArrayLike) -> RayHits:
        """First hit along each ray; see :func:`meshfit.mesh.locate.ray_first_hit`."""
        from meshfit.mesh.locate import ray_first_hit

        return ray_first_hit(self, origins, directions)
