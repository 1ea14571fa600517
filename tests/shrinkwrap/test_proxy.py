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
def test_collapse_pass_matches_oracle(name):
    mesh = _mesh(name)
    V = np.ascontiguousarray(mesh.vertices)
    F = np.array(mesh.faces, order="C")
    alive = np.ones(len(F), dtype=bool)
    min_cos = float(np.cos(np.radians(MAX_NORMAL_TURN_DEG)))
    want_F, want_alive, want_n = reference.collapse_pass(
        V, F.copy(), alive.copy(), 400, MAX_VALENCE, min_cos, MIN_QUALITY
    )
    got_n = _k.collapse_pass(V, F, alive, 400, MAX_VALENCE, min_cos, MIN_QUALITY)
    assert got_n == want_n > 0
    np.testing.assert_array_equal(alive, want_alive)
    np.testing.assert_array_equal(F[alive], want_F[want_alive])


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
