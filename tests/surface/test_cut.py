"""Cutting meshes along face-point curves."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import sparse
from scipy.sparse.csgraph import shortest_path as csgraph_shortest_path

from meshfit import tol
from meshfit.errors import CutError, InputError
from meshfit.mesh import Mesh
from meshfit.mesh.locate import barycentric
from meshfit.surface import cut_mesh, greedy_path, path_to_surface_points
from meshfit.types import SurfaceCurve, SurfacePoints
from tests.conftest import analytic_mesh, real_mesh
from tests.shapes import plane


# ------------------------------------------------------------------------------ helpers
def any_mesh(name: str) -> Mesh:
    return (
        analytic_mesh(name)
        if name in ("icosphere", "plane", "cylinder", "torus")
        else real_mesh(name)
    )


def plane_loops(mesh: Mesh, normal, offset: float) -> list[SurfacePoints]:
    """Closed loops where the plane ``x . normal = offset`` meets the mesh, as face points.

    Each loop alternates a point on a crossed edge and the midpoint of the chord inside the
    face it enters, so consecutive points share a face and the polyline lies in the plane.
    """
    n = np.asarray(normal, dtype=float)
    n /= np.linalg.norm(n)
    d = mesh.vertices @ n - offset
    assert np.abs(d).min() > 1e-9 * mesh.bbox_diagonal, "plane passes through a vertex"
    e = mesh.edges
    crossed = (d[e[:, 0]] > 0) != (d[e[:, 1]] > 0)
    fc = crossed[mesh.face_edges]  # (nf, 3): which edges of each face are crossed
    faces = np.flatnonzero(fc.any(axis=1))
    edge_faces: dict[int, list[tuple[int, int]]] = {}
    for f in faces.tolist():
        for k in np.flatnonzero(fc[f]).tolist():
            edge_faces.setdefault(int(mesh.face_edges[f, k]), []).append((f, k))

    def edge_point(f, k):
        a, b = mesh.faces[f, k], mesh.faces[f, (k + 1) % 3]
        t = d[a] / (d[a] - d[b])
        bary = np.zeros(3)
        bary[k], bary[(k + 1) % 3] = 1 - t, t
        return bary

    loops, used = [], set()
    for f0 in faces.tolist():
        if f0 in used:
            continue
        f, k_in = f0, int(np.flatnonzero(fc[f0])[0])
        face, bary, closed = [], [], False
        while True:
            used.add(f)
            k_out = int(next(k for k in np.flatnonzero(fc[f]) if k != k_in))
            p_in, p_out = edge_point(f, k_in), edge_point(f, k_out)
            face += [f, f]
            bary += [p_in, 0.5 * (p_in + p_out)]
            nxt = [(g, k) for g, k in edge_faces[int(mesh.face_edges[f, k_out])] if g != f]
            if not nxt or nxt[0][0] in used:
                closed = bool(nxt) and nxt[0][0] == f0
                break
            f, k_in = nxt[0]
        if closed:
            loops.append(SurfacePoints(np.asarray(face), np.asarray(bary)))
    return loops


def longest_plane_loop(mesh: Mesh, normal=(0.3, 1.0, 0.2), shift: float = 1e-3) -> SurfacePoints:
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    offset = mesh.vertices.mean(axis=0) @ n + shift * mesh.bbox_diagonal
    return max(plane_loops(mesh, n, offset), key=len)


def face_strip(mesh: Mesh, f0: int, f1: int, rng, *, concentration: float = 2.0) -> SurfacePoints:
    """One random point in each face of a shortest chain of edge-adjacent faces f0 -> f1."""
    r = np.repeat(np.arange(mesh.n_faces), 3)
    c = mesh.face_neighbors.reshape(-1)
    keep = c >= 0
    g = sparse.coo_matrix(
        (np.ones(int(keep.sum())), (r[keep], c[keep])), shape=(mesh.n_faces, mesh.n_faces)
    ).tocsr()
    _, pred = csgraph_shortest_path(g, unweighted=True, indices=f0, return_predecessors=True)
    chain = [f1]
    while chain[-1] != f0:
        chain.append(int(pred[chain[-1]]))
    chain = np.asarray(chain[::-1])
    return SurfacePoints(chain, rng.dirichlet([concentration] * 3, size=chain.size))


def are_edges(mesh: Mesh, a, b) -> np.ndarray:
    n = mesh.n_vertices
    keys = mesh.edges[:, 0] * n + mesh.edges[:, 1]
    q = np.minimum(a, b) * n + np.maximum(a, b)
    i = np.minimum(np.searchsorted(keys, q), keys.size - 1)
    return keys[i] == q


def assert_path_of_edges(mesh: Mesh, path, closed: bool) -> None:
    path = np.asarray(path)
    nxt = np.roll(path, -1) if closed else path[1:]
    assert are_edges(mesh, path[: nxt.size], nxt).all()


def component_stats(mesh: Mesh) -> list[tuple[int, int]]:
    """(Euler characteristic, number of boundary loops) of each component."""
    fc = mesh.face_components
    vc = mesh.vertex_components
    ec = vc[mesh.edges[:, 0]]
    loops = np.bincount([vc[loop[0]] for loop in mesh.boundary_loops], minlength=mesh.n_components)
    return [
        (int((vc == c).sum() - (ec == c).sum() + (fc == c).sum()), int(loops[c]))
        for c in range(mesh.n_components)
    ]


def distance_to_polyline(points, polyline, closed: bool) -> np.ndarray:
    a = polyline
    b = np.roll(polyline, -1, axis=0) if closed else polyline[1:]
    a = a[: b.shape[0]]
    ab = b - a
    t = np.einsum("psk,sk->ps", points[:, None, :] - a[None], ab) / np.einsum("sk,sk->s", ab, ab)
    c = a[None] + np.clip(t, 0, 1)[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - c, axis=2).min(axis=1)


def check_common(mesh: Mesh, res, *, split: bool) -> None:
    """Invariants of every cut: area, sources, parents, path made of edges."""
    new = res.mesh
    assert_allclose(new.area, mesh.area, rtol=1e3 * np.finfo(float).eps * np.sqrt(mesh.n_faces))
    atol = tol.TEST_ATOL * mesh.bbox_diagonal
    assert_allclose(mesh.xyz(res.vertex_source), new.vertices, atol=atol)
    assert res.face_parent.shape == (new.n_faces,) and res.face_parent.dtype == np.int64
    assert res.vertex_parent.shape == (new.n_vertices,) and res.vertex_parent.dtype == np.int64
    orig = res.vertex_parent >= 0
    assert_allclose(new.vertices[orig], mesh.vertices[res.vertex_parent[orig]], atol=0)
    # every new face lies inside its parent face
    centroid = new.vertices[new.faces].mean(axis=1)
    b = barycentric(mesh, res.face_parent, centroid)
    assert (b > -1e-9).all()
    assert_allclose(mesh.xyz(SurfacePoints(res.face_parent, b)), centroid, atol=atol)
    assert new.face_areas.min() >= min(
        mesh.face_areas.min(), tol.CUT_MIN_AREA * mesh.bbox_diagonal**2
    )
    for side in (res.path, res.path_other_side):
        assert side.dtype == np.int64
        assert_path_of_edges(new, side, res.closed)
    assert_allclose(new.vertices[res.path], new.vertices[res.path_other_side], atol=0)
    if not split:
        assert (res.path == res.path_other_side).all()
        assert new.euler_characteristic == mesh.euler_characteristic
        assert len(new.boundary_loops) == len(mesh.boundary_loops)


# ------------------------------------------------------------------------- closed loops
@pytest.mark.parametrize("name", ["icosphere", "spot", "igea"])
def test_closed_loop_separates_genus0_into_two_disks(name):
    mesh = any_mesh(name)
    loop = longest_plane_loop(mesh)
    res = cut_mesh(mesh, loop, closed=True)
    check_common(mesh, res, split=True)
    new = res.mesh
    assert new.n_components == 2
    assert sorted(component_stats(new)) == [(1, 1), (1, 1)]  # two disks
    k = res.path.size
    assert sorted(len(b) for b in new.boundary_loops) == [k, k]
    assert not set(res.path.tolist()) & set(res.path_other_side.tolist())
    # the two sides are on different components
    assert len(set(new.vertex_components[res.path].tolist())) == 1
    assert new.vertex_components[res.path[0]] != new.vertex_components[res.path_other_side[0]]


@pytest.mark.parametrize("name", ["icosphere", "spot", "bunny", "igea"])
def test_loop_path_follows_the_polyline(name):
    mesh = any_mesh(name)
    loop = longest_plane_loop(mesh, normal=(1.0, 0.2, 0.5))
    res = cut_mesh(mesh, SurfaceCurve(loop, closed=True), split=False)
    assert res.closed
    check_common(mesh, res, split=False)
    xyz = mesh.xyz(loop)
    path_xyz = res.mesh.vertices[res.path]
    atol = tol.TEST_ATOL * mesh.bbox_diagonal
    # the path is on the polyline; where the curve passes so near a vertex that the triangles
    # between them would be degenerate, it snaps to the vertex (a tiny fraction of an edge)
    d = distance_to_polyline(path_xyz, xyz, closed=True)
    assert (d < atol).mean() > 0.99
    assert d.max() < 1e-3 * mesh.mean_edge_length
    # every input point is a path vertex, in order
    d = np.linalg.norm(xyz[:, None, :] - path_xyz[None], axis=2)
    hit = d.argmin(axis=1)
    assert (d.min(axis=1) < atol).mean() > 0.99
    assert d.min(axis=1).max() < 1e-3 * mesh.mean_edge_length
    assert (np.diff(hit) >= 0).all()
    # no vertex but the curve's was added: each new vertex is on the path
    assert set(np.flatnonzero(res.vertex_parent < 0).tolist()) <= set(res.path.tolist())


def test_loop_on_open_scan_bunny():
    mesh = real_mesh("bunny")
    loop = longest_plane_loop(mesh)
    res = cut_mesh(mesh, loop, closed=True)
    check_common(mesh, res, split=True)
    new = res.mesh
    # a simple closed curve separates a genus-0 surface with holes
    assert new.n_components == 2
    assert new.euler_characteristic == mesh.euler_characteristic
    assert len(new.boundary_loops) == len(mesh.boundary_loops) + 2


def test_closed_loop_of_greedy_paths_nefertiti(rng):
    mesh = real_mesh("nefertiti")
    corners = [0, 0, 0]
    while len({int(c) for c in corners}) < 3:
        corners = rng.integers(0, mesh.n_vertices, 3)
    parts = []
    for a, b in zip(corners, np.roll(corners, -1), strict=True):
        parts.append(path_to_surface_points(mesh, greedy_path(mesh, a, b).vertices, per_edge=1))
    loop = SurfacePoints.concatenate(parts)
    res = cut_mesh(mesh, loop, closed=True, split=False)
    check_common(mesh, res, split=False)
    assert set(corners.tolist()) <= set(res.path.tolist())


# ---------------------------------------------------------------------------- open cuts
@pytest.mark.parametrize("name", ["icosphere", "spot", "nefertiti_fraunhofer"])
def test_open_cut_makes_a_slit(name, rng):
    mesh = any_mesh(name)
    interior = np.flatnonzero((mesh.face_neighbors >= 0).all(axis=1))
    f0, f1 = rng.choice(interior, 2, replace=False)
    strip = face_strip(mesh, int(f0), int(f1), rng)
    res = cut_mesh(mesh, strip)
    check_common(mesh, res, split=True)
    new = res.mesh
    k = res.path.size
    if not set(res.vertex_parent[res.path].tolist()) & set(
        np.concatenate(mesh.boundary_loops).tolist() if mesh.boundary_loops else []
    ):
        assert new.n_components == mesh.n_components
        assert new.euler_characteristic == mesh.euler_characteristic - 1
        assert len(new.boundary_loops) == len(mesh.boundary_loops) + 1
        assert 2 * (k - 1) in [len(b) for b in new.boundary_loops]
    # the ends are shared, the interior vertices are split in two
    assert res.path[0] == res.path_other_side[0] and res.path[-1] == res.path_other_side[-1]
    assert (res.path[1:-1] != res.path_other_side[1:-1]).all()
    # unsplit, the same cut only refines the triangulation
    flat = cut_mesh(mesh, strip, split=False)
    check_common(mesh, flat, split=False)
    assert flat.mesh.n_vertices == new.n_vertices - (k - 2)
    assert_allclose(flat.mesh.vertices[flat.path], new.vertices[res.path], atol=0)


def test_open_cut_length_is_the_unfolded_polyline(rng):
    """Between points on adjacent faces the cut is straight in the unfolded pair of faces."""
    mesh = real_mesh("spot")
    strip = face_strip(mesh, 10, 3000, rng, concentration=8.0)  # points well inside faces
    res = cut_mesh(mesh, strip, split=False)
    want = 0.0
    xyz = mesh.xyz(strip)
    for i in range(len(strip) - 1):
        f, g = strip.face[i], strip.face[i + 1]
        k = int(np.flatnonzero(mesh.face_neighbors[f] == g)[0])
        a, b = mesh.vertices[mesh.faces[f, k]], mesh.vertices[mesh.faces[f, (k + 1) % 3]]
        e = (b - a) / np.linalg.norm(b - a)
        p, q = xyz[i] - a, xyz[i + 1] - a
        pa, qa = p @ e, q @ e
        ph, qh = np.linalg.norm(p - pa * e), np.linalg.norm(q - qa * e)
        s = (pa + (qa - pa) * ph / (ph + qh)) / np.linalg.norm(b - a)
        assert 0 < s < 1  # the unfolded segment crosses the shared edge inside it
        want += np.hypot(qa - pa, ph + qh)
    got = np.linalg.norm(np.diff(res.mesh.vertices[res.path], axis=0), axis=1).sum()
    assert_allclose(got, want, rtol=1e-12)


def test_cut_along_existing_edges_adds_no_vertices(rng):
    mesh = real_mesh("spot")
    path = greedy_path(mesh, 100, 2500).vertices
    curve = path_to_surface_points(mesh, path)
    res = cut_mesh(mesh, curve, split=False)
    assert res.mesh.n_vertices == mesh.n_vertices
    assert (res.mesh.faces == mesh.faces).all()
    assert res.path.tolist() == path.tolist()
    assert (res.face_parent == np.arange(mesh.n_faces)).all()
    split = cut_mesh(mesh, curve)
    check_common(mesh, split, split=True)
    assert (split.vertex_parent >= 0).all()  # only copies
    assert split.mesh.n_vertices == mesh.n_vertices + path.size - 2
    assert split.vertex_parent[split.path].tolist() == path.tolist()
    assert split.vertex_parent[split.path_other_side].tolist() == path.tolist()


def test_curve_through_vertices_and_along_edges():
    mesh = analytic_mesh("icosphere")
    path = greedy_path(mesh, 0, mesh.n_vertices - 1).vertices
    curve = path_to_surface_points(mesh, path, per_edge=2)  # vertices and edge points
    res = cut_mesh(mesh, curve, split=False)
    check_common(mesh, res, split=False)
    assert res.mesh.n_vertices == mesh.n_vertices + 2 * (path.size - 1)
    assert_allclose(res.mesh.vertices[res.path], mesh.xyz(curve), atol=1e-15)
    assert res.vertex_parent[res.path[::3]].tolist() == path.tolist()
    # the edge points keep an exact zero barycentric coordinate (they are on mesh edges)
    new = res.vertex_source[np.flatnonzero(res.vertex_parent < 0)]
    assert ((new.bary == 0).sum(axis=1) == 1).all()


def test_faces_sharing_only_a_vertex_route_through_it():
    mesh = analytic_mesh("icosphere")
    v = 0
    indptr, vf = mesh.vertex_faces
    around = vf[indptr[v] : indptr[v + 1]]
    f = int(around[0])
    g = next(int(h) for h in around if h != f and h not in mesh.face_neighbors[f])
    centre = np.full((2, 3), 1 / 3)
    res = cut_mesh(mesh, SurfacePoints([f, g], centre), split=False)
    check_common(mesh, res, split=False)
    assert res.path.size == 3 and res.path[1] == v


def test_adjacent_and_same_face_points_and_duplicates():
    mesh = analytic_mesh("icosphere")
    f = 0
    g = int(mesh.face_neighbors[f, 1])
    pts = SurfacePoints(
        [f, f, f, g], [[0.6, 0.2, 0.2], [0.2, 0.6, 0.2], [0.2, 0.6, 0.2], [0.3, 0.3, 0.4]]
    )
    res = cut_mesh(mesh, pts, split=False)
    check_common(mesh, res, split=False)
    assert res.path.size == 4  # the duplicate merges; the crossing of the shared edge is added


def test_colours_are_interpolated():
    mesh = real_mesh("spot")
    assert mesh.vertex_colors is not None
    res = cut_mesh(mesh, longest_plane_loop(mesh), closed=True)
    colors = res.mesh.vertex_colors
    assert colors is not None and colors.dtype == np.uint8
    orig = res.vertex_parent >= 0
    assert (colors[orig] == mesh.vertex_colors[res.vertex_parent[orig]]).all()
    new = np.flatnonzero(~orig)
    assert new.size > 0
    corner = mesh.vertex_colors[mesh.faces[res.vertex_source.face[new]]].astype(int)
    c = colors[new].astype(int)
    assert ((c >= corner.min(axis=1)) & (c <= corner.max(axis=1))).all()
    # and they are the barycentric blend, rounded
    want = np.einsum("ij,ijk->ik", res.vertex_source.bary[new], corner)
    assert np.abs(c - want).max() <= 0.5 + 1e-9
    # both copies of a split vertex have one colour
    assert (colors[res.path] == colors[res.path_other_side]).all()


@pytest.mark.parametrize("eps", [1e-4, 1e-7, 1e-9, 1e-13, 0.0])
def test_points_near_vertices_and_edges_give_valid_meshes(eps, rng):
    """Points within or near CUT_SNAP of vertices and edges snap without slivers."""
    mesh = real_mesh("spot")
    strip = face_strip(mesh, 50, 4000, rng, concentration=1.0)
    bary = strip.bary.copy()
    k = rng.integers(0, 3, size=len(strip))
    rows = np.arange(len(strip))
    near_vertex = rows % 3 == 0
    bary[near_vertex] = eps / 2
    bary[rows[near_vertex], k[near_vertex]] = 1 - eps
    near_edge = rows % 3 == 1
    bary[rows[near_edge], k[near_edge]] = eps
    bary /= bary.sum(axis=1, keepdims=True)
    curve = SurfacePoints(strip.face, bary)
    res = cut_mesh(mesh, curve, split=False)  # Mesh() validates: no degenerate faces
    check_common(mesh, res, split=False)
    atol = tol.TEST_ATOL * mesh.bbox_diagonal
    xyz = mesh.xyz(curve)
    d = np.linalg.norm(xyz[:, None, :] - res.mesh.vertices[res.path][None], axis=2).min(axis=1)
    assert (d < max(atol, 2 * tol.length(mesh, tol.CUT_SNAP))).all()
    check_common(mesh, cut_mesh(mesh, curve), split=True)


# ------------------------------------------------------------------------------- errors
def test_points_on_distant_faces_raise_cut_error():
    mesh = analytic_mesh("icosphere")
    far = int(np.argmin(mesh.vertices[mesh.faces].mean(axis=1) @ mesh.vertices[mesh.faces[0, 0]]))
    bary = np.full((3, 3), 1 / 3)
    bary[0] = [0.4333, 0.2833, 0.2834]
    pts = SurfacePoints([0, 0, far], bary)
    with pytest.raises(CutError, match="curve points 1 and 2 lie on faces 0 and"):
        cut_mesh(mesh, pts)


def test_bad_input_raises():
    mesh = analytic_mesh("icosphere")
    with pytest.raises(InputError, match="at least 2"):
        cut_mesh(mesh, SurfacePoints([0], [[1 / 3] * 3]))
    with pytest.raises(InputError, match="outside the mesh"):
        cut_mesh(mesh, SurfacePoints([0, mesh.n_faces], [[1 / 3] * 3] * 2))
    with pytest.raises(CutError, match="nothing to cut"):
        cut_mesh(mesh, SurfacePoints([0, 0], [[1 / 3] * 3] * 2))


# ------------------------------------------------------------------------- network cuts
def _sphere_network():
    from meshfit.layout.cube import cube_layout

    mesh = analytic_mesh("icosphere")
    layout = cube_layout(mesh, frame=np.eye(3))
    return mesh, layout


def test_network_cut_shares_corners_and_separates_regions():
    from meshfit.surface.cut import cut_mesh_network

    mesh, layout = _sphere_network()
    res = cut_mesh_network(mesh, list(layout.curves), layout.corners, layout.curve_ends)
    # each corner is one vertex of the refined triangulation, where its curves start or end
    for i, path in enumerate(res.curve_vertices):
        a, b = layout.curve_ends[i]
        assert path[0] == res.corners[a] and path[-1] == res.corners[b]
    assert len(set(res.corners.tolist())) == len(layout.corners)
    # the 48 curves of the projected cube cut the sphere into its 24 patches, all disks
    assert res.mesh.n_components == layout.n_patches
    assert len(res.mesh.boundary_loops) == layout.n_patches
    assert_allclose(res.mesh.area, mesh.area, rtol=1e-12)
    assert_allclose(
        mesh.xyz(res.vertex_source), res.mesh.vertices, atol=tol.TEST_ATOL * mesh.bbox_diagonal
    )
    assert np.array_equal(res.vertex_source.face.shape, (res.mesh.n_vertices,))
    assert (res.copy_of < res.mesh.n_vertices).all()


def test_network_cut_without_split_only_refines():
    from meshfit.surface.cut import cut_mesh_network

    mesh, layout = _sphere_network()
    res = cut_mesh_network(
        mesh, list(layout.curves), layout.corners, layout.curve_ends, split=False
    )
    assert res.mesh.is_closed and res.mesh.n_components == 1
    assert np.array_equal(res.copy_of, np.arange(res.mesh.n_vertices))


def test_network_cut_rejects_meeting_curves():
    from meshfit.surface.cut import cut_mesh_network

    mesh, layout = _sphere_network()
    curves = list(layout.curves)
    ends = layout.curve_ends.copy()
    # curve 0 twice: the copy runs on top of it
    with pytest.raises(CutError, match="curve 48 crosses or touches curve 0"):
        cut_mesh_network(mesh, [*curves, curves[0]], layout.corners, np.vstack([ends, ends[:1]]))
    with pytest.raises(InputError, match="corner index out of range"):
        cut_mesh_network(mesh, curves[:1], layout.corners, [[0, 999]])


@pytest.mark.parametrize("size", [1.0, 1e3])
@pytest.mark.parametrize("offset", [0.1, 1e-3, 1e-6, 1e-7])
def test_two_curves_leaving_a_corner_beside_an_edge_do_not_touch(offset, size):
    # a corner a hair's breadth inside a face, two curves leaving it at right angles
    # across the near edge: their crossings would split off triangles below the cut's
    # least area and merge into one vertex, were the corner not put on the edge
    from meshfit.curves.base import densify_curves
    from meshfit.surface.cut import network_meetings

    mesh = plane(8, size=size, jitter=0.0)
    h = mesh.mean_edge_length
    V, F = mesh.vertices, mesh.faces
    a, b, c = F[len(F) // 2]
    foot = 0.5 * (V[a] + V[b])
    along = (V[b] - V[a]) / np.linalg.norm(V[b] - V[a])
    inward = V[c] - foot
    inward -= (inward @ along) * along
    inward /= np.linalg.norm(inward)
    corner = foot + offset * h * inward
    lines = []
    for side in (1.0, -1.0):
        d = np.sqrt(0.5) * (side * along - inward)
        x = np.array([corner, corner + 0.3 * h * d, corner + 2.5 * h * d])
        lines.append(SurfaceCurve(mesh.closest_points(x).points))
    curves = [c.points for c in densify_curves(mesh, lines)]
    one = np.array([0])
    corners = SurfacePoints.concatenate([curves[0][one], curves[0][one - 1], curves[1][one - 1]])
    assert network_meetings(mesh, curves, corners, np.array([[0, 1], [0, 2]])) == set()


def test_network_meetings_names_every_curve_at_fault():
    from meshfit.surface.cut import cut_mesh_network, network_meetings

    mesh, layout = _sphere_network()
    curves = list(layout.curves)
    ends = layout.curve_ends
    assert network_meetings(mesh, curves, layout.corners, ends) == set()
    # curves 0 and 5 doubled: all four are named at once, where the cut names the first
    doubled = [*curves, curves[0], curves[5]]
    twice = np.vstack([ends, ends[[0, 5]]])
    assert network_meetings(mesh, doubled, layout.corners, twice) == {0, 5, 48, 49}
    with pytest.raises(CutError, match="curve 48 crosses or touches curve 0"):
        cut_mesh_network(mesh, doubled, layout.corners, twice)
    with pytest.raises(InputError, match="corner index out of range"):
        network_meetings(mesh, curves[:1], layout.corners, [[0, 999]])
