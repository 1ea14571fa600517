"""Automatic four-sided layouts of closed genus-0 meshes from the shrink-wrap base mesh.

Method
------
1. Parameterize the mesh over the unit sphere (:func:`meshfit.shrinkwrap.sphere_map`) and
   build the area-equalised base mesh on it (:func:`meshfit.shrinkwrap.base_mesh`, Kobbelt
   et al. 1999, sec. 6): spherical triangles covering about equal surface areas.
   Beyond 20 triangles (more than 60 patches) the base vertices are then moved over the
   sphere so that the quads of step 2 are close to squares of equal area on the surface
   (:func:`meshfit.layout.shaping.shape_base`): equal areas alone leave slivers where the
   sphere map stretches one way more than the other.
2. Split every base triangle into three quads: each corner with the two adjacent edge
   mid-points and the centroid. The mid-point of an edge halves the surface length of the
   edge's image, the centroid is the sphere point at the area-weighted centre of the
   triangle's image, so the three quads cover similar surface areas where the sphere map
   is distorted.
3. Every quad side is a great-circle arc on the sphere; its image under the parameterization
   is traced onto the surface as a face-point curve (arc samples located in the spherical
   triangulation, then densified so consecutive points lie on the same or adjacent faces).
   Distinct arcs meet only at their ends, and the parameterization is a bijection, so the
   curves cross nowhere but at the corners.

The result is an ordinary :class:`meshfit.layout.Layout`: it can be saved, edited and
re-used.
4. Each traced curve is relaxed as a surface snake with fixed ends (a tight, evenly sampled
   curve on the surface instead of the image of an arc, which follows the parameterization's
   distortion); a relaxed curve that meets another away from the corners is put back as
   it was traced (only the curves at fault; if that does not mend the network, all traced
   curves are kept). One kernel relaxes all curves, each curve on its own thread.
5. A dense mesh (more than ``PROXY_RATIO * PROXY_FACES`` faces) goes through steps 1-4 on a
   coarse proxy (:func:`meshfit.shrinkwrap.proxy.simplify_mesh`, vertices a subset of the
   input's); corners and curve points are carried to their closest points on the mesh, the
   curves densified and relaxed a few more iterations there. If that network does not cut
   the mesh into disks, steps 1-4 run on the mesh itself.
6. A layout with a sliver patch (:data:`meshfit.layout.patch.THIN`: a spring grid across
   it folds) is made again from the next rotations of the base mesh, and the one with the
   fewest slivers is kept.
7. Where a quad of the base mesh would hold a protrusion whole (`quad_depths`), or the
   curves cross with every rotation tried, the mesh is laid out by the region route
   (:mod:`meshfit.layout.regions`) instead: each attempt here is one trace and one check,
   and the region route's rounds are bounded, so no mesh meets a search without an end.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from meshfit.curves.base import densify_curves
from meshfit.errors import InputError, LayoutError, MeshfitError, TopologyError
from meshfit.layout.layout import Layout, layout_from_curves
from meshfit.layout.patch import THIN
from meshfit.mesh import Mesh
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = [
    "LayoutOptions",
    "auto_layout",
    "auto_route",
    "balance_degrees",
    "quad_depths",
    "quad_network",
]

#: patches per base triangle
PATCHES_PER_TRIANGLE = 3
#: default patch count (the icosahedron: 20 base triangles)
DEFAULT_PATCHES = 60
#: fewest patches of an automatic layout (the octahedron: 8 base triangles); bases of fewer
#: than 20 triangles start from the octahedron, the others from the icosahedron
MIN_PATCHES = 24
#: fewest mesh faces a patch of an automatic layout may average: more patches are refused
#: at once, since a layout this fine for its mesh fails anyway, only after a long search
MIN_FACES_PER_PATCH = 16
#: aspect-ratio bound of the spherical triangles of the default sphere map: a map that
#: squeezes triangles gives base cells whose images are very uneven, and spring grids that
#: fold in the fit
SPHERE_MAX_ASPECT = 10.0
#: base-mesh rotations (seeds ``seed``, ``seed + 1``, ...) tried before the automatic layout
#: gives up on curves that cross, or settles for the layout with the fewest sliver patches
#: (whose grids fold): whether curves cross or a patch along a protrusion is a sliver
#: depends on the rotation, and another one often has neither
SEED_TRIES = 3
#: largest base-rotation seed (the tries take the next seeds; a seed is 32 bits)
MAX_SEED = 2**32 - 1 - SEED_TRIES
#: default face count of the coarse proxy a dense mesh is laid out on (``auto_layout``)
PROXY_FACES = 25_000
#: a mesh is laid out on a proxy when it has more than this many times ``proxy_faces`` faces
#: (meshes up to 100,000 faces are laid out on themselves)
PROXY_RATIO = 4.0
#: snake iterations on the full mesh after the curves relaxed on the proxy are carried over
#: (the stop test does not end them earlier on a dense scan, so this bounds the time; the
#: curves relaxed on the proxy need only a local correction, and more iterations leave
#: the fit of a dense scan unchanged)
FINE_RELAX_ITERATIONS = 50
#: revision of what `auto_layout` makes for given options: part of the fit's stage keys, so a
#: resumed fit does not re-use a layout cached by an earlier revision (2: shaped bases above
#: `SHAPE_ABOVE_FACES` triangles; 3: fewer than 60 patches from an octahedron's base, where
#: earlier revisions made 60; 4: base vertices moved onto protrusions, traced arcs sampled
#: densely where the sphere map squeezes the surface; 5: the degrees of a base mesh with
#: split edges balanced by flips; 6: another rotation of the base mesh tried where a patch
#: is a sliver; 7: meshes of any other topology laid out by :mod:`meshfit.layout.regions`;
#: 8: a mesh with a protrusion a quad would hold, or whose curves cross, goes there too;
#: 9: only the relaxed curves that meet another are put back, not the whole network;
#: 10: points of a carried curve that turn back are dropped before it is densified;
#: 11: traced curves are the arcs' exact images, crossing each edge where the arc does)
AUTO_LAYOUT_REVISION = 11
#: rounds of putting back relaxed curves that meet another (`_keep_relaxed`)
UNRELAX_ROUNDS = 8
#: ``shape=None`` of `auto_layout` shapes base meshes of more than this many triangles. The
#: bisections that take the relaxed icosahedron beyond 20 triangles leave cells of equal area
#: that are slivers where the sphere map stretches, whose spring grids fold, and at the
#: finest layouts curves that cross; shaping removes most of these folds. The 20-triangle
#: base (the relaxed icosahedron, no bisection) is kept as it is; whether shaping it too is
#: better is not settled: it depends on the rotation, so it should be judged over rotations
SHAPE_ABOVE_FACES = 20
#: samples of a base edge's image when it is split at half its surface length
_SPLIT_SAMPLES = 65
#: a traced curve's consecutive samples are at most this many mean edge lengths apart (the
#: arc is sampled more densely where its image stretches, see `_fill_gaps`) ...
TRACE_GAP_EDGES = 3.0
#: ... within this many rounds of halving, down to this step of the arc's parameter
TRACE_ROUNDS = 40
TRACE_MIN_STEP = 1e-12
#: a quad of the base network deeper than this (`quad_depths`: graph distance from its
#: boundary over the square root of its area; a flat square 0.5) holds a protrusion, and the
#: mesh goes to the region route
PROTRUSION_DEPTH = 0.65
#: degree-balancing flips of a base mesh at most, per triangle (`balance_degrees`)
BALANCE_FLIPS_PER_FACE = 4
#: a base triangle's image is split n x n ways to find its area centre
_SPLIT_GRID = 12


def _unit(x: NDArray[np.float64]) -> NDArray[np.float64]:
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def quad_network(
    sphere: NDArray[np.float64],
    faces: NDArray[np.int64],
    *,
    midpoint=None,
    centroid=None,
):
    """Split a spherical triangulation into three quads per triangle.

    Parameters
    ----------
    sphere : (nv, 3) float64
        Unit vectors of the base vertices.
    faces : (nf, 3) int64
        Base triangles, counter-clockwise seen from outside.
    midpoint : callable(a, b) -> (3,) float64, optional
        Split point of the arc between base vertices ``a`` and ``b`` (default the spherical
        mid-point).
    centroid : callable(face) -> (3,) float64, optional
        Centre of a base triangle (default its normalised vertex mean).

    Returns
    -------
    points : (nv + ne + nf, 3) float64
        Corners on the sphere: base vertices, edge mid-points, face centroids.
    ends : (nk, 2) int64
        Arcs between corners (half edges of the base and centroid-to-mid-point spokes).
    patches : list of four (arc, reversed) pairs per quad, counter-clockwise.
    """
    sphere = np.asarray(sphere, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    nv = sphere.shape[0]
    mids: dict[tuple[int, int], int] = {}
    points = [p for p in sphere]
    for f in faces.tolist():
        for k in range(3):
            a, b = f[k], f[(k + 1) % 3]
            key = (min(a, b), max(a, b))
            if key not in mids:
                mids[key] = len(points)
                m = _unit(sphere[a] + sphere[b]) if midpoint is None else midpoint(*key)
                points.append(np.asarray(m, dtype=np.float64))
    cent = []
    for fi, f in enumerate(faces):
        cent.append(len(points))
        c = _unit(sphere[f].sum(axis=0)) if centroid is None else centroid(fi)
        points.append(np.asarray(c, dtype=np.float64))
    arcs: dict[tuple[int, int], int] = {}
    ends: list[tuple[int, int]] = []

    def arc(p: int, q: int) -> tuple[int, bool]:
        key = (min(p, q), max(p, q))
        if key not in arcs:
            arcs[key] = len(ends)
            ends.append(key)
        return arcs[key], p > q

    patches = []
    for fi, f in enumerate(faces.tolist()):
        c = cent[fi]
        for k in range(3):
            v = f[k]
            nxt, prv = f[(k + 1) % 3], f[(k + 2) % 3]
            m_next = mids[(min(v, nxt), max(v, nxt))]
            m_prev = mids[(min(v, prv), max(v, prv))]
            quad = [v, m_next, c, m_prev]  # counter-clockwise like the triangle
            patches.append([arc(quad[s], quad[(s + 1) % 4]) for s in range(4)])
    del nv
    return np.asarray(points), np.asarray(ends, dtype=np.int64), patches


def _trace_all(
    mesh: Mesh, smap, pts: NDArray, ends: NDArray[np.int64], corners: SurfacePoints
) -> list[SurfaceCurve]:
    """The images of the great-circle arcs ``pts[a] -> pts[b]`` (rows of ``ends``) as
    face-point curves between their corners (to be densified); the sphere map is searched
    once for all arcs' samples, then for those added where the samples spread
    (`_fill_gaps`)."""
    arcs = []
    for a, b in ends.tolist():
        w = float(np.arccos(np.clip(pts[a] @ pts[b], -1.0, 1.0)))
        arcs.append((pts[a], pts[b], w))
    # samples: about two per mean edge length of each traced image
    t = np.linspace(0.0, 1.0, 17)
    coarse = smap.evaluate(np.vstack([_slerp(a, b, w, t) for a, b, w in arcs])).reshape(
        len(arcs), t.size, 3
    )
    lengths = np.linalg.norm(np.diff(coarse, axis=1), axis=2).sum(axis=1)
    counts = [max(2, int(np.ceil(2.0 * x / mesh.mean_edge_length)) + 1) for x in lengths]
    sizes, inner = _fill_gaps(
        mesh, smap, arcs, [np.linspace(0.0, 1.0, n) for n in counts], TRACE_GAP_EDGES
    )
    return _between_corners(inner, sizes, corners, ends, "boundary")


def _fill_gaps(
    mesh: Mesh, smap, arcs: list, params: list, edges: float
) -> tuple[list[int], SurfacePoints]:
    """The exact images of the arcs ``arcs`` (``(a, b, angle)``) through the sphere map, from
    samples at the parameters ``params`` (one increasing array from 0 to 1 per arc).

    Mid-parameters are added, round after round, wherever the images of two consecutive
    samples are more than ``edges`` mean edge lengths apart, or lie in two faces the arc
    does not pass between across their shared edge. Where the sphere map squeezes part of
    the surface (the tip of a protrusion can get a tiny fraction of its share of the
    sphere), samples evenly spaced on the arc step over it, and the traced curve would cut
    across it instead of following the arc's image. At most `TRACE_ROUNDS` rounds. Then the
    point where the arc crosses that edge is put between the two samples
    (`_edge_crossings`): the map is linear on each face, so the curve is the arc's image
    exactly, and the images of two arcs that do not cross do not cross (joined straight
    across the edge, two images that run close together on a noisy surface can). Returns
    the inner samples' count per arc and the inner samples as face points, arc after arc
    (the ends are the corners)."""
    gap = edges * mesh.mean_edge_length
    ends = np.array([[a, b] for a, b, _ in arcs], dtype=np.float64).reshape(-1, 2, 3)
    angle = np.array([w for _, _, w in arcs], dtype=np.float64)
    normal = np.cross(ends[:, 0], ends[:, 1])
    # all arcs' samples in one sequence: their parameters, arcs, faces and coordinates
    t = np.concatenate([np.asarray(x, dtype=np.float64) for x in params])
    owner = np.repeat(np.arange(len(arcs)), [len(x) for x in params])

    def locate(t: NDArray[np.float64], arc: NDArray[np.int64]) -> SurfacePoints:
        return smap.locate(_slerp_rows(ends[arc, 0], ends[arc, 1], angle[arc], t))

    at = locate(t, owner)
    face, bary = at.face, at.bary
    for _ in range(TRACE_ROUNDS):
        x = mesh.xyz(SurfacePoints(face, bary))
        far = np.linalg.norm(np.diff(x, axis=0), axis=1) > gap
        pair, _, cross = _edge_crossings(mesh, smap.sphere, normal[owner[:-1]], face)
        across = np.zeros(face.size - 1, dtype=bool)
        across[pair] = (cross >= 0.0) & (cross <= 1.0)
        far |= (face[1:] != face[:-1]) & ~across
        far &= (owner[1:] == owner[:-1]) & (np.diff(t) > TRACE_MIN_STEP)
        if not far.any():
            break
        w = np.flatnonzero(far)
        mid = 0.5 * (t[w] + t[w + 1])
        at = locate(mid, owner[w])
        t = np.insert(t, w + 1, mid)
        owner = np.insert(owner, w + 1, owner[w])
        face = np.insert(face, w + 1, at.face)
        bary = np.insert(bary, w + 1, at.bary, axis=0)
    # an arc still through a vertex's fan after the last round crosses at the vertex
    pair, side, cross = _edge_crossings(mesh, smap.sphere, normal[owner[:-1]], face)
    inside = owner[pair] == owner[pair + 1]
    pair, side, cross = pair[inside], side[inside], np.clip(cross[inside], 0.0, 1.0)
    w = np.zeros((pair.size, 3))
    w[np.arange(pair.size), side] = 1.0 - cross
    w[np.arange(pair.size), (side + 1) % 3] = cross
    owner = np.insert(owner, pair + 1, owner[pair])
    face = np.insert(face, pair + 1, face[pair])
    bary = np.insert(bary, pair + 1, w, axis=0)
    count = np.bincount(owner, minlength=len(arcs))
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    inner = np.ones(owner.size, dtype=bool)
    inner[start] = False
    inner[start + count - 1] = False
    return [int(c) - 2 for c in count], SurfacePoints(face[inner], bary[inner])


def _slerp_rows(a, b, w, t):
    """The point at parameter ``t[i]`` of the arc from ``a[i]`` to ``b[i]`` of angle
    ``w[i]``, row by row (an arc under 1e-12 radians is its start)."""
    out = np.array(a, dtype=np.float64)
    on = w >= 1e-12
    s = np.sin(w[on])
    wa = np.sin((1.0 - t[on]) * w[on]) / s
    wb = np.sin(t[on] * w[on]) / s
    out[on] = wa[:, None] * a[on] + wb[:, None] * b[on]
    return out


def _edge_crossings(
    mesh: Mesh, sphere: NDArray[np.float64], normal: NDArray[np.float64], face: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """Where great circles cross the edge between consecutive faces ``face[i]``,
    ``face[i + 1]`` of samples that share one: the circle of pair ``i`` is the plane
    through the origin with normal ``normal[i]`` (its arc's two ends crossed).

    Returns, for each such pair, ``i`` (``pair``), the shared edge's slot in ``face[i]``
    (``side``: edge ``k`` joins corners ``k`` and ``k + 1``) and the arc's plane's crossing
    parameter ``t`` along the edge, on the sphere images ``sphere`` of the mesh vertices (a
    point of a chord maps to the surface point at the same edge parameter). A ``t`` outside
    [0, 1] means the arc passes between the two faces through a vertex's fan rather than
    across the edge.
    """
    nbr = mesh.face_neighbors
    f0, f1 = face[:-1], face[1:]
    shared = nbr[f0] == f1[:, None]
    pair = np.flatnonzero(shared.any(axis=1))
    side = np.argmax(shared[pair], axis=1)
    F = mesh.faces[f0[pair]]
    rows = np.arange(pair.size)
    a, b = F[rows, side], F[rows, (side + 1) % 3]
    n = normal[pair]
    sa = np.einsum("ij,ij->i", sphere[a], n)
    sb = np.einsum("ij,ij->i", sphere[b], n)
    den = sa - sb
    ok = den != 0.0
    t = np.full(pair.size, 0.5)
    t[ok] = sa[ok] / den[ok]
    return pair, side, t


def _between_corners(
    inner: SurfacePoints,
    sizes: list[int],
    corners: SurfacePoints,
    ends: NDArray[np.int64],
    kinds: str | list[str],
) -> list[SurfaceCurve]:
    """Curves from their inner points (``inner``, ``sizes[i]`` of them for curve ``i``, in
    order) between their end corners (rows of ``ends``), exact repeats of a point dropped
    (dense samples inside one face are kept; a point on a corner leaves the corner)."""
    out = []
    at = 0
    for i, (n, (a, b)) in enumerate(zip(sizes, ends.tolist(), strict=True)):
        mid = inner[np.arange(at, at + n)]
        at += n
        pts = SurfacePoints.concatenate([corners[np.array([a])], mid, corners[np.array([b])]])
        same = (pts.face[1:] == pts.face[:-1]) & np.all(pts.bary[1:] == pts.bary[:-1], axis=1)
        keep = np.concatenate([[True], ~same])
        if same[-1]:
            keep[-1] = True
            keep[-2] = len(keep) == 2
        kind = kinds if isinstance(kinds, str) else kinds[i]
        out.append(SurfaceCurve(pts[np.flatnonzero(keep)], kind=kind))
    return out


def _triangle_grid(tri: NDArray[np.float64], n: int):
    """Points (on the sphere) and small triangles of an ``n``-fold split spherical triangle."""
    idx = {}
    pts = []
    for i in range(n + 1):
        for j in range(n + 1 - i):
            idx[(i, j)] = len(pts)
            k = n - i - j
            pts.append((i * tri[0] + j * tri[1] + k * tri[2]) / n)
    tris = []
    for i in range(n):
        for j in range(n - i):
            tris.append((idx[(i, j)], idx[(i + 1, j)], idx[(i, j + 1)]))
            if i + j < n - 1:
                tris.append((idx[(i + 1, j)], idx[(i + 1, j + 1)], idx[(i, j + 1)]))
    return _unit(np.asarray(pts)), np.asarray(tris, dtype=np.int64)


def _slerp(a, b, w, t):
    """Points at the parameters ``t`` of the arc from ``a`` to ``b`` of angle ``w``."""
    t = np.asarray(t, dtype=np.float64)
    rows = (t.size, 3)
    return _slerp_rows(np.broadcast_to(a, rows), np.broadcast_to(b, rows), np.full(t.size, w), t)


def auto_route(mesh: Mesh, *, patches: int | None = None, crease_angle: float | None = 40.0) -> str:
    """Which method :func:`auto_layout` uses for ``mesh`` (without a ready sphere map).

    Returns
    -------
    str
        ``"sphere"`` (the sphere map and the shrink-wrap base mesh) for one closed genus-0
        surface without creases and with faces for at least `MIN_PATCHES` patches;
        ``"regions"`` (:func:`meshfit.layout.regions.region_layout`) for every other mesh:
        any genus, open boundaries, several components (the sphere map does not exist), sharp
        creases (the sphere map's curves would cross them), or a mesh too small for the
        fewest patches of a base mesh when no count is asked.
    """
    from meshfit.layout.regions import crease_edges

    few = patches is None and mesh.n_faces < MIN_FACES_PER_PATCH * MIN_PATCHES
    if (
        few
        or not (mesh.is_closed and _one_sphere(mesh))
        or (crease_angle is not None and crease_edges(mesh, crease_angle).any())
    ):
        return "regions"
    return "sphere"


@dataclass(frozen=True)
class LayoutOptions:
    """What :func:`auto_layout` is asked for (all have defaults; frozen, so one value can be
    shared and be part of a cache key).

    Attributes
    ----------
    patches : int, optional
        Wanted patch count; the base mesh gets ``round(patches / 3)`` faces (an even number,
        at least 8), so the result has about ``patches`` patches (default `DEFAULT_PATCHES`,
        at least `MIN_PATCHES`). Bases of fewer than 20 faces are made from an octahedron,
        the others from an icosahedron (:func:`meshfit.shrinkwrap.base_mesh`); a base whose
        edges were split has its vertex degrees balanced by flips (:func:`balance_degrees`).
        At most one patch per `MIN_FACES_PER_PATCH` faces of the mesh.
    seed : int
        Seed of the base mesh's starting rotation (default 0). Where the curves cross, or a
        patch is a sliver (area under `THIN` of a square with its perimeter), the next
        ``SEED_TRIES - 1`` seeds are tried (on the proxy first, then on the mesh); of
        layouts that all have slivers, the one with the fewest is returned (slivers along a
        protrusion fold the spring grids of the fit, and another rotation may have none).
    shape : bool, optional
        Move the base vertices over the sphere so that the quads' images are close to
        squares of equal area (:func:`meshfit.layout.shaping.shape_base`) before the curves
        are traced. None (default): when the base mesh has more than `SHAPE_ABOVE_FACES`
        triangles, where the area-equalised base mesh gives slivers.
    crease_angle : float, optional
        A mesh with chains of edges sharper than this many degrees
        (:func:`meshfit.layout.regions.crease_edges`), like a mesh that is not one closed
        genus-0 surface, is laid out by :func:`meshfit.layout.regions.region_layout`, which
        puts the creases on patch boundaries (default 40; None: creases are not looked for).
    relax : bool
        Relax every traced curve as a surface snake with fixed ends (membrane and arc-length
        forces, :func:`meshfit.curves.relax_snake`; default True). If the relaxed curves
        cross, the traced images are kept (they never cross).
    relax_iterations : int
        Iteration cap of each snake (default 200).
    sphere_max_aspect : float, optional
        Aspect-ratio bound of the default sphere map's triangles (default
        `SPHERE_MAX_ASPECT`; None: unbounded).
    proxy_faces : int, optional
        A mesh with more than `PROXY_RATIO` times this many faces (and no caller's sphere
        map) is laid out on a coarse proxy: :func:`meshfit.shrinkwrap.simplify_mesh` to
        about ``proxy_faces`` faces, the sphere map, base mesh, traced curves and their
        relaxation on the proxy; then the corners and curve points are carried to the
        closest points of the mesh, the curves densified there and relaxed for
        `FINE_RELAX_ITERATIONS` more iterations. If the carried network does not cut the
        mesh into disks, the layout is made on the mesh itself. Default `PROXY_FACES`;
        None: never.
    protrusions : bool
        Where a quad of the base mesh would hold a protrusion whole (an ear, a tail: deeper
        than `PROTRUSION_DEPTH`, :func:`quad_depths`), lay the mesh out by the region route
        instead, whose cells split where the surface turns (default True). A patch holding
        a protrusion is anchored round its foot and its spring mesh misses the tip.
    """

    patches: int | None = None
    seed: int = 0
    shape: bool | None = None
    crease_angle: float | None = 40.0
    relax: bool = True
    relax_iterations: int = 200
    sphere_max_aspect: float | None = SPHERE_MAX_ASPECT
    proxy_faces: int | None = PROXY_FACES
    protrusions: bool = True

    def __post_init__(self) -> None:
        if self.patches is not None and int(self.patches) < 1:
            raise InputError(f"patches must be >= 1, got {self.patches}")
        if self.proxy_faces is not None and int(self.proxy_faces) < 20:
            raise InputError(f"proxy_faces must be >= 20, got {self.proxy_faces}")
        if int(self.relax_iterations) < 0:
            raise InputError(f"relax_iterations must be >= 0, got {self.relax_iterations}")
        s = self.seed
        if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or not 0 <= s <= MAX_SEED:
            raise InputError(f"seed must be a whole number from 0 to {MAX_SEED}, got {s!r}")


def auto_layout(
    mesh: Mesh,
    options: LayoutOptions | None = None,
    *,
    sphere=None,
    report: list | None = None,
) -> Layout:
    """A four-sided layout of any mesh: for one closed genus-0 surface without creases,
    three quads per triangle of the shrink-wrap base mesh; for every other mesh, and where
    that route cannot hold the shape, :func:`meshfit.layout.regions.region_layout`.

    Parameters
    ----------
    mesh : Mesh
        Any mesh: closed or open, of any genus, one component or several.
    options : LayoutOptions, optional
        Default ``LayoutOptions()``.
    sphere : meshfit.shrinkwrap.SphereMap, keyword-only, optional
        A ready parameterization of ``mesh`` over the unit sphere (the sphere route only);
        default :func:`meshfit.shrinkwrap.sphere_map` with ``options.sphere_max_aspect``.
    report : list, keyword-only, optional
        Gets a dict appended: ``route`` (``"sphere"``, ``"regions"``, or ``"sphere ->
        regions"`` where the sphere route handed the mesh on) and, from the region route,
        ``cells`` and ``seeds_added`` (:class:`meshfit.layout.regions.CellReport`).

    Returns
    -------
    Layout

    Raises
    ------
    meshfit.errors.InputError
        ``patches`` below 1, or more patches than the mesh has faces for (fewer than
        `MIN_FACES_PER_PATCH` = 16 faces a patch).
    meshfit.errors.TopologyError
        With the caller's ``sphere``: a mesh that is not one closed genus-0 surface.
    meshfit.errors.LayoutError
        With the caller's ``sphere``: the traced curves cross with every one of the
        ``SEED_TRIES`` rotations tried. Without it such a mesh goes to the region route,
        which raises only where its cells cannot all be made disks within its budget.

    References
    ----------
    .. [1] Kobbelt, Vorsatz, Labsik & Seidel 1999, sec. 6 (sphere parameterization and the
       area-equalised base mesh).
    .. [2] Krishnamurthy 2000, sec. 1.3 (four-sided patch layouts).
    """

    o = options if options is not None else LayoutOptions()
    patches, crease_angle, proxy_faces = o.patches, o.crease_angle, o.proxy_faces
    proxy = sphere is None and proxy_faces is not None and mesh.n_faces > PROXY_RATIO * proxy_faces
    info: dict = {}
    if report is not None:
        report.append(info)
    regions = dict(patches=patches, crease_angle=crease_angle, relax=o.relax)
    if sphere is None and auto_route(mesh, patches=patches, crease_angle=crease_angle) != "sphere":
        info["route"] = "regions"
        return _region_route(mesh, regions, o.relax_iterations, info)
    info["route"] = "sphere"
    try:
        return _sphere_route(
            mesh,
            patches=patches,
            sphere=sphere,
            seed=o.seed,
            relax=o.relax,
            relax_iterations=o.relax_iterations,
            sphere_max_aspect=o.sphere_max_aspect,
            proxy_faces=proxy_faces,
            shape=o.shape,
            # (with the caller's sphere map there is no other route to hand the mesh to)
            protrusions=o.protrusions and sphere is None,
            proxy=proxy,
        )
    except (_HoldsProtrusion, LayoutError):
        # a protrusion that a quad would hold whole, or curves that cross with every
        # rotation tried: the region route's cells follow the shape instead
        if sphere is not None:
            raise
        info["route"] = "sphere -> regions"
        return _region_route(mesh, regions, o.relax_iterations, info)


def _region_route(mesh: Mesh, options: dict, relax_iterations: int, info: dict) -> Layout:
    from meshfit.layout.regions import region_layout

    cells: list = []
    out = region_layout(mesh, **options, relax_iterations=relax_iterations, report=cells)
    info.update(cells=cells[0].cells, seeds_added=dict(cells[0].seeds_added))
    return out


def _sphere_route(
    mesh: Mesh,
    *,
    patches,
    sphere,
    seed: int,
    relax: bool,
    relax_iterations: int,
    sphere_max_aspect,
    proxy_faces,
    shape,
    protrusions: bool,
    proxy: bool,
) -> Layout:
    """The sphere-map route of `auto_layout` (its arguments checked there)."""
    from meshfit.shrinkwrap import sphere_map

    if not mesh.is_closed:
        raise _topology_error(mesh)
    n_faces = _base_triangles(mesh, patches)
    if shape is None:
        shape = n_faces > SHAPE_ABOVE_FACES
    tries = _Tries(
        seeds=[int(seed) + k for k in range(SEED_TRIES)],
        relax=relax,
        iters=int(relax_iterations),
        shape=shape,
        protrusions=protrusions,
        pick=_Fewest(mesh),
        relaxed=_RelaxMemo(),
    )
    if proxy:
        out = _layout_on_proxy(mesh, n_faces, tries, sphere_max_aspect, proxy_faces)
        if out is not None:
            return out
        # the carried network does not cut the mesh: lay out on the mesh itself
    smap = sphere_map(mesh, max_aspect=sphere_max_aspect) if sphere is None else sphere
    return _layout_on_mesh(mesh, smap, n_faces, tries)


def _base_triangles(mesh: Mesh, patches) -> int:
    """Triangles of the base mesh for ``patches`` (default `DEFAULT_PATCHES`), an even
    number; InputError where the mesh has too few faces for them (`MIN_FACES_PER_PATCH`)."""
    want = DEFAULT_PATCHES if patches is None else int(patches)
    n_faces = max(MIN_PATCHES // PATCHES_PER_TRIANGLE, round(want / PATCHES_PER_TRIANGLE))
    n_faces += n_faces % 2
    most = mesh.n_faces // MIN_FACES_PER_PATCH // PATCHES_PER_TRIANGLE  # base triangles
    most -= most % 2
    if n_faces > most:
        name = mesh.name or "the mesh"
        raise InputError(
            f"{want} patches on {name} ({mesh.n_faces} faces): an automatic layout needs at "
            f"least {MIN_FACES_PER_PATCH} faces a patch, "
            + (
                f"ask for at most {PATCHES_PER_TRIANGLE * most} patches"
                if PATCHES_PER_TRIANGLE * most >= MIN_PATCHES
                else f"and makes at least {MIN_PATCHES}: give a layout file or a finer mesh"
            )
        )
    return n_faces


@dataclass(frozen=True)
class _Tries:
    """What the sphere route's tries share: the base-mesh rotations (``seeds``), the curve
    relaxation, shaping and protrusion options, the layout kept so far (``pick``) and the
    relaxed curves already computed (``relaxed``)."""

    seeds: list[int]
    relax: bool
    iters: int
    shape: bool
    protrusions: bool
    pick: _Fewest
    relaxed: _RelaxMemo


def _layout_on_proxy(
    mesh: Mesh, n_faces: int, tries: _Tries, sphere_max_aspect, proxy_faces
) -> Layout | None:
    """The sphere route on a coarse proxy of ``mesh``, its network carried over to ``mesh``:
    the first layout without slivers, else the one with the fewest, or None when no
    carried network cuts ``mesh`` into disks."""
    from concurrent.futures import ThreadPoolExecutor

    from meshfit._threads import n_workers
    from meshfit.layout.extract import check_layout_topology
    from meshfit.shrinkwrap import sphere_map
    from meshfit.shrinkwrap.proxy import simplify_mesh

    t = tries
    # the genus and component count, then what the curves need on the full mesh, are
    # found on a second thread while the proxy is made (a closed mesh of another genus
    # keeps it through the simplification, which then goes unused)
    with ThreadPoolExecutor(max_workers=1) as pool:
        one_sphere = pool.submit(_one_sphere, mesh)
        ready = pool.submit(_prepare_fine, mesh)
        coarse = simplify_mesh(mesh, int(proxy_faces), workers=n_workers(None)).mesh
        if not one_sphere.result():
            raise _topology_error(mesh)
        c_smap = sphere_map(coarse, max_aspect=sphere_max_aspect)
        first = _proxy_tries(
            coarse, c_smap, n_faces, t.seeds[0], t.relax, t.iters, t.shape, t.protrusions,
            t.relaxed,
        )  # fmt: skip
        ready.result()
    for k, s in enumerate(t.seeds):
        c_corners, ends, quads, c_sets = (
            first
            if k == 0
            else _proxy_tries(
                coarse, c_smap, n_faces, s, t.relax, t.iters, t.shape, t.protrusions, t.relaxed
            )
        )
        corners = _carry_points(mesh, coarse, c_corners)
        for c_set, fine_iters in c_sets:
            try:
                curves = _carry_curves(mesh, coarse, c_set, corners, ends)
                if fine_iters > 0:
                    curves = _relax_all(mesh, curves, fine_iters)
                out = layout_from_curves(mesh, corners, curves, ends, quads)
                _drop_fine(mesh)
                check_layout_topology(mesh, out)
            except MeshfitError:
                continue
            if t.pick.take(out):
                return out
            break  # slivers: the next rotation
    return t.pick.best


def _layout_on_mesh(mesh: Mesh, smap, n_faces: int, tries: _Tries) -> Layout:
    """The sphere route on ``mesh`` itself with the sphere map ``smap``: the first layout
    without slivers, else the one with the fewest (the last LayoutError where none is a
    layout)."""
    t = tries
    iters = t.iters
    failed: LayoutError | None = None
    for s in t.seeds:
        corners, curves, ends, quads = _network(
            mesh, smap, n_faces, s, t.shape, t.protrusions, iters if t.relax else 0, t.relaxed
        )
        traced = layout_from_curves(mesh, corners, curves, ends, quads)
        out = None
        if t.relax:
            relaxed = t.relaxed(mesh, curves, iters)
            out = _keep_relaxed(mesh, corners, curves, relaxed, ends, quads)
        if out is None:
            try:
                out = _checked(mesh, traced, len(t.seeds))
            except LayoutError as exc:  # another rotation of the base mesh
                failed = failed or exc
                continue
        if t.pick.take(out):
            return out
    if t.pick.best is not None:
        return t.pick.best
    assert failed is not None
    raise failed


class _Fewest:
    """The layout with the fewest sliver patches among those offered (`THIN`: the grid
    across a sliver folds), the thinnest one's bulge deciding between equal counts."""

    def __init__(self, mesh: Mesh) -> None:
        self.mesh = mesh
        self.best: Layout | None = None
        self._score: tuple[int, float] | None = None

    def take(self, layout: Layout) -> bool:
        """Offer ``layout`` (checked to cut the mesh into disks); True when it has no sliver."""
        from meshfit.layout.extract import patch_bulges

        bulge = patch_bulges(self.mesh, layout)
        score = (int((bulge < THIN).sum()), -float(bulge.min(initial=np.inf)))
        if self._score is None or score < self._score:
            self.best, self._score = layout, score
        return score[0] == 0


class _RelaxMemo:
    """`_relax_all`, remembering its results for the curve lists they came from during one
    `auto_layout` call: a move onto a protrusion accepted on its relaxed curves
    (`_cuts_disks`) is not relaxed again when the layout is made from it."""

    def __init__(self) -> None:
        self._got: dict[tuple[int, int, int], tuple] = {}

    def __call__(
        self, mesh: Mesh, curves: list[SurfaceCurve], iterations: int
    ) -> list[SurfaceCurve]:
        key = (id(mesh), id(curves), int(iterations))
        hit = self._got.get(key)
        if hit is not None and hit[0] is mesh and hit[1] is curves:
            return hit[2]
        out = _relax_all(mesh, curves, iterations)
        self._got[key] = (mesh, curves, out)  # the references keep the ids unique
        return out


def _one_sphere(mesh: Mesh) -> bool:
    """True for one connected genus-0 surface (the mesh is closed)."""
    return mesh.n_components == 1 and mesh.genus == 0


def _topology_error(mesh: Mesh) -> TopologyError:
    """The error for a mesh that is not one closed genus-0 surface."""
    what = (
        "is open (has boundary loops)"
        if not mesh.is_closed
        else f"has genus {mesh.genus}"
        if mesh.genus != 0
        else f"has {mesh.n_components} components"
    )
    return TopologyError(
        f"automatic layout needs one closed genus-0 surface, but {mesh.name or 'the mesh'} "
        f"{what}: give a layout file (--layout FILE), or fill small holes first "
        "(--fill-holes / meshfit.shrinkwrap.fill_holes)"
    )


def _proxy_tries(
    coarse: Mesh,
    smap,
    n_faces: int,
    seed: int,
    relax: bool,
    iters: int,
    shape: bool,
    protrusions: bool = True,
    relaxed: _RelaxMemo | None = None,
):
    """Corners, curve ends, quads and the curve sets to carry (relaxed first, then traced)
    of the base mesh of ``seed`` on the proxy ``coarse``."""
    relaxed = relaxed or _RelaxMemo()
    c_corners, c_curves, ends, quads = _network(
        coarse, smap, n_faces, seed, shape, protrusions, iters if relax else 0, relaxed
    )
    tries = []
    if relax:
        tries.append((relaxed(coarse, c_curves, iters), min(iters, FINE_RELAX_ITERATIONS)))
    tries.append((c_curves, 0))
    return c_corners, ends, quads, tries


def _prepare_fine(mesh: Mesh) -> None:
    """Build the full mesh's cached search tree, normals, vertex stars, edge lengths, edge
    faces and vertex adjacency (carrying, densifying and relaxing the curves use them: the
    last two where a carried pair is joined by a graph path)."""
    _ = mesh.triangle_tree, mesh.vertex_normals, mesh.vertex_faces, mesh.mean_edge_length
    _ = mesh.edge_face, mesh.vertex_adjacency


#: what `_prepare_fine` builds that neither the cut nor the stages after it read
_FINE_ONLY = ("vertex_normals", "_vertex_adjacency", "edge_face", "edge_lengths", "edge_graph")


def _drop_fine(mesh: Mesh) -> None:
    """Forget the full mesh's `_FINE_ONLY` arrays once the curves are carried and relaxed:
    the partition that checks the layout is as large as the mesh's adjacency, and the two
    side by side were a dense scan's peak (a later try derives them again)."""
    mesh.drop_caches(keep=[k for k in vars(mesh) if k not in _FINE_ONLY])


def _network(
    mesh: Mesh,
    smap,
    n_faces: int,
    seed: int,
    shape: bool = False,
    protrusions: bool = True,
    relax_iterations: int = 0,
    relaxed: _RelaxMemo | None = None,
):
    """Corners, traced curves, curve ends and quads of the base mesh of ``smap`` (its
    vertices moved by :func:`meshfit.layout.shaping.shape_base` with ``shape``); with
    ``protrusions``, `_HoldsProtrusion` where a quad is deeper than `PROTRUSION_DEPTH`."""
    del relax_iterations, relaxed
    from meshfit.layout.shaping import shape_base
    from meshfit.shrinkwrap import BaseOptions, base_mesh
    from meshfit.shrinkwrap.base import STARTS

    start = "octahedron" if n_faces < STARTS["icosahedron"][1] else "icosahedron"
    opts = BaseOptions(max_faces=n_faces, min_faces=n_faces, seed=seed, start=start)
    base = base_mesh(smap, opts)
    S, BF = base.sphere, base.faces
    if len(BF) > STARTS[start][1]:  # edges were split: even out the vertex degrees
        BF = balance_degrees(S, BF)
    if shape:
        S = shape_base(smap, S, BF, seed=seed).sphere
    if protrusions:
        depth, _ = quad_depths(mesh, smap.sphere, S, BF)
        if depth.max(initial=0.0) > PROTRUSION_DEPTH:
            raise _HoldsProtrusion(float(depth.max()))
    return _traced(mesh, smap, S, BF)


class _HoldsProtrusion(Exception):
    """A quad of the base mesh would hold a protrusion whole: the sphere route's patches
    cannot follow it, the region route's cells can."""


def _traced(mesh: Mesh, smap, S: NDArray[np.float64], BF: NDArray[np.int64]):
    """Corners, traced curves, curve ends and quads of the base mesh ``S``, ``BF`` (vertices
    on the unit sphere, triangles) of ``smap``."""

    def midpoint(a: int, b: int) -> NDArray[np.float64]:
        # the point halving the surface length of the arc's image
        w = float(np.arccos(np.clip(S[a] @ S[b], -1.0, 1.0)))
        t = np.linspace(0.0, 1.0, _SPLIT_SAMPLES)
        x = smap.evaluate(_slerp(S[a], S[b], w, t))
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(x, axis=0), axis=1))])
        th = float(np.interp(0.5 * cum[-1], cum, t)) if cum[-1] > 0 else 0.5
        return _slerp(S[a], S[b], w, np.array([th]))[0]

    def centroid(f: int) -> NDArray[np.float64]:
        # the sphere point at the surface-area-weighted centre of the triangle's image
        P, T = _triangle_grid(S[BF[f]], _SPLIT_GRID)
        X = smap.evaluate(P)
        area = 0.5 * np.linalg.norm(
            np.cross(X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]), axis=1
        )
        mid = P[T].mean(axis=1)
        if area.sum() <= 0:
            return _unit(S[BF[f]].sum(axis=0))
        return _unit((area[:, None] * mid).sum(axis=0))

    pts, ends, quads = quad_network(S, BF, midpoint=midpoint, centroid=centroid)
    corners = smap.locate(pts)
    return corners, densify_curves(mesh, _trace_all(mesh, smap, pts, ends, corners)), ends, quads


def quad_depths(
    mesh: Mesh, sphere: NDArray[np.float64], S: NDArray[np.float64], BF: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """How deep each quad of the base mesh ``S``, ``BF`` reaches into ``mesh``.

    The quads are those of :func:`quad_network` (spherical mid-points and centroids, base
    vertex first). A vertex belongs to the quad whose four great-circle sides it lies inside.

    Parameters
    ----------
    mesh : Mesh
        The closed genus-0 mesh.
    sphere : (nv, 3) float64
        Each mesh vertex on the unit sphere (``SphereMap.sphere``).
    S : (nb, 3) float64
        Base vertices, unit vectors.
    BF : (nf, 3) int64
        Base triangles, counter-clockwise seen from outside (``3 nf`` quads).

    Returns
    -------
    depth : (nq,) float64
        The largest graph distance (along mesh edges) from a vertex of the quad to the
        quad's boundary, over the square root of the quad's surface area: about 0.5 for a
        flat square, larger where a protrusion (an ear, a horn) rises inside the quad.
        0 for a quad holding fewer than three vertices.
    tip : (nq,) int64
        The mesh vertex at that largest distance (-1 for an empty quad).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3 and 5.1 (patch layouts; a patch's parametric
       distortion). Kobbelt, Vorsatz, Labsik & Seidel 1999, sec. 6 (the base mesh).
    """
    from scipy.sparse.csgraph import dijkstra

    pts, ends, quads = quad_network(S, BF)
    corners = np.array([[ends[a][1] if rev else ends[a][0] for a, rev in q] for q in quads])
    Q = pts[corners]
    inside = np.ones((len(sphere), len(Q)), dtype=bool)
    for s in range(4):
        inside &= sphere @ np.cross(Q[:, s], Q[:, (s + 1) % 4]).T >= 0.0
    quad = np.where(inside.any(axis=1), np.argmax(inside, axis=1), -1)
    E, G, faces = mesh.edges, mesh.edge_graph, mesh.faces
    depth = np.zeros(len(Q))
    tip = np.full(len(Q), -1, dtype=np.int64)
    for q in range(len(Q)):
        mine = quad == q
        if mine.sum() < 3:
            continue
        edge = mine[E[:, 0]] != mine[E[:, 1]]  # edges leaving the quad
        rim = np.unique(E[edge][mine[E[edge]]])
        area = float(mesh.face_areas[mine[faces].all(axis=1)].sum())
        idx = np.flatnonzero(mine)
        if rim.size == 0 or area <= 0.0:
            continue
        d = dijkstra(G[idx][:, idx], indices=np.searchsorted(idx, rim), min_only=True)
        d[~np.isfinite(d)] = -1.0
        k = int(np.argmax(d))
        depth[q], tip[q] = d[k] / np.sqrt(area), idx[k]
    return depth, tip


def balance_degrees(
    S: NDArray[np.float64], BF: NDArray[np.int64], *, target: int = 6, least: int = 4
) -> NDArray[np.int64]:
    """The triangles ``BF`` of the spherical base mesh ``S`` with edges flipped, one at a
    time, the flip that most lowers the summed squared deviation of the four vertices'
    degrees from ``target`` first, while one lowers it. A flip keeps both new triangles
    counter-clockwise on the sphere, repeats no edge and leaves no vertex below ``least``.

    The base mesh's edge splits (:func:`meshfit.shrinkwrap.base_mesh`) pile up round a few
    vertices where the sphere map squeezes the surface: a vertex of high degree gets many
    curves a few degrees apart at its corner, which cross at once, so fine layouts cannot be
    made; balanced, the degrees stay close to ``target``.

    Parameters
    ----------
    S : (nb, 3) float64
        Base vertices, unit vectors.
    BF : (nf, 3) int64
        Base triangles, counter-clockwise seen from outside.
    target, least : int, keyword-only
        Degree aimed at (default 6) and the lowest allowed (default 4).

    Returns
    -------
    (nf, 3) int64
        The triangles after the flips (same vertices, same count).

    References
    ----------
    .. [1] Kobbelt, Vorsatz, Labsik & Seidel 1999, sec. 6 (the base mesh).
    """
    F = [[int(v) for v in f] for f in BF]
    deg = np.bincount(np.asarray(BF).ravel(), minlength=len(S)).astype(np.int64)

    def cost(v: int, change: int) -> int:
        return int((deg[v] + change - target) ** 2 - (deg[v] - target) ** 2)

    for _ in range(BALANCE_FLIPS_PER_FACE * len(F)):
        where = {(f[s], f[(s + 1) % 3]): (t, s) for t, f in enumerate(F) for s in range(3)}
        best = None
        for (a, b), (t1, s1) in where.items():
            if a > b:
                continue
            t2, s2 = where[(b, a)]
            c, d = F[t1][(s1 + 2) % 3], F[t2][(s2 + 2) % 3]
            if c == d or (c, d) in where or min(deg[a], deg[b]) - 1 < least:
                continue
            gain = -(cost(a, -1) + cost(b, -1) + cost(c, 1) + cost(d, 1))
            if gain > 0 and (best is None or gain > best[0]):
                if _upright(S, np.array([[c, a, d], [d, b, c]])):
                    best = (gain, t1, t2, a, b, c, d)
        if best is None:
            break
        _, t1, t2, a, b, c, d = best
        F[t1], F[t2] = [c, a, d], [d, b, c]
        deg[[a, b]] -= 1
        deg[[c, d]] += 1
    return np.asarray(F, dtype=np.int64)


def _upright(S: NDArray[np.float64], BF: NDArray[np.int64]) -> bool:
    """Whether every spherical triangle of ``S``, ``BF`` is counter-clockwise seen from
    outside (:func:`meshfit.shrinkwrap.spherical_orientation` positive)."""
    from meshfit.shrinkwrap import spherical_orientation

    return bool((spherical_orientation(S, np.asarray(BF, dtype=np.int64)) > 0.0).all())


def _relax_inputs(mesh: Mesh, curves: list[SurfaceCurve]) -> dict:
    """Arguments of `_kernels.snakes.relax_many` for ``curves`` on ``mesh`` (keywords).

    Negative barycentrics are clipped and renormalised; ``levels`` per curve as
    :func:`meshfit.curves.relax_snake` chooses them; ``floor`` is a tenth of the curve's mean
    spacing; ``gain`` is ``1 / max(1, w_fair + w_curv + w_arc)`` with the default weights
    (1, 0, 1).
    """
    from meshfit import tol
    from meshfit._kernels.snake import positions
    from meshfit.curves.snake import _MAX_FACES, SNAKE_MOVE_TOL, _auto_levels, _share_pairs

    sizes = np.array([len(c) for c in curves], dtype=np.int64)
    start = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    face = np.ascontiguousarray(np.concatenate([c.points.face for c in curves]), dtype=np.int64)
    bary = np.array(np.concatenate([c.points.bary for c in curves]), dtype=np.float64, order="C")
    neg = (bary < 0).any(axis=1)
    if neg.any():
        c = np.clip(bary[neg], 0.0, None)
        bary[neg] = c / c.sum(axis=1, keepdims=True)
    for a, b in itertools.pairwise(start.tolist()):  # (the kernel keeps the ends)
        ends = np.zeros(b - a, dtype=bool)
        ends[[0, -1]] = True
        face[a:b] = _share_pairs(mesh, face[a:b], bary[a:b], False, ends)
    x = positions(mesh.vertices, mesh.faces, face, bary)
    seg_len = np.linalg.norm(np.diff(x, axis=0), axis=1)
    # segments inside a curve (the pair from one curve's end to the next's start is not one)
    inner_seg = np.ones(max(face.size - 1, 0), dtype=bool)
    inner_seg[start[1:-1] - 1] = False
    owner = np.repeat(np.arange(len(curves)), sizes)
    sums = np.bincount(owner[:-1][inner_seg], weights=seg_len[inner_seg], minlength=len(curves))
    return {
        "V": mesh.vertices,
        "F": mesh.faces,
        "FN": mesh.face_neighbors,
        "VN": mesh.vertex_normals,
        "face": face,
        "bary": bary,
        "start": start,
        "levels": np.array([_auto_levels(int(n), False) for n in sizes], dtype=np.int64),
        "floor": 0.1 * np.where(sizes > 1, sums / np.maximum(sizes - 1, 1), 0.0),
        "gain": 1.0 / 2.0,
        "step": 0.25,
        "stop": SNAKE_MOVE_TOL * mesh.mean_edge_length,
        "max_faces": _MAX_FACES,
        "eps_len": tol.length(mesh, tol.WALK_EPS),
        "bary_eps": tol.BARY_EPS,
    }


def _relax_all(mesh: Mesh, curves: list[SurfaceCurve], iterations: int) -> list[SurfaceCurve]:
    """Every curve relaxed as a snake with fixed ends, densified where the rule breaks.

    The same forces, moves, sampling guard and per-curve stopping tests as
    :func:`meshfit.curves.relax_snake` with its default weights (a converged curve stops
    moving); one kernel relaxes all curves, one curve per thread.
    """
    from meshfit._kernels import snakes as _kb

    if not curves:
        return []
    args = _relax_inputs(mesh, curves)
    face, bary, _ = _kb.relax_many(**args, iterations=int(iterations))
    return _relaxed_curves(mesh, curves, args["start"], face, bary)


def _keep_relaxed(
    mesh: Mesh,
    corners: SurfacePoints,
    plain: list[SurfaceCurve],
    relaxed: list[SurfaceCurve],
    ends: NDArray[np.int64],
    quads,
    creases: NDArray[np.bool_] | None = None,
) -> Layout | None:
    """The layout of the relaxed curves, with each relaxed curve that meets another away
    from the corners put back as it was before relaxing (``plain``, a network that cuts the
    mesh into disks), or None when no such mix does.

    A snake pulled tight can slide across a neighbour near a shared corner; putting back
    only the curves at fault keeps every other curve relaxed (one fault would otherwise
    cost the whole network its relaxation). Each round puts back at least one curve, and
    at most `UNRELAX_ROUNDS` rounds run. After the first, a round looks only at the curves
    of the patches of those just put back and at their corners (a cut of a few curves,
    not of the network); the last look is at the whole network.
    """
    from meshfit.layout.extract import check_layout_topology
    from meshfit.surface.cut import network_meetings

    def layout(curves: list[SurfaceCurve]) -> Layout | None:
        try:
            out = layout_from_curves(mesh, corners, curves, ends, quads, creases=creases)
            check_layout_topology(mesh, out)
        except MeshfitError:
            return None
        return out

    first = layout(relaxed)
    if first is not None:
        return first
    cur = list(relaxed)
    near = _neighbourhoods(ends, quads, len(cur))
    check = list(range(len(cur)))  # the curves whose meetings are looked for
    rounds = 0
    while True:
        try:
            found = network_meetings(mesh, [cur[i] for i in check], corners, ends[check])
        except MeshfitError:
            return None
        back = [check[k] for k in found if cur[check[k]] is not plain[check[k]]]
        if not back:
            if len(check) == len(cur):
                break
            # (a put-back curve may also meet one beyond its patches: a full check)
            check = list(range(len(cur)))
            continue
        rounds += 1
        if rounds > UNRELAX_ROUNDS:
            break
        for i in back:
            cur[i] = plain[i]
        # a curve put back meets only curves it did not meet relaxed, most likely those
        # of its patches and at its corners: they are looked at first
        check = sorted(set().union(*(near[i] for i in back)))
    return layout(cur)


def _neighbourhoods(ends: NDArray[np.int64], quads, n: int) -> list[set[int]]:
    """Per curve, itself and the curves of its patches and at its end corners."""
    at: dict[int, set[int]] = {}
    for i, (a, b) in enumerate(np.asarray(ends, dtype=np.int64).tolist()):
        at.setdefault(a, set()).add(i)
        at.setdefault(b, set()).add(i)
    out = [{i} | at[int(ends[i][0])] | at[int(ends[i][1])] for i in range(n)]
    for q in quads:
        sides = {int(c) for c, _ in q}
        for c in sides:
            out[c] |= sides
    return out


def _relaxed_curves(
    mesh: Mesh,
    curves: list[SurfaceCurve],
    start: NDArray[np.int64],
    face: NDArray[np.int64],
    bary: NDArray[np.float64],
) -> list[SurfaceCurve]:
    """``curves`` with the relaxed points ``face``, ``bary`` (rows ``start[c]:start[c + 1]``),
    ends exactly as given, densified where consecutive points stop sharing a face."""
    out = []
    for c, curve in enumerate(curves):
        a, b = int(start[c]), int(start[c + 1])
        fc, bc = face[a:b].copy(), bary[a:b].copy()
        fc[0], fc[-1] = curve.points.face[0], curve.points.face[-1]
        bc[0], bc[-1] = curve.points.bary[0], curve.points.bary[-1]
        out.append(SurfaceCurve(SurfacePoints(fc, bc), curve.closed, curve.kind))
    return densify_curves(mesh, out)


def _carry_points(mesh: Mesh, coarse: Mesh, points: SurfacePoints) -> SurfacePoints:
    """Face points of ``coarse`` carried to the closest points of ``mesh``."""
    return mesh.closest_points(coarse.xyz(points)).points


def _carry_curves(
    mesh: Mesh,
    coarse: Mesh,
    curves: list[SurfaceCurve],
    corners: SurfacePoints,
    ends: NDArray[np.int64],
) -> list[SurfaceCurve]:
    """Curves of ``coarse`` carried point by point to the closest points of ``mesh``, ends
    on the carried ``corners``, densified on ``mesh``."""
    sizes = [len(c) for c in curves]
    inner = SurfacePoints.concatenate(
        [c.points[np.arange(1, n - 1)] for c, n in zip(curves, sizes, strict=True)]
    )
    moved = _carry_points(mesh, coarse, inner)
    carried = _between_corners(
        moved, [n - 2 for n in sizes], corners, ends, [c.kind for c in curves]
    )
    return densify_curves(mesh, [_without_reversals(mesh, c) for c in carried])


def _without_reversals(mesh: Mesh, curve: SurfaceCurve) -> SurfaceCurve:
    """``curve`` without the points where it turns back (`forward_points`), ends kept.

    Consecutive points of a curve relaxed on the proxy turn little, but their closest
    points on the full mesh can step back and forth across the curve where the proxy lies
    off a curved surface. Densified, such a step is a spike a few fine edges long that the
    fine relaxation removes only slowly (a spike of the proxy's size spans more fine edges
    the denser the scan), and a patch side with a spike folds its spring grid.
    """
    keep = forward_points(mesh.xyz(curve.points))
    if keep.size == len(curve):
        return curve
    return SurfaceCurve(curve.points[keep], curve.closed, curve.kind)


def forward_points(x: NDArray[np.float64]) -> NDArray[np.int64]:
    """The points of a polyline kept so that no chord turns back against the one before.

    One pass with a stack: when the chord to the next point turns back against the last
    kept chord (a negative dot product), the last kept point is dropped, and the test
    repeats against the chord before it. A lone point off to one side (out and back) is
    dropped; of a point and one that steps back behind it, the first goes. Invariant under
    rigid motions and scalings.

    Parameters
    ----------
    x : (n, 3) float64
        The polyline's points, n >= 1.

    Returns
    -------
    (k,) int64
        Increasing row indices of ``x``, with the first and the last.
    """
    keep = [0]
    for k in range(1, len(x)):
        while len(keep) >= 2 and float(np.dot(x[keep[-1]] - x[keep[-2]], x[k] - x[keep[-1]])) < 0:
            keep.pop()
        keep.append(k)
    return np.array(keep, dtype=np.int64)


def _checked(mesh: Mesh, layout: Layout, tries: int = 1) -> Layout:
    """The layout if it cuts the mesh into disks, else a LayoutError with a hint."""
    from meshfit.layout.extract import check_layout_topology

    try:
        check_layout_topology(mesh, layout)
    except MeshfitError as exc:
        rotations = (
            ""
            if tries < 2
            else " (nor with another rotation of the base mesh)"
            if tries == 2
            else f" (nor with {tries - 1} other rotations of the base mesh)"
        )
        raise LayoutError(
            f"the automatic layout of {layout.n_patches} patches does not cut the mesh into "
            f"disks ({str(exc).splitlines()[0]}){rotations}: ask for fewer patches "
            "(--patches) or give a layout file"
        ) from None
    return layout
