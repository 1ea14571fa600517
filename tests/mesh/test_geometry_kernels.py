"""Face cross products and vertex sums (meshfit._kernels.geometry) against their slow
references and, bitwise, against the numpy expressions they replace."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from meshfit._kernels import geometry as _g

from ..conftest import real_mesh
from ..reference import geometry as ref


def _random_soup(rng, nv=40, nf=90):
    V = rng.normal(size=(nv, 3)) * rng.uniform(1e-3, 1e3)
    F = rng.integers(0, nv, size=(nf, 3))
    return V, F


@pytest.mark.parametrize("seed", range(5))
def test_kernels_match_the_references(seed):
    rng = np.random.default_rng(seed)
    V, F = _random_soup(rng)
    cross = _g.face_cross(V, F)
    assert_array_equal(cross, ref.face_cross(V, F))
    W = rng.normal(size=(len(F), 3))
    sums = _g.vertex_sums(F, W, len(V) + 2)  # two vertices on no face
    np.testing.assert_allclose(sums, ref.vertex_sums(F, W, len(V) + 2))
    assert_array_equal(sums[-2:], 0.0)


@pytest.mark.parametrize("name", ["spot", "nefertiti", "igea"])
def test_mesh_normals_equal_the_numpy_expressions(name):
    mesh = real_mesh(name)
    p = mesh.vertices[mesh.faces]
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert_array_equal(mesh._face_cross, cross)
    acc = np.stack(
        [
            np.bincount(mesh.faces.ravel(), np.repeat(cross[:, d], 3), mesh.n_vertices)
            for d in range(3)
        ],
        axis=1,
    )
    ln = np.linalg.norm(acc, axis=1, keepdims=True)
    assert_array_equal(mesh.vertex_normals, acc / np.where(ln > 0, ln, 1.0))
    assert_array_equal(mesh.face_areas, 0.5 * np.linalg.norm(cross, axis=1))


@pytest.mark.parametrize("seed", range(5))
def test_polyline_gap_matches_the_reference(seed):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(int(rng.integers(1, 30)), 3))
    b = rng.normal(size=(int(rng.integers(2, 30)), 3))
    b[3 % len(b)] = b[2 % len(b)]  # a segment of zero length
    np.testing.assert_allclose(_g.polyline_gap(a, b), ref.polyline_gap(a, b), rtol=1e-12)
    assert _g.polyline_gap(b, b) < 1e-14  # every point on its own polyline


@pytest.mark.parametrize("seed", range(3))
def test_label_corner_max_matches_the_reference(seed):
    rng = np.random.default_rng(seed)
    mesh = real_mesh("spot")
    n = 9
    label = rng.integers(-1, n - 1, mesh.n_faces)  # label n - 1 has no faces, -1 is skipped
    value = rng.normal(size=mesh.n_vertices)
    got = _g.label_corner_max(mesh.faces, label, value, n)
    want = ref.label_corner_max(mesh.faces, label, value, n)
    np.testing.assert_array_equal(got, want)
    assert got[-1] == -np.inf


@pytest.mark.parametrize("seed", range(5))
def test_needle_areas_match_the_reference(seed):
    rng = np.random.default_rng(seed)
    V, F = _random_soup(rng, nf=3 * (1 << 14) + 7)  # three blocks and a part of one
    F[0] = [0, 0, 1]  # a face of zero area with an edge: a needle
    F[1] = [2, 2, 2]  # a face on one point: none
    got = _g.needle_areas(V, F, 8.0)
    want = ref.needle_areas(V, F, 8.0)
    np.testing.assert_allclose(got, want, rtol=1e-12)
    assert 0.0 < got[1] < got[0]  # random triangles: some needles, not all


def test_needle_share_of_a_mesh_matches_the_numpy_expression():
    from meshfit.layout.even import NEEDLE_RATIO, needle_share

    mesh = real_mesh("nefertiti")
    P = mesh.vertices[mesh.faces]
    longest = np.linalg.norm(P[:, [1, 2, 0]] - P, axis=2).max(axis=1)
    area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    needles = longest * longest > NEEDLE_RATIO * 2.0 * np.maximum(area, np.finfo(float).tiny)
    share = needle_share(mesh)
    assert share > 0.0  # (the scan has some needles)
    assert share == pytest.approx(area[needles].sum() / area.sum(), rel=1e-12)
