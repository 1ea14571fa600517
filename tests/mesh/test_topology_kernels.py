"""Connectivity kernels against their slow references: boundary-loop tracing on real scans
cut open and on random half-edge sets with pinches and dead ends; the edge table and the
connected components on real scans, on non-manifold soups and on a vertex of high valence."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from meshfit._kernels import topology as kernel
from meshfit.mesh import topology

from ..conftest import real_mesh
from ..reference import topology as ref


def _same(got, want):
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)


def _kernel_loops(t, h):
    out, starts = kernel.trace_loops(t, h, int(max(t.max(), h.max())) + 1)
    return [out[a:b] for a, b in itertools.pairwise(starts)]


@pytest.mark.parametrize("name", ["spot", "bunny"])
def test_loops_of_real_meshes_with_holes(name, rng):
    mesh = real_mesh(name)
    # punch holes: drop random faces (some sharing vertices: pinched boundaries)
    faces = mesh.faces[rng.random(mesh.n_faces) > 0.02]
    table = topology.edge_table(faces, mesh.n_vertices)
    loops = topology.boundary_loops(faces, table)
    assert len(loops) > 10
    bnd = np.flatnonzero(table.edge_count == 1)
    he = table.order[table.start[bnd]]
    tail, head = topology.halfedges(faces)
    _same(loops, ref.trace_loops(tail[he], head[he]))


def test_random_half_edge_sets(rng):
    for _ in range(50):
        k = int(rng.integers(1, 40))
        t = rng.integers(0, 12, k)
        h = rng.integers(0, 12, k)
        _same(_kernel_loops(t, h), ref.trace_loops(t, h))


def _same_table(faces, nv):
    got = topology.edge_table(faces, nv)
    want = ref.edge_table(faces, nv)
    names = ("edges", "halfedge_edge", "edge_count", "order", "start")
    for name, w in zip(names, want, strict=True):
        g = getattr(got, name)
        assert g.dtype == np.int64, name
        np.testing.assert_array_equal(g, w, err_msg=name)


@pytest.mark.parametrize("name", ["spot", "bunny", "igea"])
def test_edge_table_of_real_meshes(name, rng):
    mesh = real_mesh(name)
    _same_table(mesh.faces, mesh.n_vertices)
    # shuffled faces and a cut-open copy change the order the half-edges arrive in
    _same_table(mesh.faces[rng.permutation(mesh.n_faces)], mesh.n_vertices)
    _same_table(mesh.faces[rng.random(mesh.n_faces) > 0.1], mesh.n_vertices)


def test_edge_table_of_soups_and_fans(rng):
    for _ in range(30):
        nv = int(rng.integers(3, 15))
        faces = rng.integers(0, nv, (int(rng.integers(1, 60)), 3))  # repeats, fins, non-manifold
        _same_table(faces, nv)
    # one vertex in 500 faces: its bucket is merge-sorted, not insertion-sorted
    ring = rng.permutation(500) + 1
    fan = np.stack([np.zeros(500, np.int64), ring, np.roll(ring, -1)], axis=1)
    assert (fan[:, 0] == 0).sum() > kernel._SMALL_BUCKET
    _same_table(fan, 501)
    _same_table(np.zeros((0, 3), np.int64), 4)


def test_components_match_scipy(rng):
    for _ in range(30):
        n = int(rng.integers(1, 80))
        k = int(rng.integers(0, 2 * n))
        a, b = rng.integers(0, n, k), rng.integers(0, n, k)
        count, labels = kernel.components(n, a, b)
        want_count, want = ref.components(n, a, b)
        assert count == want_count
        np.testing.assert_array_equal(labels, want)
        # rows of neighbours (-1 for none, not necessarily symmetric)
        nbr = rng.integers(-n, n, (n, 3))
        count, labels = kernel.neighbor_components(nbr)
        rows = np.repeat(np.arange(n), 3)
        keep = nbr.reshape(-1) >= 0
        want_count, want = ref.components(n, rows[keep], nbr.reshape(-1)[keep])
        assert count == want_count
        np.testing.assert_array_equal(labels, want)


@pytest.mark.parametrize("name", ["spot", "bunny"])
def test_fans_and_face_components_of_real_meshes(name, rng):
    mesh = real_mesh(name)
    faces = mesh.faces[rng.random(mesh.n_faces) > 0.05]  # pinched vertices: several fans
    table = topology.edge_table(faces, mesh.n_vertices)
    fan, n_fans = topology.corner_fans(faces, mesh.n_vertices, table)
    assert n_fans > mesh.n_vertices * 0.9
    nbr = topology.face_neighbors(faces, table)
    n, labels = topology.face_components(faces.shape[0], nbr)
    f = np.repeat(np.arange(faces.shape[0]), 3)
    g = nbr.reshape(-1)
    want_n, want = ref.components(faces.shape[0], f[g >= 0], g[g >= 0])
    assert n == want_n > 1
    np.testing.assert_array_equal(labels, want)
    # every fan is one vertex's corners joined across shared edges (checked by scipy on the
    # same corner graph the fans are built from)
    fan_vertex = np.full(n_fans, -1)
    fan_vertex[fan] = faces.reshape(-1)
    assert (fan_vertex[fan] == faces.reshape(-1)).all()


@pytest.mark.parametrize("name", ["spot", "bunny"])
def test_vertex_face_components_match_scipy(name, rng):
    mesh = real_mesh(name)
    # strips of faces (every other band across x, with holes) and two triangles of new
    # vertices that share only a vertex (one component through it)
    x = mesh.vertices[mesh.faces].mean(axis=1)[:, 0]
    band = np.floor((x - x.min()) / (0.05 * mesh.bbox_diagonal)).astype(int)
    keep = (band % 2 == 0) & (rng.random(mesh.n_faces) > 0.1)
    n0 = mesh.n_vertices
    bowtie = np.array([[n0, n0 + 1, n0 + 2], [n0, n0 + 3, n0 + 4]])
    faces = np.concatenate([mesh.faces[keep], bowtie])
    nf, nv = faces.shape[0], n0 + 5
    count, labels = kernel.vertex_face_components(faces, nv)
    # faces and vertices as one graph, each face joined to its three vertices
    _, both = ref.components(nf + nv, np.repeat(np.arange(nf), 3), nf + faces.reshape(-1))
    _, first, inverse = np.unique(both[:nf], return_index=True, return_inverse=True)
    rank = np.argsort(np.argsort(first))  # numbered in order of each one's first face
    assert count == first.size > 5
    np.testing.assert_array_equal(labels, rank[inverse.reshape(-1)])
    # on the whole (manifold) mesh they are its edge-connected components
    count, labels = kernel.vertex_face_components(mesh.faces, nv)
    assert count == mesh.n_components
    np.testing.assert_array_equal(labels, mesh.face_components)


def _stars_cases(rng):
    """Real scans, a scan with faces dropped and its vertices shuffled (unused vertices,
    holes), non-manifold soups and a fan of high valence."""
    for name in ("spot", "bunny"):
        mesh = real_mesh(name)
        yield mesh.faces, mesh.n_vertices
        perm = rng.permutation(mesh.n_vertices)
        yield perm[mesh.faces[rng.random(mesh.n_faces) > 0.1]], mesh.n_vertices + 3
    for _ in range(20):
        nv = int(rng.integers(3, 30))
        faces = np.array(
            [rng.choice(nv, 3, replace=False) for _ in range(int(rng.integers(1, 60)))]
        )
        yield faces.astype(np.int64), nv
    k = 200
    yield np.array([[0, i, i + 1] for i in range(1, k)], dtype=np.int64), k + 1


def test_vertex_faces_and_adjacency_match_references(rng):
    for faces, nv in _stars_cases(rng):
        faces = np.ascontiguousarray(faces, dtype=np.int64)
        _same(kernel.vertex_faces(faces, nv), ref.vertex_faces(faces, nv))
        edges = topology.edge_table(faces, nv).edges
        _same(kernel.vertex_adjacency(edges, nv), ref.vertex_adjacency(edges, nv))


def test_lengths_of_some_edges_match_all_lengths(rng):
    mesh = real_mesh("spot")
    pick = rng.choice(mesh.edges.shape[0], 500, replace=False)
    fresh = type(mesh)(mesh.vertices, mesh.faces)
    got = fresh.lengths_of(pick)
    assert "edge_lengths" not in vars(fresh)  # (not made for all edges)
    np.testing.assert_array_equal(got, mesh.edge_lengths[pick])
    np.testing.assert_array_equal(mesh.lengths_of(pick), got)  # (read from the cache)


def test_faces_around_keeps_only_the_alive_faces(rng):
    mesh = real_mesh("spot")
    faces = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    alive = rng.random(len(faces)) < 0.7
    got = kernel.faces_around(faces, alive, mesh.n_vertices)
    want = ref.vertex_faces(faces, mesh.n_vertices, alive)
    _same(got, want)


def test_star_builders_refuse_bad_indices():
    from meshfit.errors import InputError

    faces = np.array([[0, 1, 2], [0, 2, 3]])
    with pytest.raises(InputError, match=r"faces: an index is outside 0\.\.2"):
        topology.vertex_faces(faces, 3)
    with pytest.raises(InputError, match="shape"):
        topology.vertex_faces(faces[:, :2], 4)
    with pytest.raises(InputError, match="edges: an index is outside"):
        topology.vertex_adjacency(np.array([[0, -1]]), 3)
    indptr, around = topology.vertex_faces(faces, 4)
    np.testing.assert_array_equal(indptr, [0, 2, 3, 5, 6])
    np.testing.assert_array_equal(around, [0, 1, 0, 0, 1, 1])
