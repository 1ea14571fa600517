"""Distances from points to triangle soups (meshfit.mesh.locate.triangle_distances) against
the brute-force reference and libigl."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit.errors import InputError
from meshfit.mesh.locate import build_tree, grid_tree, triangle_distances, triangles_within

from ..conftest import real_mesh
from ..reference import bvh as ref


def _soup(rng, m):
    V = rng.normal(size=(3 * m, 3))
    F = np.arange(3 * m).reshape(m, 3)
    return V, F


@pytest.mark.parametrize("m", [1, 7, 9, 200])
def test_random_soups_match_the_reference(rng, m):
    V, F = _soup(rng, m)
    # degenerate triangles: a repeated corner and three collinear corners
    if m >= 7:
        V[F[0, 1]] = V[F[0, 0]]
        V[F[1, 2]] = 0.5 * (V[F[1, 0]] + V[F[1, 1]])
    Q = rng.normal(size=(300, 3)) * 1.5
    Q[:3] = V[F[0]]  # on corners
    d, face = triangle_distances(Q, V, F)
    want = np.sqrt(ref.squared_distances(V, F, Q))
    assert_allclose(d, want, rtol=1e-12, atol=1e-12)
    # the reported triangle is at that distance
    own = np.sqrt(ref.squared_distances(V, F[face[:1]], Q[:1]))
    assert_allclose(own, d[:1], rtol=1e-12, atol=1e-12)
    for i in range(0, 300, 37):
        assert_allclose(
            np.sqrt(ref.squared_distances(V, F[face[i : i + 1]], Q[i : i + 1])),
            d[i : i + 1],
            rtol=1e-12,
            atol=1e-12,
        )


def test_points_on_a_real_scan_match_libigl(rng):
    import igl

    mesh = real_mesh("spot")
    h = mesh.mean_edge_length
    Q = mesh.vertices[rng.choice(mesh.n_vertices, 2000)] + rng.normal(scale=2 * h, size=(2000, 3))
    Q = np.concatenate([Q, mesh.vertices[:100]])
    d, _ = triangle_distances(Q, mesh.vertices, mesh.faces)
    sq, _, _ = igl.point_mesh_squared_distance(Q, mesh.vertices, mesh.faces)
    assert_allclose(d, np.sqrt(sq), rtol=0, atol=1e-12 * mesh.bbox_diagonal)
    assert (d[-100:] == 0).all()  # the mesh's own vertices


def test_bad_input_is_refused():
    V = np.eye(3)
    with pytest.raises(InputError, match="faces"):
        triangle_distances(np.zeros((1, 3)), V, np.zeros((0, 3), dtype=np.int64))
    with pytest.raises(InputError, match="out of range"):
        triangle_distances(np.zeros((1, 3)), V, np.array([[0, 1, 3]]))
    with pytest.raises(InputError, match="points"):
        triangle_distances(np.full((1, 3), np.nan), V, np.array([[0, 1, 2]]))


def test_a_kept_tree_gives_the_same_distances(rng):
    mesh = real_mesh("igea")
    q = rng.uniform(*mesh.bbox, size=(500, 3))
    want, _ = triangle_distances(q, mesh.vertices, mesh.faces)
    got, _ = triangle_distances(q, mesh.vertices, mesh.faces, tree=mesh.triangle_tree)
    assert_array_equal(got, want)
    assert_array_equal(got, mesh.closest_points(q).distance)
    with pytest.raises(InputError, match="tree has"):
        triangle_distances(q, mesh.vertices, mesh.faces[:10], tree=mesh.triangle_tree)


@pytest.mark.parametrize("m", [1, 9, 200])
def test_triangles_within_is_the_squared_distance_against_the_radius(rng, m):
    from meshfit._kernels import bvh

    V, F = _soup(rng, m)
    if m >= 9:
        V[F[0, 1]] = V[F[0, 0]]  # a degenerate triangle
    Q = rng.normal(size=(400, 3)) * 1.5
    tree = build_tree(V, F)
    qorder = np.argsort(bvh.point_morton_codes(Q), kind="stable")
    sq, _, _ = bvh.closest_points(V, F, *tree, Q, qorder)
    want = ref.squared_distances(V, F, Q)
    # radii around the typical distance, and exactly at some points' own squared distances
    # (a point at the radius is within it)
    for r2 in [0.0, *np.quantile(sq, [0.1, 0.5, 0.9]), sq[5], sq[77], 100.0]:
        got = bvh.within(V, F, *tree, Q, qorder, r2)
        assert_array_equal(got, sq <= r2)
        # the reference agrees away from the last bits
        clear = np.abs(want - r2) > 1e-9 * max(r2, 1e-300)
        assert_array_equal(got[clear], (want <= r2)[clear])
        # the public form takes the radius
        r = np.sqrt(r2)
        assert_array_equal(triangles_within(Q, V, F, r)[clear], got[clear])
    assert triangles_within(Q, V, F, 10.0).all()


def test_triangles_within_on_a_grid_tree_and_a_real_scan(rng):
    mesh = real_mesh("spot")
    h = mesh.mean_edge_length
    Q = mesh.vertices[rng.choice(mesh.n_vertices, 3000)] + rng.normal(scale=3 * h, size=(3000, 3))
    d, _ = triangle_distances(Q, mesh.vertices, mesh.faces, tree=mesh.triangle_tree)
    got = triangles_within(Q, mesh.vertices, mesh.faces, 2 * h, tree=mesh.triangle_tree)
    assert 0 < got.sum() < got.size
    clear = np.abs(d - 2 * h) > 1e-12 * h  # the square root may round across the radius
    assert_array_equal(got[clear], (d <= 2 * h)[clear])
    # a grid soup with its own tree
    u, v = np.meshgrid(np.linspace(0, 1, 12), np.linspace(0, 2, 20), indexing="ij")
    P = np.stack([u, v, 0.1 * np.sin(3 * u + v)], axis=-1).reshape(-1, 3)
    from meshfit.springs import grid_triangles

    T = grid_triangles(12, 20)
    q = rng.uniform([-0.5, -0.5, -0.5], [1.5, 2.5, 0.5], size=(2000, 3))
    tree = grid_tree(P, T, [(12, 20)])
    dq, _ = triangle_distances(q, P, T, tree=tree)
    clear = np.abs(dq - 0.2) > 1e-12
    assert_array_equal(triangles_within(q, P, T, 0.2, tree=tree)[clear], (dq <= 0.2)[clear])


def test_triangles_within_refuses_a_bad_radius():
    V, F = np.eye(3), np.array([[0, 1, 2]])
    for r in (-1.0, np.nan, np.inf):
        with pytest.raises(InputError, match="radius"):
            triangles_within(np.zeros((1, 3)), V, F, r)
    assert triangles_within(np.zeros((0, 3)), V, F, 1.0).shape == (0,)
