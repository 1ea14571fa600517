"""One welded triangle mesh of a patch network: shared boundary vertices appear once.

Each patch is tessellated on a regular grid of its parameter square; the grids of two patches
have equal vertex counts along every shared boundary (:func:`meshfit.stitch.texel_shapes`), so
the boundary rows can be identified node for node. Identifying them (and the corner nodes
where several patches meet), as connected components of those links, gives one vertex per
surface point: a closed patch
network gives a watertight, manifold mesh at every resolution, whatever the residual gaps
between the patches' own tessellations.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from meshfit._kernels import frozen
from meshfit._kernels import weld as _kw
from meshfit.bspline import BSplineSurface, grid_parameters
from meshfit.displacement import DisplacementMap, reconstruct
from meshfit.errors import InputError
from meshfit.export._common import as_maps, as_shapes, as_surfaces
from meshfit.stitch import Network, network_from_grids, texel_shapes
from meshfit.stitch.network import MATCH_BUDGET
from meshfit.types import Side, readonly

__all__ = ["UDIM_COLUMNS", "UDIM_FIRST", "PatchMesh", "patch_mesh", "spline_network", "udim"]

#: tiles per row of the UDIM texture layout: patch p lives in tile column ``p % UDIM_COLUMNS``,
#: row ``p // UDIM_COLUMNS`` (the UDIM convention's 10)
UDIM_COLUMNS = 10
#: the UDIM number of patch 0's tile; patch ``p`` is tile ``UDIM_FIRST + p``
UDIM_FIRST = 1001

#: vertex grid of a spline's own tessellation when the network is found from the splines
#: (odd, so a side has a middle sample)
_NETWORK_GRID = 9


def udim(p: int) -> int:
    """UDIM tile number of patch ``p``: ``1001 + p`` (column ``p % 10``, row ``p // 10``).

    Parameters
    ----------
    p : int
        Patch index, ``p >= 0``.

    Returns
    -------
    int
        ``UDIM_FIRST + p`` (the tile's column ``p % UDIM_COLUMNS`` and row
        ``p // UDIM_COLUMNS`` give ``1001 + column + 10 row``), the number a ``<UDIM>``
        token in an image name stands for.
    """
    p = int(p)
    if p < 0:
        raise InputError(f"patch index must be >= 0, got {p}")
    return UDIM_FIRST + p


_FIELDS = {
    "vertices": np.float64,
    "faces": np.int64,
    "normals": np.float64,
    "uv": np.float64,
    "face_uv": np.int64,
    "face_patch": np.int64,
}


@dataclass(frozen=True, eq=False)
class PatchMesh:
    """A welded tessellation of a patch network, as :func:`patch_mesh` makes it.

    Attributes
    ----------
    vertices : (n, 3) float64
        One vertex per surface point: a vertex on a shared patch boundary or at a network
        corner appears once, at the mean of the patches' own positions there.
    faces : (m, 3) int64
        Triangles into ``vertices``, turning like ``S_u x S_v`` (outward).
    normals : (n, 3) float64
        Unit vertex normals, area-weighted over all faces round the welded vertex.
    uv : (k, 2) float64
        Texture coordinates in the UDIM layout: one row per grid node of each patch, patch
        by patch and row-major within a patch (node ``(i, j)`` of patch ``p`` is row
        ``sum(h_q w_q for q < p) + i w_p + j``), so a boundary vertex has one per patch.
    face_uv : (m, 3) int64
        Corners of each face into ``uv``.
    face_patch : (m,) int64
        Patch of each face; faces are grouped by patch, in patch order.
    shapes : tuple of (int, int)
        Vertex grid ``(h, w)`` of each patch: node ``(i, j)`` is at
        ``(u, v) = (i / (h - 1), j / (w - 1))``.

    Notes
    -----
    The arrays are read-only (the constructor copies writeable ones). ``faces`` and
    ``face_uv`` index the same corners, so ``vertices[faces]`` and ``uv[face_uv]`` are the
    positions and texture coordinates of every face corner.
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    normals: NDArray[np.float64]
    uv: NDArray[np.float64]
    face_uv: NDArray[np.int64]
    face_patch: NDArray[np.int64]
    shapes: tuple[tuple[int, int], ...]

    def __post_init__(self) -> None:
        for name, dtype in _FIELDS.items():
            value = np.asarray(getattr(self, name), dtype=dtype)
            object.__setattr__(self, name, readonly(value))
        object.__setattr__(self, "shapes", tuple((int(h), int(w)) for h, w in self.shapes))
        n, m = len(self.vertices), len(self.faces)
        want = {
            "vertices": (n, 3),
            "faces": (m, 3),
            "normals": (n, 3),
            "uv": (len(self.uv), 2),
            "face_uv": (m, 3),
            "face_patch": (m,),
        }
        for name, shape in want.items():
            a = getattr(self, name)
            if a.shape != shape:
                raise InputError(f"PatchMesh.{name} must have shape {shape}, got {a.shape}")
        for name, bound in (("faces", n), ("face_uv", len(self.uv))):
            a = getattr(self, name)
            if a.size and (a.min() < 0 or a.max() >= bound):
                raise InputError(f"PatchMesh.{name} indexes outside 0 .. {bound - 1}")
        k = sum(h * w for h, w in self.shapes)
        if k != len(self.uv):
            raise InputError(f"PatchMesh.shapes hold {k} grid nodes for {len(self.uv)} uv rows")
        if m and (self.face_patch.min() < 0 or self.face_patch.max() >= len(self.shapes)):
            raise InputError(f"PatchMesh.face_patch indexes outside 0 .. {len(self.shapes) - 1}")

    @property
    def n_patches(self) -> int:
        return len(self.shapes)

    @property
    def uv_vertex(self) -> NDArray[np.int64]:
        """``(k,) int64``: the vertex of each ``uv`` row (-1 for a node no face uses)."""
        out = np.full(len(self.uv), -1, dtype=np.int64)
        out[self.face_uv.ravel()] = self.faces.ravel()
        return out


def spline_network(surfaces: BSplineSurface | Sequence[BSplineSurface]) -> Network:
    """The shared boundaries and corners of B-spline patches, found from where they meet.

    Parameters
    ----------
    surfaces : BSplineSurface or sequence of them

    Returns
    -------
    Network
        :func:`meshfit.stitch.network_from_grids` of each spline evaluated on a 9 x 9 grid:
        sides whose end points agree within ``tol.STITCH_MATCH`` of the bbox diagonal (and
        whose middles are close) are shared. Stitched splines
        (:func:`meshfit.stitch.stitch_surfaces`) meet that closely; unstitched ones may not,
        and then nothing is welded there.

    Raises
    ------
    meshfit.errors.InputError
        A side that matches more than one other side.
    """
    t = grid_parameters(_NETWORK_GRID)
    grids = [np.asarray(s.evaluate_grid(t, t)) for s in as_surfaces(surfaces)]
    return network_from_grids(grids, continuity="C0")


def patch_mesh(
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    maps: DisplacementMap | Sequence[DisplacementMap | None] | None = None,
    network: Network | None = None,
    *,
    shapes: tuple[int, int] | Sequence[tuple[int, int]] | None = None,
    scale: float = 1.0,
) -> PatchMesh:
    """Tessellate a patch network into one welded triangle mesh with UDIM coordinates.

    Parameters
    ----------
    surfaces : BSplineSurface or sequence of them
        The patches, oriented consistently (``S_u x S_v`` outward).
    maps : DisplacementMap or sequence of (DisplacementMap or None), optional
        Per patch: the displaced surface ``S + d`` (:func:`meshfit.displacement.reconstruct`)
        for a vector or scalar map, the spline alone for a bump map or None. A map also sets
        its patch's default grid and texture coordinates (below).
    network : Network, optional
        Shared boundaries and corners of the patches (the fit's, or
        :func:`meshfit.stitch.network_from_grids`); default :func:`spline_network`, found
        from where the splines meet.
    shapes : (int, int) or sequence of them, keyword-only, optional
        Vertex grid ``(h, w)`` of every patch, or one per patch; default the map's texel
        counts, else ``(8 mu, 8 mv)``. Counts along shared boundaries are made equal
        (:func:`meshfit.stitch.texel_shapes`: each takes the largest of its class).
    scale : float, keyword-only
        Multiplies the number of grid intervals: ``n`` nodes become
        ``round((n - 1) scale) + 1`` (at least 2), the same function of ``n`` everywhere, so
        shared boundaries keep equal counts at every resolution. Default 1.

    Returns
    -------
    PatchMesh
        Vertices in the order of their first grid node (patch by patch, row-major), so
        patches that share nothing keep their grids' own order.

    Raises
    ------
    meshfit.errors.InputError
        Bad surfaces, maps, shapes or scale; a network of another patch count; a magnitude
        map (it needs the vector map it came from: reconstruct the surface with that).

    Notes
    -----
    Welding identifies the grid nodes along each shared boundary (in the boundary's own
    direction, reversed where the network says so) and the corner nodes of each network
    corner, by connected components over those links; a welded vertex's position is the
    mean of its nodes, computed once, so every output holds the same bits. Stitched patches
    with maps of equal texel counts along their boundaries agree there to the stitching
    tolerance; where the patches' own tessellations differ (unstitched patches, maps
    resampled to another count) the mean closes the gap. A closed network gives a
    watertight, manifold mesh. A triangle whose corners weld together (a
    patch welded to itself across one cell) is dropped.

    Texture coordinates: patch ``p`` lives in UDIM tile ``udim(p)``, its coordinate being
    ``(p % 10 + x, p // 10 + y)`` with ``x`` along u and ``y`` along v. With a map of
    ``(h_m, w_m)`` texels (texel ``[i, j]`` at ``(u, v) = (i / (h_m - 1), j / (w_m - 1))``)
    they address texel centres, ``x = (u (h_m - 1) + 0.5) / h_m`` and
    ``y = (v (w_m - 1) + 0.5) / w_m``, so bilinear sampling of the map's image (x along u,
    y along v, the first image row at ``v = 1``) reads the map's value at each vertex;
    without a map ``x = u``, ``y = v``.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 8.1.3 (equal counts across a network), sec. 8.2
       (crack-free displaced boundaries).
    """
    surfaces = as_surfaces(surfaces)
    maps_ = as_maps(maps, len(surfaces))
    return _weld(surfaces, maps_, network, shapes, scale, [_texels(m) for m in maps_])


def _texels(m: DisplacementMap | None) -> tuple[int, int] | None:
    return None if m is None else m.shape


def _scaled(n: int, scale: float) -> int:
    return max(1, round((n - 1) * scale)) + 1


def _weld(
    surfaces: list[BSplineSurface],
    maps: list[DisplacementMap | None],
    network: Network | None,
    shapes,
    scale: float,
    texels: Sequence[tuple[int, int] | None],
) -> PatchMesh:
    """:func:`patch_mesh` on validated surfaces and maps, with the texel counts ``texels``
    (one per patch, or None) that set the default grids and the texture coordinates."""
    n = len(surfaces)
    scale = float(scale)
    if not (np.isfinite(scale) and scale > 0):
        raise InputError(f"scale must be a positive number, got {scale}")
    if network is None:
        network = spline_network(surfaces)
    elif network.n_patches != n:
        raise InputError(f"a network of {network.n_patches} patches for {n} surfaces")
    want = as_shapes(shapes, n)
    base = [
        w if w is not None else t if t is not None else (8 * s.shape[0], 8 * s.shape[1])
        for s, w, t in zip(surfaces, want, texels, strict=True)
    ]
    # (capped: a network whose rows differ much in length would multiply the vertices)
    even = texel_shapes(network, base, budget=MATCH_BUDGET)
    grids = [(_scaled(h, scale), _scaled(w, scale)) for h, w in even]
    offs = np.concatenate([[0], np.cumsum([h * w for h, w in grids])]).astype(np.int64)
    points = np.concatenate(
        [
            _grid_points(s, m, sh).reshape(-1, 3)
            for s, m, sh in zip(surfaces, maps, grids, strict=True)
        ]
    )
    vertex_of = _weld_labels(network, grids, offs)
    nv = int(vertex_of.max()) + 1
    vertices = _kw.welded_means(points, vertex_of, nv)
    del points  # (a dense network's largest temporary, before the faces)
    shp = np.asarray(grids, dtype=np.int64).reshape(-1, 2)
    faces, face_uv, face_patch, m = _kw.welded_faces(*frozen(shp, offs, vertex_of))
    if m < len(faces):  # (triangles whose corners welded together were dropped)
        faces, face_uv, face_patch = faces[:m], face_uv[:m], face_patch[:m]
    normals = _kw.unit_vertex_normals(
        _kw.node_normal_sums(*frozen(vertices, vertex_of, shp, offs)), vertex_of, nv
    )
    bad = np.flatnonzero(~np.isfinite(normals).all(axis=1))
    if bad.size:  # no face of area round the vertex: the spline's normal at its first node
        first = np.unique(vertex_of, return_index=True)[1]
        normals[bad] = _node_normals(surfaces, grids, offs, first[bad])
    uv = np.concatenate(
        [_tile_uv(p, sh, t) for p, (sh, t) in enumerate(zip(grids, texels, strict=True))]
    )
    arrays = (vertices, faces, normals, uv, face_uv, face_patch)
    for a in arrays:  # fresh arrays, handed over without copies
        a.flags.writeable = False
    return PatchMesh(*arrays, tuple(grids))


def _grid_points(s: BSplineSurface, m: DisplacementMap | None, shape: tuple[int, int]):
    if m is None:
        return s.evaluate_grid(grid_parameters(shape[0]), grid_parameters(shape[1]))
    return reconstruct(s, m, shape=shape)  # the spline alone for a bump map


def _weld_labels(network: Network, grids, offs: NDArray[np.int64]) -> NDArray[np.int64]:
    """Vertex of every grid node ``(k,) int64``: nodes linked along shared boundaries and at
    corners share one, numbered in order of their first node."""
    k = int(offs[-1])

    def ids(p: int) -> NDArray[np.int64]:
        h, w = grids[p]
        return np.arange(offs[p], offs[p + 1], dtype=np.int64).reshape(h, w)

    a, b = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for sb in network.boundaries:  # equal counts along it (texel_shapes)
        ra = Side(sb.side_a).row(ids(sb.a))
        rb = Side(sb.side_b).row(ids(sb.b))
        if sb.reversed:
            rb = rb[::-1]
        a.append(ra)
        b.append(rb)
    for corner in network.corners:
        slots = np.array([ids(p)[i, j] for p, i, j in corner], dtype=np.int64)
        a.append(slots[:-1])
        b.append(slots[1:])
    ea, eb = np.concatenate(a), np.concatenate(b)
    label = np.arange(k, dtype=np.int64)
    if ea.size:
        nodes, inv = np.unique(np.concatenate([ea, eb]), return_inverse=True)
        inv = inv.ravel()
        links = coo_matrix(
            (np.ones(ea.size, dtype=np.int32), (inv[: ea.size], inv[ea.size :])),
            shape=(nodes.size, nodes.size),
        )
        _, comp = connected_components(links, directed=False)
        # nodes are sorted, so a component's first node is its smallest: its representative
        _, first = np.unique(comp, return_index=True)
        label[nodes] = nodes[first][comp]
    rep = label == np.arange(k)
    return (np.cumsum(rep) - 1)[label]


def _node_normals(surfaces, grids, offs, nodes: NDArray[np.int64]) -> NDArray[np.float64]:
    """Spline normals at grid nodes given by their global index."""
    out = np.zeros((nodes.size, 3))
    patch = np.searchsorted(offs, nodes, side="right") - 1
    for p in np.unique(patch):
        sel = patch == p
        h, w = grids[p]
        i, j = np.divmod(nodes[sel] - offs[p], w)
        out[sel] = surfaces[p].normals(i / (h - 1), j / (w - 1))
    return out


def _tile_uv(p: int, shape: tuple[int, int], texels: tuple[int, int] | None) -> NDArray:
    """UDIM coordinates ``(h w, 2)`` of patch ``p``'s grid nodes, row-major."""
    x, y = grid_parameters(shape[0]), grid_parameters(shape[1])
    if texels is not None:
        hm, wm = texels
        x = (x * (hm - 1) + 0.5) / hm
        y = (y * (wm - 1) + 0.5) / wm
    X, Y = np.meshgrid(p % UDIM_COLUMNS + x, p // UDIM_COLUMNS + y, indexing="ij")
    return np.stack([X.ravel(), Y.ravel()], axis=1)
