"""Graph paths: greedy (with A* fallback), A*, restricted Dijkstra, sampling into face points."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from meshfit.errors import InputError, PathError
from meshfit.mesh import Mesh
from meshfit.surface import (
    GREEDY_ASTAR_WEIGHT,
    astar_path,
    greedy_path,
    path_to_surface_points,
    shortest_path,
)
from tests.conftest import REAL, analytic_mesh, real_mesh
from tests.reference import paths as reference

SMALL = ("spot", "nefertiti_fraunhofer")


def are_edges(mesh: Mesh, a, b) -> np.ndarray:
    """(k,) bool: whether each vertex pair (a[i], b[i]) is an edge of the mesh."""
    n = mesh.n_vertices
    keys = mesh.edges[:, 0] * n + mesh.edges[:, 1]
    q = np.minimum(a, b) * n + np.maximum(a, b)
    i = np.minimum(np.searchsorted(keys, q), keys.size - 1)
    return keys[i] == q


def assert_edge_chain(mesh: Mesh, path, source: int, target: int) -> None:
    path = np.asarray(path)
    assert path.dtype == np.int64
    assert path[0] == source and path[-1] == target
    assert len(set(path.tolist())) == path.size, "a vertex repeats"
    ok = are_edges(mesh, path[:-1], path[1:])
    assert ok.all(), f"{path[:-1][~ok][0]} - {path[1:][~ok][0]} is not an edge"


def random_pairs(mesh: Mesh, n: int, rng: np.random.Generator) -> list[tuple[int, int]]:
    comp = mesh.vertex_components
    pairs = []
    while len(pairs) < n:
        a, b = rng.integers(0, mesh.n_vertices, 2)
        if comp[a] == comp[b]:
            pairs.append((int(a), int(b)))
    return pairs


def u_shape(n: int = 12) -> Mesh:
    """A flat U (horseshoe): a square grid with a notch cut from the middle of the top."""
    h = 1.0 / n
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    xy = np.stack(
        np.meshgrid(np.arange(n + 1) * h, np.arange(n + 1) * h, indexing="ij"), axis=-1
    ).reshape(-1, 2)
    faces = []
    for i in range(n):
        for j in range(n):
            if n // 3 <= i < n - n // 3 and j >= n // 4:  # the notch
                continue
            a, b, c, d = idx[i, j], idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]
            faces += [(a, b, c), (a, c, d)]
    faces = np.asarray(faces)
    used = np.unique(faces)
    remap = np.full(idx.size, -1)
    remap[used] = np.arange(used.size)
    verts = np.concatenate([xy[used], np.zeros((used.size, 1))], axis=1)
    return Mesh(verts, remap[faces], name="u_shape")


def two_spheres() -> Mesh:
    a = analytic_mesh("icosphere")
    v = np.concatenate([a.vertices, a.vertices + np.array([5.0, 0.0, 0.0])])
    f = np.concatenate([a.faces, a.faces + a.n_vertices])
    return Mesh(v, f, name="two_spheres")


# ------------------------------------------------------------------------ greedy / A*
@pytest.mark.parametrize("name", REAL)
def test_greedy_and_astar_connect_random_pairs(name, rng):
    mesh = real_mesh(name)
    for s, t in random_pairs(mesh, 12, rng):
        g = greedy_path(mesh, s, t)
        assert_edge_chain(mesh, g.vertices, s, t)
        a = astar_path(mesh, s, t)
        assert_edge_chain(mesh, a.vertices, s, t)
        want = np.linalg.norm(np.diff(mesh.vertices[g.vertices], axis=0), axis=1).sum()
        assert_allclose(g.length, want, rtol=1e-12)
        assert g.length >= a.length * (1 - 1e-12)  # A* is shortest


@pytest.mark.parametrize("name", REAL)
def test_astar_length_equals_dijkstra(name, rng):
    mesh = real_mesh(name)
    pairs = random_pairs(mesh, 6, rng)
    for s, t in pairs:
        want = shortest_path(mesh, s, t)
        got = astar_path(mesh, s, t)
        assert_allclose(got.length, want.lengths[0], rtol=1e-12)
        assert_allclose(got.length, want.distance[t], rtol=1e-12)


@pytest.mark.parametrize("name", SMALL)
def test_paths_match_reference_dijkstra(name, rng):
    mesh = real_mesh(name)
    s = int(rng.integers(mesh.n_vertices))
    dist, _ = reference.dijkstra(mesh, [s])
    got = shortest_path(mesh, s)
    reached = np.array(sorted(dist))
    assert_allclose(got.distance[reached], [dist[v] for v in reached], rtol=1e-12)
    assert np.isinf(np.delete(got.distance, reached)).all()
    for t in rng.choice(reached, 5, replace=False).tolist():
        a = astar_path(mesh, s, t)
        assert_allclose(a.length, dist[t], rtol=1e-12)
        p = got.path_to(t)
        assert_edge_chain(mesh, p, s, t)
        assert_allclose(
            np.linalg.norm(np.diff(mesh.vertices[p], axis=0), axis=1).sum(), dist[t], rtol=1e-12
        )


@pytest.mark.parametrize("name", SMALL)
def test_greedy_matches_reference_descent(name, rng):
    mesh = real_mesh(name)
    n_stalls = 0
    for s, t in random_pairs(mesh, 15, rng):
        want, stalled = reference.greedy_descent(mesh, s, t)
        got = greedy_path(mesh, s, t)
        assert got.used_fallback == stalled
        if stalled:
            n_stalls += 1
            # the greedy walk to the stall, then weighted A* from there, with loops erased
            tail = reference.weighted_astar(mesh, want[-1], t, GREEDY_ASTAR_WEIGHT)
            assert got.vertices.tolist() == reference.erase_loops(want[:-1] + tail)
            # the finish is at most the weight times the shortest path from the stall
            shortest = astar_path(mesh, want[-1], t).length
            tail_length = np.linalg.norm(np.diff(mesh.vertices[tail], axis=0), axis=1).sum()
            assert shortest <= tail_length <= GREEDY_ASTAR_WEIGHT * shortest * (1 + 1e-12)
            with pytest.raises(PathError, match=f"stalls at vertex {want[-1]}"):
                greedy_path(mesh, s, t, fallback=False)
        else:
            assert got.vertices.tolist() == want


def test_greedy_falls_back_in_u_shape():
    mesh = u_shape()
    # from the top of the left arm to the top of the right arm: greedy descends into the notch
    top = mesh.vertices[:, 1].max()
    left = int(np.flatnonzero(mesh.vertices[:, 1] == top)[0])
    right = int(np.flatnonzero(mesh.vertices[:, 1] == top)[-1])
    assert mesh.vertices[left, 0] < 0.3 and mesh.vertices[right, 0] > 0.7
    _, stalled = reference.greedy_descent(mesh, left, right)
    assert stalled
    with pytest.raises(PathError, match=f"from vertex {left} to vertex {right} stalls"):
        greedy_path(mesh, left, right, fallback=False)
    g = greedy_path(mesh, left, right)
    assert g.used_fallback
    assert_edge_chain(mesh, g.vertices, left, right)
    # the path goes around the notch: down below its bottom
    assert mesh.vertices[g.vertices, 1].min() < 0.25 + 1e-12
    dist, _ = reference.dijkstra(mesh, [left])
    assert g.length >= dist[right] * (1 - 1e-12)
    assert_allclose(astar_path(mesh, left, right).length, dist[right], rtol=1e-12)


def test_greedy_falls_back_on_real_scan(rng):
    # bunny's ears and concave face make greedy descent stall for some pairs; all still connect
    mesh = real_mesh("bunny")
    used = 0
    for s, t in random_pairs(mesh, 40, rng):
        g = greedy_path(mesh, s, t)
        used += g.used_fallback
        assert_edge_chain(mesh, g.vertices, s, t)
    assert used > 0


def test_greedy_same_vertex():
    mesh = analytic_mesh("icosphere")
    g = greedy_path(mesh, 7, 7)
    assert g.vertices.tolist() == [7] and g.length == 0.0 and not g.used_fallback
    assert astar_path(mesh, 7, 7).vertices.tolist() == [7]


def test_astar_allowed_vertices():
    mesh = analytic_mesh("plane")
    x = mesh.vertices[:, 0]
    allowed = x <= 0.5 + 1e-9
    s = int(np.argmin(np.linalg.norm(mesh.vertices - [0, 0, 0], axis=1)))
    t = int(np.argmin(np.linalg.norm(mesh.vertices - [0, 1, 0], axis=1)))
    p = astar_path(mesh, s, t, allowed_vertices=allowed)
    assert allowed[p.vertices].all()
    q = astar_path(mesh, s, t, allowed_vertices=np.flatnonzero(allowed))
    assert_allclose(p.length, q.length, rtol=1e-12)
    far = int(np.argmax(x))
    with pytest.raises(PathError, match=f"target vertex {far} is not in allowed_vertices"):
        astar_path(mesh, s, far, allowed_vertices=allowed)


# --------------------------------------------------------------------------- Dijkstra
def test_restricted_dijkstra_never_leaves_vertex_subset(rng):
    mesh = real_mesh("spot")
    s = int(rng.integers(mesh.n_vertices))
    d = np.linalg.norm(mesh.vertices - mesh.vertices[s], axis=1)
    ball = np.flatnonzero(d < 0.3 * mesh.bbox_diagonal)
    mask = np.zeros(mesh.n_vertices, bool)
    mask[ball] = True
    allowed = {(a, b) for a, b in mesh.edges.tolist() if mask[a] and mask[b]}
    inside = reference.reachable(mesh, s, allowed)
    targets = rng.choice(sorted(inside), 8, replace=False)
    got = shortest_path(mesh, s, targets, vertices=ball)
    dist, _ = reference.dijkstra(mesh, [s], allowed)
    for t, p, length in zip(targets.tolist(), got.paths, got.lengths, strict=True):
        assert mask[p].all()
        assert_edge_chain(mesh, p, s, t)
        assert_allclose(length, dist[t], rtol=1e-12)
    assert np.isinf(got.distance[~mask]).all()
    # the restricted distance is never shorter than the free one
    free = shortest_path(mesh, s, targets)
    assert (got.lengths >= free.lengths * (1 - 1e-12)).all()


def test_restricted_dijkstra_uses_only_edges_of_face_subset(rng):
    mesh = real_mesh("spot")
    centroid = mesh.vertices[mesh.faces].mean(axis=1)
    faces = np.flatnonzero(centroid[:, 1] > np.median(centroid[:, 1]))
    allowed = {
        tuple(sorted(e))
        for f in faces.tolist()
        for e in zip(mesh.faces[f], np.roll(mesh.faces[f], -1), strict=True)
    }
    allowed = {(int(a), int(b)) for a, b in allowed}
    s = int(mesh.faces[faces[0], 0])
    inside = sorted(reference.reachable(mesh, s, allowed))
    targets = rng.choice(inside, 6, replace=False)
    got = shortest_path(mesh, s, targets, faces=faces)
    dist, _ = reference.dijkstra(mesh, [s], allowed)
    for t, p, length in zip(targets.tolist(), got.paths, got.lengths, strict=True):
        for a, b in zip(p[:-1].tolist(), p[1:].tolist(), strict=True):
            assert (min(a, b), max(a, b)) in allowed
        assert_allclose(length, dist[t], rtol=1e-12)


def test_multi_source_distance_is_minimum(rng):
    mesh = real_mesh("spot")
    sources = rng.choice(mesh.n_vertices, 4, replace=False)
    got = shortest_path(mesh, sources)
    each = np.stack([shortest_path(mesh, int(s)).distance for s in sources])
    assert_allclose(got.distance, each.min(axis=0), rtol=1e-12)
    t = int(rng.integers(mesh.n_vertices))
    p = got.path_to(t)
    assert p[0] in sources.tolist() and p[-1] == t
    assert got.nearest_source[t] == p[0]


def test_unreachable_in_subset_raises():
    mesh = analytic_mesh("plane")
    x = mesh.vertices[:, 0]
    allowed = np.flatnonzero((x < 0.3) | (x > 0.7))  # two strips, not connected
    s = int(np.argmin(x))
    t = int(np.argmax(x))
    with pytest.raises(
        PathError, match=f"target vertex {t} is not reachable from source vertex\\(es\\) {s}"
    ):
        shortest_path(mesh, s, t, vertices=allowed)
    with pytest.raises(PathError, match=f"no path from vertex {s} to vertex {t}"):
        astar_path(mesh, s, t, allowed_vertices=allowed)
    with pytest.raises(PathError, match=r"source vertex \d+ is outside the allowed subset"):
        shortest_path(mesh, int(np.flatnonzero((x > 0.4) & (x < 0.6))[0]), t, vertices=allowed)
    with pytest.raises(InputError, match="not both"):
        shortest_path(mesh, s, t, vertices=allowed, faces=[0])


def test_different_components_raise_path_error():
    mesh = two_spheres()
    assert mesh.n_components == 2
    a, b = 3, mesh.n_vertices - 5
    for fn in (greedy_path, astar_path):
        with pytest.raises(PathError, match=f"from vertex {a} to vertex {b}.*different comp"):
            fn(mesh, a, b)
    with pytest.raises(PathError, match=f"target vertex {b} is not reachable .* {a}"):
        shortest_path(mesh, a, b)
    g = greedy_path(mesh, b, b - 40)
    assert_edge_chain(mesh, g.vertices, b, b - 40)


def test_bad_vertex_index_raises_input_error():
    mesh = analytic_mesh("icosphere")
    with pytest.raises(InputError, match="target"):
        greedy_path(mesh, 0, mesh.n_vertices)
    with pytest.raises(InputError, match="sources"):
        shortest_path(mesh, [-1])


# ------------------------------------------------------------------- face-point sampling
@pytest.mark.parametrize("per_edge", [0, 1, 3])
def test_path_to_surface_points(per_edge, rng):
    mesh = real_mesh("spot")
    s, t = random_pairs(mesh, 1, rng)[0]
    path = greedy_path(mesh, s, t).vertices
    pts = path_to_surface_points(mesh, path, per_edge=per_edge)
    k = path.size
    assert len(pts) == k + (k - 1) * per_edge
    xyz = mesh.xyz(pts)
    assert_allclose(xyz[:: per_edge + 1], mesh.vertices[path], atol=0)
    assert_allclose(pts.bary.sum(axis=1), 1.0, atol=1e-15)
    # interior samples are evenly spaced on the edges
    for j in range(1, per_edge + 1):
        want = mesh.vertices[path[:-1]] + j / (per_edge + 1) * np.diff(mesh.vertices[path], axis=0)
        assert_allclose(xyz[j :: per_edge + 1], want, atol=1e-15 * mesh.bbox_diagonal)
    # consecutive points share a face (a point at a vertex is on every face around it)
    indptr, vf = mesh.vertex_faces
    at_vertex = (pts.bary == 1.0).any(axis=1)

    def faces_of(i):
        if at_vertex[i]:
            v = mesh.faces[pts.face[i], np.argmax(pts.bary[i])]
            return set(vf[indptr[v] : indptr[v + 1]].tolist())
        return {int(pts.face[i])}

    for i in range(len(pts) - 1):
        assert faces_of(i) & faces_of(i + 1)


def test_path_to_surface_points_rejects_non_edges():
    mesh = analytic_mesh("icosphere")
    far = int(np.argmin(mesh.vertices @ mesh.vertices[0]))
    with pytest.raises(InputError, match=f"vertices\\[0\\] = 0 and vertices\\[1\\] = {far}"):
        path_to_surface_points(mesh, [0, far])
    assert len(path_to_surface_points(mesh, [5])) == 1


@pytest.mark.parametrize("name", ["icosphere", "torus", "plane", "igea"])
def test_vertex_points_equal_at_vertices(name, rng):
    from meshfit.surface.paths import vertex_points
    from meshfit.types import SurfacePoints

    mesh = real_mesh(name) if name == "igea" else analytic_mesh(name)
    for v in (np.array([7]), rng.integers(0, mesh.n_vertices, 300), np.arange(mesh.n_vertices)):
        got = vertex_points(mesh, v)
        want = SurfacePoints.at_vertices(mesh.faces, v)
        np.testing.assert_array_equal(got.face, want.face)
        np.testing.assert_array_equal(got.bary, want.bary)
    assert len(vertex_points(mesh, np.zeros(0, dtype=np.int64))) == 0
