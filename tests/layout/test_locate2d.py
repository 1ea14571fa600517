"""The walking point location of the region layout's disc maps against every triangle tried."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose

from meshfit._kernels.locate2d import walk_locate
from meshfit.mesh.topology import edge_table, face_neighbors

from ..reference.locate2d import locate_all
from ..shapes import disk


def _disc():
    d = disk(16)
    uv = np.ascontiguousarray(d.vertices[:, :2])
    T = np.array(d.faces, dtype=np.int64)
    a, b, c = uv[T[:, 0]], uv[T[:, 1]], uv[T[:, 2]]
    ccw = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0] > 0
    T[~ccw] = T[~ccw][:, ::-1]
    nbr = np.ascontiguousarray(face_neighbors(T, edge_table(T, uv.shape[0])))
    return uv, T, nbr


def test_walk_finds_the_triangle_every_triangle_tried_finds():
    uv, T, nbr = _disc()
    rng = np.random.default_rng(0)
    # points along random chords (the order a traced path asks in) and scattered points
    path = np.concatenate(
        [np.linspace(p, q, 40) for p, q in rng.uniform(-0.6, 0.6, size=(10, 2, 2))]
    )
    scattered = rng.uniform(-0.7, 0.7, size=(200, 2))
    for q in (path, scattered):
        tri, bary = walk_locate(uv, T, nbr, np.ascontiguousarray(q), 0, 1e-12)
        want_t, want_b = locate_all(uv, T, q)
        assert (tri >= 0).all()
        # the same triangle, or a neighbour sharing the point on an edge (ties)
        same = tri == want_t
        assert (bary[~same].min(axis=1) > -1e-9).all()
        assert_allclose(bary[same], want_b[same], atol=1e-12)
        assert_allclose((bary[:, :, None] * uv[T[tri]]).sum(axis=1), q, atol=1e-12)


def test_a_point_outside_is_reported_lost():
    uv, T, nbr = _disc()
    tri, _ = walk_locate(uv, T, nbr, np.array([[5.0, 5.0], [0.0, 0.0]]), 0, 1e-12)
    assert tri[0] == -1 and tri[1] >= 0
