"""Distances from points to triangle soups (meshfit.mesh.locate.triangle_distances) against
the brute-force reference and libigl."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit.errors import InputError
from meshfit.mesh.locate import triangle_distances

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
