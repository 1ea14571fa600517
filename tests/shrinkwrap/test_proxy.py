"""Coarse proxies of closed meshes by half-edge collapses."""

from __future__ import annotations

import numpy as np
import pytest

from meshfit._kernels import decimate as _k
from meshfit.errors import InputError, TopologyError
from meshfit.shrinkwrap.proxy import (
    MAX_NORMAL_TURN_DEG,
    MAX_VALENCE,
    MIN_QUALITY,
    simplify_mesh,
)

from ..conftest import real_mesh
from ..reference import decimate as reference
from ..shapes import plane, torus


def _mesh(name):
    return torus() if name == "torus" else real_mesh(name)


@pytest.mark.parametrize("name", ["spot", "torus"])
@pytest.mark.parametrize(("share", "longest"), [(0.0, np.inf), (0.3, np.inf), (0.0, 0.9)])
def test_collapse_pass_matches_oracle(name, share, longest):
    mesh = _mesh(name)
    V = np.ascontiguousarray(mesh.vertices)
    F = np.array(mesh.faces, order="C")
    alive = np.ones(len(F), dtype=bool)
    frozen = np.random.default_rng(1).random(len(V)) < share
    min_cos = float(np.cos(np.radians(MAX_NORMAL_TURN_DEG)))
    # (a cap at 0.9 mean edges: a pass stops among the edges it would take)
    max_sq = (longest * mesh.mean_edge_length) ** 2
    want_F, want_alive, want_n = reference.collapse_pass(
        V, F.copy(), alive.copy(), frozen, 400, MAX_VALENCE, min_cos, MIN_QUALITY, max_sq
    )
    got_n = _k.collapse_pass(V, F, alive, frozen, 400, max_sq, MAX_VALENCE, min_cos, MIN_QUALITY)
    assert got_n == want_n > 0
    np.testing.assert_array_equal(alive, want_alive)
    np.testing.assert_array_equal(F[alive], want_F[want_alive])
    # a frozen vertex never went: it is still used, and every edge between two of them (a
    # piece's rim) is still there
    assert np.isin(np.flatnonzero(frozen), F[alive]).all()

    def edges(faces):
        e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), 1)
        return {tuple(x) for x in e[frozen[e].all(axis=1)]}

    assert edges(mesh.faces) == edges(F[alive])


@pytest.mark.parametrize("n", [0, 1, 7, 5000])
def test_stable_order_is_the_stable_argsort(n):
    # squared lengths with ties, zeros, subnormals, +inf and values of one exponent: every
    # radix digit both varies and repeats
    rng = np.random.default_rng(n)
    pool = np.array([0.0, 5e-324, 1e-300, 0.25, 0.5, 1.0, 1.5, 3e200, np.inf])
    v = np.where(rng.random(n) < 0.5, rng.choice(pool, n), rng.random(n) ** 2)
    np.testing.assert_array_equal(_k.stable_order(v), np.argsort(v, kind="stable"))
    same = np.full(n, 0.75)  # every digit shared: no pass moves anything
    np.testing.assert_array_equal(_k.stable_order(same), np.arange(n))


@pytest.mark.parametrize("name", ["spot", "nefertiti", "torus"])
def test_proxy_keeps_topology_and_shape(name):
    mesh = _mesh(name)
    target = mesh.n_faces // 5
    res = simplify_mesh(mesh, target)
    m = res.mesh
    assert m.n_faces <= target + 2  # every collapse removes two faces
    assert m.n_faces >= 0.9 * target
    assert m.is_closed and m.genus == mesh.genus and m.n_components == 1
    # the proxy's vertices are input vertices, unmoved
    np.testing.assert_array_equal(m.vertices, mesh.vertices[res.vertex_parent])
    # and it stays near the input: every input vertex within 3% of the diagonal (the torus,
    # 24 segments around its tube, is the coarsest: 2.7%)
    d = m.closest_points(mesh.vertices).distance
    assert d.max() < 0.03 * mesh.bbox_diagonal
    # no triangle folds over: every face of the proxy keeps a positive area
    assert (m.face_areas > 0).all()


def test_proxy_bad_input():
    mesh = real_mesh("spot")
    with pytest.raises(InputError, match="target_faces"):
        simplify_mesh(mesh, 10)
    with pytest.raises(TopologyError, match="closed"):
        simplify_mesh(plane(6), 40)


@pytest.mark.parametrize("name", ["spot", "torus"])
def test_compact_matches_its_oracle(name):
    mesh = _mesh(name)
    rng = np.random.default_rng(3)
    V = np.ascontiguousarray(mesh.vertices)
    F = np.ascontiguousarray(rng.permutation(mesh.faces), dtype=np.int64)
    kept = rng.permutation(V.shape[0]).astype(np.int64)
    alive = rng.random(len(F)) < 0.6
    for got, want in zip(
        _k.compact(V, F, alive, kept), reference.compact(V, F, alive, kept), strict=True
    ):
        np.testing.assert_array_equal(got, want)


def _store(mesh, tmp_path, brick_faces):
    from meshfit.mesh.store import write_store

    return write_store(mesh, tmp_path / "store", brick_faces=brick_faces)


@pytest.mark.parametrize(
    ("name", "brick_faces"), [("spot", 400), ("kitten", 2000), ("genus 2", 300)]
)
def test_a_proxy_made_brick_by_brick_keeps_topology_and_shape(tmp_path, name, brick_faces):
    from meshfit.shrinkwrap.proxy import simplify_store

    from ..shapes import tori

    mesh = tori(2) if name == "genus 2" else real_mesh(name)
    store = _store(mesh, tmp_path, brick_faces)
    assert store.n_bricks >= 5
    target = mesh.n_faces // 6
    res = simplify_store(store, target, workers=2)
    m = res.mesh
    assert target - 2 <= m.n_faces <= target + 2
    assert m.is_closed and m.genus == mesh.genus and m.n_components == 1
    np.testing.assert_array_equal(m.vertices, mesh.vertices[res.vertex_parent])
    assert (m.face_areas > 0).all()
    # as near the input as the proxy made whole (within a third more)
    whole = simplify_mesh(mesh, target).mesh
    d = m.closest_points(mesh.vertices).distance
    d_whole = whole.closest_points(mesh.vertices).distance
    assert d.max() <= 1.34 * d_whole.max() + 1e-12
    assert d.mean() <= 1.34 * d_whole.mean()


@pytest.mark.parametrize(("name", "brick_faces"), [("kitten", 2000), ("genus 2", 300)])
def test_a_mesh_simplified_by_bricks_is_its_store_simplified(tmp_path, name, brick_faces):
    # the same Morton bricks in memory as in the store, so the same collapses
    from meshfit.shrinkwrap.proxy import simplify_store

    from ..shapes import tori

    mesh = tori(2) if name == "genus 2" else real_mesh(name)
    target = mesh.n_faces // 6
    got = simplify_mesh(mesh, target, workers=2, bricks=True, brick_faces=brick_faces)
    want = simplify_store(_store(mesh, tmp_path, brick_faces), target)
    np.testing.assert_array_equal(got.vertex_parent, want.vertex_parent)
    np.testing.assert_array_equal(got.mesh.faces, want.mesh.faces)
    assert got.mesh.genus == mesh.genus and got.mesh.is_closed
    with pytest.raises(InputError, match="brick_faces"):
        simplify_mesh(mesh, target, bricks=True, brick_faces=0)


@pytest.mark.parametrize("seed", [0, 1])
def test_brick_kernels_match_their_oracles(seed):
    from meshfit.mesh.store import MORTON_BITS

    mesh = real_mesh("kitten")
    rng = np.random.default_rng(seed)
    # a random rigid placement, and a flat box axis (one cell across it)
    V = mesh.vertices @ np.linalg.qr(rng.normal(size=(3, 3)))[0] + rng.normal(size=3)
    F = np.ascontiguousarray(mesh.faces)
    lo, hi = V.min(axis=0), V.max(axis=0)
    scale = (1 << MORTON_BITS) / (hi - lo)
    scale[seed] = 0.0
    codes = _k.face_cells(V, F, lo, scale, MORTON_BITS)
    np.testing.assert_array_equal(codes, reference.face_cells(V, F, lo, scale, MORTON_BITS))
    order = _k.cell_order(codes, 1 << (3 * MORTON_BITS))
    np.testing.assert_array_equal(order, np.argsort(codes, kind="stable"))
    bricks = np.array_split(F[order], 7)
    first = np.full(len(V), -1, dtype=np.int32)
    shared = np.zeros(len(V), dtype=bool)
    areas = [_k.survey_brick(V, b, i, first, shared) for i, b in enumerate(bricks)]
    want_shared, want_areas = reference.survey_bricks(V, bricks, len(V))
    np.testing.assert_array_equal(shared, want_shared)
    np.testing.assert_allclose(areas, want_areas, rtol=1e-12)


def test_a_proxy_of_an_open_scan_keeps_its_boundary(tmp_path):
    from meshfit.shrinkwrap.proxy import simplify_store

    mesh = real_mesh("bunny")
    res = simplify_store(_store(mesh, tmp_path, 3000), mesh.n_faces // 5)
    m = res.mesh
    assert m.genus == mesh.genus and m.n_components == mesh.n_components
    # every boundary edge of the input is one of the proxy's, and no other

    def boundary(faces, parent):
        e = np.sort(parent[faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)], axis=1)
        u, c = np.unique(e, axis=0, return_counts=True)
        return {tuple(x) for x in u[c == 1]}

    assert boundary(m.faces, res.vertex_parent) == boundary(mesh.faces, np.arange(mesh.n_vertices))


def test_a_proxy_from_the_store_refuses_bad_targets(tmp_path):
    from meshfit.shrinkwrap.proxy import simplify_store

    store = _store(torus(12, 8), tmp_path, 50)
    with pytest.raises(InputError, match="target_faces"):
        simplify_store(store, 10)
