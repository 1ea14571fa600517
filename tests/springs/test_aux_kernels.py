"""Spring-mesh bookkeeping kernels against their numpy oracles, bit for bit
(tests/reference/springs_aux.py)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from meshfit._kernels import springs_aux as K
from meshfit.springs.grid import dilate_grid, grid_triangles
from meshfit.springs.init import chain_arc, chain_edge_faces
from meshfit.springs.planar import square_map
from meshfit.springs.resample import _sides

from ..conftest import real_mesh
from ..reference import springs_aux as ref
from .patches import cap_map, cut_patch, param_patch


@pytest.fixture(scope="module")
def patches():
    return {
        "cap": param_patch(cap_map(), 16, 16),
        "spot": cut_patch(real_mesh("spot"), 100, 0.25),
    }


def _bits(a: np.ndarray) -> np.ndarray:
    """The float64 array's bit patterns (so that -0.0 and 0.0 differ)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def _face_points(mesh, m: int, rng, zeros: bool = False):
    face = rng.integers(0, mesh.n_faces, m)
    bary = rng.random((m, 3))
    if zeros:  # points on edges and at vertices
        bary[rng.random((m, 3)) < 0.3] = 0.0
        bary[bary.sum(axis=1) == 0.0, 0] = 1.0
    bary /= bary.sum(axis=1, keepdims=True)
    return face, bary


@pytest.mark.parametrize("name", ["cap", "spot"])
@pytest.mark.parametrize("zeros", [False, True])
def test_face_point_sums_match_einsum(patches, name, zeros, rng):
    mesh = patches[name].mesh
    face, bary = _face_points(mesh, 500, rng, zeros)
    V, F = mesh.vertices, mesh.faces
    assert_array_equal(
        _bits(K.face_point_sums(V, F, face, bary)), _bits(ref.face_point_sums(V, F, face, bary))
    )
    uv = np.ascontiguousarray(V[:, :2] - V[:, :2].mean(axis=0))  # signs of both kinds
    assert_array_equal(
        _bits(K.face_point_sums(uv, F, face, bary)),
        _bits(ref.face_point_sums(uv, F, face, bary)),
    )
    assert K.face_point_sums(V, F, face[:0], bary[:0]).shape == (0, 3)


@pytest.mark.parametrize("name", ["cap", "spot"])
def test_planar_map_parameters_match_oracle(patches, name, rng):
    patch = patches[name]
    pmap = square_map(patch.mesh, _sides(patch))
    face, bary = _face_points(patch.mesh, 400, rng, zeros=True)
    F = patch.mesh.faces
    assert_array_equal(
        _bits(pmap.uv_of(face, bary)), _bits(ref.face_point_sums(pmap.uv, F, face, bary))
    )
    a, b = rng.integers(0, 400, 300), rng.integers(0, 400, 300)
    assert_array_equal(
        _bits(pmap.mid_uv(face, bary, a, b)),
        _bits(ref.mid_parameters(pmap.uv, F, face, bary, a, b)),
    )


def test_section_positions_match_linspace(rng):
    for _ in range(200):
        s = int(rng.integers(1, 5))
        counts = rng.integers(1, 40, s)
        breaks = np.concatenate([[0.0], np.cumsum(rng.random(s) * 10.0 ** rng.integers(-3, 3))])
        if rng.random() < 0.2:  # an empty section
            breaks[1] = breaks[0]
        pos, ends = K.section_positions(breaks, counts.astype(np.int64))
        want, want_ends = ref.section_positions(breaks.tolist(), counts.tolist())
        assert_array_equal(_bits(pos), _bits(want))
        assert_array_equal(ends, want_ends)


@pytest.mark.parametrize("name", ["cap", "spot"])
def test_chain_arc_and_edge_faces_match_oracle(patches, name):
    patch = patches[name]
    mesh = patch.mesh
    chains = [np.asarray(c, dtype=np.int64) for c in patch.sides]
    chains += [c[::-1].copy() for c in chains] + [chains[0][:1]]
    for chain in chains:
        assert_array_equal(
            _bits(chain_arc(mesh, chain)), _bits(ref.chain_arc(mesh.vertices, chain))
        )
    got = chain_edge_faces(mesh, chains)
    want = ref.chain_edge_faces(mesh.faces, mesh.face_neighbors, mesh.n_vertices, chains)
    assert len(got) == len(want)
    for g, w in zip(got, want, strict=True):
        for x, y in zip(g, w, strict=True):
            assert x.dtype == np.int64
            assert_array_equal(x, y)
    inner = np.setdiff1d(np.arange(mesh.n_vertices), np.concatenate(chains))
    with pytest.raises(AssertionError, match="follow the patch boundary"):
        chain_edge_faces(mesh, [np.array([chains[0][0], inner[0]])])


@pytest.mark.parametrize(("nu", "nv"), [(2, 2), (3, 5), (7, 2), (6, 6)])
def test_grid_triangles_split_each_cell_along_its_diagonal(nu, nv):
    """Against the cells written out one by one: the first triangles, then the second ones;
    ``base`` offsets every index and ``out`` is filled in place."""
    cells = [(i * nv + j, (i + 1) * nv + j) for i in range(nu - 1) for j in range(nv - 1)]
    want = np.array([(a, b, b + 1) for a, b in cells] + [(a, b + 1, a + 1) for a, b in cells])
    assert_array_equal(grid_triangles(nu, nv), want)
    out = np.full_like(want, -1)
    assert grid_triangles(nu, nv, base=17, out=out) is out
    assert_array_equal(out, want + 17)
    with pytest.raises(ValueError, match="out has shape"):
        grid_triangles(nu, nv, out=out[1:])


def test_dilate_grid_matches_binary_dilation(rng):
    from scipy.ndimage import binary_dilation

    for _ in range(300):
        a, b = rng.integers(2, 25, 2)
        mask = rng.random((a, b)) < 0.1 * rng.random()
        reach = int(rng.integers(1, 4))
        assert_array_equal(dilate_grid(mask, reach), binary_dilation(mask, iterations=reach))


@pytest.mark.parametrize("name", ["cap", "spot"])
def test_mean_face_edge_matches_oracle(patches, name):
    mesh = patches[name].mesh
    got = K.mean_face_edge(mesh.vertices, mesh.faces)
    assert got == pytest.approx(ref.mean_face_edge(mesh.vertices, mesh.faces), rel=1e-12)
    assert K.mean_face_edge(mesh.vertices, mesh.faces[:0]) == 0.0
