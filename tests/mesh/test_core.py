"""Mesh core: read-only arrays, adjacency against brute-force oracles, topology of analytic
shapes and of the real scans (counts from ../shared/data/meshes/SOURCES.md), geometry."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit import errors, tol
from meshfit.mesh import Mesh
from meshfit.types import SurfacePoints

from .. import shapes
from ..conftest import REAL, analytic_mesh, real_mesh

ANALYTIC = ("icosphere", "plane", "cylinder", "torus")
SMALL = (*ANALYTIC, "spot")  # brute-force oracles run on these


def any_mesh(name: str) -> Mesh:
    return real_mesh(name) if name in REAL else analytic_mesh(name)


# ------------------------------------------------------------------ oracles (slow, obvious)
def edge_faces_oracle(faces) -> dict[tuple[int, int], list[tuple[int, int]]]:
    """Undirected edge -> [(face, k)] where edge k of face joins F[f,k] and F[f,(k+1)%3]."""
    out: dict[tuple[int, int], list[tuple[int, int]]] = defaultdict(list)
    for f, tri in enumerate(faces.tolist()):
        for k in range(3):
            a, b = tri[k], tri[(k + 1) % 3]
            out[(min(a, b), max(a, b))].append((f, k))
    return out


def neighbors_oracle(faces) -> np.ndarray:
    nb = np.full(faces.shape, -1, dtype=np.int64)
    for users in edge_faces_oracle(faces).values():
        if len(users) == 2:
            (f, k), (g, j) = users
            nb[f, k] = g
            nb[g, j] = f
    return nb


# ---------------------------------------------------------------- counts from SOURCES.md
# name: (vertices after repair, faces, edges, euler characteristic, boundary loops, genus,
#        boundary edges, bbox diagonal, colour channels)
SOURCES = {
    "spot": (2_930, 5_856, 8_784, 2, 0, 0, 0, 2.58809, 4),
    "bunny": (35_947 - 1_113, 69_451, 104_288, -3, 5, 0, 223, 0.250246, None),
    "nefertiti": (49_971, 99_938, 149_907, 2, 0, 0, 0, 658.055, None),
    # repaired: the 3 back-to-back pairs and the 3 vertices only they used are dropped
    "nefertiti_fraunhofer": (9_997, 19_476, 29_472, 1, 1, 0, 516, 36.4421, 4),
    "igea": (134_345, 268_686, 403_029, 2, 0, 0, 0, 0.156399, None),
}


@pytest.mark.parametrize("name", REAL)
def test_real_mesh_counts_match_sources(name):
    mesh = real_mesh(name)
    nv, nf, ne, chi, loops, genus, bnd, diag, channels = SOURCES[name]
    assert mesh.n_vertices == nv
    assert mesh.n_faces == nf
    assert mesh.edges.shape == (ne, 2)
    assert mesh.euler_characteristic == chi == nv - ne + nf
    assert len(mesh.boundary_loops) == loops
    assert mesh.genus == genus
    assert mesh.n_components == 1
    assert int((mesh.edge_face_count == 1).sum()) == bnd
    assert sum(loop.size for loop in mesh.boundary_loops) == bnd
    assert mesh.is_closed == (loops == 0)
    assert_allclose(mesh.bbox_diagonal, diag, rtol=5e-6)  # SOURCES.md gives 6 digits
    assert (mesh.vertex_colors is None) == (channels is None)
    if channels is not None:
        assert mesh.vertex_colors.shape == (nv, channels)


def test_bunny_holes():
    sizes = sorted(loop.size for loop in real_mesh("bunny").boundary_loops)
    assert len(sizes) == 5
    assert 22 <= sizes[0] and sizes[-1] <= 80  # "22-80 edges each" (SOURCES.md)


# -------------------------------------------------------------------------- read-only
@pytest.mark.parametrize("name", ["spot", "cylinder"])
def test_arrays_are_read_only(name):
    mesh = any_mesh(name)
    arrays = {
        "vertices": mesh.vertices,
        "faces": mesh.faces,
        "edges": mesh.edges,
        "face_edges": mesh.face_edges,
        "edge_face_count": mesh.edge_face_count,
        "face_neighbors": mesh.face_neighbors,
        "face_areas": mesh.face_areas,
        "face_normals": mesh.face_normals,
        "edge_lengths": mesh.edge_lengths,
        "bbox": mesh.bbox,
        "face_components": mesh.face_components,
        "vertex_components": mesh.vertex_components,
        "adjacency_indptr": mesh.vertex_adjacency[0],
        "adjacency_indices": mesh.vertex_adjacency[1],
        "vertex_faces_indptr": mesh.vertex_faces[0],
        "vertex_faces": mesh.vertex_faces[1],
    }
    if mesh.vertex_colors is not None:
        arrays["vertex_colors"] = mesh.vertex_colors
    arrays.update({f"loop{i}": loop for i, loop in enumerate(mesh.boundary_loops)})
    for key, a in arrays.items():
        assert not a.flags.writeable, key
        with pytest.raises(ValueError, match="read-only"):
            a[(0,) * a.ndim] = a[(0,) * a.ndim]
        with pytest.raises(ValueError):
            a.flags.writeable = True  # nor can it be made writeable again


def test_constructor_copies_its_input():
    v = np.array(shapes.cylinder().vertices)
    f = np.array(shapes.cylinder().faces)
    mesh = Mesh(v, f)
    v[0] = 99.0
    f[0] = [1, 2, 3]
    assert mesh.vertices[0, 0] != 99.0
    assert mesh.faces[0].tolist() != [1, 2, 3]


def test_mesh_is_frozen():
    mesh = analytic_mesh("plane")
    with pytest.raises(AttributeError):
        mesh.vertices = np.zeros((3, 3))


# --------------------------------------------------------------------- constructor input
@pytest.mark.parametrize(
    ("vertices", "faces", "match"),
    [
        (np.zeros((4, 2)), [[0, 1, 2]], r"vertices must have shape \(nv, 3\)"),
        ([["a", "b", "c"]] * 3, [[0, 1, 2]], "vertices must be numeric"),
        (np.eye(3), [[0, 1, 2, 0]], r"faces must have shape \(nf, 3\)"),
        (np.eye(3), [[0, 1, 2.5]], "integer vertex indices"),
        (np.eye(3), [[0, 1, np.nan]], "integer vertex indices"),
    ],
)
def test_constructor_rejects_bad_arrays(vertices, faces, match):
    with pytest.raises(errors.InputError, match=match):
        Mesh(vertices, faces)


def test_constructor_accepts_integral_float_faces_and_float_colors():
    mesh = Mesh(np.eye(3), np.array([[0.0, 1.0, 2.0]]), vertex_colors=np.full((3, 3), 0.5))
    assert mesh.faces.dtype == np.int64
    assert_array_equal(mesh.vertex_colors, np.full((3, 3), 128))
    assert mesh.vertices.dtype == np.float64
    with pytest.raises(errors.InputError, match=r"vertex_colors must have shape \(3, 3 or 4\)"):
        Mesh(np.eye(3), [[0, 1, 2]], vertex_colors=np.zeros((2, 3)))


def test_repr_and_sizes(spot):
    assert repr(spot) == "Mesh('spot.ply', 2930 vertices, 5856 faces)"
    assert spot.n_vertices == 2930
    assert spot.n_faces == 5856


# ---------------------------------------------------------------------------- adjacency
@pytest.mark.parametrize("name", SMALL)
def test_face_neighbors_match_edge_oracle(name):
    mesh = any_mesh(name)
    nb = mesh.face_neighbors
    assert nb.shape == (mesh.n_faces, 3)
    assert nb.dtype == np.int64
    assert_array_equal(nb, neighbors_oracle(mesh.faces))


@pytest.mark.parametrize("name", SMALL)
def test_face_neighbors_symmetric_and_share_edge_k(name):
    mesh = any_mesh(name)
    F, nb = mesh.faces, mesh.face_neighbors
    f, k = np.nonzero(nb >= 0)
    g = nb[f, k]
    # symmetric: f is among g's neighbours, across the same undirected edge
    back = nb[g] == f[:, None]
    assert (back.sum(axis=1) == 1).all()
    j = np.argmax(back, axis=1)
    a, b = F[f, k], F[f, (k + 1) % 3]
    c, d = F[g, j], F[g, (j + 1) % 3]
    # consistently oriented: the shared edge runs the other way in the neighbour
    assert_array_equal(a, d)
    assert_array_equal(b, c)
    # boundary entries are exactly the boundary edges
    assert (nb < 0).sum() == (mesh.edge_face_count == 1).sum()


@pytest.mark.parametrize("name", SMALL)
def test_edges_and_face_edges_match_oracle(name):
    mesh = any_mesh(name)
    oracle = edge_faces_oracle(mesh.faces)
    assert sorted(oracle) == [tuple(e) for e in mesh.edges.tolist()]  # unique, sorted, lo < hi
    for (lo, hi), users in list(oracle.items())[:2000]:
        e = mesh.face_edges[users[0]]
        assert tuple(mesh.edges[e]) == (lo, hi)
        assert mesh.edge_face_count[e] == len(users)


@pytest.mark.parametrize("name", SMALL)
def test_vertex_adjacency_matches_brute_force(name):
    mesh = any_mesh(name)
    want: list[set[int]] = [set() for _ in range(mesh.n_vertices)]
    for a, b, c in mesh.faces.tolist():
        want[a] |= {b, c}
        want[b] |= {a, c}
        want[c] |= {a, b}
    indptr, indices = mesh.vertex_adjacency
    assert indptr.shape == (mesh.n_vertices + 1,)
    assert indices.shape == (2 * mesh.edges.shape[0],)
    for v in range(mesh.n_vertices):
        got = indices[indptr[v] : indptr[v + 1]]
        assert got.tolist() == sorted(want[v])
        assert_array_equal(mesh.vertex_neighbors(v), got)


@pytest.mark.parametrize("name", ["plane", "spot"])
def test_vertex_faces_matches_brute_force(name):
    mesh = any_mesh(name)
    indptr, fs = mesh.vertex_faces
    for v in range(0, mesh.n_vertices, 7):
        want = np.flatnonzero((mesh.faces == v).any(axis=1))
        assert_array_equal(np.sort(fs[indptr[v] : indptr[v + 1]]), want)


def test_edge_graph_is_symmetric_with_edge_lengths():
    mesh = analytic_mesh("plane")
    g = mesh.edge_graph
    assert (g != g.T).nnz == 0
    e = mesh.edges
    assert_allclose(np.asarray(g[e[:, 0], e[:, 1]]).ravel(), mesh.edge_lengths)
    assert g.nnz == 2 * e.shape[0]


# --------------------------------------------------------------------------- topology
def test_cylinder_boundary_loops():
    mesh = analytic_mesh("cylinder")  # 32 around, 16 along, height 2
    loops = mesh.boundary_loops
    assert [loop.size for loop in loops] == [32, 32]
    heights = sorted(float(np.unique(mesh.vertices[loop, 2]).item()) for loop in loops)
    assert heights == [0.0, 2.0]
    half = {
        (a, b) for tri in mesh.faces.tolist() for a, b in zip(tri, tri[1:] + tri[:1], strict=True)
    }
    for loop in loops:
        assert np.unique(loop).size == loop.size
        # consecutive loop vertices form boundary half-edges in face order
        for a, b in zip(loop.tolist(), np.roll(loop, -1).tolist(), strict=True):
            assert (a, b) in half
            assert (b, a) not in half
    assert mesh.euler_characteristic == 0
    assert mesh.genus == 0


def test_plane_boundary_loop_is_the_square():
    mesh = analytic_mesh("plane")  # 20 x 20 cells, boundary vertices not jittered
    (loop,) = mesh.boundary_loops
    assert loop.size == 4 * 20
    xy = mesh.vertices[loop, :2]
    on_side = np.isclose(xy, 0.0) | np.isclose(xy, 1.0)
    assert on_side.any(axis=1).all()
    assert mesh.euler_characteristic == 1
    assert mesh.genus == 0
    # counter-clockwise seen from +z: positive signed area (shoelace)
    x, y = xy[:, 0], xy[:, 1]
    assert_allclose(0.5 * (np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))), 1.0)


@pytest.mark.parametrize(
    ("name", "genus", "chi"),
    [("icosphere", 0, 2), ("torus", 1, 0), ("cylinder", 0, 0), ("plane", 0, 1)],
)
def test_genus(name, genus, chi):
    mesh = analytic_mesh(name)
    assert mesh.genus == genus
    assert mesh.euler_characteristic == chi
    assert mesh.n_components == 1


def test_components_of_a_two_piece_mesh():
    a = shapes.icosphere(2)
    b = shapes.torus()
    v = np.vstack([b.vertices + np.array([5.0, 0, 0]), a.vertices])
    f = np.vstack([b.faces, a.faces + b.n_vertices])
    mesh = Mesh(v, f)
    assert mesh.n_components == 2
    labels = mesh.face_components
    assert np.unique(labels[: b.n_faces]).size == 1
    assert np.unique(labels[b.n_faces :]).size == 1
    assert labels[0] != labels[-1]
    assert_array_equal(np.sort(np.unique(labels)), [0, 1])
    assert_array_equal(mesh.vertex_components[: b.n_vertices], labels[0])
    assert_array_equal(mesh.vertex_components[b.n_vertices :], labels[-1])
    # chi = 0 + 2; genus sums over components
    assert mesh.euler_characteristic == 2
    assert mesh.genus == 1
    assert mesh.is_closed


# ---------------------------------------------------------------------------- geometry
def test_icosphere_normals_point_outward():
    mesh = analytic_mesh("icosphere")
    centroid = mesh.vertices[mesh.faces].mean(axis=1)
    radial = np.einsum(
        "ij,ij->i", mesh.face_normals, centroid / np.linalg.norm(centroid, axis=1, keepdims=True)
    )
    assert (radial > 0.99).all()  # nearly radial: the mesh approximates the sphere
    assert_allclose(np.linalg.norm(mesh.face_normals, axis=1), 1.0, rtol=1e-14)


def test_cylinder_normals_point_outward():
    mesh = analytic_mesh("cylinder")
    c = mesh.vertices[mesh.faces].mean(axis=1)
    n = mesh.face_normals
    assert (np.einsum("ij,ij->i", n[:, :2], c[:, :2]) > 0).all()
    assert_allclose(n[:, 2], 0.0, atol=1e-15)


@pytest.mark.parametrize("radius", [1.0, 3.5])
def test_icosphere_area(radius):
    mesh = shapes.icosphere(3, radius=radius)
    sphere = 4.0 * np.pi * radius**2
    # the inscribed polyhedron has less area than its sphere (a convex body inside another);
    # and projecting each flat face radially onto the sphere shrinks areas by at most
    # (d / r)^2, d the face plane's distance to the centre: area >= sphere (d_min / r)^2
    d = np.abs(np.einsum("ij,ij->i", mesh.face_normals, mesh.vertices[mesh.faces[:, 0]]))
    assert mesh.area <= sphere
    assert mesh.area >= sphere * (d.min() / radius) ** 2
    # for 1280 faces that bound is about 1 %
    assert mesh.area == pytest.approx(sphere, rel=0.01)
    assert_allclose(mesh.area, mesh.face_areas.sum())


@pytest.mark.parametrize("name", SMALL)
def test_face_areas_and_normals_match_heron_and_cross(name):
    mesh = any_mesh(name)
    p = mesh.vertices[mesh.faces]
    a = np.linalg.norm(p[:, 1] - p[:, 0], axis=1)
    b = np.linalg.norm(p[:, 2] - p[:, 1], axis=1)
    c = np.linalg.norm(p[:, 0] - p[:, 2], axis=1)
    s = (a + b + c) / 2
    heron = np.sqrt(np.maximum(s * (s - a) * (s - b) * (s - c), 0))
    assert_allclose(mesh.face_areas, heron, rtol=1e-6)
    # normals are perpendicular to every face edge
    for i, j in ((0, 1), (1, 2), (2, 0)):
        e = p[:, j] - p[:, i]
        dot = np.einsum("ij,ij->i", mesh.face_normals, e)
        assert_allclose(dot, 0.0, atol=1e-12 * mesh.bbox_diagonal)


@pytest.mark.parametrize("name", SMALL)
def test_mean_edge_length_and_bbox_diagonal(name):
    mesh = any_mesh(name)
    edges = {
        tuple(sorted((a, b)))
        for tri in mesh.faces.tolist()
        for a, b in zip(tri, tri[1:] + tri[:1], strict=True)
    }
    lengths = [np.linalg.norm(mesh.vertices[a] - mesh.vertices[b]) for a, b in sorted(edges)]
    assert_allclose(mesh.edge_lengths, lengths, rtol=1e-15)
    assert_allclose(mesh.mean_edge_length, np.mean(lengths), rtol=1e-12)
    lo = mesh.vertices.min(axis=0)
    hi = mesh.vertices.max(axis=0)
    assert_array_equal(mesh.bbox, [lo, hi])
    assert_allclose(mesh.bbox_diagonal, np.sqrt(((hi - lo) ** 2).sum()), rtol=1e-15)


def test_plane_bbox_and_area_exact():
    mesh = analytic_mesh("plane")
    assert_allclose(mesh.bbox_diagonal, np.sqrt(2.0), rtol=1e-15)
    assert_allclose(mesh.area, 1.0, rtol=1e-12)


def test_tolerance_lengths(spot):
    assert tol.length(spot, tol.WALK_EPS) == tol.WALK_EPS * spot.mean_edge_length
    assert tol.length(spot, tol.ON_SURFACE, scale="bbox_diagonal") == (
        tol.ON_SURFACE * spot.bbox_diagonal
    )
    with pytest.raises(ValueError, match="unknown scale"):
        tol.length(spot, 1.0, scale="area")


# -------------------------------------------------------------------- face points (xyz)
@pytest.mark.parametrize("name", SMALL)
def test_xyz_of_vertex_face_points(name, rng):
    mesh = any_mesh(name)
    vs = rng.integers(0, mesh.n_vertices, size=200)
    sp = SurfacePoints.at_vertices(mesh.faces, vs)
    assert len(sp) == 200
    # each point sits on a face that uses the vertex, with weight 1 at that corner
    assert (mesh.faces[sp.face] == vs[:, None]).any(axis=1).all()
    assert_array_equal(sp.bary.sum(axis=1), 1.0)
    assert_array_equal(mesh.xyz(sp), mesh.vertices[vs])


def test_xyz_of_interior_points_is_the_barycentric_combination(spot, rng):
    face = rng.integers(0, spot.n_faces, size=100)
    bary = rng.dirichlet([1, 1, 1], size=100)
    sp = SurfacePoints(face, bary)
    p = spot.vertices[spot.faces[face]]
    want = bary[:, :1] * p[:, 0] + bary[:, 1:2] * p[:, 1] + bary[:, 2:] * p[:, 2]
    assert_allclose(spot.xyz(sp), want, atol=tol.TEST_ATOL * spot.bbox_diagonal)


def test_at_vertices_rejects_unused_and_out_of_range_vertices():
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    with pytest.raises(errors.InputError, match="vertex 4 is not referenced"):
        SurfacePoints.at_vertices(faces, [1, 4])
    with pytest.raises(errors.InputError, match="vertex -1 is not referenced"):
        SurfacePoints.at_vertices(faces, [-1])
    with pytest.raises(errors.InputError, match="vertex 1 is not referenced"):
        SurfacePoints.at_vertices(np.array([[0, 2, 3]]), [1])
    empty = SurfacePoints.at_vertices(faces, np.zeros(0, dtype=np.int64))
    assert len(empty) == 0


def test_vertex_normals_point_outward_on_a_sphere():
    mesh = analytic_mesh("icosphere")
    radial = mesh.vertices / np.linalg.norm(mesh.vertices, axis=1)[:, None]
    n = mesh.vertex_normals
    assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    assert (np.einsum("ij,ij->i", n, radial) > 0.99).all()
    assert not n.flags.writeable
