"""random_surface_points (uniform by area, valid barycentrics, seeded, face subsets) and
closest_surface_points."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit import errors, tol
from meshfit.mesh import Mesh
from meshfit.surface import closest_surface_points, random_surface_points

from ..conftest import REAL, analytic_mesh, real_mesh

N = 40_000
SIGMAS = 4.5  # a fraction of N Bernoulli samples lies within 4.5 sigma with p > 1 - 1e-5


def graded_plane(n: int = 12) -> Mesh:
    """Unit square whose cells shrink quadratically towards x = 0: face areas differ ~100x."""
    x = (np.arange(n + 1) / n) ** 2
    y = np.arange(n + 1) / n
    X, Y = np.meshgrid(x, y, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = (
        idx[:-1, :-1].ravel(),
        idx[1:, :-1].ravel(),
        idx[1:, 1:].ravel(),
        idx[:-1, 1:].ravel(),
    )
    return Mesh(v, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]))


def two_triangles() -> Mesh:
    return Mesh(
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float),
        np.array([[0, 1, 2], [0, 2, 3]]),
    )


def assert_fraction(hits: np.ndarray, p: float) -> None:
    """The fraction of True in ``hits`` matches probability ``p`` within SIGMAS sigma."""
    sigma = np.sqrt(p * (1 - p) / hits.size)
    assert abs(hits.mean() - p) < SIGMAS * sigma, (hits.mean(), p, sigma)


@pytest.mark.parametrize("make", [graded_plane, two_triangles], ids=["graded", "two_triangles"])
@pytest.mark.parametrize("cut", [0.3, 0.55])
def test_uniform_by_area(make, cut):
    # a unit square in z = 0: the samples left of x = cut must be a fraction `cut` of them.
    # The line cuts through triangles, so this checks both the choice of face (by area) and
    # the distribution inside each triangle.
    mesh = make()
    xyz = mesh.xyz(random_surface_points(mesh, N, 1))
    assert_fraction(xyz[:, 0] < cut, cut)
    assert_fraction(xyz[:, 1] < cut, cut)
    assert_fraction(xyz[:, 0] + xyz[:, 1] < 1.0, 0.5)  # the diagonal halves of the square


def test_uniform_on_a_sphere():
    # on the sphere the area above height z is proportional to (1 - z) / 2
    mesh = analytic_mesh("icosphere")
    xyz = mesh.xyz(random_surface_points(mesh, N, 2))
    assert_fraction(xyz[:, 2] > 0.5, 0.25)  # the polyhedron's bias is well inside 4 sigma
    assert_fraction(xyz[:, 0] > 0, 0.5)


def test_face_frequency_proportional_to_area():
    mesh = graded_plane(4)
    sp = random_surface_points(mesh, N, 3)
    counts = np.bincount(sp.face, minlength=mesh.n_faces)
    p = mesh.face_areas / mesh.area
    sigma = np.sqrt(p * (1 - p) / N)
    assert (np.abs(counts / N - p) < SIGMAS * sigma).all()


@pytest.mark.parametrize("name", REAL)
def test_bary_valid(name, rng):
    mesh = real_mesh(name)
    sp = random_surface_points(mesh, 5000, rng)
    assert sp.face.dtype == np.int64
    assert sp.bary.dtype == np.float64
    assert ((sp.face >= 0) & (sp.face < mesh.n_faces)).all()
    assert (sp.bary >= 0).all()
    assert_allclose(sp.bary.sum(axis=1), 1.0, atol=1e-15)
    assert len(sp) == 5000


def test_deterministic_with_a_seed(spot):
    a = random_surface_points(spot, 100, 42)
    b = random_surface_points(spot, 100, 42)
    c = random_surface_points(spot, 100, np.random.default_rng(42))
    d = random_surface_points(spot, 100, 43)
    assert_array_equal(a.face, b.face)
    assert_array_equal(a.bary, b.bary)
    assert_array_equal(a.face, c.face)
    assert_array_equal(a.bary, c.bary)
    assert not np.array_equal(a.face, d.face)


def test_generator_state_advances(spot):
    rng = np.random.default_rng(5)
    a = random_surface_points(spot, 50, rng)
    b = random_surface_points(spot, 50, rng)
    assert not np.array_equal(a.face, b.face)


def test_faces_restriction(spot, rng):
    subset = np.array([10, 20, 4000, 5855])
    sp = random_surface_points(spot, 8000, rng, faces=subset)
    assert np.isin(sp.face, subset).all()
    counts = np.array([(sp.face == f).sum() for f in subset])
    p = spot.face_areas[subset] / spot.face_areas[subset].sum()
    sigma = np.sqrt(p * (1 - p) / 8000)
    assert (np.abs(counts / 8000 - p) < SIGMAS * sigma).all()
    one = random_surface_points(spot, 10, rng, faces=[7])
    assert_array_equal(one.face, 7)


def test_zero_points_and_bad_arguments(spot):
    assert len(random_surface_points(spot, 0, 1)) == 0
    with pytest.raises(errors.InputError, match="n must be >= 0"):
        random_surface_points(spot, -1)
    with pytest.raises(errors.InputError, match="non-empty"):
        random_surface_points(spot, 5, faces=[])
    with pytest.raises(errors.InputError, match="face indices of the mesh"):
        random_surface_points(spot, 5, faces=[spot.n_faces])
    with pytest.raises(errors.InputError, match="face indices of the mesh"):
        random_surface_points(spot, 5, faces=[-1])


@pytest.mark.parametrize("name", [*REAL, "torus"])
def test_closest_surface_points_round_trip(name, rng):
    mesh = real_mesh(name) if name in REAL else analytic_mesh(name)
    sp = random_surface_points(mesh, 300, rng)
    xyz = mesh.xyz(sp)
    back = closest_surface_points(mesh, xyz)
    assert len(back) == 300
    assert_allclose(mesh.xyz(back), xyz, atol=tol.ON_SURFACE * mesh.bbox_diagonal)
    # the face found is the sampled one, or one touching it (points near shared edges)
    same = back.face == sp.face
    assert same.mean() > 0.95
    shares = [
        np.intersect1d(mesh.faces[a], mesh.faces[b]).size > 0
        for a, b in zip(back.face[~same], sp.face[~same], strict=True)
    ]
    assert all(shares)


def test_closest_surface_points_of_off_surface_positions(spot, rng):
    sp = random_surface_points(spot, 100, rng)
    xyz = spot.xyz(sp)
    n = spot.face_normals[sp.face]
    eps = 1e-4 * spot.mean_edge_length
    back = closest_surface_points(spot, xyz + eps * n)
    assert_allclose(spot.xyz(back), xyz, atol=2 * eps)
