"""Closest-point and ray queries on a mesh.

Closest points are answered by the project's bounding-volume hierarchy
(:mod:`meshfit._kernels.bvh`, one tree per mesh, searched on all cores), first ray hits by
one ``igl.AABB`` tree per mesh.
"""

from __future__ import annotations

import atexit
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from meshfit._validate import as_points, as_vectors
from meshfit.errors import InputError
from meshfit.types import SurfacePoints

if TYPE_CHECKING:
    from meshfit.mesh.core import Mesh

__all__ = [
    "ClosestPoints",
    "RayHits",
    "TriangleTree",
    "barycentric",
    "closest_points",
    "query_order",
    "ray_first_hit",
    "triangle_distances",
    "triangles_within",
]


#: meshes holding an ``igl.AABB`` tree (``mesh.aabb``), whose trees are dropped at exit
_WITH_AABB: weakref.WeakSet = weakref.WeakSet()


def _drop_aabb_trees() -> None:
    """Free the ``igl.AABB`` trees of meshes still alive at interpreter exit: a tree freed
    after libigl's bindings are torn down is reported by nanobind as a leak (a mesh kept
    by a daemon thread, e.g. the web app's session)."""
    for mesh in list(_WITH_AABB):
        mesh.__dict__.pop("aabb", None)


atexit.register(_drop_aabb_trees)


def build_aabb(mesh: Mesh):
    """Build the ``igl.AABB`` tree of ``mesh`` (called once, through ``mesh.aabb``)."""
    import igl

    tree = igl.AABB()
    tree.init(mesh.vertices, mesh.faces)
    _WITH_AABB.add(mesh)
    return tree


class TriangleTree(NamedTuple):
    """Bounding-volume hierarchy over the triangles of one vertex and face array, as the
    kernels of :mod:`meshfit._kernels.bvh` take it (see :func:`build_tree`).

    Attributes
    ----------
    flat : (m,) bool
        Triangles of zero area (searched as their three edges).
    order : (m,) int64
        Triangles in tree order; node ``k`` holds ``order[start[k]:stop[k]]``.
    lo, hi : (k, 3) float64
        Box of each node.
    child : (k,) int64
        First child of each node (the second is ``child + 1``), -1 for a leaf.
    start, stop : (k,) int64
        Range of ``order`` under each node. Node 0 is the root.
    """

    flat: NDArray[np.bool_]
    order: NDArray[np.int64]
    lo: NDArray[np.float64]
    hi: NDArray[np.float64]
    child: NDArray[np.int64]
    start: NDArray[np.int64]
    stop: NDArray[np.int64]


def build_tree(
    vertices: NDArray[np.float64], faces: NDArray[np.int64], *, leaf_size: int | None = None
) -> TriangleTree:
    """Build the bounding-volume hierarchy over validated triangles.

    Parameters
    ----------
    vertices : (k, 3) float64
        Finite coordinates.
    faces : (m, 3) int64
        Triangles, ``m >= 1``, indices in range.
    leaf_size : int, optional
        Most triangles per leaf; :data:`meshfit._kernels.bvh.LEAF_SIZE` by default.

    Returns
    -------
    TriangleTree
        Triangles in the Morton order of their centroids, split at the median centroid along
        the longest axis down to ``leaf_size`` per leaf.

    Raises
    ------
    meshfit.errors.InputError
        ``leaf_size`` below 1.
    """
    from meshfit._kernels import bvh, frozen

    size = bvh.LEAF_SIZE if leaf_size is None else int(leaf_size)
    if size < 1:
        raise InputError(f"leaf_size must be >= 1, got {leaf_size}")
    order = np.argsort(bvh.morton_codes(vertices, faces), kind="stable")
    order, lo, hi, child, start, stop = bvh.build(vertices, faces, order, size)
    return TriangleTree(bvh.zero_area(*frozen(vertices, faces)), order, lo, hi, child, start, stop)


def grid_tree(
    vertices: NDArray[np.float64], faces: NDArray[np.int64], shapes: ArrayLike
) -> TriangleTree:
    """Build the bounding-volume hierarchy over a soup of grids without sorting triangles.

    For the triangulations of stacked row-major grids (:func:`meshfit.springs.grid_triangles`
    of each grid, offset by the points before it; e.g. spline or displaced patch grids):
    the grids are split at the median of their centroids, each grid's cells in halves
    across its longer index direction down to single cells. Searches are exact for any
    ``faces`` of the right count (each box holds its triangles as ``faces`` gives them); the
    tree is tight when ``faces`` are laid out as above.

    Parameters
    ----------
    vertices : (k, 3) float64
        Finite coordinates: the grids' points, grid after grid.
    faces : (m, 3) int64
        The grids' triangles, ``m = sum 2 (nu - 1) (nv - 1)``.
    shapes : (n, 2) int
        Each grid's ``(nu, nv)``, every one at least 2 x 2.

    Returns
    -------
    TriangleTree

    Raises
    ------
    meshfit.errors.InputError
        No grid, a grid under 2 x 2, or a face count that does not match the shapes.
    """
    from meshfit._kernels import bvh, frozen

    sh = np.asarray(shapes, dtype=np.int64).reshape(-1, 2)
    if sh.shape[0] == 0 or (sh < 2).any():
        raise InputError(f"grid shapes must be (n >= 1, 2) with every size >= 2, got {sh.tolist()}")
    tris = 2 * (sh[:, 0] - 1) * (sh[:, 1] - 1)
    if int(tris.sum()) != faces.shape[0]:
        raise InputError(
            f"the grid shapes have {int(tris.sum())} triangles, faces {faces.shape[0]}"
        )
    pts = sh[:, 0] * sh[:, 1]
    vbase = np.concatenate([[0], np.cumsum(pts)])
    if vbase[-1] != vertices.shape[0]:
        raise InputError(
            f"the grid shapes have {int(vbase[-1])} points, vertices {vertices.shape[0]}"
        )
    tbase = np.concatenate([[0], np.cumsum(tris)[:-1]]).astype(np.int64)
    centroid = np.add.reduceat(vertices, vbase[:-1], axis=0) / pts[:, None]
    order, lo, hi, child, start, stop = bvh.build_grids(
        *frozen(vertices, faces, sh, tbase, centroid)
    )
    return TriangleTree(bvh.zero_area(*frozen(vertices, faces)), order, lo, hi, child, start, stop)


def triangle_distances(
    points: ArrayLike,
    vertices: ArrayLike,
    faces: ArrayLike,
    *,
    tree: TriangleTree | None = None,
    qorder: NDArray[np.int64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Distance from each point to the nearest of a set of triangles (any soup: no
    connectivity is needed), on all cores.

    A bounding-volume hierarchy is built over the triangles (Morton order of their centroids,
    :mod:`meshfit._kernels.bvh`) and searched per point in parallel; unlike one-off queries
    through ``igl.point_mesh_squared_distance`` it releases the GIL and uses every core.

    Parameters
    ----------
    points : (n, 3) float64
        Query points.
    vertices : (k, 3) float64
    faces : (m, 3) int64
        Triangles; ``m >= 1``.
    tree : TriangleTree, keyword-only, optional
        A tree already built over these ``vertices`` and ``faces`` (e.g.
        :attr:`meshfit.mesh.Mesh.triangle_tree` with the mesh's arrays); default: build one.
    qorder : (n,) int64, keyword-only, optional
        `query_order` of these ``points``, when one set of points is searched in several
        soups; default: computed here. Any permutation gives the same distances; the
        kernel indexes with it, so anything else is refused.

    Returns
    -------
    distance : (n,) float64
        Euclidean distance to the nearest triangle.
    face : (n,) int64
        That triangle.

    Raises
    ------
    meshfit.errors.InputError
        Points or vertices not (k, 3) finite numbers, no faces, a face index out of range, a
        ``tree`` over another number of triangles, a ``qorder`` that is not a permutation of
        the points' indices.

    References
    ----------
    .. [1] Ericson, "Real-Time Collision Detection", 2005, sec. 5.1.5 (closest point on a
       triangle) and ch. 6 (bounding-volume hierarchies).
    """
    from meshfit._kernels import bvh, frozen

    Q, V, F, tree = _soup_query(points, vertices, faces, tree)
    if Q.shape[0] == 0:
        return np.empty(0), np.empty(0, dtype=np.int64)
    qorder = query_order(Q) if qorder is None else _permutation(qorder, Q.shape[0])
    sq, face, _ = bvh.closest_points(*frozen(V, F, *tree, Q, qorder))
    return np.sqrt(sq), face


def _permutation(order: ArrayLike, n: int) -> NDArray[np.int64]:
    """``order`` as int64 when it is a permutation of ``range(n)`` (a kernel indexes the
    points with it unchecked); else InputError."""
    q = np.asarray(order)
    ok = q.shape == (n,) and np.issubdtype(q.dtype, np.integer)
    if ok and n:
        ok = bool(q.min() >= 0 and q.max() < n and (np.bincount(q, minlength=n) == 1).all())
    if not ok:
        raise InputError(f"qorder must be a permutation of the {n} points' indices")
    return np.ascontiguousarray(q, dtype=np.int64)


def query_order(points: NDArray[np.float64]) -> NDArray[np.int64]:
    """The order in which the tree searches take a set of query points: their Morton order in
    their own bounding box, so consecutive queries are near each other and each search
    starts from the last one's answer. Made once, it serves every soup the same points are
    searched in (`triangle_distances`' ``qorder``).

    Parameters
    ----------
    points : (n, 3) float64
        Finite query points.

    Returns
    -------
    (n,) int64
        A permutation of ``range(n)`` (stable for equal codes).

    References
    ----------
    .. [1] Morton, "A computer oriented geodetic data base and a new technique in file
       sequencing", IBM, 1966 (the order); Ericson, "Real-Time Collision Detection", 2005,
       ch. 6 (bounding-volume hierarchies).
    """
    from meshfit._kernels import bvh, frozen

    Q = np.ascontiguousarray(points, dtype=np.float64)
    return np.argsort(bvh.point_morton_codes(*frozen(Q)), kind="stable")


def triangles_within(
    points: ArrayLike,
    vertices: ArrayLike,
    faces: ArrayLike,
    radius: float,
    *,
    tree: TriangleTree | None = None,
) -> NDArray[np.bool_]:
    """Whether each point has one of a set of triangles within ``radius``, on all cores.

    The yes-or-no form of :func:`triangle_distances` (the same distances, compared as
    squares with ``radius**2``): each search stops at the first triangle within the radius,
    so with a radius of a few spacings of a surface near the points most take one triangle
    test instead of a full descent of the tree.

    Parameters
    ----------
    points : (n, 3) float64
    vertices : (k, 3) float64
    faces : (m, 3) int64
        Triangles; ``m >= 1``.
    radius : float
        A finite distance >= 0.
    tree : TriangleTree, keyword-only, optional
        As for :func:`triangle_distances`.

    Returns
    -------
    (n,) bool

    Raises
    ------
    meshfit.errors.InputError
        As :func:`triangle_distances`, or a negative or non-finite radius.

    References
    ----------
    .. [1] Ericson, "Real-Time Collision Detection", 2005, ch. 6 (bounding-volume
       hierarchies).
    """
    from meshfit._kernels import bvh, frozen

    r = float(radius)
    if not (np.isfinite(r) and r >= 0.0):
        raise InputError(f"radius must be a finite distance >= 0, got {radius}")
    Q, V, F, tree = _soup_query(points, vertices, faces, tree)
    if Q.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    qorder = np.argsort(bvh.point_morton_codes(*frozen(Q)), kind="stable")
    return bvh.within(*frozen(V, F, *tree, Q, qorder), r * r)


def _soup_query(points, vertices, faces, tree):
    """Checked query points, vertices, faces and a tree over the triangles (built when
    ``tree`` is None) of the soup queries."""
    Q = as_points(points, name="points")
    V = as_points(vertices, name="vertices")
    F = np.ascontiguousarray(faces, dtype=np.int64)
    if F.ndim != 2 or F.shape[1] != 3 or F.shape[0] == 0:
        raise InputError(f"faces must have shape (m >= 1, 3), got {F.shape}")
    if F.min() < 0 or F.max() >= V.shape[0]:
        raise InputError(f"a face index is out of range 0..{V.shape[0] - 1}")
    if tree is None:
        tree = build_tree(V, F)
    elif tree.order.shape[0] != F.shape[0]:
        raise InputError(f"tree has {tree.order.shape[0]} triangles, faces {F.shape[0]}")
    return Q, V, F, tree


def barycentric(
    mesh: Mesh, face: NDArray[np.int64], xyz: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Barycentric coordinates of points in the planes of the given faces.

    Parameters
    ----------
    mesh : Mesh
    face : (n,) int64
    xyz : (n, 3) float64
        Points, projected orthogonally onto each face's plane.

    Returns
    -------
    (n, 3) float64
        Coordinates summing to 1 (not clipped: negative outside the triangle).
    """
    p = mesh.vertices[mesh.faces[face]]
    e1 = p[:, 1] - p[:, 0]
    e2 = p[:, 2] - p[:, 0]
    d = xyz - p[:, 0]
    a11 = np.einsum("ij,ij->i", e1, e1)
    a12 = np.einsum("ij,ij->i", e1, e2)
    a22 = np.einsum("ij,ij->i", e2, e2)
    b1 = np.einsum("ij,ij->i", d, e1)
    b2 = np.einsum("ij,ij->i", d, e2)
    det = a11 * a22 - a12 * a12
    u = (a22 * b1 - a12 * b2) / det
    v = (a11 * b2 - a12 * b1) / det
    return np.stack([1.0 - u - v, u, v], axis=1)


def _clip_bary(b: NDArray[np.float64]) -> NDArray[np.float64]:
    b = np.clip(b, 0.0, None)
    return b / b.sum(axis=1, keepdims=True)


@dataclass(frozen=True)
class ClosestPoints:
    """Result of :func:`closest_points`.

    Attributes
    ----------
    points : SurfacePoints
        Closest face point of each query.
    distance : (n,) float64
        Euclidean distance, model units.
    xyz : (n, 3) float64
        The closest positions.
    """

    points: SurfacePoints
    distance: NDArray[np.float64]
    xyz: NDArray[np.float64]


def closest_points(mesh: Mesh, xyz: ArrayLike) -> ClosestPoints:
    """Closest point on the surface to each query point, on all cores.

    The mesh's bounding-volume hierarchy (``mesh.triangle_tree``, built on first use and kept
    with the mesh) is searched per point in parallel; the closest point on each triangle is
    exact (Ericson's region test [1]_). Where the closest point lies on an edge or vertex
    shared by several faces, the face reported is one of them.

    Parameters
    ----------
    mesh : Mesh
    xyz : (n, 3) float64
        Query points, model units.

    Returns
    -------
    ClosestPoints
        ``points`` with barycentrics ``>= 0`` summing to 1 (exact zeros on the far side of a
        clamped edge or vertex), ``distance``, and ``xyz = mesh.xyz(points)``.

    Raises
    ------
    meshfit.errors.InputError
        Query points not (n, 3) finite numbers.

    References
    ----------
    .. [1] Ericson, "Real-Time Collision Detection", 2005, sec. 5.1.5 (closest point on a
       triangle) and ch. 6 (bounding-volume hierarchies).
    """
    from meshfit._kernels import bvh, frozen

    q = as_points(xyz, name="xyz")
    if q.shape[0] == 0:
        return ClosestPoints(
            SurfacePoints(np.zeros(0, np.int64), np.zeros((0, 3))), np.zeros(0), np.zeros((0, 3))
        )
    qorder = np.argsort(bvh.point_morton_codes(*frozen(q)), kind="stable")
    sq, face, bary = bvh.closest_points(
        *frozen(mesh.vertices, mesh.faces, *mesh.triangle_tree, q, qorder)
    )
    pts = SurfacePoints(face, bary)
    return ClosestPoints(pts, np.sqrt(sq), mesh.xyz(pts))


@dataclass(frozen=True)
class RayHits:
    """Result of :func:`ray_first_hit`.

    Attributes
    ----------
    hit : (n,) bool
        Whether each ray met the surface.
    t : (n,) float64
        Ray parameter of the hit (distance when directions are unit), ``inf`` on a miss.
    face : (n,) int64
        Face hit, -1 on a miss.
    bary : (n, 3) float64
        Barycentric coordinates of the hit, zeros on a miss.
    """

    hit: NDArray[np.bool_]
    t: NDArray[np.float64]
    face: NDArray[np.int64]
    bary: NDArray[np.float64]

    @property
    def points(self) -> SurfacePoints:
        """The hits as face points (rows where ``hit`` is True, in order)."""
        return SurfacePoints(self.face[self.hit], self.bary[self.hit])


def ray_first_hit(mesh: Mesh, origins: ArrayLike, directions: ArrayLike) -> RayHits:
    """First intersection of each ray ``origin + t direction, t >= 0`` with the surface.

    Parameters
    ----------
    mesh : Mesh
    origins : (n, 3) float64
    directions : (n, 3) float64
        Need not be unit length; ``t`` is in units of ``|direction|``.

    Returns
    -------
    RayHits
    """
    o = as_points(origins, name="origins")
    d = as_vectors(directions, n=o.shape[0], name="directions")
    if o.shape[0] == 0:
        return RayHits(np.zeros(0, bool), np.zeros(0), np.zeros(0, np.int64), np.zeros((0, 3)))
    # libigl rejects a triangle when d . (e1 x e2) is below an absolute 1e-6 (Moeller's
    # EPSILON), which misses every triangle of a finely tessellated small model (its face
    # areas can be far below that). The query uses unit directions scaled by 1 / (2 median face
    # area), so that product is near |cos| for a typical face whatever the model's scale;
    # t is recomputed below for the caller's directions.
    dn = np.linalg.norm(d, axis=1, keepdims=True)
    scale = 1.0 / (2.0 * float(np.median(mesh.face_areas)))
    dq = np.where(dn > 0, d / np.where(dn > 0, dn, 1.0) * scale, 0.0)
    face, t, uv = mesh.aabb.intersect_ray_first(mesh.vertices, mesh.faces, o, dq)
    face = np.asarray(face, dtype=np.int64)
    hit = face >= 0
    t = np.asarray(t, dtype=np.float64)
    uv = np.where(hit[:, None], np.asarray(uv, dtype=np.float64), 0.0)
    t = t * np.where(dn[:, 0] > 0, scale / np.where(dn[:, 0] > 0, dn[:, 0], 1.0), 0.0)
    if hit.any():  # libigl returns t and uv rounded to float32: recompute them in float64
        t[hit], uv[hit] = _ray_face(mesh, face[hit], o[hit], d[hit], t[hit], uv[hit])
    bary = np.stack([1.0 - uv[:, 0] - uv[:, 1], uv[:, 0], uv[:, 1]], axis=1)
    bary[~hit] = 0.0
    bary[hit] = _clip_bary(bary[hit]) if hit.any() else bary[hit]
    t = np.where(hit, t, np.inf)
    return RayHits(hit, t, np.where(hit, face, -1), bary)


def _ray_face(
    mesh: Mesh,
    face: NDArray[np.int64],
    o: NDArray[np.float64],
    d: NDArray[np.float64],
    t: NDArray[np.float64],
    uv: NDArray[np.float64],
):
    """Ray parameter and (u, v) of each ray's intersection with the plane of its hit face,
    in float64 (Moeller & Trumbore 1997); rays nearly parallel to the face keep ``t, uv``."""
    p = mesh.vertices[mesh.faces[face]]
    e1 = p[:, 1] - p[:, 0]
    e2 = p[:, 2] - p[:, 0]
    h = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, h)
    s = o - p[:, 0]
    q = np.cross(s, e1)
    ok = np.abs(det) > 1e-12 * np.linalg.norm(e1, axis=1) * np.linalg.norm(h, axis=1)
    inv = 1.0 / np.where(ok, det, 1.0)
    u = np.einsum("ij,ij->i", s, h) * inv
    v = np.einsum("ij,ij->i", d, q) * inv
    t_new = np.einsum("ij,ij->i", e2, q) * inv
    return (np.where(ok, t_new, t), np.where(ok[:, None], np.stack([u, v], axis=1), uv))
