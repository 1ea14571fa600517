"""Closest points on a mesh through its bounding-volume hierarchy (meshfit.mesh.closest_points,
meshfit._kernels.bvh.closest_points) against the brute-force reference and libigl, on the
analytic shapes and the real scans, including queries on vertices and edges and far away."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit._kernels import bvh
from meshfit.errors import InputError
from meshfit.mesh import closest_points
from meshfit.mesh.locate import build_tree, grid_tree, triangle_distances
from meshfit.surface import random_surface_points

from ..conftest import analytic_mesh, real_mesh
from ..reference import bvh as ref

ANALYTIC = ("icosphere", "plane", "cylinder", "torus")


def _queries(mesh, rng, n=150):
    """Points around the mesh, on its vertices, on its edges, and far from it."""
    lo, hi = mesh.bbox
    diag = mesh.bbox_diagonal
    box = rng.uniform(lo - 0.2 * diag, hi + 0.2 * diag, size=(n, 3))
    near = mesh.xyz(random_surface_points(mesh, n, rng))
    near += rng.normal(scale=mesh.mean_edge_length, size=near.shape)
    verts = mesh.vertices[rng.choice(mesh.n_vertices, 30)]
    e = mesh.edges[rng.choice(len(mesh.edges), 30)]
    s = rng.uniform(size=(30, 1))
    edges = (1 - s) * mesh.vertices[e[:, 0]] + s * mesh.vertices[e[:, 1]]
    mids = 0.5 * (mesh.vertices[e[:, 0]] + mesh.vertices[e[:, 1]])
    u = rng.normal(size=(20, 3))
    far = 0.5 * (lo + hi) + 1e3 * diag * u / np.linalg.norm(u, axis=1, keepdims=True)
    return np.concatenate([box, near, verts, edges, mids, far])


def _check_consistent(mesh, q, got):
    """Barycentrics valid, ``xyz`` on the reported face, ``distance`` to ``xyz``."""
    atol = 1e-12 * mesh.bbox_diagonal
    assert (got.points.bary >= 0).all()
    assert_allclose(got.points.bary.sum(axis=1), 1.0, rtol=0, atol=4e-16)
    assert ((got.points.face >= 0) & (got.points.face < mesh.n_faces)).all()
    assert_array_equal(got.xyz, mesh.xyz(got.points))
    assert_allclose(np.linalg.norm(got.xyz - q, axis=1), got.distance, rtol=1e-12, atol=atol)


@pytest.mark.parametrize("name", ANALYTIC)
def test_analytic_shapes_match_the_reference(name, rng):
    mesh = analytic_mesh(name)
    q = _queries(mesh, rng)
    got = closest_points(mesh, q)
    sq, _, xyz = ref.closest_points(mesh.vertices, mesh.faces, q)
    diag = mesh.bbox_diagonal
    assert_allclose(got.distance, np.sqrt(sq), rtol=1e-12, atol=1e-12 * diag)
    assert_allclose(got.xyz, xyz, rtol=0, atol=1e-9 * diag)  # unique nearest points
    _check_consistent(mesh, q, got)
    # the reported face is a nearest face (ties only where faces meet)
    for i in range(0, len(q), 7):
        f = got.points.face[i : i + 1]
        own = ref.squared_distances(mesh.vertices, mesh.faces[f], q[i : i + 1])
        assert_allclose(np.sqrt(own), got.distance[i : i + 1], rtol=1e-12, atol=1e-12 * diag)


@pytest.mark.parametrize("name", ANALYTIC)
def test_vertices_and_edges_are_their_own_closest_points(name, rng):
    mesh = analytic_mesh(name)
    got = closest_points(mesh, mesh.vertices)
    assert (got.distance == 0).all()  # the vertex region of a face holding it is exact
    assert_array_equal(got.xyz, mesh.vertices)
    assert (mesh.faces[got.points.face] == np.arange(mesh.n_vertices)[:, None]).any(axis=1).all()
    e = mesh.edges
    s = rng.uniform(size=(len(e), 1))
    x = (1 - s) * mesh.vertices[e[:, 0]] + s * mesh.vertices[e[:, 1]]
    got = closest_points(mesh, x)
    assert_allclose(got.distance, 0.0, atol=1e-15 * mesh.bbox_diagonal)
    assert_allclose(got.xyz, x, rtol=0, atol=1e-15 * mesh.bbox_diagonal)
    _check_consistent(mesh, x, got)


@pytest.mark.parametrize("name", ["spot", "bunny", "igea"])
def test_real_scans_match_libigl(name, rng):
    import igl

    mesh = real_mesh(name)
    q = _queries(mesh, rng, n=4000)
    got = closest_points(mesh, q)
    sq, _, c = igl.point_mesh_squared_distance(q, mesh.vertices, mesh.faces)
    atol = 1e-12 * mesh.bbox_diagonal
    assert_allclose(got.distance, np.sqrt(sq), rtol=1e-12, atol=atol)
    assert_allclose(got.xyz, c, rtol=0, atol=atol)
    _check_consistent(mesh, q, got)


def test_result_does_not_depend_on_the_query_order(rng):
    mesh = real_mesh("spot")
    q = _queries(mesh, rng, n=3000)
    perm = rng.permutation(len(q))
    a = closest_points(mesh, q)
    b = closest_points(mesh, q[perm])
    atol = 1e-12 * mesh.bbox_diagonal
    assert_allclose(b.distance, a.distance[perm], rtol=1e-12, atol=atol)
    assert_allclose(b.xyz, a.xyz[perm], rtol=0, atol=atol)


def test_tree_is_built_once_per_mesh():
    mesh = analytic_mesh("torus")
    tree = mesh.triangle_tree
    closest_points(mesh, mesh.vertices[:3])
    assert mesh.triangle_tree is tree
    leaves = tree.child < 0
    sizes = tree.stop[leaves] - tree.start[leaves]
    assert sizes.max() <= bvh.LEAF_SIZE
    assert_array_equal(np.sort(tree.order), np.arange(mesh.n_faces))
    assert not any(a.flags.writeable for a in tree)
    with pytest.raises(InputError, match="leaf_size"):
        build_tree(mesh.vertices, mesh.faces, leaf_size=0)


def test_empty_query():
    mesh = analytic_mesh("icosphere")
    for q in (np.zeros((0, 3)), []):
        got = closest_points(mesh, np.reshape(q, (0, 3)))
        assert got.points.face.shape == (0,)
        assert got.points.bary.shape == (0, 3)
        assert got.distance.shape == (0,)
        assert got.xyz.shape == (0, 3)


@pytest.mark.parametrize("leaf_size", [1, 2, 8])
def test_kernel_on_soups_with_zero_area_triangles_matches_the_reference(rng, leaf_size):
    # a soup, not a Mesh: repeated corners, collinear corners, a triangle shrunk to a point
    m = 60
    V = rng.normal(size=(3 * m, 3))
    F = np.arange(3 * m).reshape(m, 3)
    V[F[0, 1]] = V[F[0, 0]]
    V[F[1, 2]] = 0.5 * (V[F[1, 0]] + V[F[1, 1]])
    V[F[2, 1]] = V[F[2, 2]] = V[F[2, 0]]
    V[F[3, 0]] = V[F[3, 1]] + 2.0 * (V[F[3, 2]] - V[F[3, 1]])  # collinear, corner outside
    Q = rng.normal(size=(400, 3)) * 1.5
    Q[:9] = V[F[:3]].reshape(-1, 3)
    tree = build_tree(V, F, leaf_size=leaf_size)
    sq, face, bary = bvh.closest_points(V, F, *tree, Q, np.arange(len(Q))[::-1].copy())
    want_sq, _, want_xyz = ref.closest_points(V, F, Q)
    assert_allclose(sq, want_sq, rtol=1e-12, atol=1e-14)
    xyz = np.einsum("ij,ijk->ik", bary, V[F[face]])
    assert_allclose(xyz, want_xyz, rtol=0, atol=1e-9)
    assert (bary >= 0).all()
    assert_allclose(bary.sum(axis=1), 1.0, rtol=0, atol=4e-16)
    assert_allclose(np.einsum("ij,ij->i", Q - xyz, Q - xyz), sq, rtol=1e-12, atol=1e-14)
    # the same distances in another query order (each search starts from the previous one)
    sq2, _, _ = bvh.closest_points(V, F, *tree, Q, np.arange(len(Q)))
    assert_array_equal(sq, sq2)


@pytest.mark.parametrize(("m", "leaf_size"), [(1, 2), (3, 2), (200, 2), (3000, 2), (3000, 8)])
def test_tree_equals_the_one_thread_breadth_first_build(rng, m, leaf_size):
    # 3000 triangles: the top is split on one thread, the subtrees below it in parallel
    V = rng.normal(size=(3 * m, 3))
    F = np.arange(3 * m).reshape(m, 3)
    order = np.argsort(bvh.morton_codes(V, F), kind="stable")
    got = bvh.build(V, F, order.copy(), leaf_size)
    want = ref.build(V, F, order, leaf_size)
    for g, w in zip(got, want, strict=True):
        assert_array_equal(g, w)
    tree = build_tree(V, F, leaf_size=leaf_size)
    assert_array_equal(tree.order, want[0])


def _grid_soup(rng, shapes):
    """Bumpy grids side by side, stacked as the fit's error stage stacks its patch grids."""
    from meshfit.springs import grid_triangles

    Vs, Fs, base = [], [], 0
    for k, (nu, nv) in enumerate(shapes):
        u, v = np.meshgrid(np.linspace(0, 1, nu), np.linspace(0, 1, nv), indexing="ij")
        z = 0.1 * np.sin(5 * u + 3 * v) + 0.02 * rng.standard_normal(u.shape)
        Vs.append(np.stack([u + 1.1 * k, 2 * v, z], axis=-1).reshape(-1, 3))
        Fs.append(grid_triangles(nu, nv) + base)
        base += nu * nv
    return np.vstack(Vs), np.vstack(Fs)


def test_grid_tree_matches_its_reference_and_finds_the_same_distances(rng):
    # the spline and displaced grids of a fit, as the error stage measures them
    shapes = [(2, 2), (5, 3), (17, 9), (2, 30), (12, 12)]
    V, F = _grid_soup(rng, shapes)
    tree = grid_tree(V, F, shapes)
    for got, want in zip(tree[1:], ref.build_grids(V, F, shapes, bvh.GRID_LEAF_CELLS), strict=True):
        assert_array_equal(got, want)
    assert_array_equal(np.sort(tree.order), np.arange(len(F)))
    q = rng.uniform(V.min(axis=0) - 0.5, V.max(axis=0) + 0.5, size=(3000, 3))
    got, _ = triangle_distances(q, V, F, tree=tree)
    want, _ = triangle_distances(q, V, F)
    assert_array_equal(got, want)
    assert_allclose(got[:50] ** 2, ref.squared_distances(V, F, q[:50]), rtol=1e-12, atol=0)
    # exact for any faces of the right count, only looser
    shuffled = F[rng.permutation(len(F))]
    got, _ = triangle_distances(q, V, shuffled, tree=grid_tree(V, shuffled, shapes))
    assert_array_equal(got, want)
    with pytest.raises(InputError, match="triangles"):
        grid_tree(V, F[:-2], shapes)
    with pytest.raises(InputError, match="points"):
        grid_tree(V[:-1], F, shapes)
    with pytest.raises(InputError, match="every size >= 2"):
        grid_tree(V, F, [(1, 4), *shapes])
