"""A mesh store's faces sorted into the patches of a layout made on its proxy.

The out-of-core preparation lays a dense scan out on a coarse proxy
(:func:`meshfit.shrinkwrap.proxy.simplify_store`), cuts the proxy into its patches, and
then needs each patch's share of the full mesh without ever holding the full mesh:
:func:`assign_faces` streams the store's bricks, gives each face the patch of the point of
the cut proxy nearest its centroid (its *core* patch), and adds it to the *halo* of every
other patch whose boundary passes within ``halo`` of that centroid. Near a patch boundary
the proxy and the scan differ by up to the proxy's deviation, so the nearest proxy point
may lie across the boundary from where the scan's own curve will run; the halo holds
every face a patch's cut along its carried curves can need. The result is a
:class:`PatchStore`: each patch's faces (core, then halo) as one run of a memory-mapped
array, which a worker reads alone.

Layout of a patch store folder: ``patches.json`` (format, version, counts, the halo
width), ``faces.npy`` (n, 3) int64 (vertex indices of the mesh store), ``store_face.npy``
(n,) int64 (face of the mesh store), ``core.npy`` (n,) bool and ``patch_start.npy``
(n_patches + 1,) int64.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from meshfit import errors, tol
from meshfit._threads import map_threads, n_workers
from meshfit.mesh import Mesh
from meshfit.mesh.store import check_new_folder, load_array, read_meta, writing_folder
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = [
    "HALO_EDGES",
    "PATCHES_FORMAT",
    "PATCHES_VERSION",
    "PatchPiece",
    "PatchStore",
    "assign_faces",
    "open_patch_store",
]

PATCHES_FORMAT = "meshfit-patch-store"
PATCHES_VERSION = 1
#: default halo width in mean edge lengths of the proxy (`_proxy_edge`)
HALO_EDGES = 1.0
#: a scan face whose reach and distance from the proxy add up to at most this share of a
#: proxy edge takes the halo patches of its proxy piece (`assign_faces`)
PIECE_MARGIN = 0.5
#: boundary samples per halo width along each patch boundary
_SAMPLES_PER_HALO = 3
#: boundary samples searched per face centroid for its halo patches
_NEAREST = 48
#: centroids searched at once
_QUERY_CHUNK = 1 << 15


@dataclass(frozen=True, eq=False)
class PatchPiece:
    """One patch's faces of a mesh store (:meth:`PatchStore.piece`).

    Attributes
    ----------
    mesh : Mesh
        The faces as a mesh of their own (core and halo).
    vertex_ids : (nv,) int64
        Vertex of the mesh store of each vertex of ``mesh`` (a vertex where the piece
        pinches has a copy per fan).
    store_face : (nf,) int64
        Face of the mesh store of each face of ``mesh``.
    core : (nf,) bool
        Whether the face's nearest proxy point is in this patch (else it is halo).
    """

    mesh: Mesh
    vertex_ids: NDArray[np.int64]
    store_face: NDArray[np.int64]
    core: NDArray[np.bool_]


@dataclass(frozen=True, eq=False)
class PatchStore:
    """Faces of a mesh store by patch (:func:`assign_faces`, :func:`open_patch_store`).

    Attributes
    ----------
    folder : Path
    faces, store_face, core : memory-mapped, read-only
        All patches' faces, patch by patch (see the module).
    patch_start : (n_patches + 1,) int64
    halo : float
        The halo width, model units.
    scale : (float, float)
        The whole scan's mean edge length and bounding-box diagonal: the tolerances of
        every piece's cut.
    """

    folder: Path
    faces: NDArray[np.int64]
    store_face: NDArray[np.int64]
    core: NDArray[np.bool_]
    patch_start: NDArray[np.int64]
    halo: float
    scale: tuple[float, float]

    @property
    def n_patches(self) -> int:
        return int(self.patch_start.size - 1)

    def piece(self, p: int, vertices: NDArray[np.float64]) -> PatchPiece:
        """Patch ``p``'s faces as a mesh, its vertices read from ``vertices`` (the mesh
        store's, memory-mapped)."""
        if not 0 <= p < self.n_patches:
            raise errors.InputError(f"patch {p} out of range ({self.n_patches} patches)")
        a, b = self.patch_start[p], self.patch_start[p + 1]
        mesh, ids = _piece_mesh(vertices, np.array(self.faces[a:b]), f"patch{p}")
        return PatchPiece(mesh, ids, np.array(self.store_face[a:b]), np.array(self.core[a:b]))


def _piece_mesh(vertices, faces: NDArray[np.int64], name: str) -> tuple[Mesh, NDArray[np.int64]]:
    """Store faces (store vertex indices) as a mesh of their own, and the store vertex of each
    of its vertices. A piece of a manifold surface can pinch where two of its fans meet at
    one vertex: such a vertex gets a copy per fan (so an id may repeat)."""
    from meshfit.mesh.validate import _split_fans

    used, local = np.unique(faces, return_inverse=True)
    local, parent = _split_fans(local.reshape(-1, 3).astype(np.int64), used.size)
    ids = used[parent]
    return Mesh(np.array(vertices[ids]), local, name=name), ids


def open_patch_store(folder: str | os.PathLike) -> PatchStore:
    """The patch store written by :func:`assign_faces` in ``folder``.

    Raises
    ------
    meshfit.errors.InputError
        Not a patch store, another version, or arrays that disagree with ``patches.json``.
    """
    root = Path(folder)
    meta_path, meta = read_meta(
        root, "patches.json", PATCHES_FORMAT, PATCHES_VERSION, "patch store"
    )
    try:
        n, n_patches, halo = int(meta["n_rows"]), int(meta["n_patches"]), float(meta["halo"])
        scale = (float(meta["scale"][0]), float(meta["scale"][1]))
    except (KeyError, TypeError, ValueError) as exc:
        raise errors.InputError(f"{meta_path}: missing or malformed field ({exc})") from None

    def load(name: str, shape: tuple[int, ...], dtype) -> NDArray:
        return load_array(root, name, shape, dtype, "patches.json")

    if min(n, n_patches) < 0:
        raise errors.InputError(f"{meta_path}: negative counts")
    faces = load("faces.npy", (n, 3), np.int64)
    store_face = load("store_face.npy", (n,), np.int64)
    core = load("core.npy", (n,), np.bool_)
    start = np.array(load("patch_start.npy", (n_patches + 1,), np.int64))
    if start[0] != 0 or start[-1] != n or (np.diff(start) < 0).any():
        raise errors.InputError(f"{root / 'patch_start.npy'}: not the starts of {n} rows")
    return PatchStore(root, faces, store_face, core, start, halo, scale)


def _boundary_samples(
    patches: Sequence, spacing: float
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Points along every patch's boundary loop, at most ``spacing`` apart, and the patch of
    each (a curve shared by two patches is sampled for both); of a patch's samples in one
    cell of a grid of ``spacing / 2``, the first (a cut proxy's boundary crowds its
    vertices by the corners, and a search near them would meet hundreds)."""
    pts, lab = [], []
    for p in patches:
        loop = np.concatenate([s[:-1] for s in p.sides])
        x = p.mesh.vertices[loop]
        y = np.roll(x, -1, axis=0)
        n = np.maximum(1, np.ceil(np.linalg.norm(y - x, axis=1) / spacing).astype(np.int64))
        t = (np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
        seg = np.repeat(np.arange(len(x)), n)
        q = x[seg] + t[:, None] * (y[seg] - x[seg])
        cell = np.floor(q / (0.5 * spacing)).astype(np.int64)
        _, first = np.unique(cell, axis=0, return_index=True)
        first.sort()
        pts.append(q[first])
        lab.append(np.full(first.size, p.index, dtype=np.int64))
    return np.concatenate(pts), np.concatenate(lab)


def _proxy_edge(patches: Sequence) -> float:
    """Side of the equilateral triangle of the uncut proxy's mean face area (the cut's
    slivers would shorten a mean of the patches' own edges)."""
    area = sum(float(p.mesh.face_areas.sum()) for p in patches)
    n = np.unique(np.concatenate([p.face_parent for p in patches])).size
    return float(np.sqrt(4.0 * area / (np.sqrt(3.0) * max(n, 1))))


def _halo_pairs(tree, sample_patch, c, reach, core, n_patches: int) -> NDArray[np.int64]:
    """(face, patch) rows, faces as indices into ``c``: each face with boundary samples of
    another patch than its ``core`` one within ``reach`` of its centroid, and those patches,
    sorted.

    The `_NEAREST` nearest samples of each centroid are searched, and all samples within
    reach of the few centroids whose `_NEAREST` are all that near (by a corner where many
    patches meet)."""
    if not len(c) or reach.max() <= 0:
        return np.zeros((0, 2), dtype=np.int64)
    d, _ = tree.query(c, k=1, distance_upper_bound=float(reach.max()))
    close = np.flatnonzero(d <= reach)
    keys = []
    for a in range(0, close.size, _QUERY_CHUNK):
        i = close[a : a + _QUERY_CHUNK]
        r = reach[i]
        d, j = tree.query(c[i], k=_NEAREST, distance_upper_bound=float(r.max()))
        ok = d <= r[:, None]
        lab = sample_patch[np.where(ok, j, 0)]
        ok &= lab != core[i][:, None]
        keys.append(i[:, None].repeat(_NEAREST, 1)[ok] * n_patches + lab[ok])
        full = np.flatnonzero(d[:, -1] <= r)  # (more samples within: all of them)
        if full.size:
            near = tree.query_ball_point(c[i[full]], r[full])
            f = np.repeat(i[full], [len(x) for x in near])
            lab = sample_patch[np.fromiter((j for x in near for j in x), np.int64, f.size)]
            keep = lab != core[f]
            keys.append(f[keep] * n_patches + lab[keep])
    key = np.unique(np.concatenate(keys)) if keys else np.zeros(0, np.int64)
    return np.stack([key // n_patches, key % n_patches], axis=1)


def assign_faces(
    store,
    patches: Sequence,
    folder: str | os.PathLike,
    *,
    halo: float | None = None,
    workers: int | None = 1,
    progress: Callable[[int, int], None] | None = None,
) -> PatchStore:
    """Sort the faces of a mesh store into the patches of its proxy: a patch store.

    Parameters
    ----------
    store : meshfit.mesh.store.MeshStore
    patches : sequence of Patch
        The proxy cut along its layout (:func:`meshfit.layout.extract_patches`), in the
        layout's patch order.
    folder : path
        A new (or empty) folder; written through a temporary sibling renamed at the end.
    halo : float, optional
        Model units; default `HALO_EDGES` times the side of an equilateral triangle of the
        proxy's mean face area (a proxy's faces are far larger than the scan's, so this
        covers a scan face cut by a curve and the proxy's deviation from the scan).
    workers : int or None
        Threads sorting the bricks (None: one per core); the store is the same for any.
    progress : callable(done, total), optional
        After each brick of each of the two passes.

    Returns
    -------
    PatchStore
        Every store face is the core face of exactly one patch; a face that comes within
        ``halo`` of another patch's boundary (its centroid within ``halo`` plus the face's
        reach from its centroid to its farthest corner) is in that patch's halo too. So
        is a face whose proxy piece comes within ``halo`` plus `PIECE_MARGIN` proxy edges
        plus the piece's own reach of it: each piece's halo patches are found once and a
        scan face near the proxy takes its piece's (those of a face whose reach and
        distance from the proxy add up to more are searched for that face alone).
    """
    root = Path(folder)
    check_new_folder(root)
    if not patches:
        raise errors.InputError("no patches to sort the faces into")
    n_patches = len(patches)
    if [p.index for p in patches] != list(range(n_patches)):
        raise errors.InputError("the patches must be the layout's, in its order")
    offsets = np.cumsum([0] + [p.mesh.n_vertices for p in patches])
    soup = Mesh(
        np.concatenate([p.mesh.vertices for p in patches]),
        np.concatenate([p.mesh.faces + o for p, o in zip(patches, offsets, strict=False)]),
        name="cut proxy",
    )
    soup_patch = np.repeat(np.arange(n_patches), [p.mesh.n_faces for p in patches])
    width = float(HALO_EDGES * _proxy_edge(patches) if halo is None else halo)
    if not np.isfinite(width) or width < 0:
        raise errors.InputError(f"halo must be a length >= 0, got {halo!r}")
    samples, sample_patch = _boundary_samples(patches, max(width, 1e-300) / _SAMPLES_PER_HALO)
    tree = cKDTree(samples)
    # each proxy piece's halo patches, wide enough for any scan face near it whose reach
    # and distance from the proxy add up to at most `margin` (the others are searched
    # face by face)
    margin = PIECE_MARGIN * _proxy_edge(patches)
    sx = soup.vertices[soup.faces]
    sc = sx.mean(axis=1)
    s_reach = width + margin + np.sqrt(((sx - sc[:, None]) ** 2).sum(axis=2).max(axis=1))
    s_pairs = _halo_pairs(tree, sample_patch, sc, s_reach, soup_patch, n_patches)
    s_ptr = np.searchsorted(s_pairs[:, 0], np.arange(soup.n_faces + 1))
    nb = store.n_bricks
    with writing_folder(root) as tmp:
        # 1. per brick: each face's core patch and its halo patches, as (face, patch, core)
        # rows kept in the scratch folder; rows per patch counted
        def rows_of(b: int) -> tuple[NDArray[np.int64], float]:
            a = int(store.brick_start[b])
            f = store.brick(b)
            x = np.asarray(store.vertices)[f.reshape(-1)].reshape(-1, 3, 3)
            c = x.mean(axis=1)
            near = soup.closest_points(c)
            piece = near.points.face
            core = soup_patch[piece]
            # a face reaches as far as its farthest corner from its centroid
            own = np.sqrt(((x - c[:, None]) ** 2).sum(axis=2).max(axis=1))
            edges = float(np.linalg.norm(x - np.roll(x, -1, axis=1), axis=2).sum())
            face = np.arange(a, a + f.shape[0], dtype=np.int64)
            # the halo patches of the face's proxy piece, which hold every patch the face
            # comes within ``width`` of when own + distance <= margin (triangle inequality);
            # the rest searched on their own
            inside = own + near.distance <= margin
            i = np.flatnonzero(inside)
            k = s_ptr[piece[i] + 1] - s_ptr[piece[i]]
            at = np.repeat(s_ptr[piece[i]], k) + (
                np.arange(int(k.sum())) - np.repeat(np.cumsum(k) - k, k)
            )
            mine = np.stack([np.repeat(i, k), s_pairs[at, 1]], axis=1)
            o = np.flatnonzero(~inside)
            rest = _halo_pairs(tree, sample_patch, c[o], width + own[o], core[o], n_patches)
            rest[:, 0] = o[rest[:, 0]]
            pair = np.concatenate([mine, rest]) + np.array([a, 0])
            rows_f = np.concatenate([face, pair[:, 0]])
            rows_p = np.concatenate([core, pair[:, 1]])
            rows_c = np.concatenate([np.ones(face.size, bool), np.zeros(len(pair), bool)])
            np.save(tmp / f"rows_{b}.npy", np.stack([rows_f, rows_p, rows_c], axis=1))
            return np.bincount(rows_p, minlength=n_patches), edges

        tick = None if progress is None else (lambda k, _: progress(k, 2 * nb))
        out = map_threads(rows_of, list(range(nb)), n_workers(workers), progress=tick)
        count = np.sum([r[0] for r in out], axis=0).astype(np.int64)
        edge_sum = math.fsum(r[1] for r in out)
        # 2. the rows placed patch by patch: core rows first (every brick's), then halo
        total = int(count.sum())
        start = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
        out_f = np.lib.format.open_memmap(tmp / "faces.npy", "w+", np.int64, (total, 3))
        out_s = np.lib.format.open_memmap(tmp / "store_face.npy", "w+", np.int64, (total,))
        out_c = np.lib.format.open_memmap(tmp / "core.npy", "w+", np.bool_, (total,))
        cursor = start[:-1].copy()
        for want_core in (True, False):
            for b in range(nb):
                rows = np.load(tmp / f"rows_{b}.npy")
                rows = rows[rows[:, 2].astype(bool) == want_core]
                order = np.argsort(rows[:, 1], kind="stable")
                rows = rows[order]
                p = rows[:, 1]
                first = np.searchsorted(p, np.arange(n_patches), "left")
                at = cursor[p] + (np.arange(p.size) - first[p])
                out_f[at] = store.faces[rows[:, 0]]
                out_s[at] = rows[:, 0]
                out_c[at] = want_core
                cursor += np.bincount(p, minlength=n_patches)
                if not want_core:
                    (tmp / f"rows_{b}.npy").unlink()
                    if progress is not None:
                        progress(nb + b + 1, 2 * nb)
        for arr in (out_f, out_s, out_c):
            arr.flush()
        np.save(tmp / "patch_start.npy", start)
        meta = {
            "format": PATCHES_FORMAT,
            "version": PATCHES_VERSION,
            "n_rows": total,
            "n_patches": n_patches,
            "halo": width,
            "core_rows": int(store.n_faces),
            # (each edge of a closed surface is on two faces: the mean over its edges)
            "scale": [
                edge_sum / max(3 * store.n_faces, 1),
                float(np.linalg.norm(store.bbox[1] - store.bbox[0])),
            ],
        }
        (tmp / "patches.json").write_text(json.dumps(meta, indent=1))
    return open_patch_store(root)


# ----------------------------------------------------------------------------- the cut


@dataclass(frozen=True, eq=False)
class CarriedNetwork:
    """A proxy layout's corners and curves carried to the scan of a mesh store, as points
    of the store's faces (:func:`carry_network`): each curve once, so the two patches it
    bounds cut the scan along the same points.

    Attributes
    ----------
    corners : SurfacePoints
        Faces are store faces.
    curves : list of SurfaceCurve
        Faces are store faces; curve ``i`` from corner ``layout.curve_ends[i, 0]``.
    """

    corners: SurfacePoints
    curves: list[SurfaceCurve]


def _to_local(piece: PatchPiece, points: SurfacePoints, what: str) -> SurfacePoints:
    """Store-face points as points of ``piece`` (LayoutError where a face is not in it)."""
    order = np.argsort(piece.store_face, kind="stable")
    at = np.searchsorted(piece.store_face, points.face, sorter=order)
    at = np.minimum(at, order.size - 1)
    local = order[at]
    missing = piece.store_face[local] != points.face
    if missing.any():
        raise errors.LayoutError(
            f"{what} passes through store face {int(points.face[np.argmax(missing)])}, "
            "outside the patch's piece: the halo is narrower than the proxy's distance from "
            "the scan (a larger halo, or a finer proxy)"
        )
    return SurfacePoints(local, points.bary)


def _to_store(piece: PatchPiece, points: SurfacePoints) -> SurfacePoints:
    return SurfacePoints(piece.store_face[points.face], points.bary)


def _resampled(x: NDArray[np.float64], spacing: float) -> NDArray[np.float64]:
    """The polyline ``x`` with points inserted so that none is more than ``spacing`` from
    the next (its own points kept)."""
    seg = np.diff(x, axis=0)
    n = np.maximum(1, np.ceil(np.linalg.norm(seg, axis=1) / spacing).astype(np.int64))
    t = (np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
    i = np.repeat(np.arange(len(seg)), n)
    return np.concatenate([x[i] + t[:, None] * seg[i], x[-1:]])


#: a carried curve keeps no sample nearer its corner than where it is this many times the
#: proxy's distance from the scan (at least a scan edge) away from the nearest other curve
#: leaving that corner (`_clearances`); none where the proxy lies on the scan
CORNER_CLEARANCE = 2.0


def _walk_out(
    mesh: Mesh, corner: SurfacePoints, target: NDArray[np.float64], spacing: float, clear: float
) -> SurfacePoints:
    """Points of the straight surface walk from ``corner`` toward ``target``, ``spacing``
    apart (each the end of a walk of its own length from the corner, so all lie on one
    straight line of the unfolded surface), without the corner and the last; none when
    ``clear`` is 0."""
    from meshfit.surface.walk import walk_points

    v = target - mesh.xyz(corner)[0]
    m = int(np.ceil(float(np.linalg.norm(v)) / spacing))
    if clear <= 0 or m < 2:
        return SurfacePoints(np.zeros(0, np.int64), np.zeros((0, 3)))
    t = np.arange(1, m) / m
    start = SurfacePoints(np.repeat(corner.face, t.size), np.repeat(corner.bary, t.size, 0))
    return walk_points(mesh, start, t[:, None] * v).end


def _clearances(proxy: Mesh, layout) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per curve and end: ``1 / (2 sin(t / 2))`` for the angle ``t`` at which the nearest
    other curve leaves the same corner (0 for none), and a third of the curve's chord.

    Two curves leaving a corner at an angle ``t`` are ``2 r sin(t / 2)`` apart at distance
    ``r``; where that is less than about the proxy's distance ``d`` from the scan, the
    closest points of both may fall on one scan vertex (a convex scan maps a region of
    space of about that size onto a vertex, and one scan face may hold both) and the curves
    touch. Within `CORNER_CLEARANCE` ``max(d, scan edge)`` times the first figure of the
    corner (at most the second), the samples are dropped and the curve walks straight out
    of the corner instead."""
    ends = np.asarray(layout.curve_ends)
    n = ends.shape[0]
    direction = np.zeros((n, 2, 3))
    chord = np.zeros(n)
    for k, curve in enumerate(layout.curves):
        x = proxy.xyz(curve.points)
        chord[k] = float(np.linalg.norm(x[-1] - x[0]))
        for e, (a, y) in enumerate(((x[0], x), (x[-1], x[::-1]))):
            d = np.linalg.norm(y - a, axis=1)
            # the direction to the first point a proxy edge out (or the far end)
            far = np.flatnonzero(d >= min(proxy.mean_edge_length, d.max()))
            v = y[far[0]] - a
            direction[k, e] = v / max(float(np.linalg.norm(v)), 1e-300)
    out = np.zeros(2 * n)
    cap = np.repeat(chord[:, None] / 3.0, 2, axis=1)
    # the curve ends at each corner together: the largest cosine to another end there
    flat_dir = direction.reshape(-1, 3)
    at = ends.reshape(-1)
    order = np.argsort(at, kind="stable")
    bounds = np.flatnonzero(np.diff(at[order])) + 1
    for group in np.split(order, bounds):
        if group.size < 2:
            continue
        cos = flat_dir[group] @ flat_dir[group].T
        np.fill_diagonal(cos, -np.inf)
        half = 0.5 * np.arccos(np.clip(cos.max(axis=1), -1.0, 1.0))
        out[group] = 1.0 / np.maximum(2.0 * np.sin(half), 1e-12)
    return out.reshape(n, 2), cap


def carry_network(
    store, pstore: PatchStore, proxy: Mesh, layout, relax_iterations: int | None = None
) -> CarriedNetwork:
    """Carry the corners and curves of ``layout`` (made on ``proxy``) to the scan, each
    curve once, on the piece of the first patch it bounds: the proxy's polyline sampled
    at half the scan's edge length, the samples moved to their closest points of the scan
    (so two curves that leave a corner close together stay apart, as the projection of a
    nearby surface onto the scan does not fold), points where the carried curve turns back
    dropped, the rest joined on the scan's surface and relaxed there as snakes with fixed
    ends (as the in-memory proxy layout carries its curves, :mod:`meshfit.layout.auto`).
    One piece at a time is in memory.

    Parameters
    ----------
    store : MeshStore
    pstore : PatchStore
        The store's faces sorted into the layout's patches (:func:`assign_faces`).
    proxy : Mesh
    layout : Layout
        Made on ``proxy``.
    relax_iterations : int, optional
        Snake iterations of each carried curve on the scan (default
        :data:`meshfit.layout.auto.FINE_RELAX_ITERATIONS`; 0: none).

    Returns
    -------
    CarriedNetwork

    Raises
    ------
    meshfit.errors.LayoutError
        A curve or corner on no patch, or a carried curve outside its patch's piece.
    """
    from meshfit.curves.base import densify_curves
    from meshfit.layout.auto import (
        FINE_RELAX_ITERATIONS,
        _relax_all,
        _without_reversals,
        forward_points,
    )

    if relax_iterations is None:
        relax_iterations = FINE_RELAX_ITERATIONS

    pc = np.asarray(layout.patch_curves)
    ends = np.asarray(layout.curve_ends)
    corner_patch = np.full(layout.corners.face.size, -1, dtype=np.int64)
    for p in range(pc.shape[0]):
        for c in ends[pc[p]].reshape(-1):
            if corner_patch[c] < 0:
                corner_patch[c] = p
    if (corner_patch < 0).any():
        raise errors.LayoutError(f"corner {int(np.argmin(corner_patch))} is on no patch")
    x = proxy.xyz(layout.corners)
    face = np.empty(x.shape[0], dtype=np.int64)
    bary = np.empty((x.shape[0], 3))
    # each curve on the piece of the first patch it bounds (its halo holds the scan along
    # the curve), a piece read once for all the corners and curves it carries; a curve's
    # corners are corners of its patch, so they are placed by then
    owner = np.full(len(layout.curves), -1, dtype=np.int64)
    for p in range(pc.shape[0] - 1, -1, -1):
        owner[pc[p]] = p
    if (owner < 0).any():
        raise errors.LayoutError(f"curve {int(np.argmin(owner))} bounds no patch")
    curves: list[SurfaceCurve | None] = [None] * len(layout.curves)
    edge = float(pstore.scale[0])
    exact = tol.ON_SURFACE * float(pstore.scale[1])  # (a proxy that is the scan there)
    spread, cap = _clearances(proxy, layout)
    for p in np.union1d(corner_patch, owner).tolist():
        piece = pstore.piece(p, store.vertices)
        sel = np.flatnonzero(corner_patch == p)
        if sel.size:
            got = _to_store(piece, piece.mesh.closest_points(x[sel]).points)
            face[sel], bary[sel] = got.face, got.bary
        spacing = 0.5 * edge
        carried: dict[int, SurfaceCurve] = {}
        for k in np.flatnonzero(owner == p).tolist():
            curve = layout.curves[k]
            xs = _resampled(proxy.xyz(curve.points), spacing)
            # samples by a corner dropped: the curve walks straight out of the corner to
            # the first sample kept (two such walks from one corner part at once)
            near = piece.mesh.closest_points(xs)
            from_a = np.linalg.norm(xs - xs[0], axis=1)
            from_b = np.linalg.norm(xs - xs[-1], axis=1)
            off_a = near.distance[from_a <= cap[k, 0]].max(initial=0.0)
            off_b = near.distance[from_b <= cap[k, 1]].max(initial=0.0)
            clear = tuple(
                0.0
                if off <= exact
                else min(CORNER_CLEARANCE * max(off, edge) * spread[k, e], cap[k, e])
                for e, off in enumerate((off_a, off_b))
            )
            keep = (from_a > clear[0]) & (from_b > clear[1])
            # where the proxy's own polyline turns back (a zigzag the proxy's relaxation
            # left, too small for the proxy's grids to fold on), its samples go
            forward = np.zeros(len(xs), dtype=bool)
            forward[forward_points(xs)] = True
            keep &= forward
            keep[0] = keep[-1] = False
            if not keep.any():
                keep[len(xs) // 2] = True
            mid = xs[keep]
            ends_k = SurfacePoints(face[ends[k]], bary[ends[k]])
            local = _to_local(piece, ends_k, f"curve {k}'s corners")
            moved = near.points[np.flatnonzero(keep)]
            a_out = _walk_out(piece.mesh, local[np.array([0])], mid[0], spacing, clear[0])
            b_out = _walk_out(piece.mesh, local[np.array([1])], mid[-1], spacing, clear[1])
            pts = SurfacePoints.concatenate(
                [local[np.array([0])], a_out, moved, b_out[::-1], local[np.array([1])]]
            )
            same = (pts.face[1:] == pts.face[:-1]) & (pts.bary[1:] == pts.bary[:-1]).all(axis=1)
            pts = pts[np.flatnonzero(np.concatenate([[True], ~same]))]
            c = SurfaceCurve(pts, False, curve.kind)
            (c,) = densify_curves(piece.mesh, [_without_reversals(piece.mesh, c)])
            carried[k] = c
        if relax_iterations > 0 and carried:
            # the local correction on the scan that the in-memory proxy route makes
            # (:data:`meshfit.layout.auto.FINE_RELAX_ITERATIONS`), ends fixed
            ks = list(carried)
            relaxed = _relax_all(piece.mesh, [carried[k] for k in ks], relax_iterations)
            carried = dict(zip(ks, relaxed, strict=True))
        for k, c in carried.items():
            curves[k] = SurfaceCurve(_to_store(piece, c.points), c.closed, c.kind)
    return CarriedNetwork(SurfacePoints(face, bary), [c for c in curves if c is not None])


def cut_patch(store, pstore: PatchStore, layout, network: CarriedNetwork, p: int):
    """Patch ``p`` of the scan: its piece cut along its four carried sides
    (:func:`meshfit.layout.extract.extract_patch_within`), its ``face_parent`` and
    ``vertex_source`` in store faces.

    Parameters
    ----------
    store : MeshStore
    pstore : PatchStore
    layout : Layout
        The proxy's.
    network : CarriedNetwork
        ``layout`` carried to the scan (:func:`carry_network`).
    p : int

    Returns
    -------
    Patch
        Its mesh a submesh of the piece (vertices in model units).

    Raises
    ------
    meshfit.errors.LayoutError
        A side that leaves the piece, or sides that cross or touch away from the corners.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 5.3 (each patch resampled on its own), sec. 8.1.3
       (patches sharing boundary curves and corners).
    """
    from meshfit.layout.extract import extract_patch_within
    from meshfit.layout.layout import layout_from_curves
    from meshfit.layout.patch import Patch

    piece = pstore.piece(p, store.vertices)
    # the sides' curves go in in the layout's order, as the whole mesh's cut takes them
    # (where two curves meet, the second is cut into the first's split faces)
    order = np.argsort(layout.patch_curves[p], kind="stable")
    sides = np.asarray(layout.patch_curves[p])[order]
    rev = np.asarray(layout.patch_reversed[p])
    slot = np.empty(4, dtype=np.int64)
    slot[order] = np.arange(4)
    ends = np.asarray(layout.curve_ends)[sides]
    ids, local_ends = np.unique(ends, return_inverse=True)
    corners = _to_local(piece, network.corners[ids], f"patch {p}'s corners")
    curves: list[SurfaceCurve | SurfacePoints] = [
        SurfaceCurve(
            _to_local(piece, network.curves[k].points, f"curve {k}"),
            False,
            network.curves[k].kind,
        )
        for k in sides.tolist()
    ]
    creases = None if layout.creases is None else np.asarray(layout.creases)[sides]
    one = layout_from_curves(
        piece.mesh,
        corners,
        curves,
        local_ends.reshape(-1, 2),
        [[(int(slot[s]), bool(rev[s])) for s in range(4)]],
        creases=creases,
    )
    cut = extract_patch_within(piece.mesh, one, 0, scale=pstore.scale)
    src = cut.vertex_source
    return Patch(
        p,
        cut.mesh,
        cut.corners,
        cut.sides,
        piece.store_face[cut.face_parent],
        SurfacePoints(piece.store_face[src.face], src.bary),
        (),
        (),
    )
