"""Automatic four-sided layouts of meshes of any topology: geodesic Voronoi cells split into quads.

Method
------
1. **Seeds.** Farthest-point sampling by distance along mesh edges, on every component in
   proportion to its area (at least one seed each), then Lloyd steps: each seed moves to the
   vertex of its cell nearest the cell's area centroid (a centroidal Voronoi tessellation,
   whose cells are close to regular hexagons, so their sides have similar lengths).
2. **Cells.** Every vertex takes the label of its nearest seed (one multi-source Dijkstra).
   A cell must be a disk: its vertex-induced subcomplex has Euler characteristic 1 (a cell
   that wraps round a handle or a hole has a lower one). And it must hold a shape one patch
   can: no more than `CONE_SHARE` of its area may turn more than `NORMAL_CONE` from its
   mean normal (an ear, a horn, a fold back), unless it is too small to split (on a mesh
   whose noise folds its triangles, :func:`noisy_folds`, the normals are first averaged
   over a few rings: the noise is no turn of the shape). A cell that
   fails gets a second seed (on the hole or slit inside it, on its turned part, else at its
   vertex farthest from its seed), and the round repeats within a budget (`MAX_ROUNDS`
   rounds, a cell count): at its end every cell is a disk, or the layout is refused.
3. **Cell boundaries.** The mesh is clipped along the label field: cut points at the
   mid-points of edges whose ends differ and at the centroids of faces with three labels,
   so each cell is a submesh of exact face points of the input, and where the mesh is open
   its boundary runs along the mesh boundary. Points where three cells meet, or where two
   meet on the mesh boundary, are corners; a cell with fewer than three gets more at even
   arc length (a cell that is a whole disk-shaped component, a cap surrounded by one cell).
   Both sides of a crease share its corners, so before clipping the cells' ends on one
   side of a crease are moved onto nearby ends on the other side: an end on one side only
   is a corner with a straight angle across the crease.
4. **Quads.** Each side of a cell is halved at its arc-length mid-point; the cell is mapped
   onto a convex polygon inscribed in the unit circle (Tutte's embedding with mean value
   weights, a bijection for a disk: Floater 2003) and its centre, the image of the origin,
   is joined to the mid-points by the images of straight radii, which cannot cross. A
   k-sided cell gives k quads (corner, mid-point, centre, mid-point), as one Catmull-Clark
   step splits a polygon. A side much shorter than the sides at its two ends (four seeds
   nearly on a circle) is merged away first: its mid-point becomes the one corner of the
   four cells, reached by chords through the two cells that shared it (images of
   segments in their disc maps), so no quad has a side a fraction of its others' length
   and a sliver at its centre. A corner at a crease where the cell's angle is straight or
   reflex (an end of the cells across that found no partner, or a boundary leaving the
   crease at a glancing angle) would be a quad corner of about 180 degrees: a chord of
   the disc map joins it to the cell's most nearly opposite corner, and each part is
   split into quads about the centre of a disc map of its own. Should the merged corners'
   or the chords' curves not cut the mesh into disks, the cells are split as they are.
5. Interior curves are relaxed as surface snakes with fixed ends; a relaxed curve that
   meets another away from the corners is put back as it was (only those curves: the
   jagged cell boundaries left elsewhere would give patches reflex corners). Curves on the
   mesh boundary are not moved.

Why this route: it needs no global parameterization, so it works for every genus, open
meshes and several components alike, and its tests (disk, normal cone) say directly why a
cell gets more patches instead of retrying rotations. The sphere-map route of
:mod:`meshfit.layout.auto` stays the choice for one closed genus-0 surface where it
measures better (see :func:`meshfit.layout.auto.auto_layout` and the layout benchmark).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy import sparse
from scipy.sparse import csgraph
from scipy.sparse.linalg import spsolve
from scipy.spatial import cKDTree

from meshfit import tol
from meshfit._kernels import geometry as _geometry
from meshfit._kernels.locate2d import walk_locate
from meshfit.errors import InputError, LayoutError, MeshfitError
from meshfit.layout.layout import Layout, layout_from_curves
from meshfit.mesh import Mesh
from meshfit.mesh.topology import boundary_loops, corner_fans, edge_table, face_neighbors
from meshfit.types import SurfaceCurve, SurfacePoints

__all__ = ["CellReport", "crease_corners", "crease_edges", "region_layout"]

#: default patch count
DEFAULT_PATCHES = 60
#: quads per cell on average on a closed surface (a Voronoi cell has about six sides)
QUADS_PER_CELL = 6
#: Lloyd steps of the seeds before and after seeds are added
LLOYD_STEPS = 4
#: a cell may have at most this share of its area turning more than `NORMAL_CONE` from its
#: mean normal (a few noisy scan faces do not split it)
CONE_SHARE = 0.02
#: largest angle (degrees) between a cell's mean normal and its surface before the cell is
#: split: within it the cell is a height field over its mean plane, so none of its quads
#: folds over itself
NORMAL_CONE = 90.0
#: rounds of face-vertex averaging of the normals the normal-cone test reads on a noisy
#: mesh (`_cone_normals`, `noisy_folds`): each round reaches one ring of faces further, so
#: the test sees a turn a few rings wide, as a patch's spring grid does, and not a scan's
#: noise of the order of its edge length, which turns single triangles any way (and would
#: split the cells into thousands more without the surface turning). A clean mesh's own
#: normals are read: there a turn a ring or two wide is the shape's
CONE_SMOOTHING = 3
#: default ``crease_angle`` (degrees): an edge whose faces' normals differ by more is sharp
CREASE_ANGLE = 40.0
#: shortest chain of sharp edges kept as a crease, share of the bbox diagonal
CREASE_MIN_LENGTH = 0.05
#: two cells' ends on the two sides of a crease closer than this share of a regular
#: hexagonal cell's side (of the mean cell area) are moved together (`_align_crease_cuts`)
CREASE_ALIGN = 0.5
#: the creases are used only when all of them together are at least this long, share of
#: the bbox diagonal: creases that shape the part (a machined or modelled edge runs round
#: it), not the short sharp ridges a scan leaves, whose quads would be slivers
CREASE_MIN_TOTAL = 1.0
#: a cell with fewer vertices is not split for its turn: each half would hold fewer than
#: the fewest patches of a cell (three) at `MIN_FACES_PER_PATCH` faces (about two faces a
#: vertex)
CONE_MIN_VERTICES = 3 * 16
#: a cell side shorter than this share of the median of the four sides at its ends is
#: merged away, its two corners made one (`_short_sides`)
SHORT_SIDE = 0.3
#: a cell's corner on a crease that turns by less than 180 minus this many degrees on the
#: cell's side (an end of the cells across only) is joined by a chord to the opposite corner
STRAIGHT_CORNER = 150.0
#: a corner's angle is measured between chords this share of the shorter side long
CORNER_REACH = 0.25
#: parts of a cell the chord search looks at before it looks one chord ahead only
CHORD_SEARCH = 2_000
#: rounds of seed insertion at most (each round adds a seed to every cell that fails)
MAX_ROUNDS = 40
#: fewest input faces per patch (more patches are refused: a spring grid needs faces)
MIN_FACES_PER_PATCH = 16
#: barycentric slack of a point found inside a sub-triangle by the walk
WALK_EPS = 1e-12
#: a traced radius has consecutive samples at most this many mean edge lengths apart ...
TRACE_GAP_EDGES = 1.0
#: ... within this many rounds of halving
TRACE_ROUNDS = 30


@dataclass(frozen=True)
class CellReport:
    """What :func:`region_layout` did, for the fit summary.

    Attributes
    ----------
    cells : int
        Voronoi cells (each gives as many patches as it has sides).
    seeds_added : dict
        Seeds added because a cell was not a disk (``"disk"``) or turned too far
        (``"normal_cone"``).
    components : int
        Connected components laid out.
    rounds : int
        Rounds of the cell tests.
    """

    cells: int
    seeds_added: dict
    components: int
    rounds: int


# ----------------------------------------------------------------------------- seeds, cells


def _voronoi(graph: sparse.csr_matrix, seeds: NDArray[np.int64]):
    """(distance, label) of every vertex to its nearest seed along mesh edges."""
    dist, _, src = csgraph.dijkstra(
        graph, directed=False, indices=seeds, min_only=True, return_predecessors=True
    )
    label = np.full(src.shape[0], -1, dtype=np.int64)
    ok = src >= 0
    lookup = np.full(int(seeds.max()) + 1, -1, dtype=np.int64)
    lookup[seeds] = np.arange(seeds.size)
    label[ok] = lookup[src[ok]]
    return dist, label


def _quantized(values: NDArray[np.float64], unit: float) -> NDArray[np.float64]:
    return np.round(values / unit)


def _vertex_areas(mesh: Mesh) -> NDArray[np.float64]:
    return np.bincount(
        mesh.faces.reshape(-1),
        weights=np.repeat(mesh.face_areas / 3.0, 3),
        minlength=mesh.n_vertices,
    )


def _initial_seeds(mesh: Mesh, graph, n_cells: int) -> NDArray[np.int64]:
    """Farthest-point seeds, at least one per component, the rest by area share."""
    comp = mesh.vertex_components
    used = np.zeros(mesh.n_vertices, dtype=bool)
    used[mesh.faces.reshape(-1)] = True
    n_comp = int(comp.max()) + 1 if comp.size else 0
    vareas = _vertex_areas(mesh)
    areas = np.bincount(comp, weights=vareas, minlength=n_comp)
    share = areas / max(areas.sum(), 1e-300)
    counts = np.maximum(1, np.round(share * n_cells)).astype(np.int64)
    seeds: list[int] = []
    for c in range(n_comp):
        members = np.flatnonzero((comp == c) & used)
        if members.size == 0:
            continue
        # start at the vertex farthest from the component's area centroid: the same vertex
        # for any rigid motion or scaling of the mesh
        centre = (mesh.vertices[members] * vareas[members, None]).sum(0) / max(
            vareas[members].sum(), 1e-300
        )
        unit = tol.length(mesh, tol.GRAPH_QUANTUM) ** 2
        far = _quantized(((mesh.vertices[members] - centre) ** 2).sum(1), unit)
        first = int(members[np.argmax(far)])
        d = csgraph.dijkstra(graph, directed=False, indices=first)
        mine = [first]
        for _ in range(int(counts[c]) - 1):
            dm = np.where(np.isfinite(d), d, -1.0)
            dm[~((comp == c) & used)] = -1.0
            nxt = int(np.argmax(dm))
            if dm[nxt] <= 0:
                break
            mine.append(nxt)
            d = np.minimum(d, csgraph.dijkstra(graph, directed=False, indices=nxt))
        seeds.extend(mine)
    return np.asarray(seeds, dtype=np.int64)


def _lloyd(mesh: Mesh, graph, seeds: NDArray[np.int64], steps: int, vareas) -> NDArray[np.int64]:
    """Seeds moved ``steps`` times to the vertex of their cell nearest its area centroid."""
    for _ in range(steps):
        _, label = _voronoi(graph, seeds)
        ok = label >= 0
        k = seeds.size
        w = np.bincount(label[ok], weights=vareas[ok], minlength=k)
        cen = (
            np.stack(
                [
                    np.bincount(label[ok], weights=vareas[ok] * mesh.vertices[ok, j], minlength=k)
                    for j in range(3)
                ],
                axis=1,
            )
            / np.maximum(w, 1e-300)[:, None]
        )
        d2 = _quantized(
            ((mesh.vertices - cen[np.maximum(label, 0)]) ** 2).sum(1),
            tol.length(mesh, tol.GRAPH_QUANTUM) ** 2,
        )
        d2[~ok] = np.inf
        order = np.lexsort((d2, label))
        lab_sorted = label[order]
        first = np.searchsorted(lab_sorted, np.arange(k))
        new = order[np.minimum(first, order.size - 1)]
        keep = (first < order.size) & (
            lab_sorted[np.minimum(first, order.size - 1)] == np.arange(k)
        )
        moved = np.where(keep, new, seeds)
        if np.array_equal(np.sort(moved), np.sort(seeds)) or np.unique(moved).size < k:
            break
        seeds = moved
    return seeds


def _euler_per_cell(mesh: Mesh, label: NDArray[np.int64], k: int) -> NDArray[np.int64]:
    """Euler characteristic of each cell's vertex-induced subcomplex."""
    nv = np.bincount(label[label >= 0], minlength=k)
    e = mesh.edges
    le = label[e]
    same = le[:, 0] == le[:, 1]
    ne = np.bincount(le[same, 0], minlength=k)
    lf = label[mesh.faces]
    fs = (lf[:, 0] == lf[:, 1]) & (lf[:, 1] == lf[:, 2])
    nf = np.bincount(lf[fs, 0], minlength=k)
    return (nv - ne + nf).astype(np.int64)


def _not_disks(mesh: Mesh, graph, seeds: NDArray[np.int64]) -> int:
    """How many of the cells of ``seeds`` are no disk."""
    _, label = _voronoi(graph, seeds)
    return int((_euler_per_cell(mesh, label, seeds.size) != 1).sum())


def _cone_normals(mesh: Mesh, rounds: int = CONE_SMOOTHING) -> NDArray[np.float64]:
    """Unit vertex normals after ``rounds`` of averaging: each face takes the sum of its
    corners' normals times its area, each vertex the sum over its faces (a diffusion along
    the surface, so the two sides of a thin sheet mix only round its rim). A vertex whose
    sum vanishes keeps its own normal."""
    n = mesh.vertex_normals
    f, w = mesh.faces, mesh.face_areas[:, None]
    for _ in range(rounds):
        acc = _geometry.vertex_sums(f, (n[f[:, 0]] + n[f[:, 1]] + n[f[:, 2]]) * w, n.shape[0])
        ln = np.linalg.norm(acc, axis=1, keepdims=True)
        n = np.where(ln > 0, acc / np.where(ln > 0, ln, 1.0), n)
    return n


def _cone_fails(mesh: Mesh, label: NDArray[np.int64], k: int, vareas, n):
    """Cells with more than `CONE_SHARE` of their area beyond `NORMAL_CONE` of their mean
    normal (of the vertex normals ``n``), and the mask of the vertices beyond it."""
    ok = label >= 0
    lab = np.where(ok, label, 0)
    mean = np.stack(
        [np.bincount(lab, weights=vareas * n[:, j] * ok, minlength=k) for j in range(3)], axis=1
    )
    norm = np.linalg.norm(mean, axis=1)
    mean = mean / np.maximum(norm, 1e-300)[:, None]
    dots = (n * mean[lab]).sum(1)
    far = (dots < np.cos(np.radians(NORMAL_CONE))) & ok
    far_area = np.bincount(lab[far], weights=vareas[far], minlength=k)
    total = np.bincount(lab[ok], weights=vareas[ok], minlength=k)
    return far_area > CONE_SHARE * np.maximum(total, 1e-300), far


def _cells(mesh: Mesh, n_cells: int, max_cells: int):
    """Seeds and labels whose cells are disks within the normal cone (or the budget's end).

    ``n_cells`` are shared out by area; a component too small for its share still gets a
    seed, and each such seed widens ``max_cells`` by two (a closed component needs at least
    two cells), so that a mesh with many small components is not refused for their count.
    """
    graph = mesh.quantized_edge_graph()
    vareas = _vertex_areas(mesh)
    normals = _cone_normals(mesh, CONE_SMOOTHING) if noisy_folds(mesh) else mesh.vertex_normals
    seeds = _initial_seeds(mesh, graph, n_cells)
    max_cells += 2 * max(0, seeds.size - n_cells)
    seeds = _lloyd(mesh, graph, seeds, LLOYD_STEPS, vareas)
    added = {"disk": 0, "normal_cone": 0}
    rounds = 0
    loops = mesh.boundary_loops
    for rounds in range(1, MAX_ROUNDS + 1):
        dist, label = _voronoi(graph, seeds)
        k = seeds.size
        chi = _euler_per_cell(mesh, label, k)
        not_disk = chi != 1
        cone, far = _cone_fails(mesh, label, k, vareas, normals)
        # (a cell too small to give two cells of patches is not split for its turn: a thin
        # rim turns back within any cell that holds it)
        size = np.bincount(label[label >= 0], minlength=k)
        cone &= ~not_disk & (size >= CONE_MIN_VERTICES)
        bad = np.flatnonzero(not_disk | cone)
        if bad.size == 0:
            return seeds, label, added, rounds
        room = max_cells - k
        if room <= 0:
            if not_disk.any():
                break
            return seeds, label, added, rounds
        # the vertex of each failing cell farthest from its seed (cells that are no disk
        # first, when the budget is short); a cell that is no disk because a boundary loop
        # (a hole, or a crease's slit) lies inside it takes it on that loop, and a cell that
        # turns too far on its turned part
        take = bad[np.argsort(~not_disk[bad], kind="stable")][:room]
        rank = np.where(far | not_disk[np.maximum(label, 0)], dist, -1.0)
        for loop in loops:
            c = label[loop[0]]
            if c >= 0 and not_disk[c] and (label[loop] == c).all():
                rank[loop] += 2.0 * float(dist[label == c].max()) + 1.0
        order = np.lexsort((-rank, label))
        new = order[np.searchsorted(label[order], take)]
        for c in take:
            added["disk" if not_disk[c] else "normal_cone"] += 1
        seeds = np.unique(np.concatenate([seeds, new]))
        # a Lloyd step evens the cells out, but is kept only where it leaves no more cells
        # that are no disk (moving every seed can undo what the new ones fixed)
        moved = _lloyd(mesh, graph, seeds, 1, vareas)
        if _not_disks(mesh, graph, moved) <= _not_disks(mesh, graph, seeds):
            seeds = moved
    dist, label = _voronoi(graph, seeds)
    not_disk = _euler_per_cell(mesh, label, seeds.size) != 1
    if not not_disk.any():  # disks, some still turning too far: the best within the budget
        return seeds, label, added, rounds
    bad = int(np.flatnonzero(not_disk)[0])
    raise LayoutError(
        f"the automatic layout could not make every cell a disk within {max_cells} cells "
        f"(the cell round vertex {int(seeds[bad])} is not one): give a layout file, or "
        "a larger --crease-angle where the mesh has many short creases"
    )


@dataclass
class _Rims:
    """The boundary loops of the cut-open mesh as runs of edges, each edge with its twin
    (the same input edge seen from the crease's other side) and whether the cells differ
    at its ends."""

    loops: list[NDArray[np.int64]]
    cut: list[NDArray[np.bool_]]  # per loop position i: the edge loop[i] -> loop[i + 1]
    seg: list[NDArray[np.float64]]  # its length
    twin: dict[tuple[int, int], tuple[int, int]]
    order: list[tuple[int, int]]  # the positions with a cut, by input edge

    def lone(self, li: int, i: int) -> bool:
        """An end of cells on this side of a crease edge only."""
        t = self.twin.get((li, i))
        return t is not None and bool(self.cut[li][i]) and not self.cut[t[0]][t[1]]


def _rims(mesh: Mesh, label: NDArray[np.int64], parent, orig: Mesh) -> _Rims:
    """The :class:`_Rims` of ``mesh`` (the input ``orig`` cut open) under ``label``."""
    loops = [np.asarray(lp, dtype=np.int64) for lp in mesh.boundary_loops]
    where: dict[int, list[tuple[int, int]]] = {}
    cut, seg, keyed = [], [], []
    for li, lp in enumerate(loops):
        nxt = np.roll(lp, -1)
        oe = _orig_edge_index(orig, parent[lp], parent[nxt]).tolist()
        cut.append(label[lp] != label[nxt])
        seg.append(np.linalg.norm(mesh.vertices[nxt] - mesh.vertices[lp], axis=1))
        for i, e in enumerate(oe):
            where.setdefault(e, []).append((li, i))
            if cut[-1][i]:
                keyed.append((e, li, i))
    twin: dict[tuple[int, int], tuple[int, int]] = {}
    for pair in where.values():
        if len(pair) == 2:
            twin[pair[0]], twin[pair[1]] = pair[1], pair[0]
    return _Rims(loops, cut, seg, twin, [(li, i) for _, li, i in sorted(keyed)])


def _nearest_lone(rims: _Rims, li: int, i: int, reach: float, stop) -> int:
    """Position of the nearest end on loop ``li`` from position ``i``, looking either way up
    to the first end, ``reach`` away, a vertex in ``stop`` or a position without a twin,
    if it is lone; -1 if there is none."""
    lp, n, seg = rims.loops[li], rims.loops[li].size, rims.seg[li]
    best, best_d = -1, np.inf
    for step in (1, -1):
        j, d = i, 0.0
        while True:
            passed = lp[(j + 1) % n] if step == 1 else lp[j]
            d += 0.5 * (seg[j] + seg[(j + step) % n])
            j = (j + step) % n
            if d > reach or stop[passed] or (li, j) not in rims.twin or j == i:
                break
            if rims.cut[li][j]:
                if rims.lone(li, j) and d < best_d:
                    best, best_d = j, d
                break
    return best


def _align_crease_cuts(
    mesh: Mesh, label: NDArray[np.int64], parent, orig: Mesh, corner_vertices, k: int
) -> NDArray[np.int64]:
    """Labels of ``mesh`` (the input cut open along its creases) with the cells' ends on
    each side of a crease moved onto the other side's where the two are within
    `CREASE_ALIGN` of a cell side.

    Both sides of a crease share its corners, so where a cell boundary meets the crease on
    one side only, the cell across it gets a corner in the middle of a straight side (a
    straight angle, whose quads are triangles and whose grids fold). Each such end is
    paired with the nearest unpaired end on the other side along the same crease (up to
    the next end either way, not past a crease corner) and that side's crease vertices in
    between change cell. Where that would leave a cell that is no disk, the labels are
    returned unchanged. Ends that find no partner keep their corner on both sides.
    """
    rims = _rims(mesh, label, parent, orig)
    if not rims.order:
        return label
    stop = np.isin(parent, np.asarray(corner_vertices, dtype=np.int64))
    area = float(mesh.face_areas.sum())
    reach = CREASE_ALIGN * np.sqrt(2.0 * area / max(k, 1) / (3.0 * np.sqrt(3.0)))
    lab = label.copy()
    for li, i in rims.order:
        if not rims.lone(li, i):
            continue
        l2, i2 = rims.twin[(li, i)]
        j = _nearest_lone(rims, l2, i2, reach, stop)
        if j < 0:
            continue
        lp, n = rims.loops[l2], rims.loops[l2].size
        # the vertices between the two ends take the cell beyond the end that moves
        if (j - i2) % n < (i2 - j) % n:  # ahead: i2 + 1 .. j change
            lab[lp[(i2 + 1 + np.arange((j - i2) % n)) % n]] = lab[lp[(j + 1) % n]]
        else:  # behind: j + 1 .. i2 change
            lab[lp[(j + 1 + np.arange((i2 - j) % n)) % n]] = lab[lp[j]]
        rims.cut[l2][j], rims.cut[l2][i2] = False, True
    if np.array_equal(_euler_per_cell(mesh, lab, k), _euler_per_cell(mesh, label, k)):
        return lab
    return label


# ----------------------------------------------------------------------------- clipping


@dataclass
class _Clip:
    """The mesh clipped along the label field: sub-triangles of the input faces, each in one
    cell, over the input's vertices plus edge and face cut points."""

    tri: NDArray[np.int64]  # (nt, 3) clipped-vertex ids
    tri_label: NDArray[np.int64]  # (nt,)
    tri_face: NDArray[np.int64]  # (nt,) input face
    tri_bary: NDArray[np.float64]  # (nt, 3, 3) corner barycentrics in the input face
    src_face: NDArray[np.int64]  # (nc,) a face holding each clipped vertex
    src_bary: NDArray[np.float64]  # (nc, 3)
    xyz: NDArray[np.float64]  # (nc, 3)
    is_junction: NDArray[np.bool_]  # (nc,) three cells meet, or two on the mesh boundary
    canon: NDArray[np.int64]  # (nc,) the point of the uncut mesh (both sides of a crease)


def _clip(mesh: Mesh, label: NDArray[np.int64], parent, orig: Mesh) -> _Clip:
    """Clip ``mesh`` (the input cut open along its creases; ``parent`` the input vertex of
    each of its vertices, ``orig`` the input) along ``label``."""
    F = mesh.faces
    nv = mesh.n_vertices
    E = mesh.edges
    le = label[E]
    cut_edge = le[:, 0] != le[:, 1]
    edge_node = np.full(E.shape[0], -1, dtype=np.int64)
    edge_node[cut_edge] = nv + np.arange(int(cut_edge.sum()))
    n_en = int(cut_edge.sum())
    L = label[F]
    three = (L[:, 0] != L[:, 1]) & (L[:, 1] != L[:, 2]) & (L[:, 2] != L[:, 0])
    face_node = np.full(F.shape[0], -1, dtype=np.int64)
    face_node[three] = nv + n_en + np.arange(int(three.sum()))
    n_clip = nv + n_en + int(three.sum())

    eye = np.eye(3)
    mid = np.array([(eye[k] + eye[(k + 1) % 3]) / 2.0 for k in range(3)])
    cen = np.full(3, 1.0 / 3.0)
    FE = mesh.face_edges
    tris, labs, faces, barys = [], [], [], []

    def add(f, ids, bary, lab):
        tris.append(ids)
        labs.append(lab)
        faces.append(f)
        barys.append(bary)

    # one label: the face itself
    one = (L[:, 0] == L[:, 1]) & (L[:, 1] == L[:, 2])
    f1 = np.flatnonzero(one)
    add(f1, F[f1], np.broadcast_to(eye, (f1.size, 3, 3)), L[f1, 0])
    # two labels: the odd vertex k cut off by the mid-points of its two edges
    two = ~one & ~three
    for k in range(3):
        a, b, c = k, (k + 1) % 3, (k + 2) % 3
        fk = np.flatnonzero(two & (L[:, b] == L[:, c]))
        if not fk.size:
            continue
        m_ab = edge_node[FE[fk, a]]  # edge a is (F[a], F[a+1])
        m_ca = edge_node[FE[fk, c]]  # edge c is (F[c], F[a])
        va, vb, vc = F[fk, a], F[fk, b], F[fk, c]
        ba = np.broadcast_to(np.stack([eye[a], mid[a], mid[c]]), (fk.size, 3, 3))
        add(fk, np.stack([va, m_ab, m_ca], 1), ba, L[fk, a])
        b1 = np.broadcast_to(np.stack([mid[a], eye[b], eye[c]]), (fk.size, 3, 3))
        add(fk, np.stack([m_ab, vb, vc], 1), b1, L[fk, b])
        b2 = np.broadcast_to(np.stack([mid[a], eye[c], mid[c]]), (fk.size, 3, 3))
        add(fk, np.stack([m_ab, vc, m_ca], 1), b2, L[fk, b])
    # three labels: each vertex keeps the quad (vertex, mid-point, centroid, mid-point)
    f3 = np.flatnonzero(three)
    for k in range(3):
        a, c = k, (k + 2) % 3
        va = F[f3, a]
        m_next, m_prev, cf = edge_node[FE[f3, a]], edge_node[FE[f3, c]], face_node[f3]
        b1 = np.broadcast_to(np.stack([eye[a], mid[a], cen]), (f3.size, 3, 3))
        add(f3, np.stack([va, m_next, cf], 1), b1, L[f3, a])
        b2 = np.broadcast_to(np.stack([eye[a], cen, mid[c]]), (f3.size, 3, 3))
        add(f3, np.stack([va, cf, m_prev], 1), b2, L[f3, a])

    tri = np.concatenate(tris).astype(np.int64)
    tri_bary = np.concatenate([np.asarray(b) for b in barys])
    tri_face = np.concatenate(faces).astype(np.int64)
    # each clipped vertex's source: the first sub-triangle corner that names it
    src_face = np.zeros(n_clip, dtype=np.int64)
    src_bary = np.zeros((n_clip, 3))
    flat = tri.reshape(-1)
    first = np.full(n_clip, -1, dtype=np.int64)
    order = np.arange(flat.size)[::-1]
    first[flat[order]] = order
    has = first >= 0
    src_face[has] = tri_face[first[has] // 3]
    src_bary[has] = tri_bary.reshape(-1, 3)[first[has]]
    xyz = np.einsum("nk,nkj->nj", src_bary, mesh.vertices[mesh.faces[src_face]])
    junction = np.zeros(n_clip, dtype=bool)
    junction[face_node[three]] = True
    border_cut = cut_edge & (mesh.edge_face_count == 1)
    junction[edge_node[border_cut]] = True
    canon = np.empty(n_clip, dtype=np.int64)
    canon[:nv] = parent
    canon[edge_node[cut_edge]] = orig.n_vertices + _orig_edges(mesh, parent, orig)[cut_edge]
    canon[face_node[three]] = orig.n_vertices + orig.edges.shape[0] + np.flatnonzero(three)
    return _Clip(
        tri,
        np.concatenate(labs).astype(np.int64),
        tri_face,
        tri_bary,
        src_face,
        src_bary,
        xyz,
        junction,
        canon,
    )


def _orig_edges(mesh: Mesh, parent, orig: Mesh) -> NDArray[np.int64]:
    """Index in ``orig.edges`` of every edge of ``mesh`` (``orig`` cut open)."""
    if mesh is orig:
        return np.arange(mesh.edges.shape[0], dtype=np.int64)
    return _orig_edge_index(orig, parent[mesh.edges[:, 0]], parent[mesh.edges[:, 1]])


def _orig_edge_index(orig: Mesh, a: NDArray[np.int64], b: NDArray[np.int64]) -> NDArray[np.int64]:
    """Index in ``orig.edges`` of the edges ``a[i] - b[i]`` (input vertices, either order)."""
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    keys = lo * np.int64(max(orig.n_vertices, 1)) + hi
    return np.searchsorted(orig.edge_keys, keys).astype(np.int64)


def _crease_nodes(clip: _Clip, mesh: Mesh, label, parent, orig: Mesh, corner_vertices) -> _Clip:
    """Where one side of a crease has a cut point on an edge and the other does not, the
    other side gets one too (its sub-triangle on that edge halved), so both sides of every
    crease have the same points and corners; the copies of ``corner_vertices`` (input
    vertices) become junctions."""
    border = np.flatnonzero(mesh.edge_face_count == 1)
    oe_all = _orig_edges(mesh, parent, orig)
    oe = oe_all[border]
    nv_o = orig.n_vertices
    present = np.zeros(orig.edges.shape[0], dtype=bool)
    le = label[mesh.edges[border]]
    has = le[:, 0] != le[:, 1]  # this side has a cut point on the edge
    present[oe[has]] = True
    missing = border[~has & present[oe]]
    tri = [list(t) for t in clip.tri.tolist()]
    lab = clip.tri_label.tolist()
    face = clip.tri_face.tolist()
    bary = list(clip.tri_bary)
    sf, sb, xyz, junc, canon = [], [], [], [], []
    n = clip.canon.size
    todo = {int(e) for e in missing.tolist()}
    for _ in range(3):  # a sub-triangle with two such edges is split once per pass
        if not todo:
            break
        where = {}
        for t, T in enumerate(tri):
            for k in range(3):
                where[(T[k], T[(k + 1) % 3])] = (t, k)
        for e in sorted(todo):
            u, w = (int(x) for x in mesh.edges[e])
            hit = where.get((u, w)) or where.get((w, u))
            if hit is None or hit[0] < 0:
                continue
            t, k = hit
            T, B = tri[t], bary[t]
            a_, b_, x_ = T[k], T[(k + 1) % 3], T[(k + 2) % 3]
            ba, bb, bx = B[k], B[(k + 1) % 3], B[(k + 2) % 3]
            bm = (ba + bb) / 2.0
            m = n + len(sf)
            tri[t], bary[t] = [a_, m, x_], np.stack([ba, bm, bx])
            tri.append([m, b_, x_])
            bary.append(np.stack([bm, bb, bx]))
            lab.append(lab[t])
            face.append(face[t])
            for kk in range(3):  # the halved triangle is not split again in this pass
                where[(T[kk], T[(kk + 1) % 3])] = (-1, 0)
            sf.append(face[t])
            sb.append(bm)
            xyz.append(bm @ orig.vertices[orig.faces[face[t]]])
            junc.append(True)
            canon.append(nv_o + int(oe_all[e]))
            todo.discard(e)
    junction = np.concatenate([clip.is_junction, np.asarray(junc, dtype=bool)])
    canon_all = np.concatenate([clip.canon, np.asarray(canon, dtype=np.int64)])
    junction |= np.isin(canon_all, np.asarray(corner_vertices, dtype=np.int64))
    if not sf:
        clip.is_junction = junction
        return clip
    return _Clip(
        np.asarray(tri, dtype=np.int64),
        np.asarray(lab, dtype=np.int64),
        np.asarray(face, dtype=np.int64),
        np.asarray(bary),
        np.concatenate([clip.src_face, np.asarray(sf, dtype=np.int64)]),
        np.concatenate([clip.src_bary, np.asarray(sb)]),
        np.concatenate([clip.xyz, np.asarray(xyz)]),
        junction,
        canon_all,
    )


# ----------------------------------------------------------------------------- creases


#: edges whose dihedral angles are taken at a time (bounds the gathered normals' memory)
SHARP_CHUNK = 1 << 20
#: the folds of a mesh's edges below the crease angle are told apart in this many bins
FOLD_BINS = 400
#: the median fold is taken over about this many edges at most, evenly spread over the
#: edge table (a median of a million folds is as good as one of tens of millions)
FOLD_SAMPLE = 1 << 20
#: sharp edges make creases only where the median fold of the mesh's other edges is at
#: most this share of the crease angle: a scan whose noise folds its triangles by a quarter
#: of the crease angle as a rule folds many by the whole of it, in nets that cling to the
#: true creases and make new ones (clean scans and parts measure well under it)
CREASE_NOISE = 0.25


def sharp_edges(mesh: Mesh, angle: float) -> NDArray[np.bool_]:
    """Interior edges (over ``mesh.edges``) whose two faces' normals differ by more than
    ``angle`` degrees, each on its own: no chains, lengths or pruning (see
    :func:`crease_edges` for the creases a layout follows).

    The two faces of an edge are its first two half-edges in the edge table's order (no
    sort), and the normals are gathered a chunk of edges at a time: on a scan of tens of
    millions of faces, the whole gather would hold two normals per edge at once."""
    return _folds(mesh, angle, with_median=False)[0]


def _folds(mesh: Mesh, angle: float, *, with_median: bool) -> tuple[NDArray[np.bool_], float]:
    """`sharp_edges`, and (``with_median``) the median fold in degrees of the other
    interior edges (of every stride-th edge when there are over `FOLD_SAMPLE`), from a
    histogram of `FOLD_BINS` bins: no per-edge angles are kept."""
    table = mesh._edge_table
    ne = table.edges.shape[0]
    two = table.edge_count == 2
    last = max(table.order.size - 1, 0)
    n = mesh.face_normals
    limit = np.cos(np.radians(angle))
    # bin edges in cosine, ascending: folds from ``angle`` down to 0 degrees
    cut = np.cos(np.radians(np.linspace(angle, 0.0, FOLD_BINS + 1)))
    counts = np.zeros(FOLD_BINS + 2, dtype=np.int64)
    stride = max(1, ne // FOLD_SAMPLE)  # every stride-th edge, at most some FOLD_SAMPLE
    out = np.zeros(ne, dtype=bool)
    for a in range(0, ne, SHARP_CHUNK):
        b = min(a + SHARP_CHUNK, ne)
        first = table.start[a:b]
        fa = table.order[first] // 3
        fb = table.order[np.minimum(first + 1, last)] // 3
        dot = np.einsum("ij,ij->i", n[fa], n[fb])
        out[a:b] = two[a:b] & (dot < limit)
        if with_median:
            take = slice((-a) % stride, None, stride)
            d, t = dot[take], two[a:b][take]
            rest = d[t & (d >= limit)]
            counts += np.bincount(np.searchsorted(cut, rest), minlength=counts.size)
    if not with_median or counts.sum() == 0:
        return out, 0.0
    # bin i of ``cut`` (1..FOLD_BINS) holds folds between its two edges, largest first
    half = np.searchsorted(np.cumsum(counts[::-1]), 0.5 * counts.sum())
    return out, float(angle) * min(half, FOLD_BINS) / FOLD_BINS


def noisy_folds(mesh: Mesh) -> bool:
    """Whether ``mesh`` is noisy at the scale of its edges: the median fold of its interior
    edges that fold by at most `CREASE_ANGLE` is over `CREASE_NOISE` of it (the test by
    which :func:`crease_edges` finds no creases at the default angle, and on which the
    normal-cone test of the cells reads smoothed normals).

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    bool
        A fold is the angle in degrees between the normals of an edge's two faces; the
        median is taken over at most about `FOLD_SAMPLE` edges.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3 (four-sided patch layouts).
    """
    return _folds(mesh, CREASE_ANGLE, with_median=True)[1] > CREASE_NOISE * CREASE_ANGLE


def crease_edges(mesh: Mesh, angle: float = CREASE_ANGLE) -> NDArray[np.bool_]:
    """Edges where the surface folds by more than ``angle`` degrees.

    Parameters
    ----------
    mesh : Mesh
    angle : float
        Dihedral turn, degrees: the angle between the normals of the edge's two faces.

    Returns
    -------
    (ne,) bool
        Over ``mesh.edges``: sharp interior edges in chains at least `CREASE_MIN_LENGTH` of
        the bbox diagonal long (shorter runs are scan noise, not features), whose loops
        are as long on average (each chain's length over its independent cycles, ``edges
        - vertices + 1``: a loop of creases bounds a face of the part, while scan noise that
        folds the triangles by more than ``angle`` makes a net of loops a few edges
        long), and only when
        they add up to `CREASE_MIN_TOTAL` of the diagonal; without their dangling ends: a
        chain is kept where it closes, meets another or reaches the mesh boundary, so that
        the creases cut the surface into pieces without slits (a crease fading out inside
        the surface stays inside a patch, where a slit would leave a patch bordering
        itself). None on a mesh whose other interior edges fold by more than
        `CREASE_NOISE` of ``angle`` at the median: there a fold of ``angle`` is scan
        noise as often as a crease, and the chains above would be nets of noise.
    """
    ne = mesh.edges.shape[0]
    sharp, fold = _folds(mesh, angle, with_median=True)
    if not sharp.any() or fold > CREASE_NOISE * angle:
        return np.zeros(ne, dtype=bool)
    e = mesh.edges[sharp]
    nv = mesh.n_vertices
    g = sparse.coo_matrix((np.ones(e.shape[0]), (e[:, 0], e[:, 1])), shape=(nv, nv))
    _, comp = csgraph.connected_components(g, directed=False)
    sharp_idx = np.flatnonzero(sharp)
    lengths = np.zeros(ne)  # of the sharp edges only: all of them are not needed here
    lengths[sharp_idx] = mesh.lengths_of(sharp_idx)
    length = np.bincount(comp[e[:, 0]], weights=lengths[sharp_idx])
    ok = length[comp[e[:, 0]]] >= CREASE_MIN_LENGTH * mesh.bbox_diagonal
    idx = sharp_idx[ok]
    anchor = np.zeros(nv, dtype=bool)
    anchor[mesh.edges[mesh.edge_face_count == 1].reshape(-1)] = True
    while idx.size:  # prune dangling ends until every end is anchored
        ee = mesh.edges[idx]
        deg = np.bincount(ee.reshape(-1), minlength=nv)
        leaf = (deg == 1) & ~anchor
        drop = leaf[ee[:, 0]] | leaf[ee[:, 1]]
        if not drop.any():
            break
        idx = idx[~drop]
    if idx.size:  # what is left of each chain must still be long enough
        ee = mesh.edges[idx]
        g = sparse.coo_matrix((np.ones(idx.size), (ee[:, 0], ee[:, 1])), shape=(nv, nv))
        _, comp = csgraph.connected_components(g, directed=False)
        length = np.bincount(comp[ee[:, 0]], weights=lengths[idx])
        on = np.zeros(nv, dtype=bool)
        on[ee.reshape(-1)] = True
        loops = (
            np.bincount(comp[ee[:, 0]], minlength=length.size)
            - np.bincount(comp[on], minlength=length.size)
            + 1
        )
        per_loop = length / np.maximum(loops, 1)
        idx = idx[per_loop[comp[ee[:, 0]]] >= CREASE_MIN_LENGTH * mesh.bbox_diagonal]
    if lengths[idx].sum() < CREASE_MIN_TOTAL * mesh.bbox_diagonal:
        idx = idx[:0]
    out = np.zeros(ne, dtype=bool)
    out[idx] = True
    return out


def crease_corners(mesh: Mesh, crease: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Vertices where crease chains meet (three or more chains) or end (on the mesh
    boundary: dangling ends are pruned by :func:`crease_edges`).

    Parameters
    ----------
    mesh : Mesh
    crease : (ne,) bool
        Over ``mesh.edges``, from :func:`crease_edges`.

    Returns
    -------
    (k,) int64
        Ascending vertex indices. A chain's turns are no corners: a cell on the outer side
        of a turn would have a reflex corner there, and the quads at it fold.
    """
    deg = np.bincount(mesh.edges[crease].reshape(-1), minlength=mesh.n_vertices)
    return np.flatnonzero((deg >= 3) | (deg == 1)).astype(np.int64)


def _cut_open(mesh: Mesh, crease: NDArray[np.bool_]) -> tuple[Mesh, NDArray[np.int64]]:
    """``mesh`` with every crease edge made a boundary edge on both sides (faces in the same
    order), and the input vertex of each vertex."""
    fan, n_fans = corner_fans(mesh.faces, mesh.n_vertices, mesh._edge_table, crease)
    parent = np.empty(n_fans, dtype=np.int64)
    parent[fan] = mesh.faces.reshape(-1)
    return Mesh(mesh.vertices[parent], fan.reshape(-1, 3), name=mesh.name), parent


# ----------------------------------------------------------------------------- cells' loops


@dataclass
class _Cell:
    tris: NDArray[np.int64]  # sub-triangles of the clip
    verts: NDArray[np.int64]  # clipped vertices used, ascending (local index = position)
    loop: NDArray[np.int64]  # boundary loop, clipped ids, cell on the left


def _cell_loops(clip: _Clip, k: int) -> list[_Cell]:
    order = np.argsort(clip.tri_label, kind="stable")
    starts = np.searchsorted(clip.tri_label[order], np.arange(k + 1))
    cells = []
    for c in range(k):
        tris = order[starts[c] : starts[c + 1]]
        T = clip.tri[tris]
        verts, inv = np.unique(T.reshape(-1), return_inverse=True)
        local = inv.reshape(-1, 3).astype(np.int64)
        loops = boundary_loops(local, edge_table(local, verts.size))
        if len(loops) != 1:
            raise LayoutError(f"cell {c} has {len(loops)} boundary loops")
        cells.append(_Cell(tris, verts, verts[loops[0]]))
    return cells


def _arc(xyz: NDArray[np.float64], ids: NDArray[np.int64], closed: bool) -> NDArray[np.float64]:
    p = xyz[ids]
    if closed:
        p = np.vstack([p, p[:1]])
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])


def _corners(clip: _Clip, cells: list[_Cell]) -> NDArray[np.bool_]:
    """Corners over the canonical points: the junctions, plus corners added at even arc
    length on every cell loop with fewer than three (a corner on a crease is one on both
    of its sides)."""
    corner = np.zeros(int(clip.canon.max()) + 1, dtype=bool)
    corner[clip.canon[clip.is_junction]] = True
    for _ in range(3 * len(cells) + 3):
        changed = False
        for cell in cells:
            loop = cell.loop
            pos = np.flatnonzero(corner[clip.canon[loop]])
            if pos.size >= 3:
                continue
            arc = _arc(clip.xyz, loop, True)
            total = arc[-1]
            if pos.size == 0:
                picks = [int(np.argmin(np.abs(arc[:-1] - t * total))) for t in (0, 1 / 3, 2 / 3)]
            else:
                # halve the longest stretch between consecutive corners (arc lengths along
                # the loop run twice round, so a stretch may pass the loop's start)
                arc2 = np.concatenate([arc[:-1], total + arc[:-1]])
                ends = np.append(pos, pos[0] + loop.size)
                lens = arc2[ends[1:]] - arc2[ends[:-1]]
                j = int(np.argmax(lens))
                a, b = int(ends[j]), int(ends[j + 1])
                idx = np.arange(a + 1, b)
                if idx.size == 0:
                    raise LayoutError("a cell side too short to take another corner")
                half = arc2[a] + lens[j] / 2.0
                picks = [int(idx[np.argmin(np.abs(arc2[idx] - half))] % loop.size)]
            corner[clip.canon[loop[picks]]] = True
            changed = True
        if not changed:
            return corner
    raise LayoutError("corners could not be placed on every cell")


# ----------------------------------------------------------------------------- the layout


@dataclass
class _Stretch:
    ids: NDArray[np.int64]  # clipped vertices, corner to corner (of the first cell seen)
    mid_seg: int  # the mid-point lies on segment ids[mid_seg] -> ids[mid_seg + 1] ...
    mid_t: float  # ... at this fraction
    uses: int
    on_border: bool  # along the boundary of the cut-open mesh (mesh boundary or crease)


def _border_pairs(clip: _Clip) -> set[tuple[int, int]]:
    """Sub-triangle edges on the boundary of the cut-open mesh, as sorted clipped ids."""
    T = clip.tri
    e = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(e, axis=0, return_counts=True)
    return {(int(a), int(b)) for a, b in uniq[count == 1].tolist()}


def _stretches(clip: _Clip, cells: list[_Cell], corner: NDArray[np.bool_]):
    """The stretches between corners, and every cell's sides as (stretch, reversed, start)
    in loop order (``start``: the side's first position in ``cell.loop``, which is rolled
    to start at a corner). Stretches are matched across cells by canonical points."""
    found: dict[tuple[int, int], tuple[int, bool]] = {}
    stretches: list[_Stretch] = []
    sides: list[list[tuple[int, bool, int]]] = []
    border = _border_pairs(clip)
    canon = clip.canon
    for cell in cells:
        pos = np.flatnonzero(corner[canon[cell.loop]])
        cell.loop = np.roll(cell.loop, -int(pos[0]))
        loop = cell.loop
        pos = pos - pos[0]
        mine = []
        for j in range(pos.size):
            a = int(pos[j])
            b = int(pos[j + 1]) if j + 1 < pos.size else loop.size
            ids = np.append(loop[a:b], loop[b % loop.size])
            key = (int(canon[ids[0]]), int(canon[ids[1]]))
            if key in found:
                s, rev = found[key]
                stretches[s].uses += 1
                mine.append((s, rev, a))
                continue
            arc = _arc(clip.xyz, ids, False)
            if ids.size > 2:
                # the mid-point at the inner vertex nearest half the length: a point just
                # beside a vertex of the stretch would put the radius that ends at it
                # within the cut's snapping distance of the stretch
                k = 1 + int(np.argmin(np.abs(arc[1:-1] - arc[-1] / 2.0)))
                seg, t = k - 1, 1.0
            else:
                seg, t = 0, 0.5
            on_border = all(
                (min(u, w), max(u, w)) in border
                for u, w in zip(ids[:-1].tolist(), ids[1:].tolist(), strict=True)
            )
            s = len(stretches)
            stretches.append(_Stretch(ids, seg, t, 1, on_border))
            found[key] = (s, False)
            found[(int(canon[ids[-1]]), int(canon[ids[-2]]))] = (s, True)
            mine.append((s, False, a))
        sides.append(mine)
    return stretches, sides


def _segment_point(clip: _Clip, cell: _Cell, u: int, w: int, t: float):
    """Face point at fraction ``t`` from clipped vertex ``u`` to ``w`` along a boundary edge
    of ``cell`` (in the input face of the sub-triangle holding that edge)."""
    T = clip.tri[cell.tris]
    for k in range(3):
        hit = np.flatnonzero(
            ((T[:, k] == u) & (T[:, (k + 1) % 3] == w))
            | ((T[:, k] == w) & (T[:, (k + 1) % 3] == u))
        )
        if hit.size:
            i = int(hit[0])
            ku = int(np.flatnonzero(T[i] == u)[0])
            kw = int(np.flatnonzero(T[i] == w)[0])
            b = clip.tri_bary[cell.tris[i]]
            return int(clip.tri_face[cell.tris[i]]), (1.0 - t) * b[ku] + t * b[kw]
    raise LayoutError("a cell side has no sub-triangle")


def _mean_value_weights(P: NDArray[np.float64], T: NDArray[np.int64], n: int) -> sparse.csr_matrix:
    """Floater's mean value weights ``w[i, j]`` (positive, so Tutte's embedding with them is a
    bijection onto a convex boundary polygon)."""
    rows, cols, vals = [], [], []
    for k in range(3):
        i, j, l = T[:, k], T[:, (k + 1) % 3], T[:, (k + 2) % 3]
        eij, eil = P[j] - P[i], P[l] - P[i]
        nij = np.linalg.norm(eij, axis=1)
        nil = np.linalg.norm(eil, axis=1)
        cosang = np.clip((eij * eil).sum(1) / np.maximum(nij * nil, 1e-300), -1.0, 1.0)
        t = np.tan(np.arccos(cosang) / 2.0)
        rows += [i, i]
        cols += [j, l]
        vals += [t / np.maximum(nij, 1e-300), t / np.maximum(nil, 1e-300)]
    W = sparse.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
    )
    return W


def _disc_map(clip: _Clip, cell: _Cell, starts) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """2-d positions of the cell's vertices and its sub-triangles in local indices.

    The boundary goes onto the unit circle with an equal arc for each of the cell's ``k``
    sides (``starts``: their first positions in ``cell.loop``, ascending from 0), by arc
    length within a side: the radii to the sides' mid-points then leave the centre evenly,
    and the quads meeting there share its angle (by arc length alone, a cell with one long
    side gives the quads beside it slivers at the centre).
    """
    verts = cell.verts
    T = np.searchsorted(verts, clip.tri[cell.tris])
    loop = np.searchsorted(verts, cell.loop)
    P = clip.xyz[verts]
    n = verts.size
    arc = _arc(clip.xyz, cell.loop, True)
    k = len(starts)
    bounds = np.append(np.asarray(starts, dtype=np.int64), cell.loop.size)
    ang = np.empty(cell.loop.size)
    for j in range(k):
        a, b = int(bounds[j]), int(bounds[j + 1])
        span = max(arc[b] - arc[a], 1e-300)
        ang[a:b] = 2.0 * np.pi * (j + (arc[a:b] - arc[a]) / span) / k
    uv = np.zeros((n, 2))
    uv[loop] = np.stack([np.cos(ang), np.sin(ang)], 1)
    inner = np.ones(n, dtype=bool)
    inner[loop] = False
    if inner.any():
        W = _mean_value_weights(P, T, n)
        deg = np.asarray(W.sum(axis=1)).ravel()
        A = sparse.diags(deg) - W
        A = A.tocsr()
        ii = np.flatnonzero(inner)
        bb = np.flatnonzero(~inner)
        Aii = A[ii][:, ii].tocsc()
        rhs = -(A[ii][:, bb] @ uv[bb])
        sol = spsolve(Aii, rhs)
        uv[ii] = np.asarray(sol).reshape(-1, 2)
    return uv, T


class _Locator:
    """Point location in a cell's 2-d triangulation."""

    def __init__(self, uv: NDArray[np.float64], T: NDArray[np.int64]) -> None:
        self.uv, self.T = uv, T
        self.tree = cKDTree(uv[T].mean(axis=1))
        self.neighbors = np.ascontiguousarray(face_neighbors(T, edge_table(T, uv.shape[0])))
        self.uv = np.ascontiguousarray(uv, dtype=np.float64)
        self.T = np.ascontiguousarray(T, dtype=np.int64)

    def bary(self, q: NDArray[np.float64], tris: NDArray[np.int64]):
        a, b, c = (self.uv[self.T[tris, k]] for k in range(3))
        v0, v1, v2 = b - a, c - a, q - a
        den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
        den = np.where(np.abs(den) > 1e-300, den, 1e-300)
        l1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
        l2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
        return np.stack([1.0 - l1 - l2, l1, l2], 1)

    def locate(self, q: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Sub-triangle and barycentrics of each point: a walk from triangle to triangle
        (the points come along a path), the nearest triangles by their centroids where the
        walk does not settle."""
        q = np.ascontiguousarray(q, dtype=np.float64)
        if q.shape[0] == 0:
            return np.zeros(0, dtype=np.int64), np.zeros((0, 3))
        start = int(self.tree.query(q[0])[1])
        out_t, out_b = walk_locate(self.uv, self.T, self.neighbors, q, start, WALK_EPS)
        lost = np.flatnonzero(out_t < 0)
        if lost.size:
            t, b = self._nearest(q[lost])
            out_t[lost], out_b[lost] = t, b
        out_b = np.clip(out_b, 0.0, None)
        out_b /= out_b.sum(axis=1, keepdims=True)
        return out_t, out_b

    def _nearest(self, q: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        n = q.shape[0]
        out_t = np.full(n, -1, dtype=np.int64)
        out_b = np.zeros((n, 3))
        best = np.full(n, -np.inf)
        nt = self.T.shape[0]
        for kk in (8, 32, 128, nt):
            todo = np.flatnonzero(best < -1e-9)
            if not todo.size:
                break
            kq = min(kk, nt)
            _, cand = self.tree.query(q[todo], k=kq)
            cand = np.asarray(cand).reshape(todo.size, kq)
            for j in range(kq):
                b = self.bary(q[todo], cand[:, j])
                m = b.min(axis=1)
                better = m > best[todo]
                sel = todo[better]
                best[sel] = m[better]
                out_t[sel] = cand[better, j]
                out_b[sel] = b[better]
            if kq == nt:
                break
        return out_t, out_b


def _face_points(clip: _Clip, cell: _Cell, tloc: NDArray[np.int64], b: NDArray[np.float64]):
    g = cell.tris[tloc]
    bary = np.einsum("nk,nkj->nj", b, clip.tri_bary[g])
    return clip.tri_face[g], bary


def _radius(mesh: Mesh, clip: _Clip, cell: _Cell, loc: _Locator, start, end):
    """Face points of the image of the 2-d segment ``start -> end``.

    Sampled until consecutive samples lie in the same or edge-adjacent sub-triangles and at
    most `TRACE_GAP_EDGES` apart; where two consecutive samples lie in different
    sub-triangles, the point where the segment crosses their shared sub-edge is inserted,
    so that consecutive points always share a sub-triangle and the curve follows the map
    exactly, as the map is affine on each sub-triangle only. Between two input faces the
    cut would otherwise join the samples by unfolding the faces, another path where the
    surface bends; inside one face a chord across a sub-edge is another path where the map
    bends, and two radii close to their common centre could cross (on noisy scans, whose
    folded triangles bend the map sharply)."""
    gap = TRACE_GAP_EDGES * mesh.mean_edge_length
    nbr = loc.neighbors
    ts = np.linspace(0.0, 1.0, 17)
    for _ in range(TRACE_ROUNDS):
        t_loc, b = loc.locate(start[None] + ts[:, None] * (end - start)[None])
        f, bary = _face_points(clip, cell, t_loc, b)
        x = np.einsum("nk,nkj->nj", bary, mesh.vertices[mesh.faces[f]])
        a, c = t_loc[:-1], t_loc[1:]
        touching = (a == c) | (nbr[a] == c[:, None]).any(axis=1)
        bad = ~touching | (np.linalg.norm(np.diff(x, axis=0), axis=1) > gap)
        if not bad.any() or ts.size > 1 << 16:
            break
        ts = np.sort(np.concatenate([ts, (ts[:-1][bad] + ts[1:][bad]) / 2.0]))
    else:
        t_loc, b = loc.locate(start[None] + ts[:, None] * (end - start)[None])
        f, bary = _face_points(clip, cell, t_loc, b)
    faces_out, bary_out = [int(f[0])], [bary[0]]
    for i in range(1, ts.size):
        ta, tc = int(t_loc[i - 1]), int(t_loc[i])
        if ta != tc:
            qa = start + ts[i - 1] * (end - start)
            qc = start + ts[i] * (end - start)
            cross = _crossing(clip, cell, loc, ta, tc, qa, qc)
            if cross is not None:
                faces_out.append(cross[0])
                bary_out.append(cross[1])
        faces_out.append(int(f[i]))
        bary_out.append(bary[i])
    return np.asarray(faces_out, dtype=np.int64), np.asarray(bary_out)


def _crossing(clip: _Clip, cell: _Cell, loc: _Locator, ta: int, tc: int, qa, qc):
    """Face point where the 2-d segment ``qa -> qc`` crosses the sub-edge shared by local
    sub-triangles ``ta`` and ``tc`` (in the input face of ``ta``), or None."""
    Ta, Tc = loc.T[ta], loc.T[tc]
    shared = [k for k in range(3) if Ta[k] in Tc]
    if len(shared) != 2:
        return None
    k0, k1 = shared
    p, r = loc.uv[Ta[k0]], loc.uv[Ta[k1]]
    d, e = qc - qa, r - p
    den = d[0] * e[1] - d[1] * e[0]
    if abs(den) < 1e-300:
        return None
    w = p - qa
    s = float(np.clip((w[0] * d[1] - w[1] * d[0]) / den, 0.0, 1.0))
    gb = clip.tri_bary[cell.tris[ta]]
    return int(clip.tri_face[cell.tris[ta]]), (1.0 - s) * gb[k0] + s * gb[k1]


@dataclass(frozen=True)
class _Merge:
    """A short side ``s`` (between cells ``a`` and ``b``) whose two end corners become one
    at its mid-point; ``cut[t]``: for each other side ``t`` at those ends, the index in
    ``stretches[t].ids`` where the curve leaves ``t`` for a chord through ``a`` or ``b``."""

    s: int
    a: int
    b: int
    cut: dict[int, int]


def _stretch_length(clip: _Clip, st: _Stretch) -> float:
    return float(_arc(clip.xyz, st.ids, False)[-1])


def _short_sides(clip: _Clip, stretches: list[_Stretch], sides) -> list[_Merge]:
    """Sides shorter than `SHORT_SIDE` times the median of the four sides at their ends,
    whose two ends (three cells each, all sides inside the mesh) become one corner where
    four cells meet.

    Two corners joined by a short side give the quads of both cells along it a side a
    fraction of the others' length and a sliver at the cell's centre, whose grids fold; a
    Voronoi diagram has such sides wherever four seeds lie nearly on a circle. Each cell
    keeps at least three sides, the four cells are distinct, and no corner takes part in
    two merges.
    """
    canon = clip.canon
    at: dict[int, list[int]] = {}
    cells_of: dict[int, list[int]] = {}
    for ci, cs in enumerate(sides):
        for s, _, _ in cs:
            cells_of.setdefault(s, []).append(ci)
    for s, st in enumerate(stretches):
        for v in (int(canon[st.ids[0]]), int(canon[st.ids[-1]])):
            at.setdefault(v, []).append(s)
    length = [_stretch_length(clip, st) for st in stretches]
    n_sides = [len(cs) for cs in sides]
    used: set[int] = set()
    out: list[_Merge] = []
    for s in sorted(range(len(stretches)), key=lambda i: length[i]):
        st = stretches[s]
        ends = (int(canon[st.ids[0]]), int(canon[st.ids[-1]]))
        if st.on_border or st.uses != 2 or ends[0] == ends[1] or used & set(ends):
            continue
        if any(len(at[v]) != 3 for v in ends):
            continue
        others = [t for v in ends for t in at[v] if t != s]
        if len(set(others)) != 4 or any(stretches[t].on_border for t in others):
            continue
        if length[s] >= SHORT_SIDE * float(np.median([length[t] for t in others])):
            continue
        a, b = cells_of[s]
        if a == b or n_sides[a] < 4 or n_sides[b] < 4:
            continue
        thirds = [
            next((c for t in at[v] if t != s for c in cells_of[t] if c not in (a, b)), -1)
            for v in ends
        ]
        if min(thirds) < 0 or thirds[0] == thirds[1]:
            continue
        cut = {
            t: _cut_index(clip, stretches[t], v, length[s] / 2.0)
            for v in ends
            for t in at[v]
            if t != s
        }
        if min(cut.values()) < 0:
            continue
        used.update(ends)
        n_sides[a] -= 1
        n_sides[b] -= 1
        out.append(_Merge(s, a, b, cut))
    return out


def _cut_index(clip: _Clip, st: _Stretch, end: int, dist: float) -> int:
    """Index in ``st.ids`` about ``dist`` along the stretch from its end at canonical point
    ``end``, strictly between that end and the stretch's mid-point; -1 if there is none."""
    arc = _arc(clip.xyz, st.ids, False)
    last = st.ids.size - 1
    mid_after = st.mid_seg + 1  # the first index past the mid-point (or at it, mid_t = 1)
    if int(clip.canon[st.ids[0]]) == end:
        lo, hi = 1, st.mid_seg
        target = arc[0] + dist
    else:
        lo, hi = mid_after + (1 if st.mid_t == 1.0 else 0), last - 1
        target = arc[-1] - dist
    if lo > hi:
        return -1
    idx = np.arange(lo, hi + 1)
    return int(idx[np.argmin(np.abs(arc[idx] - target))])


def _loop_pos(cell: _Cell, st: _Stretch, rev: bool, a: int, q: int) -> int:
    """Position in ``cell.loop`` of ``st.ids[q]``, for the cell's side ``(st, rev, a)``."""
    last = st.ids.size - 1
    return (a + (last - q if rev else q)) % cell.loop.size


def _mid_uv(cell: _Cell, uv, loop_local, st: _Stretch, rev: bool, a: int):
    """Disc point of a stretch's mid-point in a cell's map."""
    pu = uv[loop_local[_loop_pos(cell, st, rev, a, st.mid_seg)]]
    pw = uv[loop_local[_loop_pos(cell, st, rev, a, st.mid_seg + 1)]]
    return (1.0 - st.mid_t) * pu + st.mid_t * pw


def _disc_starts(sides: list[tuple[int, bool, int]], merged) -> list[int]:
    """The sides' first loop positions for the disc map, a merged side joined to the side
    after it (to the one before it when it is the last)."""
    starts = [a for _, _, a in sides]
    drop = set()
    for m, (s, _, _) in enumerate(sides):
        if s in merged:
            drop.add(m + 1 if m + 1 < len(sides) else m)
    return [a for m, a in enumerate(starts) if m not in drop]


def _chords(mesh: Mesh, clip: _Clip, cells, stretches, merges, entry, maps, points) -> dict:
    """Per side ``t`` at a merged corner: ``(p, faces, barys)``, the face points of the
    chord from the merged corner to ``stretches[t].ids[p]`` through the cell that had the
    short side (``points``: the corner points so far and each stretch's mid-point index)."""
    cf, cb, mid_index = points
    out: dict[int, list] = {}
    for m in merges:
        st_s = stretches[m.s]
        for t, p in m.cut.items():
            x = m.a if (m.a, t) in entry else m.b
            uv, loc, loop_local = maps[x]
            start = _mid_uv(cells[x], uv, loop_local, st_s, *entry[x, m.s])
            st_t = stretches[t]
            end = uv[loop_local[_loop_pos(cells[x], st_t, *entry[x, t], p)]]
            f, bary = _radius(mesh, clip, cells[x], loc, start, end)
            f, bary = list(f), list(bary)
            f[0], bary[0] = cf[mid_index[m.s]], cb[mid_index[m.s]]
            f[-1], bary[-1] = clip.src_face[st_t.ids[p]], clip.src_bary[st_t.ids[p]]
            out.setdefault(t, []).append((p, f, bary))
    return out


def _halves(clip: _Clip, st: _Stretch, mid, chords) -> tuple[tuple[list, list], ...]:
    """The face points of a stretch's two halves (corner to mid-point, mid-point to corner);
    an end at a merged corner is cut at the chord's point and the chord leads on."""
    f, b = mid
    lo, hi = 0, st.ids.size  # the stretch's ids the halves keep
    head: tuple[list, list] = ([], [])  # chord points before ids[lo] ...
    tail: tuple[list, list] = ([], [])  # ... and after ids[hi - 1]
    for p, fc, bc in chords:
        if p <= st.mid_seg:
            lo, head = p, (fc[:-1], bc[:-1])
        else:
            hi, tail = p + 1, (fc[::-1][1:], bc[::-1][1:])
    ids = st.ids[lo : st.mid_seg + 1]
    first = ([*head[0], *clip.src_face[ids], f], [*head[1], *clip.src_bary[ids], b])
    # (a mid-point at the vertex ids[mid_seg + 1] replaces it in the second half)
    ids = st.ids[st.mid_seg + 1 + int(st.mid_t == 1.0) : hi]
    second = ([f, *clip.src_face[ids], *tail[0]], [b, *clip.src_bary[ids], *tail[1]])
    return first, second


@dataclass
class _Net:
    """The layout under construction: corner points, curves with their ends and flags
    (fixed: not relaxed; crease), and patches as four (curve, reversed) sides."""

    cf: list
    cb: list
    curves: list
    ends: list
    fixed: list
    crease: list
    patches: list

    def point(self, f: int, b) -> int:
        self.cf.append(int(f))
        self.cb.append(b)
        return len(self.cf) - 1

    def curve(self, f, b, start: int, end: int) -> int:
        """An interior curve from corner ``start`` to ``end`` (its end points made exactly
        theirs)."""
        f, b = np.asarray(f, dtype=np.int64).copy(), np.asarray(b, dtype=np.float64).copy()
        f[0], b[0] = self.cf[start], self.cb[start]
        f[-1], b[-1] = self.cf[end], self.cb[end]
        self.curves.append(SurfacePoints(f, b))
        self.ends.append((start, end))
        self.fixed.append(False)
        self.crease.append(False)
        return len(self.curves) - 1


@dataclass
class _Side:
    """A side of a polygon to split into quads: its halves as (curve, reversed), from its
    first corner to its mid-point and on to its last corner; the mid-point (corner index,
    disc point); the first corner (corner index, vertex of the disc map, disc point);
    whether the polygon's angle at the first corner is straight (`_straight`) and whether a
    chord ends there."""

    first: tuple[int, bool]
    second: tuple[int, bool]
    mid: int
    mid_uv: NDArray[np.float64]
    start: int
    start_v: int
    start_uv: NDArray[np.float64]
    straight: bool = False
    chorded: bool = False  # a chord ends at the first corner


@dataclass
class _Domain:
    """A cell or a part of one with its disc map: ``clip`` and ``cell`` hold its
    sub-triangles (for a part, local ones cut from its parent's), ``loc`` their disc map."""

    clip: _Clip
    cell: _Cell
    loc: _Locator


def _ring(clip: _Clip, cell: _Cell, stretches, mine, disc, index) -> list[_Side]:
    """The cell's sides (``mine``: (stretch, reversed, start) in loop order) as `_Side`."""
    uv, _, loop_local = disc
    c_index, mid_index, halves = index
    out = []
    for s, rev, a in mine:
        h = halves[s]
        out.append(
            _Side(
                (h[1], True) if rev else (h[0], False),
                (h[0], True) if rev else (h[1], False),
                mid_index[s],
                _mid_uv(cell, uv, loop_local, stretches[s], rev, a),
                int(c_index[clip.canon[cell.loop[a]]]),
                int(loop_local[a]),
                uv[loop_local[a]],
            )
        )
    return out


def _straight(mesh: Mesh, clip: _Clip, cell: _Cell, stretches, mine, i: int) -> bool:
    """Whether the cell's corner before side ``i`` is at a crease and turns by less than
    ``180 - STRAIGHT_CORNER`` degrees (or back: a reflex angle) on the cell's side.

    Cells on the two sides of a crease are grown apart, so a cell may have a corner in the
    middle of a straight crease side (an end of the cells across that found no partner on
    this side) or a boundary that leaves the crease at a glancing angle. Elsewhere the
    cells' corners are Voronoi junctions, whose angles are left as they are."""
    if not any(
        stretches[t].on_border and stretches[t].uses == 2 for t in (mine[i][0], mine[i - 1][0])
    ):
        return False
    return _corner_angle(mesh, clip, cell, [a for _, _, a in mine], i) >= STRAIGHT_CORNER


def _corner_angle(mesh: Mesh, clip: _Clip, cell: _Cell, starts: list[int], i: int) -> float:
    """The cell's angle (degrees, 0 to 360) at its corner ``starts[i]`` (a loop position):
    between the chords to the points `CORNER_REACH` of the shorter side along each side,
    about the normal of the cell's faces at the corner."""
    loop, n = cell.loop, cell.loop.size
    a, k = starts[i], len(starts)
    nxt, prv = starts[(i + 1) % k], starts[i - 1]
    fwd = loop[(a + np.arange((nxt - a - 1) % n + 1) + 1) % n]  # a + 1 .. next corner
    bwd = loop[(a - np.arange((a - prv - 1) % n + 1) - 1) % n]  # a - 1 .. previous corner
    x0 = clip.xyz[loop[a]]

    def along(ids):
        p = clip.xyz[ids]
        arc = np.cumsum(np.linalg.norm(np.diff(np.vstack([x0, p]), axis=0), axis=1))
        return p, arc

    pf, af = along(fwd)
    pb, ab = along(bwd)
    reach = CORNER_REACH * min(af[-1], ab[-1])
    d_out = pf[min(int(np.searchsorted(af, reach)), pf.shape[0] - 1)] - x0
    d_in = pb[min(int(np.searchsorted(ab, reach)), pb.shape[0] - 1)] - x0
    touch = cell.tris[(clip.tri[cell.tris] == loop[a]).any(axis=1)]
    nrm = mesh.face_normals[clip.tri_face[touch]].sum(axis=0)
    ang = np.arctan2(
        float(nrm @ np.cross(d_out, d_in)) / max(np.linalg.norm(nrm), 1e-300), float(d_out @ d_in)
    )
    return float(np.degrees(ang) % 360.0)


def _split_straight(mesh: Mesh, dom: _Domain, ring: list[_Side], net) -> list:
    """The cell's polygon cut by chords until no part has a straight corner: its parts as
    (domain, sides).

    A straight corner (a cell end across a crease that found no partner on this side, or a
    cell boundary leaving another at a glancing angle) would be a quad's corner of about
    180 degrees, a triangle whose grid folds. A chord of the disc map from it to the corner
    most nearly opposite (`_chord_ends`) makes it a corner of two parts, and each part gets
    a disc map of its own (`_halve`), so its radii leave its centre evenly. Chords and radii
    are images of segments in convex disc polygons, so none crosses another."""
    todo, out = [(dom, list(ring))], []
    while todo:
        dom, poly = todo.pop()
        cut = _chord_ends([sd.straight for sd in poly], [sd.chorded for sd in poly])
        halves = _halve(mesh, dom, poly, cut, net) if cut is not None else None
        if halves is None:
            out.append((dom, poly))
        else:
            todo += halves
    return out


def _parts(flags: list[tuple[bool, bool]], j: int, p: int) -> tuple[list, list]:
    """The (straight, chorded) flags of the two parts of a polygon cut by the chord
    ``j -> p`` (the chord is the last side of each; its ends are chorded)."""
    n = len(flags)
    fore = [flags[(p + t) % n] for t in range((j - p) % n)] + [(False, True)]
    aft = [flags[(j + t) % n] for t in range((p - j) % n)] + [(False, True)]
    fore[0] = aft[0] = (False, True)
    return fore, aft


def _chord_ends(straight: list[bool], chorded: list[bool]) -> tuple[int, int] | None:
    """The chord that cuts a polygon with straight corners (flags per corner), or None.

    From the first straight corner to the corner most nearly opposite (another straight
    one at half a step's advantage), never a neighbour (each part keeps three corners) nor
    a corner a chord already ends at (two chords from one corner run side by side), and
    only where both parts can be cut on until no straight corner is left: an exact search
    over the parts for up to `CHORD_SEARCH` of them, then a look one chord ahead (a cell
    of many straight corners would otherwise cost a search exponential in its sides)."""
    flags = tuple(zip(straight, chorded, strict=True))
    return _chord_search(flags, {}, [CHORD_SEARCH])


def _chord_search(flags, memo: dict, budget: list[int]) -> tuple[int, int] | None:
    if flags in memo:
        return memo[flags]
    budget[0] -= 1
    n = len(flags)
    out = None
    for j in (j for j in range(n) if flags[j][0]):
        far = [d for d in range(2, n - 1) if not flags[(j + d) % n][1]]
        far.sort(key=lambda d: abs(d - n / 2.0) - 0.5 * flags[(j + d) % n][0])
        for d in far:
            p = (j + d) % n
            if all(_clears(part, memo, budget) for part in _parts(list(flags), j, p)):
                out = (j, p)
                break
        if out is not None:
            break
    memo[flags] = out
    return out


def _clears(flags: list[tuple[bool, bool]], memo: dict, budget: list[int]) -> bool:
    """Whether a part can be cut down to parts without straight corners: by the search
    while its budget lasts, else whether each straight corner has a corner to reach."""
    n = len(flags)
    if not any(f[0] for f in flags):
        return True
    if budget[0] > 0:
        return _chord_search(tuple(flags), memo, budget) is not None
    return all(
        any(not flags[(j + d) % n][1] for d in range(2, n - 1)) for j in range(n) if flags[j][0]
    )


def _halve(mesh: Mesh, dom: _Domain, poly: list[_Side], cut, net):
    """The two parts of ``poly`` cut by the chord between its corners ``cut = (j, p)``, each
    as (domain with its own disc map, sides); None where the chord crosses no sub-triangle
    edge (no point for its mid-point)."""
    j, p = cut
    n = len(poly)
    ua, ub = poly[j].start_uv, poly[p].start_uv
    pieces = _cut_triangles(dom, ua, ub)
    if pieces is None:
        return None
    (Vuv, Vxyz, tris, tface, tbary), on_line, ts = pieces
    # the chord's mid-point: the vertex on it nearest half its length
    order = on_line[np.argsort(ts)]
    if order.size < 3:
        return None
    arc = _arc(Vxyz, order, False)
    k = 1 + int(np.argmin(np.abs(arc[1:-1] - arc[-1] / 2.0)))
    mv = int(order[k])
    hit = np.flatnonzero((tris == mv).any(axis=1))[0]
    corner = int(np.flatnonzero(tris[hit] == mv)[0])
    mid = net.point(int(tface[hit]), tbary[hit, corner])
    mid_uv = Vuv[mv]
    h0 = net.curve(*_radius(mesh, dom.clip, dom.cell, dom.loc, ua, mid_uv), poly[j].start, mid)
    h1 = net.curve(*_radius(mesh, dom.clip, dom.cell, dom.loc, mid_uv, ub), mid, poly[p].start)
    # (the chord's vertices lie on it exactly: the parts are told apart by the others)
    d = ub - ua
    side = d[0] * (Vuv[:, 1] - ua[1]) - d[1] * (Vuv[:, 0] - ua[0])
    side[on_line] = 0.0
    tri_side = side[tris].sum(axis=1)
    fore = [poly[(p + t) % n] for t in range((j - p) % n)]
    fore.append(_Side((h0, False), (h1, False), mid, mid_uv, poly[j].start, -1, ua, False, True))
    aft = [poly[(j + t) % n] for t in range((p - j) % n)]
    aft.append(_Side((h1, True), (h0, True), mid, mid_uv, poly[p].start, -1, ub, False, True))
    fore[0] = replace(fore[0], straight=False, chorded=True)
    aft[0] = replace(aft[0], straight=False, chorded=True)
    starts_v = {poly[j].start: poly[j].start_v, poly[p].start: poly[p].start_v}
    out = []
    # (the disc maps run counter-clockwise: the corners after the chord's start lie on its
    # right)
    for sides, keep in ((aft, tri_side < 0), (fore, tri_side > 0)):
        part = _part(dom, sides, starts_v, (Vuv, Vxyz, tris[keep], tface[keep], tbary[keep]))
        if part is None:
            return None
        out.append(part)
    return out


def _cut_triangles(dom: _Domain, ua, ub):
    """The domain's sub-triangles cut along the disc segment ``ua -> ub``: vertices (disc
    point, 3-d point; the domain's first, then one per crossed edge), triangles with their
    input faces and corner barycentrics; the vertices on the segment and their parameters
    along it. None where no edge is crossed."""
    uv, T = dom.loc.uv, dom.loc.T
    face = dom.clip.tri_face[dom.cell.tris]
    bary = dom.clip.tri_bary[dom.cell.tris]
    xyz = dom.clip.xyz[dom.cell.verts]
    d = ub - ua
    side = d[0] * (uv[:, 1] - ua[1]) - d[1] * (uv[:, 0] - ua[0])
    side[np.abs(side) <= 1e-12 * float(d @ d)] = 0.0
    new_uv, new_xyz, key = [], [], {}
    tris, tface, tbary = [], [], []
    for t in range(T.shape[0]):
        tv, ts_ = T[t], side[T[t]]
        if (ts_ >= 0).all() or (ts_ <= 0).all():
            tris.append(tv)
            tface.append(face[t])
            tbary.append(bary[t])
            continue
        ring_v, ring_b = [], []
        for k in range(3):
            a, b = int(tv[k]), int(tv[(k + 1) % 3])
            ring_v.append(a)
            ring_b.append(bary[t, k])
            if ts_[k] * ts_[(k + 1) % 3] < 0:
                s = ts_[k] / (ts_[k] - ts_[(k + 1) % 3])
                e = (min(a, b), max(a, b))
                if e not in key:
                    key[e] = uv.shape[0] + len(new_uv)
                    new_uv.append(uv[a] + s * (uv[b] - uv[a]))
                    new_xyz.append(xyz[a] + s * (xyz[b] - xyz[a]))
                ring_v.append(key[e])
                ring_b.append(bary[t, k] + s * (bary[t, (k + 1) % 3] - bary[t, k]))
        for sign in (1.0, -1.0):  # each side's polygon, fanned
            sel = [i for i, v in enumerate(ring_v) if v >= uv.shape[0] or sign * side[v] >= 0]
            for i in range(1, len(sel) - 1):
                q = (sel[0], sel[i], sel[i + 1])
                tris.append(np.asarray([ring_v[x] for x in q]))
                tface.append(face[t])
                tbary.append(np.stack([ring_b[x] for x in q]))
    if not new_uv:
        return None
    Vuv = np.vstack([uv, np.asarray(new_uv)])
    Vxyz = np.vstack([xyz, np.asarray(new_xyz)])
    on = np.concatenate([np.flatnonzero(side == 0.0), uv.shape[0] + np.arange(len(new_uv))])
    ts = ((Vuv[on] - ua) @ d) / float(d @ d)
    inside = (ts >= 0.0) & (ts <= 1.0)
    return (
        (Vuv, Vxyz, np.asarray(tris, dtype=np.int64), np.asarray(tface), np.asarray(tbary)),
        on[inside],
        ts[inside],
    )


def _part(dom: _Domain, sides: list[_Side], starts_v: dict, pieces):
    """One part of a cut domain as (domain, sides): its triangles re-indexed, its own disc
    map with an equal arc per side, the sides' corners and mid-points carried into it;
    None where the part is not one disk."""
    Vuv, Vxyz, tris, tface, tbary = pieces
    verts, inv = np.unique(tris.reshape(-1), return_inverse=True)
    local = inv.reshape(-1, 3).astype(np.int64)
    loops = boundary_loops(local, edge_table(local, verts.size))
    if len(loops) != 1:
        return None
    m = verts.size
    clip = _Clip(
        local,
        np.zeros(local.shape[0], dtype=np.int64),
        tface,
        tbary,
        np.zeros(m, dtype=np.int64),
        np.zeros((m, 3)),
        Vxyz[verts],
        np.zeros(m, dtype=bool),
        np.zeros(m, dtype=np.int64),
    )
    old = _Locator(Vuv[verts], local)  # the parent's disc points of the part
    corner_v = []
    for sd in sides:
        v = sd.start_v if sd.start_v >= 0 else starts_v[sd.start]
        corner_v.append(int(np.searchsorted(verts, v)))
    loop = np.asarray(loops[0], dtype=np.int64)
    pos = [int(np.flatnonzero(loop == v)[0]) for v in corner_v]
    loop = np.roll(loop, -pos[0])
    starts = [(q - pos[0]) % loop.size for q in pos]
    if any(b <= a for a, b in itertools.pairwise(starts)):
        return None
    cell = _Cell(np.arange(local.shape[0]), np.arange(m), loop)
    uv, T = _disc_map(clip, cell, starts)
    loc = _Locator(uv, T)

    def carry(q):
        t, b = old.locate(np.asarray(q, dtype=np.float64)[None])
        return b[0] @ uv[T[t[0]]]

    moved = [
        replace(sd, mid_uv=carry(sd.mid_uv), start_v=int(cell.loop[st]), start_uv=uv[loop[st]])
        for sd, st in zip(sides, starts, strict=True)
    ]
    return _Domain(clip, cell, loc), moved


def _quads(mesh: Mesh, dom: _Domain, poly: list[_Side], net) -> None:
    """One quad per corner of a polygon (corner, mid-point, centre, mid-point), its centre
    the image of its disc map's centre, joined to the sides' mid-points by images of
    radii."""
    loc = dom.loc
    # the centroid of the sub-triangle holding it, inside an input face (a centre on an
    # edge would start the radii on it)
    tloc, _ = loc.locate(np.zeros((1, 2)))
    start = loc.uv[loc.T[tloc[0]]].mean(axis=0)
    f0, b0 = _face_points(dom.clip, dom.cell, tloc, np.full((1, 3), 1.0 / 3.0))
    c = net.point(int(f0[0]), b0[0])
    spokes = [
        net.curve(*_radius(mesh, dom.clip, dom.cell, loc, start, sd.mid_uv), c, sd.mid)
        for sd in poly
    ]
    for i in range(len(poly)):
        net.patches.append(
            [poly[i].first, (spokes[i], True), (spokes[i - 1], False), poly[i - 1].second]
        )


def _side_halves(clip: _Clip, stretches, merged, chords, index, net: _Net) -> list:
    """Each stretch's two halves as curves of ``net`` (fixed along the mesh boundary and the
    creases), ``(-1, -1)`` for a merged one."""
    c_index, mid_index = index
    canon = clip.canon
    halves: list[tuple[int, int]] = []
    for s, st in enumerate(stretches):
        if s in merged:
            halves.append((-1, -1))
            continue
        mid = (net.cf[mid_index[s]], net.cb[mid_index[s]])
        first, second = _halves(clip, st, mid, chords.get(s, []))
        a_c = int(c_index[canon[st.ids[0]]])
        b_c = int(c_index[canon[st.ids[-1]]])
        h0 = len(net.curves)
        for (fs, bs), e in ((first, (a_c, mid_index[s])), (second, (mid_index[s], b_c))):
            net.curves.append(SurfacePoints(np.asarray(fs), np.asarray(bs)))
            net.ends.append(e)
            net.fixed.append(st.on_border)
            net.crease.append(st.on_border and st.uses == 2)
        halves.append((h0, h0 + 1))
    return halves


def _assemble(
    mesh: Mesh,
    clip: _Clip,
    cells: list[_Cell],
    corner: NDArray[np.bool_],
    made: dict | None = None,
):
    """Corners, curves, curve ends, patches, and per curve whether it lies on the mesh
    boundary or along a crease (neither is moved by the relaxation) and whether it is a
    crease.

    With ``made`` (a dict: the counts go into it as ``"merges"`` and ``"chords"``), short
    sides are merged away (`_short_sides`): their mid-point is the corner of the four
    cells, and each other side at their ends reaches it by a chord through the cell that
    had the short side (the image of a segment in its disc map, which no radius crosses);
    and straight corners at creases are joined to opposite corners (`_split_straight`).
    With None the cells are split as they are."""
    stretches, sides = _stretches(clip, cells, corner)
    merges = _short_sides(clip, stretches, sides) if made is not None else []
    merged = {m.s: m for m in merges}
    canon = clip.canon
    keep = corner.copy()
    for m in merges:
        keep[canon[stretches[m.s].ids[[0, -1]]]] = False
    corner_ids = np.flatnonzero(keep)
    c_index = np.full(corner.size, -1, dtype=np.int64)
    c_index[corner_ids] = np.arange(corner_ids.size)
    rep = np.full(corner.size, -1, dtype=np.int64)  # a clipped vertex of each canonical point
    rep[canon[::-1]] = np.arange(canon.size)[::-1]
    cf = list(clip.src_face[rep[corner_ids]])
    cb = list(clip.src_bary[rep[corner_ids]])
    curves: list[SurfacePoints] = []
    ends: list[tuple[int, int]] = []
    fixed: list[bool] = []
    crease: list[bool] = []
    owner: dict[int, int] = {}
    entry: dict[tuple[int, int], tuple[bool, int]] = {}  # (cell, stretch) -> (rev, start)
    for ci, cs in enumerate(sides):
        for s, rev, a in cs:
            entry[ci, s] = (rev, a)
            if not rev:
                owner.setdefault(s, ci)

    mid_index = []
    for s, st in enumerate(stretches):
        u, w = int(st.ids[st.mid_seg]), int(st.ids[st.mid_seg + 1])
        f, b = _segment_point(clip, cells[owner[s]], u, w, st.mid_t)
        mid_index.append(len(cf))
        cf.append(f)
        cb.append(b)
    for m in merges:
        c_index[canon[stretches[m.s].ids[[0, -1]]]] = mid_index[m.s]

    maps = []
    for ci, cell in enumerate(cells):
        uv, T = _disc_map(clip, cell, _disc_starts(sides[ci], merged))
        maps.append((uv, _Locator(uv, T), np.searchsorted(cell.verts, cell.loop)))

    chords = _chords(mesh, clip, cells, stretches, merges, entry, maps, (cf, cb, mid_index))
    patches: list[list[tuple[int, bool]]] = []
    net = _Net(cf, cb, curves, ends, fixed, crease, patches)
    halves = _side_halves(clip, stretches, merged, chords, (c_index, mid_index), net)
    n_chords = 0
    for ci, cell in enumerate(cells):
        mine = [(s, rev, a) for s, rev, a in sides[ci] if s not in merged]
        ring = _ring(clip, cell, stretches, mine, maps[ci], (c_index, mid_index, halves))
        # (a cell with a merged side keeps its corners)
        if made is not None and len(mine) == len(sides[ci]):
            for i in range(len(mine)):
                ring[i].straight = _straight(mesh, clip, cell, stretches, mine, i)
        parts = _split_straight(mesh, _Domain(clip, cell, maps[ci][1]), ring, net)
        n_chords += len(parts) - 1
        for dom, poly in parts:
            _quads(mesh, dom, poly, net)
    if made is not None:
        made.update(merges=len(merges), chords=n_chords)
    corners = SurfacePoints(np.asarray(cf, dtype=np.int64), np.asarray(cb, dtype=np.float64))
    return (
        corners,
        curves,
        np.asarray(ends, dtype=np.int64),
        patches,
        np.asarray(fixed, dtype=bool),
        np.asarray(crease, dtype=bool),
    )


def region_layout(
    mesh: Mesh,
    *,
    patches: int | None = None,
    crease_angle: float | None = CREASE_ANGLE,
    relax: bool = True,
    relax_iterations: int = 200,
    report: list | None = None,
) -> Layout:
    """A four-sided layout of a mesh of any genus, open or closed, of one or more components.

    Parameters
    ----------
    mesh : Mesh
        A valid (repaired) mesh.
    patches : int, keyword-only, optional
        About how many patches (default 60): ``patches / 6`` cells on a closed genus-0
        surface, more where the genus, the boundary or the cell tests ask for them. At most
        one patch per `MIN_FACES_PER_PATCH` faces.
    crease_angle : float or None, keyword-only
        Chains of edges sharper than this many degrees (:func:`crease_edges`) become patch
        boundaries, the points where they meet corners (:func:`crease_corners`);
        the layout marks those curves in ``creases``. Default
        `CREASE_ANGLE` (40); None: no creases.
    relax : bool, keyword-only
        Relax the interior curves as surface snakes with fixed ends (default True).
    relax_iterations : int, keyword-only
        Iteration cap of each snake (default 200).
    report : list, keyword-only, optional
        A :class:`CellReport` is appended to it.

    Returns
    -------
    Layout

    Raises
    ------
    meshfit.errors.InputError
        ``patches`` below 1, or more than the mesh has faces for.
    meshfit.errors.LayoutError
        The cells could not all be made disks within the patch budget (a mesh with more
        handles than its faces can hold patches for).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3 (four-sided patch layouts).
    .. [2] Du, Faber & Gunzburger 1999 (centroidal Voronoi tessellations); Floater 2003
       (mean value coordinates).
    """
    most = mesh.n_faces // MIN_FACES_PER_PATCH
    # (the default asks a small mesh for no more patches than it has faces for)
    want = min(DEFAULT_PATCHES, max(most, 1)) if patches is None else int(patches)
    if want < 1:
        raise InputError(f"patches must be >= 1, got {patches}")
    if most == 0:
        raise InputError(
            f"{mesh.name or 'the mesh'} has {mesh.n_faces} faces: an automatic layout needs "
            f"at least {MIN_FACES_PER_PATCH} faces a patch; subdivide it first, or give a "
            "layout file"
        )
    if want > most:
        raise InputError(
            f"{want} patches on {mesh.name or 'the mesh'} ({mesh.n_faces} faces): an "
            f"automatic layout needs at least {MIN_FACES_PER_PATCH} faces a patch, ask for "
            f"at most {most} patches"
        )
    genus_term = 0
    if mesh.is_closed:
        genus_term = max(0, 2 * int(mesh.genus))
    n_cells = max(1, round(want / QUADS_PER_CELL) + 2 - genus_term)
    # (a cell gives at least three patches; `_cells` adds room for the components)
    max_cells = max(2 * n_cells, mesh.n_faces // (MIN_FACES_PER_PATCH * 3))
    sharp = (
        crease_edges(mesh, crease_angle)
        if crease_angle is not None
        else np.zeros(mesh.edges.shape[0], dtype=bool)
    )
    if sharp.any():
        work, parent = _cut_open(mesh, sharp)
        corner_vertices = crease_corners(mesh, sharp)
    else:
        work, parent = mesh, np.arange(mesh.n_vertices, dtype=np.int64)
        corner_vertices = np.zeros(0, dtype=np.int64)
    seeds, label, added, rounds = _cells(work, n_cells, max_cells)
    if sharp.any():
        label = _align_crease_cuts(work, label, parent, mesh, corner_vertices, seeds.size)
    clip = _clip(work, label, parent, mesh)
    if sharp.any():
        clip = _crease_nodes(clip, work, label, parent, mesh, corner_vertices)
    cells = _cell_loops(clip, seeds.size)
    corner = _corners(clip, cells)
    if report is not None:
        report.append(CellReport(int(seeds.size), added, int(mesh.n_components), rounds))
    made: dict = {}
    try:
        return _from_cells(mesh, work, clip, cells, corner, made, relax, relax_iterations)
    except MeshfitError:  # a merged corner's or a chord's curves did not cut into disks
        if not made.get("merges", 1) and not made.get("chords", 1):
            raise
        return _from_cells(mesh, work, clip, cells, corner, None, relax, relax_iterations)


def _from_cells(
    mesh: Mesh, work: Mesh, clip: _Clip, cells, corner, made: dict | None, relax: bool, iterations
) -> Layout:
    """The layout of the clipped cells (`_assemble`), its interior curves relaxed; short
    sides merged and straight corners at creases joined by chords unless ``made`` is None
    (their counts go into it)."""
    from meshfit.curves.base import densify_curves
    from meshfit.layout.auto import _keep_relaxed, _relax_all
    from meshfit.layout.extract import check_layout_topology

    corners, curves, ends, quads, fixed, crease = _assemble(work, clip, cells, corner, made)
    surface_curves = densify_curves(mesh, [SurfaceCurve(c, False, "boundary") for c in curves])
    plain = layout_from_curves(mesh, corners, surface_curves, ends, quads, creases=crease)
    if relax:
        inner = np.flatnonzero(~fixed)
        moved = _relax_all(mesh, [surface_curves[i] for i in inner], int(iterations))
        relaxed = list(surface_curves)
        for i, c in zip(inner.tolist(), moved, strict=True):
            relaxed[i] = c
        out = _keep_relaxed(mesh, corners, surface_curves, relaxed, ends, quads, crease)
        if out is not None:
            return out
    check_layout_topology(mesh, plain)
    return plain
