import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from meshfit import errors
from meshfit.shrinkwrap import _topo, icosahedron, octahedron
from meshfit.shrinkwrap.subdivision import subdivide_step, zorin_weights


@pytest.mark.parametrize("k", range(3, 11))
def test_zorin_weights_reproduce_linear_functions_on_a_regular_ring(k):
    w = zorin_weights(k)
    t = 2 * np.pi * np.arange(k) / k
    centre = np.array([0.3, -0.2])
    ring = np.stack([np.cos(t), np.sin(t)], axis=1) + centre
    assert_allclose(w, np.roll(w[::-1], 1))  # s_j = s_{k-j}: either orientation
    assert_allclose(0.75 * centre + w @ ring, 0.5 * (centre + ring[0]), atol=1e-14)
    if k >= 4:  # quadratic precision: x^2 at the edge midpoint
        assert_allclose(w @ (ring[:, 0] - 0.3) ** 2, 0.25, atol=1e-14)


def test_zorin_weights_reject_valence_below_three():
    with pytest.raises(errors.InputError, match="valence"):
        zorin_weights(2)


@pytest.mark.parametrize("shape", [octahedron, icosahedron])
def test_modified_butterfly_interpolates_and_keeps_the_symmetry(shape):
    v, f = shape()
    n = len(v)
    vb, _ = subdivide_step(v, f, "butterfly")
    assert_allclose(vb[:n], v)  # interpolating
    r = np.linalg.norm(vb[n:], axis=1)
    assert np.ptp(r) < 1e-12  # every edge is alike under the polyhedron's symmetry
    # the rule at an extraordinary vertex, both ends alike: the mean of the two stencils
    edges, _ = _topo.unique_edges(f)
    a, b = edges[0]
    k = int((edges == a).sum())
    w = zorin_weights(k)
    e = []
    for p, q in ((a, b), (b, a)):
        rows, cols = np.nonzero(f == p)
        nxt = {f[r_, (c + 1) % 3]: f[r_, (c + 2) % 3] for r_, c in zip(rows, cols, strict=True)}
        ring = [q]
        for _ in range(k - 1):
            ring.append(nxt[ring[-1]])
        e.append(0.75 * v[p] + w @ v[ring])
    assert_allclose(vb[n], 0.5 * (e[0] + e[1]), atol=1e-14)


def test_modified_butterfly_is_affine_invariant_on_an_irregular_mesh(rng):
    v, f = icosahedron()
    v, f = subdivide_step(v, f, "butterfly")  # valence 5 and 6
    v = v + 0.05 * rng.normal(size=v.shape)
    rot = Rotation.random(random_state=1)
    out, _ = subdivide_step(v, f, "butterfly")
    moved, _ = subdivide_step(2.0 * rot.apply(v) + [1.0, 2.0, 3.0], f, "butterfly")
    assert_allclose(moved, 2.0 * rot.apply(out) + [1.0, 2.0, 3.0], atol=1e-12)


def test_modified_butterfly_keeps_the_8_point_stencil_between_regular_vertices():
    v, f = icosahedron()
    v, f = subdivide_step(v, f, "loop")
    n = len(v)
    out, _ = subdivide_step(v, f, "butterfly")
    edges, _ = _topo.unique_edges(f)
    val = np.bincount(edges.reshape(-1), minlength=n)
    regular = np.flatnonzero((val[edges] == 6).all(axis=1))
    assert len(regular) > 0
    fn = _topo.face_neighbors(f)
    for e in regular[:20]:
        a, b = edges[e]
        fa = [i for i in range(len(f)) if a in f[i] and b in f[i]]
        c, d = ((set(f[i]) - {a, b}).pop() for i in fa)
        wings = []
        for i in fa:
            for j in range(3):
                g = f[fn[i, j]]
                if {a, b} <= set(g):
                    continue
                wings += list(set(g) - set(f[i]))
        exp = 0.5 * (v[a] + v[b]) + 0.125 * (v[c] + v[d]) - 0.0625 * v[wings].sum(axis=0)
        assert len(wings) == 4
        assert_allclose(out[n + e], exp, atol=1e-14)
