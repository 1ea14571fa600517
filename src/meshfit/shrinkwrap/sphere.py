"""Parameterization of a closed genus-0 mesh over the unit sphere, and its evaluation.

``F`` maps a point of the unit sphere to the input surface: locate the spherical triangle
``(A*, B*, C*)`` containing it, take the barycentric coordinates of its central projection onto
the flat triangle, and apply them to the original triangle ``(A, B, C)`` (Kobbelt et al. 1999,
sec. 6). The inverse of a surface point is the normalised barycentric combination of the sphere
images of its face's corners.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import sparse
from scipy.sparse.linalg import splu
from scipy.spatial import cKDTree

from meshfit import errors, tol
from meshfit._kernels import frozen
from meshfit._kernels import shrinkwrap as _k
from meshfit.mesh import Mesh
from meshfit.types import SurfacePoints

__all__ = [
    "VOXEL_REMOVED",
    "SphereMap",
    "check_genus0",
    "sphere_map",
    "spherical_orientation",
    "triangle_quality",
    "vertex_stretch",
]

#: walk-step cap of the spherical point location, times sqrt(number of faces)
_WALK_STEPS_PER_SQRT_FACE = 8

#: why ``method="voxel"`` is refused: the paper's sphere map (grow the mesh along the
#: gradient of the distance to its voxelization toward a convex shape, then project it
#: radially) was implemented and measured; surfaces facing each other across a gap move
#: toward the same points of the gap's medial surface and cross there, so the projection
#: folds on every scanned mesh and no local untangling undoes it
VOXEL_REMOVED = (
    "the voxel-flow sphere map was removed: flowing a mesh outward along its distance field "
    "folds it wherever two parts of the surface face each other (it left flipped triangles "
    "on every scanned mesh measured), so it always fell back to 'tutte'; use "
    "method='tutte' (the default)"
)


def check_genus0(mesh: Mesh) -> None:
    """Raise :class:`meshfit.errors.TopologyError` unless ``mesh`` is one closed genus-0 surface.

    Parameters
    ----------
    mesh : Mesh
    """
    name = f"mesh {mesh.name!r}" if mesh.name else "the mesh"
    if mesh.n_components != 1:
        raise errors.TopologyError(
            f"{name} has {mesh.n_components} connected components; shrink wrapping needs one"
        )
    loops = mesh.boundary_loops
    if loops:
        sizes = ", ".join(str(len(lp)) for lp in loops[:8])
        raise errors.TopologyError(
            f"{name} is not closed: {len(loops)} boundary loop(s) (hole sizes in edges: {sizes}); "
            "shrink wrapping needs a closed genus-0 surface (close small holes with "
            "fill_holes, or --fill-holes on the command line)"
        )
    if mesh.genus != 0:
        raise errors.TopologyError(
            f"{name} has genus {mesh.genus} (handles); shrink wrapping needs a closed genus-0 "
            "surface"
        )


def spherical_orientation(sphere: NDArray[np.float64], faces: NDArray[np.int64]) -> NDArray:
    """``det[a, b, c]`` of each spherical triangle: positive when it is not flipped.

    Parameters
    ----------
    sphere : (nv, 3) float64
        Unit vectors.
    faces : (nf, 3) int64

    Returns
    -------
    (nf,) float64
    """
    return _k.spherical_dets(
        *frozen(
            np.ascontiguousarray(sphere, dtype=np.float64), np.ascontiguousarray(faces, np.int64)
        )
    )


def triangle_quality(
    vertices: NDArray[np.float64], faces: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Minimum angle and aspect ratio of flat triangles.

    Parameters
    ----------
    vertices : (nv, 3) float64
    faces : (nf, 3) int64

    Returns
    -------
    min_angle : (nf,) float64
        Smallest interior angle, radians.
    aspect : (nf,) float64
        ``l_max (l_0 + l_1 + l_2) / (4 sqrt(3) area)``: 1 for an equilateral triangle,
        ``inf`` for a degenerate one.
    """
    e, aspect = _edges_and_aspect(vertices, faces)
    ang = []
    for k in range(3):  # angle at corner k between edges k and k-1 reversed
        u, v = e[k], -e[(k + 2) % 3]
        c = np.einsum("ij,ij->i", u, v)
        s = np.linalg.norm(np.cross(u, v), axis=1)
        ang.append(np.arctan2(s, c))
    min_angle = np.min(np.stack(ang, axis=1), axis=1)
    return min_angle, aspect


def _edges_and_aspect(
    vertices: NDArray[np.float64], faces: NDArray[np.int64]
) -> tuple[list[NDArray[np.float64]], NDArray[np.float64]]:
    """The three edge vectors of each triangle and the aspect ratio of
    :func:`triangle_quality`."""
    p = vertices[faces]
    e = [p[:, (k + 1) % 3] - p[:, k] for k in range(3)]
    ln = np.stack([np.linalg.norm(x, axis=1) for x in e], axis=1)
    area = 0.5 * np.linalg.norm(np.cross(e[0], -e[2]), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        aspect = ln.max(axis=1) * ln.sum(axis=1) / (4.0 * np.sqrt(3.0) * area)
    return e, np.where(area > 0, aspect, np.inf)


@dataclass(frozen=True, eq=False)
class SphereMap:
    """A parameterization ``F`` of a closed genus-0 mesh over the unit sphere.

    Attributes
    ----------
    mesh : Mesh
        The input surface.
    sphere : (nv, 3) float64
        Image of each mesh vertex on the unit sphere (``F^-1`` at the vertices).
    method : str
        The construction: ``"tutte"`` (two convex disk embeddings lifted to the
        hemispheres by inverse stereographic projection).
    flips : int
        Spherical triangles with ``det[a, b, c] <= 0``; 0 for a valid map.
    min_det : float
        Smallest ``det[a, b, c]`` (6 x volume of the tetrahedron with the centre).
    max_aspect : float
        Largest aspect ratio of the flat triangles spanned by the sphere points.
    notes : list of str
        What was tried and why a fallback ran.
    """

    mesh: Mesh
    sphere: NDArray[np.float64]
    method: str
    flips: int
    min_det: float
    max_aspect: float
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        s = np.ascontiguousarray(self.sphere, dtype=np.float64)
        s.flags.writeable = False
        object.__setattr__(self, "sphere", s)

    # ------------------------------------------------------------- helpers
    @property
    def _faces(self) -> NDArray[np.int64]:
        return np.ascontiguousarray(self.mesh.faces)

    def _cache(self) -> dict:
        c = self.__dict__.get("_c")
        if c is None:
            c = {}
            object.__setattr__(self, "_c", c)
        return c

    @property
    def _tree(self) -> cKDTree:
        c = self._cache()
        if "tree" not in c:
            c["tree"] = cKDTree(self.sphere)
        return c["tree"]

    @property
    def _fn(self) -> NDArray[np.int64]:
        c = self._cache()
        if "fn" not in c:
            c["fn"] = np.ascontiguousarray(self.mesh.face_neighbors)
        return c["fn"]

    # ------------------------------------------------------------ evaluation
    def locate(self, points: ArrayLike, *, start: NDArray[np.int64] | None = None) -> SurfacePoints:
        """Spherical triangle containing each point and its barycentric coordinates.

        Parameters
        ----------
        points : (n, 3) float64
            Points on (or radially projected onto) the unit sphere.
        start : (n,) int64, optional
            Face to start each walk from (e.g. the previous location); by default a face
            of the nearest sphere vertex (KD-tree).

        Returns
        -------
        SurfacePoints
            Face and barycentric coordinates in the input mesh: ``F(points)`` as face points.
        """
        q = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        if start is None:
            _, iv = self._tree.query(q)
            indptr, vf = self.mesh.vertex_faces
            start = vf[indptr[iv]]
        start = np.ascontiguousarray(start, dtype=np.int64)
        steps = int(_WALK_STEPS_PER_SQRT_FACE * np.sqrt(self.mesh.n_faces)) + 64
        face, bary, found = _k.locate_sphere(
            *frozen(self.sphere, self._faces, self._fn), start, q, steps
        )
        if not found.all():
            bad = np.flatnonzero(~found)
            f2, b2 = _k.locate_sphere_brute(self.sphere, self._faces, q[bad])
            face[bad] = f2
            bary[bad] = b2
        return SurfacePoints(face, bary)

    def evaluate(self, points: ArrayLike) -> NDArray[np.float64]:
        """``F(points)``: positions on the input surface, ``(n, 3) float64`` model units."""
        return self.mesh.xyz(self.locate(points))

    def inverse(self, points: SurfacePoints) -> NDArray[np.float64]:
        """``F^-1`` of surface points: unit vectors ``(n, 3) float64``.

        The normalised barycentric combination of the sphere images of the face's corners;
        ``locate(inverse(p))`` returns ``p`` again (same face, same coordinates).
        """
        s = np.einsum("ij,ijk->ik", points.bary, self.sphere[self.mesh.faces[points.face]])
        return s / np.linalg.norm(s, axis=1, keepdims=True)


# --------------------------------------------------------------------------- construction
def _mean_value_matrix(v: NDArray, f: NDArray, n: int) -> sparse.csr_matrix:
    """Row-stochastic mean-value weight matrix (Floater 2003): positive weights."""
    p = v[f]
    rows, cols, vals = [], [], []
    for k in range(3):
        i, j, m = f[:, k], f[:, (k + 1) % 3], f[:, (k + 2) % 3]
        u = p[:, (k + 1) % 3] - p[:, k]
        w = p[:, (k + 2) % 3] - p[:, k]
        lu = np.linalg.norm(u, axis=1)
        lw = np.linalg.norm(w, axis=1)
        ang = np.arctan2(np.linalg.norm(np.cross(u, w), axis=1), np.einsum("ij,ij->i", u, w))
        t = np.tan(0.5 * np.minimum(ang, _MAX_ANGLE))
        rows += [i, i]
        cols += [j, m]
        vals += [t / np.maximum(lu, 1e-300), t / np.maximum(lw, 1e-300)]
    w = sparse.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
    )
    s = np.asarray(w.sum(axis=1)).ravel()
    s[s == 0] = 1.0
    return sparse.diags(1.0 / s) @ w


#: mean-value weights use angles clipped below pi (a needle triangle would give tan(pi/2))
_MAX_ANGLE = np.pi * (1 - 1e-6)


#: rounds of local smoothing that remove flips left by the lift to the sphere
_UNTANGLE_ROUNDS = 100
#: rounds of flip-guarded smoothing that bound the spherical triangles' aspect ratios
_ASPECT_ROUNDS = 100
#: repair rounds of the two-disk split
_SPLIT_ROUNDS = 200
#: distances from the centroid within this many units in the last place of the largest
#: coordinate (on top of ``tol.ON_SURFACE``) tie when the split's seed vertex is chosen
TIE_ULPS = 4096


def _farthest_vertex(mesh: Mesh) -> int:
    """The vertex farthest from the vertex centroid; of those within rounding of the
    farthest (a symmetric mesh has exact ties), the first. Rounding is the coordinates'
    own (``TIE_ULPS`` units in the last place of the largest) plus ``tol.ON_SURFACE`` of the
    diagonal: moved, turned or scaled, the mesh keeps its seed and so its split."""
    V = mesh.vertices
    c = V.mean(axis=0)
    d = np.linalg.norm(V - c, axis=1)
    slack = tol.length(mesh, tol.ON_SURFACE, scale="bbox_diagonal")
    slack += TIE_ULPS * float(np.spacing(np.abs(V).max()))
    return int(np.flatnonzero(d >= d.max() - slack)[0])


def _split_disks(mesh: Mesh) -> NDArray[np.bool_]:
    """Split a closed genus-0 mesh into two topological disks of about equal surface area.

    Region A is grown from the vertex farthest from the centroid by graph distance until it
    holds half the area; every component of the complement but the largest joins A, every
    component of A but the seed's joins the complement, and the faces around a vertex where
    the boundary pinches (more than two boundary edges) join A, until both regions are disks.
    A face with its three corners on the boundary (it would lie on the equator) changes
    side. Returns the (nf,) mask of region A.
    """
    from scipy.sparse.csgraph import connected_components, dijkstra

    f = mesh.faces
    seed = _farthest_vertex(mesh)
    # exact distances: faces a symmetric mesh puts at one distance keep their index order
    # whatever rounding moved the mesh
    dist = dijkstra(mesh.quantized_edge_graph(), indices=seed)
    fd = np.median(dist[f], axis=1)  # a face follows the majority of its corners
    order = np.argsort(fd, kind="stable")
    cum = np.cumsum(mesh.face_areas[order])
    in_a = np.zeros(mesh.n_faces, dtype=bool)
    in_a[order[: int(np.searchsorted(cum, 0.5 * cum[-1])) + 1]] = True
    fn = mesh.face_neighbors
    nf = mesh.n_faces
    rows = np.repeat(np.arange(nf), 3)
    cols = fn.reshape(-1)
    seed_face = int(mesh.vertex_faces[1][mesh.vertex_faces[0][seed]])
    for _ in range(_SPLIT_ROUNDS):
        same = in_a[rows] == in_a[cols]
        g = sparse.csr_matrix((np.ones(int(same.sum())), (rows[same], cols[same])), (nf, nf))
        _, lab = connected_components(g, directed=False)
        la = lab[seed_face]
        in_a = np.where(in_a, lab == la, in_a)  # stray pieces of A go to B
        lb = lab[~in_a]
        big = np.bincount(lb).argmax()
        in_a = in_a | (~in_a & (lab != big))  # stray pieces of B go to A
        # boundary edges: face in A, neighbour in B
        fa = np.flatnonzero(in_a)
        k_b = ~in_a[fn[fa]]
        ea = np.stack([f[fa], np.roll(f[fa], -1, axis=1)], axis=2)[k_b]
        cnt = np.bincount(ea.reshape(-1), minlength=mesh.n_vertices)
        pinch = np.flatnonzero(cnt > 2)
        if pinch.size == 0:
            nv_a = np.unique(f[in_a]).size
            ne_a = (3 * int(in_a.sum()) + ea.shape[0]) // 2
            if nv_a - ne_a + int(in_a.sum()) == 1:
                onb = np.zeros(mesh.n_vertices, dtype=bool)
                onb[ea.reshape(-1)] = True
                flat = onb[f].all(axis=1)  # would lie on the equator: degenerate
                if not flat.any():
                    return in_a
                # move one side's flat faces at a time (two neighbours must not swap)
                side = flat & in_a if (flat & in_a).any() else flat
                in_a[side] = ~in_a[side]
                continue

            pinch = np.unique(ea)  # not a disk: grow A across its whole boundary
        indptr, vf = mesh.vertex_faces
        grow = np.concatenate([vf[indptr[v] : indptr[v + 1]] for v in pinch])
        in_a[grow] = True
    raise errors.TopologyError("could not split the mesh into two disks for the sphere map")


def _boundary_cycle(faces: NDArray[np.int64], fn_outside: NDArray[np.bool_]) -> NDArray:
    """Ordered boundary vertex cycle of a disk, following its boundary half-edges."""
    a = faces[fn_outside.any(axis=1)]
    k = fn_outside[fn_outside.any(axis=1)]
    src = np.concatenate([a[:, j][k[:, j]] for j in range(3)])
    dst = np.concatenate([a[:, (j + 1) % 3][k[:, j]] for j in range(3)])
    nxt = dict(zip(src.tolist(), dst.tolist(), strict=True))
    start = src[0]
    cyc = [int(start)]
    while True:
        b = nxt[cyc[-1]]
        if b == start:
            break
        cyc.append(b)
    return np.asarray(cyc, dtype=np.int64)


def _tutte_disk(v, faces, boundary, bpos, n, w=None, scale=None) -> NDArray[np.float64]:
    """Mean-value embedding of the disk ``faces`` with ``boundary`` vertices fixed at
    ``bpos (k, 2)``; returns (n, 2) (rows of unused vertices are zero). ``w``: the disk's
    mean-value matrix, if already made; ``scale`` (n,): each weight ``w_ij`` multiplied by
    ``scale[j] > 0`` (rows normalised again; the weights stay positive, the map flip-free)."""
    if w is None:
        w = _mean_value_matrix(v, faces, n)
    if scale is not None:
        w = w @ sparse.diags(scale)
        rs = np.asarray(w.sum(axis=1)).ravel()
        rs[rs == 0] = 1.0
        w = sparse.diags(1.0 / rs) @ w
    used = np.zeros(n, dtype=bool)
    used[faces.reshape(-1)] = True
    fixed = np.zeros(n, dtype=bool)
    fixed[boundary] = True
    free = np.flatnonzero(used & ~fixed)
    uv = np.zeros((n, 2))
    uv[boundary] = bpos
    lap = sparse.identity(n, format="csr") - w
    a = lap[free][:, free].tocsc()
    rhs = -(lap[free][:, boundary] @ bpos)
    uv[free] = splu(a).solve(np.ascontiguousarray(rhs))
    return uv


#: most rounds of stretch-minimizing reweighting: each solves both disks again, and a few
#: rounds give protrusions their share; the weights' ratios grow each round, and far more
#: rounds would drive some to zero
MAX_STRETCH_ITERATIONS = 100


def _tutte_sphere(mesh: Mesh, stretch_iterations: int = 0) -> NDArray[np.float64]:
    """Two-disk embedding: split into halves of equal area, embed both in the unit disk
    with the same boundary positions (arc length on the circle), lift one to each
    hemisphere by inverse stereographic projection (the circle goes to the equator).

    With ``stretch_iterations``, the embeddings are solved again that many times, each
    weight ``w_ij`` divided by the area stretch of vertex ``j`` on the sphere
    (`vertex_stretch`), cumulatively: the stretch-minimizing reweighting of Yoshizawa,
    Belyaev & Seidel (2004), which spreads out what the mean-value map squeezes."""
    n = mesh.n_vertices
    v = mesh.vertices
    f = mesh.faces
    in_a = _split_disks(mesh)
    fn = mesh.face_neighbors
    out_a = ~in_a[fn[in_a]]
    cyc = _boundary_cycle(f[in_a], out_a)
    seg = np.linalg.norm(v[np.roll(cyc, -1)] - v[cyc], axis=1)
    ang = 2 * np.pi * np.concatenate([[0.0], np.cumsum(seg)[:-1]]) / seg.sum()
    bpos = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    w_a = _mean_value_matrix(v, f[in_a], n)
    w_b = _mean_value_matrix(v, f[~in_a], n)
    va = np.zeros(n, dtype=bool)
    va[f[in_a].reshape(-1)] = True
    flip_y: list[bool] = []

    def lifted(scale: NDArray[np.float64] | None) -> NDArray[np.float64]:
        uv_a = _tutte_disk(v, f[in_a], cyc, bpos, n, w_a, scale)
        uv_b = _tutte_disk(v, f[~in_a], cyc, bpos, n, w_b, scale)
        s = np.zeros((n, 3))
        for uv, zsign, mask in ((uv_a, -1.0, va), (uv_b, 1.0, ~va)):
            r2 = (uv**2).sum(axis=1)
            d = 1.0 + r2
            p = np.stack([2 * uv[:, 0] / d, 2 * uv[:, 1] / d, zsign * (1.0 - r2) / d], axis=1)
            s[mask] = p[mask]
        s[cyc, 2] = 0.0
        if not flip_y:  # make the map orientation preserving (the same way every time)
            flip_y.append(bool(np.sum(spherical_orientation(s, f)) < 0))
        if flip_y[0]:
            s[:, 1] *= -1.0
        return s / np.linalg.norm(s, axis=1, keepdims=True)

    s = lifted(None)
    scale = np.ones(n)
    for _ in range(stretch_iterations):
        scale /= vertex_stretch(mesh, s)
        scale /= scale.max()  # only ratios matter (rows are normalised): keep them in range
        s = lifted(scale)
    return s


def vertex_stretch(mesh: Mesh, sphere: NDArray[np.float64]) -> NDArray[np.float64]:
    """Area stretch of a sphere map at each vertex.

    Parameters
    ----------
    mesh : Mesh
    sphere : (nv, 3) float64
        The vertices' images on the unit sphere.

    Returns
    -------
    (nv,) float64
        ``sqrt(a / b)``: ``a`` the vertex's share of the surface area (its adjacent faces'),
        ``b`` its share of the sphere's (their flat triangles spanned by the sphere points,
        over all of them); 1 where the map keeps areas, large where it squeezes the surface
        (a protrusion), below 1 where it spreads it out.

    References
    ----------
    .. [1] Kobbelt, Vorsatz, Labsik & Seidel 1999, sec. 6 (the sphere parameterization) and
       sec. 7 (its metric against the surface's).
    .. [2] Yoshizawa, Belyaev & Seidel, "A fast and simple stretch-minimizing mesh
       parameterization", Shape Modeling International 2004 (the reweighting).
    """
    F = mesh.faces
    s = sphere
    sa = 0.5 * np.linalg.norm(np.cross(s[F[:, 1]] - s[F[:, 0]], s[F[:, 2]] - s[F[:, 0]]), axis=1)
    fa = mesh.face_areas
    n = mesh.n_vertices
    a = np.bincount(F.reshape(-1), weights=np.repeat(fa, 3), minlength=n) / (3.0 * fa.sum())
    b = np.bincount(F.reshape(-1), weights=np.repeat(sa, 3), minlength=n) / (3.0 * sa.sum())
    tiny = np.finfo(np.float64).tiny
    return np.sqrt(np.maximum(a, tiny) / np.maximum(b, tiny))


def _untangle(mesh: Mesh, s: NDArray[np.float64], rounds: int) -> NDArray[np.float64]:
    """Move the corners of flipped spherical triangles (and, if that is not enough, their
    neighbours) to the normalised mean of their neighbours until no triangle is flipped."""
    indptr, indices = mesh.vertex_adjacency
    s = s.copy()
    for r in range(rounds):
        bad = spherical_orientation(s, mesh.faces) <= 0
        if not bad.any():
            break
        verts = np.unique(mesh.faces[bad])
        for _ in range(r // 10):  # widen the smoothed region if it keeps failing
            verts = np.unique(np.concatenate([indices[indptr[v] : indptr[v + 1]] for v in verts]))
        for v in verts:
            m = s[indices[indptr[v] : indptr[v + 1]]].sum(axis=0)
            s[v] = m / np.linalg.norm(m)
    return s


def _bound_aspect(
    mesh: Mesh, s: NDArray[np.float64], bound: float, rounds: int
) -> NDArray[np.float64]:
    """Flip-guarded local smoothing of the spherical triangles whose aspect ratio exceeds
    ``bound``: their corners (and, when that is not enough, a widening ring around them)
    move to the normalised mean of their neighbours; moves that flip a triangle are undone.
    Returns the configuration with the smallest largest aspect ratio seen."""
    indptr, indices = mesh.vertex_adjacency
    faces = mesh.faces
    owner = np.repeat(np.arange(mesh.n_vertices), np.diff(indptr))
    best = s
    asp = _edges_and_aspect(s, faces)[1]
    worst = float(asp.max())
    for r in range(rounds):
        bad = asp > bound
        if not bad.any():
            break
        sel = np.zeros(len(s), dtype=bool)
        sel[faces[bad]] = True
        for _ in range(min(r // 10, 3)):  # widen the smoothed region if it keeps failing
            sel[indices[sel[owner]]] = True
        tgt = np.zeros_like(s)
        np.add.at(tgt, owner, s[indices])
        tgt /= np.linalg.norm(tgt, axis=1, keepdims=True)
        new = s.copy()
        new[sel] = tgt[sel]
        for _guard in range(20):
            flip = spherical_orientation(new, faces) <= 0
            if not flip.any():
                break
            back = np.unique(faces[flip])
            new[back] = s[back]
        else:
            break
        s = new
        asp = _edges_and_aspect(s, faces)[1]
        w = float(asp.max())
        if w < worst:
            best, worst = s, w
    return best


def _relax_area(
    mesh: Mesh, s: NDArray[np.float64], iterations: int, step: float
) -> NDArray[np.float64]:
    """Flip-guarded smoothing of the sphere points: each vertex moves toward the
    surface-area-weighted mean of the centroids of its adjacent sphere triangles; moves that
    flip a spherical triangle are undone. It evens out triangle shapes (fewer near-degenerate
    triangles in a wrap over the map) but does not equalize areas."""
    faces = mesh.faces
    af = mesh.face_areas
    indptr, vf = mesh.vertex_faces
    owner = np.repeat(np.arange(mesh.n_vertices), np.diff(indptr))
    for _ in range(iterations):
        c = s[faces].sum(axis=1)
        c /= np.linalg.norm(c, axis=1, keepdims=True)
        wc = c * af[:, None]
        tgt = np.zeros_like(s)
        np.add.at(tgt, owner, wc[vf])
        tgt /= np.linalg.norm(tgt, axis=1, keepdims=True)
        new = (1 - step) * s + step * tgt
        new /= np.linalg.norm(new, axis=1, keepdims=True)
        moved = np.ones(len(s), dtype=bool)
        for _guard in range(20):
            bad = spherical_orientation(new, faces) <= 0
            if not bad.any():
                break
            back = np.unique(faces[bad])
            new[back] = s[back]
            moved[back] = False
        else:
            break
        s = new
    return s


def sphere_map(
    mesh: Mesh,
    *,
    method: str = "tutte",
    relax_iterations: int = 0,
    relax_step: float = 0.5,
    max_aspect: float | None = None,
    stretch_iterations: int = 0,
    progress: Callable[[str, float], None] | None = None,
) -> SphereMap:
    """Parameterize a closed genus-0 mesh over the unit sphere without flipped triangles.

    Parameters
    ----------
    mesh : Mesh
        Closed, connected genus-0 surface.
    method : {"tutte"}
        ``"tutte"`` (the only construction): split the mesh into two disks of equal surface
        area, embed each in the unit disk with positive mean-value weights and the same
        boundary positions (a strictly convex boundary gives a map without flips, Floater
        2003), then lift them to the two hemispheres by inverse stereographic projection.
        ``"voxel"``, the paper's distance-field flow, is refused with the reason
        (`VOXEL_REMOVED`).
    relax_iterations : int
        Flip-guarded smoothing steps on the sphere after the embedding (default 0; each step
        is a pass over every vertex, so the cost grows with steps times vertices).
    relax_step : float
        Step of that relaxation, in (0, 1].
    max_aspect : float or None
        Bound on the aspect ratio (1 for an equilateral triangle) of the flat triangles
        spanned by the sphere points (default ``None``: no bound). The corners of the
        triangles above it are smoothed on the sphere, flip-guarded, for at most
        ``_ASPECT_ROUNDS`` rounds; the bound reached is ``SphereMap.max_aspect`` and is noted
        in ``notes``; a bound of 10 is usually reached, even where the input triangles
        themselves are far thinner. It is off by default because the local smoothing makes
        the sphere metric depart from the surface metric: a wrap over the bounded map is
        usually less close to the surface, so the bound trades the wrap's closeness for
        evenly shaped base cells (which the automatic layout wants).
    stretch_iterations : int
        Rounds of stretch-minimizing reweighting of the ``"tutte"`` embeddings (default 0):
        each round divides every mean-value weight ``w_ij`` by the area stretch of vertex
        ``j`` (:func:`vertex_stretch`) and solves the two disks again (the weights stay
        positive, so the map stays flip-free; Yoshizawa, Belyaev & Seidel 2004). The
        mean-value map squeezes protrusions: a protrusion gets a far smaller share of the
        sphere than of the surface, its tip next to none, and a wrap over such a map misses
        the tips. A few rounds give protrusions a share of the sphere much nearer their
        share of the surface (and lower the largest vertex stretch by orders of magnitude);
        the sphere's triangles are then less even in shape. Each round solves the two disks
        again, at about the cost of the embedding. Only with ``method="tutte"`` (else
        InputError).
    progress : callable(stage, fraction), optional

    Returns
    -------
    SphereMap

    Raises
    ------
    meshfit.errors.TopologyError
        The mesh is not one closed genus-0 surface.

    References
    ----------
    .. [1] Kobbelt, Vorsatz, Labsik & Seidel, "A shrink wrapping approach to remeshing
       polygonal surfaces", Eurographics 1999, sec. 6.
    .. [2] Floater, "Mean value coordinates", CAGD 20, 2003.
    """
    check_genus0(mesh)
    _check_method(method, stretch_iterations)
    if max_aspect is not None and not 1.0 <= float(max_aspect) < np.inf:  # (NaN fails too)
        raise errors.InputError(
            f"max_aspect must be a finite number >= 1 (equilateral), got {max_aspect}"
        )
    notes: list[str] = []
    s = _tutte_points(mesh, int(stretch_iterations), progress, notes)
    if relax_iterations > 0:
        s = _relax_area(mesh, s, relax_iterations, relax_step)
    if max_aspect is not None:
        s = _aspect_bounded(mesh, s, max_aspect, notes)
    dets = spherical_orientation(s, mesh.faces)
    _, aspect = triangle_quality(s, mesh.faces)
    if progress:
        progress("sphere map", 1.0)
    return SphereMap(
        mesh,
        s,
        "tutte",
        int((dets <= 0).sum()),
        float(dets.min()),
        float(aspect.max()),
        notes,
    )


def _check_method(method: str, stretch_iterations) -> None:
    if method == "voxel":
        raise errors.InputError(VOXEL_REMOVED)
    if method != "tutte":
        raise errors.InputError(f"method must be 'tutte', got {method!r}")
    if isinstance(stretch_iterations, bool) or int(stretch_iterations) != stretch_iterations:
        raise errors.InputError(
            f"stretch_iterations must be a whole number, got {stretch_iterations!r}"
        )
    if not 0 <= stretch_iterations <= MAX_STRETCH_ITERATIONS:
        raise errors.InputError(
            f"stretch_iterations must be in 0..{MAX_STRETCH_ITERATIONS}, got {stretch_iterations}"
        )


def _tutte_points(
    mesh: Mesh, stretch_iterations: int, progress, notes: list[str]
) -> NDArray[np.float64]:
    """Sphere points of the ``"tutte"`` method of `sphere_map` (with its stretch
    reweighting), any triangle the lift to the sphere flips untangled."""
    if progress:
        progress("sphere map (tutte)", 0.0)
    s = _tutte_sphere(mesh, stretch_iterations)
    if stretch_iterations:
        notes.append(f"tutte: {stretch_iterations} rounds of stretch reweighting")
    if (spherical_orientation(s, mesh.faces) <= 0).any():
        nflip = int((spherical_orientation(s, mesh.faces) <= 0).sum())
        s = _untangle(mesh, s, _UNTANGLE_ROUNDS)
        notes.append(f"tutte: untangled {nflip} triangle(s) flipped by the lift to the sphere")
    return s


def _aspect_bounded(
    mesh: Mesh, s: NDArray[np.float64], max_aspect: float, notes: list[str]
) -> NDArray[np.float64]:
    """``s`` with the corners of triangles above ``max_aspect`` smoothed (`_bound_aspect`)."""
    before = float(triangle_quality(s, mesh.faces)[1].max())
    if before > max_aspect:
        s = _bound_aspect(mesh, s, max_aspect, _ASPECT_ROUNDS)
        after = float(triangle_quality(s, mesh.faces)[1].max())
        notes.append(f"aspect bound {max_aspect:g}: max aspect {before:.4g} -> {after:.4g}")
    return s
