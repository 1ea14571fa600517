"""Hole filling: the least-area triangulation kernel against its oracle, and the patch."""

from __future__ import annotations

import numpy as np
import pytest

from meshfit._kernels.holes import least_area_table
from meshfit.shrinkwrap.holes import _least_area, _relax_edges

from ..reference import holes as ref


@pytest.mark.parametrize("k", [3, 4, 5, 7, 9])
def test_least_area_table_matches_the_oracle(k, rng):
    for _ in range(6):
        P = rng.normal(size=(k, 3))
        forbidden = rng.random((k, k)) < 0.2
        forbidden = forbidden | forbidden.T
        for i in range(k):  # the polygon's sides are never diagonals
            forbidden[i, (i + 1) % k] = forbidden[(i + 1) % k, i] = False
        W, _ = least_area_table(P, forbidden)
        want = ref.least_area(P, forbidden)
        if np.isinf(want):
            assert np.isinf(W[0, k - 1])
        else:
            np.testing.assert_allclose(W[0, k - 1], want, rtol=1e-12)


def test_least_area_triangulation_closes_the_polygon_against_its_order(rng):
    k = 12
    t = np.linspace(0.0, 2 * np.pi, k, endpoint=False)
    P = np.column_stack([np.cos(t), np.sin(t), 0.1 * rng.normal(size=k)])
    tris = _least_area(P, np.zeros((k, k), dtype=bool))
    assert tris.shape == (k - 2, 3)
    half = {(int(a), int(b)) for f in tris for a, b in zip(f, np.roll(f, -1), strict=True)}
    # every side i -> i + 1 of the loop is used once, the other way round (the mesh's faces
    # run along the loop), and every diagonal in both directions
    for i in range(k):
        assert ((i + 1) % k, i) in half and (i, (i + 1) % k) not in half
    assert len(half) == 3 * (k - 2)
    # a forbidden diagonal is avoided; with every diagonal forbidden there is none
    forbidden = np.zeros((k, k), dtype=bool)
    forbidden[0, 6] = forbidden[6, 0] = True
    assert not any({0, 6} <= set(f.tolist()) for f in _least_area(P, forbidden))
    gap = np.abs(np.subtract.outer(np.arange(k), np.arange(k)))
    every = (gap > 1) & (gap < k - 1)  # all pairs but the sides
    assert _least_area(P, every) is None


def test_edge_flips_make_a_flat_patch_delaunay(rng):
    # a square split along its long diagonal's wrong way: the flip takes the other diagonal
    pos = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.2, 1.2, 0.0), (0.0, 1.0, 0.0)]
    faces = [(0, 1, 3), (1, 2, 3)]  # edge 1-3, opposite angles at 0 (90) and 2 (< 90)
    assert _relax_edges(pos, faces, np.zeros((0, 0), dtype=bool)) == faces
    faces = [(0, 1, 2), (0, 2, 3)]  # edge 0-2: angles at 1 and 3 add up to more than 180
    out = _relax_edges(pos, faces, np.zeros((0, 0), dtype=bool))
    assert {frozenset(f) for f in out} == {frozenset((1, 3, 0)), frozenset((1, 2, 3))}
    # ... unless the mesh joins 1 and 3 outside the patch
    forbidden = np.zeros((4, 4), dtype=bool)
    forbidden[1, 3] = forbidden[3, 1] = True
    assert _relax_edges(pos, faces, forbidden) == faces
