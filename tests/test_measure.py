"""Error searches split by patch (meshfit.pipeline.measure)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from meshfit.mesh.locate import triangle_distances
from meshfit.pipeline import measure


def _cube_sphere(n: int = 17) -> list[np.ndarray]:
    """A sphere as six grids (the cube's faces projected), each ``(n, n, 3)``."""
    t = np.linspace(-1.0, 1.0, n)
    a, b = np.meshgrid(t, t, indexing="ij")
    one = np.ones_like(a)
    faces = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            cols = [a, b]
            cols.insert(axis, sign * one)
            P = np.stack(cols, axis=-1)
            faces.append(P / np.linalg.norm(P, axis=-1, keepdims=True))
    return faces


def _plates(n: int = 12) -> list[np.ndarray]:
    """Two parallel wavy plates a little apart, each split into two grids."""
    u, v = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 0.5, n), indexing="ij")
    out = []
    for z0 in (0.0, 0.05):
        for v0 in (0.0, 0.5):
            w = z0 + 0.01 * np.sin(7 * u) * np.cos(5 * (v + v0))
            out.append(np.stack([u, v + v0, w], axis=-1))
    return out


def _whole(points, grids):
    V, F = measure.soup(grids)
    return triangle_distances(points, V, F)[0]


@pytest.mark.parametrize("shape", [_cube_sphere, _plates])
@pytest.mark.parametrize("seed", [0, 1])
def test_split_search_equals_the_whole_soup(shape, seed):
    # any rigid motion and scale, points on, near and far from the grids, each set searched
    # as patch p's: the same distances as the search of every grid at once, to the bit
    rng = np.random.default_rng(seed)
    R = Rotation.random(random_state=seed).as_matrix()
    scale, shift = 10.0 ** rng.uniform(-3, 3), rng.normal(size=3) * 100
    grids = [g @ R.T * scale + shift for g in shape()]
    boxes = measure.grid_boxes(grids)
    for p, g in enumerate(grids):
        pts = g.reshape(-1, 3)
        X = np.vstack(
            [
                pts,  # on the grid points (ties across seams)
                pts + rng.normal(scale=0.02 * scale, size=pts.shape),
                pts + rng.normal(scale=0.3 * scale, size=pts.shape),
            ]
        )
        got = measure.nearest_grid_distances(X, p, boxes, grids.__getitem__)
        np.testing.assert_array_equal(got, _whole(X, grids))


def test_split_search_reads_only_the_grids_it_needs():
    # points inside one plate's grid need neither of the other plate's grids; points
    # between the plates need the plate across
    grids = _plates()
    boxes = measure.grid_boxes(grids)
    read: list[int] = []

    def grid(q):
        read.append(q)
        return grids[q]

    inner = grids[0][3:-3, 3:-3].reshape(-1, 3)
    measure.nearest_grid_distances(inner, 0, boxes, grid)
    assert 0 in read and not {2, 3} & set(read)
    read.clear()
    between = inner + np.array([0.0, 0.0, 0.04])
    got = measure.nearest_grid_distances(between, 0, boxes, grid)
    assert 2 in read
    np.testing.assert_array_equal(got, _whole(between, grids))


def test_split_search_of_no_points():
    grids = _plates()
    got = measure.nearest_grid_distances(np.empty((0, 3)), 1, measure.grid_boxes(grids), None)
    assert got.shape == (0,)
