"""Patch extraction: cut the mesh along every boundary curve and take each patch as a submesh.

Method
------
1. One network cut (:func:`meshfit.surface.cut.cut_mesh_network`) inserts all curves into one
   triangulation, each corner once, and splits the mesh along the union of the cut edges.
   Curves meeting away from their corners are an error.
2. The face components of the split mesh are the patch regions (found through shared
   vertices: the split leaves one fan of faces around every vertex). Each is checked as a
   mesh of its own, on threads, and must be a disk: one boundary loop and Euler
   characteristic 1 (a second loop means a hole of the mesh inside the region, a lower
   characteristic a handle).
3. A region's boundary loop, in half-edge order (the region on the left), is split at the
   corners into chains; each chain runs along one curve, forwards or backwards. The cyclic
   sequence of (curve, reversed) pairs is matched against the layout's patches, which fixes
   the patch's corner 0 and side order.
4. Every face must belong to a patch: a region that is no patch of the layout is an error
   naming one of its faces (the policy for closed and open meshes alike; on an open mesh the
   layout's curves run along the mesh boundary where a patch side lies on it).
5. Feature curves are mapped to face points of the patch submesh (each point into the
   sub-triangle of its original face that holds it), and their ends snapped onto the nearest
   side.
"""

from __future__ import annotations

import threading
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial

import numpy as np
from numpy.typing import NDArray

from meshfit import _threads, tol
from meshfit._kernels.topology import vertex_face_components
from meshfit.errors import CutError, LayoutError, MeshfitError
from meshfit.layout.layout import Layout, check_layout
from meshfit.layout.patch import Patch, loop_bulge
from meshfit.mesh import Mesh
from meshfit.mesh.locate import barycentric
from meshfit.surface.cut import NetworkCutArrays, network_cut_arrays
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = ["check_layout_topology", "extract_patch_within", "extract_patches", "patch_bulges"]


@dataclass
class _Region:
    """One face component of the split mesh matched to a layout patch."""

    patch: int
    faces: NDArray[np.int64]  # faces of the split mesh
    loop: NDArray[np.int64]  # boundary loop (split-mesh vertices), starting at corner 0
    corner_pos: list[int]  # positions in ``loop`` of corners 0..3
    sub: Mesh  # the region as a checked mesh (named for its component)
    used: NDArray[np.int64]  # split-mesh vertex of each vertex of ``sub`` (ascending)


#: the last partition computed, for the mesh and layout objects it was computed for (both are
#: immutable): ``load_layout`` checks a layout by partitioning the mesh, and the
#: ``extract_patches`` call that usually follows reuses that work
_LAST: list = [None]
_LAST_LOCK = threading.Lock()


def forget_partition() -> None:
    """Drop the kept partition (its regions' meshes are as large as the mesh itself): a fit
    calls this once its patches are made."""
    with _LAST_LOCK:
        _LAST[0] = None


def _partition(
    mesh: Mesh,
    layout: Layout,
    progress: Callable[[int, int], None] | None,
    workers: int | None = None,
) -> tuple[NetworkCutArrays, list[_Region], int]:
    """The cut, the regions matched to patches and the number of regions (the last ones
    computed are kept for the same mesh and layout objects)."""
    with _LAST_LOCK:
        last = _LAST[0]
        if last is not None and last[0]() is mesh and last[1]() is layout:
            return last[2]
    out = _compute_partition(mesh, layout, progress, workers)
    with _LAST_LOCK:
        _LAST[0] = (weakref.ref(mesh), weakref.ref(layout), out)
    return out


def _piece(
    mesh: Mesh, cut: NetworkCutArrays, faces: NDArray[np.int64], c: int
) -> tuple[Mesh, NDArray[np.int64], int] | MeshfitError:
    """Region ``c`` (split-mesh ``faces``) as a checked mesh with its boundary loops traced,
    the split-mesh vertex of each of its vertices and its Euler characteristic; or the error
    the check raised. The region's adjacency is dropped once the loops are traced: over a
    dense scan the regions' tables together are as large as the mesh's own, and the patch
    that keeps the region derives what it needs when its spring mesh is made."""
    F = cut.faces[faces]
    used, inv = np.unique(F.reshape(-1), return_inverse=True)
    colors = None if cut.colors is None else cut.colors[used]
    try:
        sub = Mesh(
            cut.vertices[used],
            inv.reshape(-1, 3).astype(np.int64),
            colors,
            name=f"{mesh.name or 'mesh'}-region{c}",
        )
    except MeshfitError as exc:
        return exc
    _ = sub.boundary_loops
    chi = sub.euler_characteristic
    sub.drop_caches(keep=("boundary_loops",))
    return sub, used, chi


def _cut_regions(mesh: Mesh, layout: Layout, scale: tuple[float, float] | None):
    """The mesh cut along the layout's curves (tolerances scaled by ``scale``, see
    :func:`meshfit.surface.cut.network_cut_arrays`) and its regions: ``(cut, along,
    is_corner, n_regions, order, starts)``, region ``c``'s faces of the cut mesh being
    ``order[starts[c]:starts[c + 1]]``, ascending."""
    check_layout(mesh, layout)
    try:
        res = network_cut_arrays(
            mesh, list(layout.curves), layout.corners, layout.curve_ends, scale=scale
        )
    except CutError as exc:
        raise LayoutError(str(exc)) from None
    copy_of = res.copy_of
    # refined vertices: every one has a copy in the cut mesh
    n_ref = int(max([copy_of.max(initial=0), *(p.max(initial=0) for p in res.curve_vertices)])) + 1
    along = _Along(res.curve_vertices, n_ref)
    is_corner = np.zeros(n_ref, dtype=np.bool_)
    is_corner[res.corners] = True
    # the regions: faces joined through shared vertices (the split leaves one fan of faces
    # around every vertex, so these are the edge-connected pieces), numbered by first face
    n_comp, labels = vertex_face_components(res.faces, res.vertices.shape[0])
    order = np.argsort(labels, kind="stable")
    starts = np.searchsorted(labels[order], np.arange(n_comp + 1))
    return res, along, is_corner, n_comp, order, starts


def _compute_partition(
    mesh: Mesh,
    layout: Layout,
    progress: Callable[[int, int], None] | None,
    workers: int | None,
) -> tuple[NetworkCutArrays, list[_Region], int]:
    res, along, is_corner, n_comp, order, starts = _cut_regions(mesh, layout, None)
    copy_of = res.copy_of
    first_face = order[starts[:-1]]
    # each region checked as a mesh of its own (the pieces make up the cut mesh) and its
    # boundary loops traced, on threads (the numpy work and the kernels release the GIL)
    n_workers = _threads.n_workers(workers)
    spans = [(order[starts[c] : starts[c + 1]], c) for c in range(n_comp)]
    pieces = _threads.map_threads(lambda fc: _piece(mesh, res, *fc), spans, n_workers)

    by_set: dict[frozenset[int], list[int]] = {}
    for p in range(layout.n_patches):
        by_set.setdefault(frozenset(layout.patch_curves[p].tolist()), []).append(p)

    def orig_face(c: int) -> int:
        return int(res.face_parent[first_face[c]])

    def chains(loop: NDArray[np.int64], c: int) -> tuple[list[tuple[int, bool]], list[int]]:
        ref = copy_of[loop]
        curve, rev = along.lookup(ref)
        missing = np.flatnonzero(curve < 0)
        if missing.size:
            raise LayoutError(
                f"the region containing face {orig_face(c)} reaches the mesh boundary away "
                f"from the curves (at vertex {int(loop[missing[0]])} of the cut mesh): a hole "
                "of the mesh inside a patch, or a patch side that is no curve"
            )
        pos = np.flatnonzero(is_corner[ref]).tolist()
        return [(int(curve[k]), bool(rev[k])) for k in pos], pos

    regions: list[_Region] = []
    claimed: dict[int, int] = {}
    for c in range(n_comp):
        if progress is not None:
            progress(c, n_comp + layout.n_patches)
        got = pieces[c]
        if isinstance(got, MeshfitError):
            raise got
        sub, used, chi = got
        boundary = _disk_boundary(layout, along, copy_of, sub, used, chi, orig_face(c))
        seq, pos = chains(boundary, c)
        match = _match(layout, by_set, seq)
        if match is None:
            raise _no_patch_error(layout, by_set, seq, pos, orig_face(c))
        p, rot = match
        if p in claimed:
            raise LayoutError(
                f"patch {p}: two regions (faces {orig_face(claimed[p])} and {orig_face(c)}) "
                "are bounded by its sides"
            )
        claimed[p] = c
        start = pos[rot]
        loop = np.roll(boundary, -start)
        cpos = [(pos[(rot + s) % 4] - start) % boundary.size for s in range(4)]
        regions.append(_Region(p, order[starts[c] : starts[c + 1]], loop, cpos, sub, used))
    missing = [p for p in range(layout.n_patches) if p not in claimed]
    if missing:
        raise LayoutError(f"patch {missing[0]} bounds no region of its own")
    regions.sort(key=lambda r: r.patch)
    return res, regions, n_comp


def _disk_boundary(
    layout: Layout,
    along: _Along,
    copy_of: NDArray[np.int64],
    sub: Mesh,
    used: NDArray[np.int64],
    chi: int,
    face: int,
) -> NDArray[np.int64]:
    """The one boundary loop (split-mesh vertices) of a region (``sub``, its vertices
    ``used``, Euler characteristic ``chi``, containing original face ``face``); LayoutError
    where the region is no disk, naming the patch whose curves all bound it if there is one
    such patch."""
    loops = [used[loop] for loop in sub.boundary_loops]  # split-mesh vertices
    curves_seen: set[int] = set()
    for loop in loops:
        curve, _ = along.lookup(copy_of[loop])
        curves_seen.update(np.unique(curve[curve >= 0]).tolist())

    def name() -> str:  # (only for a message: a scan of every patch per region is quadratic)
        cand = [
            p
            for p in range(layout.n_patches)
            if set(layout.patch_curves[p].tolist()) <= curves_seen
        ]
        return f"patch {cand[0]}" if len(cand) == 1 else f"the region containing face {face}"

    if not loops:
        raise LayoutError(
            f"face {face} lies in a closed piece of the mesh that no curve bounds: "
            "every face must belong to a four-sided patch"
        )
    if len(loops) != 1:
        raise LayoutError(
            f"{name()} is not a disk: its region has {len(loops)} boundary loops "
            "(a hole of the mesh inside it, or curves that do not close around it)"
        )
    if chi != 1:
        raise LayoutError(
            f"{name()} is not a disk: Euler characteristic {chi} instead of 1 (a handle inside it)"
        )
    return loops[0]


def _no_patch_error(
    layout: Layout,
    by_set: dict[frozenset[int], list[int]],
    seq: list[tuple[int, bool]],
    pos: list[int],
    face: int,
) -> LayoutError:
    """Why a region bounded by the sides ``seq`` (corners at ``pos`` of its loop) matches
    no patch: a patch listed clockwise, or none with those sides."""
    curves = sorted({s[0] for s in seq})
    rev = _match(layout, by_set, [(ci, not r) for ci, r in reversed(seq)])
    if rev is not None:
        return LayoutError(
            f"patch {rev[0]}: its sides run clockwise seen from outside; list them "
            "counter-clockwise (the patch on the left of each side)"
        )
    return LayoutError(
        f"face {face} lies in a region bounded by {len(seq)} curve(s) "
        f"{curves} at {len(pos)} corner(s) that is no patch of the layout: every face "
        "must belong to a four-sided patch"
    )


class _Along:
    """Which curve each directed edge of the refined mesh follows, and in which direction:
    the edges of the curves' vertex paths as sorted keys ``a * n + b`` (a later curve wins
    an edge two curves share, as it would in a dict)."""

    def __init__(self, paths: Sequence[NDArray[np.int64]], n: int) -> None:
        a = [np.asarray(p[:-1], dtype=np.int64) for p in paths]
        b = [np.asarray(p[1:], dtype=np.int64) for p in paths]
        curve = np.concatenate(
            [np.full(x.size, i, dtype=np.int64) for i, x in enumerate(a)] or [[]]
        )
        a_all = np.concatenate(a or [[]]).astype(np.int64)
        b_all = np.concatenate(b or [[]]).astype(np.int64)
        # forward then backward per curve, curves in order: a stable sort keeps that order
        # among equal keys and the last of them is the one a dict would hold
        keys = np.stack([a_all * n + b_all, b_all * n + a_all], axis=1).ravel()
        self.n = n
        order = np.argsort(keys, kind="stable")
        self.keys = keys[order]
        self.curve = np.repeat(curve, 2)[order]
        self.reversed = np.tile([False, True], curve.size)[order]

    def lookup(self, ref: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        """For the closed loop of refined vertices ``ref``: the curve each edge
        ``ref[k] -> ref[k + 1]`` follows (-1 for none) and whether it runs against it."""
        q = ref * self.n + np.roll(ref, -1)
        at = np.searchsorted(self.keys, q, side="right") - 1
        ok = at >= 0
        ok[ok] = self.keys[at[ok]] == q[ok]
        curve = np.where(ok, self.curve[np.maximum(at, 0)], -1)
        rev = np.where(ok, self.reversed[np.maximum(at, 0)], False)
        return curve, rev


def _match(
    layout: Layout, by_set: dict[frozenset[int], list[int]], seq: list[tuple[int, bool]]
) -> tuple[int, int] | None:
    """The patch whose sides are ``seq`` up to rotation, and the rotation (side 0 at
    ``seq[rot]``)."""
    if len(seq) != 4:
        return None
    for p in by_set.get(frozenset(s[0] for s in seq), []):
        want = layout.patch_sides(p)
        for rot in range(4):
            if [seq[(rot + s) % 4] for s in range(4)] == want:
                return p, rot
    return None


def check_layout_topology(mesh: Mesh, layout: Layout) -> None:
    """Check that a layout's curves meet only at corners and every patch is a disk bounded by
    its four sides, the patches covering the mesh.

    Raises
    ------
    meshfit.errors.LayoutError
        Naming the curve, patch or face at fault.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3, fig. 1.2.
    """
    _partition(mesh, layout, None, None)


def patch_bulges(mesh: Mesh, layout: Layout) -> NDArray[np.float64]:
    """Each patch's :attr:`meshfit.layout.Patch.bulge`, without building the patches.

    The regions of the layout's cut (the partition :func:`check_layout_topology` makes, reused
    when it was just made for the same mesh and layout objects) give each patch's area and
    boundary loop.

    Returns
    -------
    (n_patches,) float64
        Area over that of a square with the same perimeter, patch by patch.

    Raises
    ------
    meshfit.errors.LayoutError
        As :func:`check_layout_topology`.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3 (four-sided patches) and sec. 5.3 (a patch's grid;
       a sliver's grid folds).
    """
    _, regions, _ = _partition(mesh, layout, None, None)
    out = np.empty(layout.n_patches)
    for reg in regions:
        loop = reg.sub.vertices[np.searchsorted(reg.used, reg.loop)]
        out[reg.patch] = loop_bulge(reg.sub.area, loop)
    return out


def extract_patches(
    mesh: Mesh,
    layout: Layout,
    *,
    progress: Callable[[int, int], None] | None = None,
    workers: int | None = 1,
) -> list[Patch]:
    """Cut a mesh along a layout's curves into one four-sided submesh per patch.

    Parameters
    ----------
    mesh : Mesh
        The mesh the layout was made for (checked by fingerprint).
    layout : Layout
    progress : callable(done, total), keyword-only, optional
        Called as regions are identified and patches built.
    workers : int or None, keyword-only
        Threads that check the regions as meshes and build the patches once the mesh is cut
        (default 1; None: one per core). The patches are the same for any count. A
        partition already made for the same mesh and layout objects (by
        :func:`check_layout_topology`, which uses every core, or ``load_layout``) is reused.

    Returns
    -------
    list of Patch
        ``patches[p]`` is layout patch ``p``: its submesh (a disk), corners and sides in the
        layout's order (side ``s`` along ``layout.patch_curves[p, s]``), ``face_parent`` (face
        of ``mesh``), ``vertex_source`` (points of ``mesh``) and its feature curves as face
        points of the submesh with ``feature_sides`` (the sides their ends were snapped onto).

    Raises
    ------
    meshfit.errors.LayoutError
        Layout of another mesh, curves crossing away from corners, a patch that is not a disk or
        not bounded by its four sides, faces in no patch (every face must belong to a patch).

    Notes
    -----
    The patch face areas sum to the mesh area: the cut only subdivides faces.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3 and fig. 1.2 (polygonal patches bounded by the painted
       curves), sec. 5.3 (each patch resampled on its own), sec. 5.10 (feature curves).
    """
    n_workers = _threads.n_workers(workers)
    res, regions, n_comp = _partition(mesh, layout, progress, n_workers)
    n_steps = n_comp + layout.n_patches
    build = partial(_build_patch, mesh, layout, res)
    # the submeshes' numpy work and validation kernels release the GIL, so threads scale
    # nearly with the cores on a dense mesh of many patches
    out: list[Patch] = _threads.map_threads(
        build,
        regions,
        n_workers,
        progress=None if progress is None else lambda k, _: progress(n_comp + k - 1, n_steps),
    )
    if progress is not None:
        progress(n_steps, n_steps)
    return out


def _build_patch(mesh: Mesh, layout: Layout, res: NetworkCutArrays, reg: _Region) -> Patch:
    sub = reg.sub.with_name(f"{mesh.name or 'mesh'}-patch{reg.patch}")
    used = reg.used
    loop = np.searchsorted(used, reg.loop)  # the loop's vertices in ``sub``
    n = loop.size
    cpos = reg.corner_pos
    corners = loop[cpos]
    sides = []
    for s in range(4):
        a, b = cpos[s], cpos[(s + 1) % 4]
        if b <= a:
            b += n
        sides.append(np.take(loop, np.arange(a, b + 1), mode="wrap"))
    face_parent = res.face_parent[reg.faces]
    vertex_source = res.vertex_source[used]
    feats, feat_sides = [], []
    for j, f in enumerate(layout.features[reg.patch]):
        try:
            curve, fs = _map_feature(mesh, sub, face_parent, sides, f)
        except LayoutError as exc:
            raise LayoutError(f"patch {reg.patch} feature {j}: {exc}") from None
        if fs[1] != (fs[0] + 2) % 4:
            raise LayoutError(
                f"patch {reg.patch} feature {j} runs from side {fs[0]} to side {fs[1]}: a "
                "feature curve must run from one side to the opposite side"
            )
        feats.append(curve)
        feat_sides.append(fs)
    return Patch(
        reg.patch,
        sub,
        corners,
        (sides[0], sides[1], sides[2], sides[3]),
        face_parent,
        vertex_source,
        tuple(feats),
        tuple(feat_sides),
    )


def _map_feature(
    mesh: Mesh,
    sub: Mesh,
    face_parent: NDArray[np.int64],
    sides: list[NDArray[np.int64]],
    feature: SurfaceCurve,
) -> tuple[SurfaceCurve, tuple[int, int]]:
    """A feature curve of ``mesh`` as face points of the patch submesh, ends on sides."""
    xyz = mesh.xyz(feature.points)
    order = np.argsort(face_parent, kind="stable")
    sorted_parent = face_parent[order]
    n = xyz.shape[0]
    face = np.full(n, -1, dtype=np.int64)
    bary = np.zeros((n, 3))
    for i in range(n):
        f = int(feature.points.face[i])
        lo, hi = np.searchsorted(sorted_parent, [f, f + 1])
        if hi > lo:
            cand = order[lo:hi]
            b = barycentric(sub, cand, np.repeat(xyz[i : i + 1], cand.size, axis=0))
            j = int(np.argmax(b.min(axis=1)))
            if b[j].min() > -tol.LAYOUT_BARY_SUM:
                face[i] = cand[j]
                bb = np.clip(b[j], 0.0, None)
                bary[i] = bb / bb.sum()
    near = tol.length(sub, tol.LAYOUT_FEATURE_INSIDE)
    miss = np.flatnonzero(face < 0)
    if miss.size:  # points on faces outside the patch, or on a side: the closest patch point
        cp = sub.closest_points(xyz[miss])
        face[miss] = cp.points.face
        bary[miss] = cp.points.bary
        inner = (miss > 0) & (miss < n - 1)  # the ends are checked against the sides below
        far = miss[inner & (cp.distance > near)]
        if far.size:
            raise LayoutError(f"point {int(far[0])} lies outside the patch")
    end_sides = []
    edge_face = _boundary_edge_faces(sub)
    for k in (0, n - 1):
        s, f, b, d = _snap_to_sides(sub, sides, edge_face, xyz[k])
        if d > near:
            raise LayoutError(
                f"its {'first' if k == 0 else 'last'} point is {d:.3g} away from the patch "
                f"sides: a feature curve starts and ends on sides"
            )
        face[k], bary[k] = f, b
        end_sides.append(s)
    curve = SurfaceCurve(SurfacePoints(face, bary), kind="feature")
    return curve, (end_sides[0], end_sides[1])


def _boundary_edge_faces(sub: Mesh) -> dict[tuple[int, int], tuple[int, int]]:
    """Directed boundary half-edge (a, b) -> (face, slot of a)."""
    out = {}
    fn = sub.face_neighbors
    for f, k in zip(*np.nonzero(fn < 0), strict=True):
        a, b = int(sub.faces[f, k]), int(sub.faces[f, (k + 1) % 3])
        out[(a, b)] = (int(f), int(k))
    return out


def _snap_to_sides(sub: Mesh, sides, edge_face, x: NDArray[np.float64]):
    """The nearest point to ``x`` on the patch sides: (side, face, bary)."""
    best = (np.inf, 0, 0, 0, 0.0)
    V = sub.vertices
    for s, chain in enumerate(sides):
        a, b = V[chain[:-1]], V[chain[1:]]
        e = b - a
        ee = np.einsum("ij,ij->i", e, e)
        t = np.clip(np.einsum("ij,ij->i", x - a, e) / np.where(ee > 0, ee, 1.0), 0.0, 1.0)
        d = np.linalg.norm(a + t[:, None] * e - x, axis=1)
        j = int(np.argmin(d))
        if d[j] < best[0]:
            best = (float(d[j]), s, int(chain[j]), int(chain[j + 1]), float(t[j]))
    d, s, va, vb, t = best
    f, k = edge_face[(va, vb)]
    bary = np.zeros(3)
    bary[k] = 1.0 - t
    bary[(k + 1) % 3] = t
    return s, f, bary, d


def extract_patch_within(
    mesh: Mesh, layout: Layout, patch: int, *, scale: tuple[float, float] | None = None
) -> Patch:
    """Patch ``patch`` of ``layout`` cut from ``mesh``, a piece of a larger surface that
    holds the patch and more (a patch store's piece: the patch's faces and a halo round
    them).

    The mesh is cut along all the layout's curves as :func:`extract_patches` cuts it; of the
    regions, the one that is a disk bounded by the patch's four sides, in their order and
    directions, is the patch. The others (the halo, which reaches the piece's own boundary)
    are left. ``scale`` (mean edge length, diagonal) sets the cut's tolerances, as in
    :func:`meshfit.surface.cut.network_cut_arrays`: the whole surface's, so that the
    pieces of two patches are cut alike along the curve they share.

    Parameters
    ----------
    mesh : Mesh
        The piece (the layout was made for it).
    layout : Layout
    patch : int
    scale : (float, float), keyword-only, optional
        Mean edge length and bounding-box diagonal, model units.

    Returns
    -------
    Patch
        As :func:`extract_patches` gives it, of ``mesh``.

    Raises
    ------
    meshfit.errors.LayoutError
        No region, or more than one, is bounded by the patch's sides.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3, fig. 1.2 (polygonal patches bounded by the painted
       curves), sec. 5.3 (each patch resampled on its own).
    """
    res, along, is_corner, n_comp, order, starts = _cut_regions(mesh, layout, scale)
    copy_of = res.copy_of
    by_set = {frozenset(layout.patch_curves[patch].tolist()): [patch]}
    found: list[_Region] = []
    for c in range(n_comp):
        faces = order[starts[c] : starts[c + 1]]
        got = _piece(mesh, res, faces, c)
        if isinstance(got, MeshfitError):
            continue  # (a halo region need not be a clean mesh)
        sub, used, chi = got
        loops = sub.boundary_loops
        if len(loops) != 1 or chi != 1:
            continue
        boundary = used[loops[0]]
        ref = copy_of[boundary]
        curve, rev = along.lookup(ref)
        if (curve < 0).any():
            continue
        pos = np.flatnonzero(is_corner[ref]).tolist()
        match = _match(layout, by_set, [(int(curve[k]), bool(rev[k])) for k in pos])
        if match is None:
            continue
        _, rot = match
        start = pos[rot]
        loop = np.roll(boundary, -start)
        cpos = [(pos[(rot + s) % 4] - start) % boundary.size for s in range(4)]
        found.append(_Region(patch, faces, loop, cpos, sub, used))
    if len(found) != 1:
        raise LayoutError(
            f"patch {patch}: {len(found)} regions of the piece are bounded by its four sides "
            "(one was wanted)"
        )
    return _build_patch(mesh, layout, res, found[0])
