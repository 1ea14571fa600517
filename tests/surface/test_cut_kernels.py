"""Kernels of the mesh cut (`meshfit._kernels.cut`) against plain Python."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from meshfit._kernels import cut as kc
from meshfit.errors import CutError
from meshfit.layout import load_layout
from meshfit.surface.cut import cut_mesh, cut_mesh_network
from meshfit.types import SurfacePoints
from tests.conftest import real_mesh
from tests.reference import cut as reference

LAYOUTS = Path(__file__).resolve().parents[2] / "examples" / "layouts"


def _face_table(S, FL, P, f):
    off, mask = FL[f, 0], FL[f, 1]
    return [int(t) for t in P[off : off + mask + 1] if t >= 0]


@pytest.mark.parametrize("seed", range(6))
def test_face_table_iterates_as_a_python_set(seed):
    """A face's triangle table visits its triangles in the order a ``set`` grown by ``add``
    (and by ``discard`` then ``add`` of the same element) iterates them."""
    rng = np.random.default_rng(seed)
    nf0 = 50
    F0 = np.zeros((nf0, 3), dtype=np.int64)
    S, _, FL, _, _, _, _, P = kc.new_state(F0, 3, 16, 16)
    sets: dict[int, set[int]] = {}
    next_t = nf0 + int(rng.integers(0, 100_000))
    for _ in range(3000):
        f = int(rng.integers(0, nf0))
        s = sets.setdefault(f, set())
        if s and rng.random() < 0.3:  # a triangle re-registered: out and back in
            t = list(s)[int(rng.integers(0, len(s)))]
            s.discard(t)
            s.add(t)
            continue
        t = f if f not in s and rng.random() < 0.05 else next_t
        if t in s:
            continue
        if t == next_t:
            next_t += int(rng.integers(1, 5))
        s.add(t)
        kc._face_add(S, FL, P, f, t)
    assert S[kc.ERR] == 0
    for f, s in sets.items():
        assert _face_table(S, FL, P, f) == list(s)


def test_split_faces_keeps_uncut_fans():
    """Two triangles sharing a cut edge: the edge's ends get a copy each; no cut, no copy."""
    faces = np.array([[0, 1, 2], [2, 1, 3]], dtype=np.int64)
    out, copy_of = kc.split_faces(faces, 4, np.zeros((0, 2), dtype=np.int64))
    np.testing.assert_array_equal(out, faces)
    np.testing.assert_array_equal(copy_of, np.arange(4))
    out, copy_of = kc.split_faces(faces, 4, np.array([[1, 2]], dtype=np.int64))
    np.testing.assert_array_equal(out, [[0, 1, 2], [5, 4, 3]])
    np.testing.assert_array_equal(copy_of, [0, 1, 2, 3, 1, 2])


def _drop_spikes(path, closed):
    stack = []
    for v in path + ([path[0]] if closed else []):
        if len(stack) >= 2 and stack[-2] == v:
            stack.pop()
        else:
            stack.append(v)
    if closed:
        while len(stack) >= 3 and stack[1] == stack[-2]:
            stack = stack[1:-1]
        stack.pop()
    return stack


def _drop_loops(path):
    out, where = [], {}
    for v in path:
        k = where.get(v)
        if k is not None:
            for u in out[k + 1 :]:
                del where[u]
            del out[k + 1 :]
            continue
        where[v] = len(out)
        out.append(v)
    return out


@pytest.mark.parametrize("seed", range(4))
def test_path_cleanups_match_plain_python(seed):
    rng = np.random.default_rng(seed)
    for _ in range(200):
        path = rng.integers(0, 6, size=int(rng.integers(1, 30))).tolist()
        got = kc.drop_loops(np.asarray(path, dtype=np.int64)).tolist()
        assert got == _drop_loops(path)
        for closed in (False, True):
            got = kc.drop_spikes(np.asarray(path, dtype=np.int64), closed).tolist()
            assert got == _drop_spikes(path, closed)


def test_network_cut_with_tiny_initial_arrays_matches_oracle(monkeypatch):
    """The triangle, vertex and edge arrays of the triangulation are grown many times over:
    the cut is unchanged."""
    mesh = real_mesh("spot")
    layout = load_layout(LAYOUTS / "spot.json", mesh, check_topology=False)
    new_state = kc.new_state
    monkeypatch.setattr(kc, "new_state", lambda F0, nv0, cap_v, cap_h: new_state(F0, nv0, 1, 1))
    args = (mesh, list(layout.curves), layout.corners, layout.curve_ends)
    got = cut_mesh_network(*args)
    want = reference.cut_mesh_network(*args)
    np.testing.assert_array_equal(got.mesh.vertices, want.mesh.vertices)
    np.testing.assert_array_equal(got.mesh.faces, want.mesh.faces)
    np.testing.assert_array_equal(got.face_parent, want.face_parent)
    np.testing.assert_array_equal(got.vertex_source.bary, want.vertex_source.bary)
    for a, b in zip(got.curve_vertices, want.curve_vertices, strict=True):
        np.testing.assert_array_equal(a, b)


def test_reserve_keeps_the_face_tables():
    F0 = np.zeros((4, 3), dtype=np.int64)
    state = kc.new_state(F0, 3, 1, 1)
    S, P = state[0], state[7]
    for t in range(4, 40):
        kc._face_add(S, state[2], P, t % 4, t)
    used = int(S[kc.N_POOL])
    before = P[:used].copy()
    S[kc.N_POOL] = P.shape[0] - 10  # as if the pool were nearly full
    grown = kc.reserve(*state, 1, 1)
    assert grown[7].shape[0] > P.shape[0]
    np.testing.assert_array_equal(grown[7][:used], before)


def _vertex_chain(mesh, rng, n_faces):
    """Face points on faces each sharing only a vertex with the one before."""
    indptr, around = mesh.vertex_faces
    fn = mesh.face_neighbors
    faces = [int(rng.integers(0, mesh.n_faces))]
    while len(faces) < n_faces:
        f = faces[-1]
        v = int(mesh.faces[f, rng.integers(0, 3)])
        fan = [int(h) for h in around[indptr[v] : indptr[v + 1]] if h != f and h not in fn[f]]
        if not fan:
            continue
        faces.append(fan[int(rng.integers(0, len(fan)))])
    bary = rng.uniform(0.2, 1.0, size=(n_faces, 3))
    return SurfacePoints(np.asarray(faces), bary / bary.sum(axis=1, keepdims=True))


def _same_or_same_error(new, old, *args, **kwargs):
    """Both results, or (None, None) when both raise the same CutError."""
    try:
        want = old(*args, **kwargs)
    except CutError as exc:
        with pytest.raises(CutError) as got:
            new(*args, **kwargs)
        assert str(got.value) == str(exc)
        return None, None
    return new(*args, **kwargs), want


@pytest.mark.parametrize("seed", range(3))
def test_points_on_faces_sharing_only_a_vertex_match_oracle(seed):
    """Joining points whose faces share only a vertex: across the fan of faces around it
    (network cut) or through the vertex (single cut), as the per-point algorithm does."""
    mesh = real_mesh("spot")
    rng = np.random.default_rng(seed)
    n_cut = 0
    for _ in range(8):
        pts = _vertex_chain(mesh, rng, int(rng.integers(2, 6)))
        corners = pts[np.array([0, len(pts) - 1])]
        ends = np.array([[0, 1]])
        got, want = _same_or_same_error(
            cut_mesh_network, reference.cut_mesh_network, mesh, [pts], corners, ends, split=False
        )
        if got is not None:
            n_cut += 1
            np.testing.assert_array_equal(got.mesh.vertices, want.mesh.vertices)
            np.testing.assert_array_equal(got.mesh.faces, want.mesh.faces)
            np.testing.assert_array_equal(got.curve_vertices[0], want.curve_vertices[0])
            np.testing.assert_array_equal(got.vertex_source.bary, want.vertex_source.bary)
        got, want = _same_or_same_error(cut_mesh, reference.cut_mesh, mesh, pts)
        if got is not None:
            n_cut += 1
            np.testing.assert_array_equal(got.mesh.vertices, want.mesh.vertices)
            np.testing.assert_array_equal(got.mesh.faces, want.mesh.faces)
            np.testing.assert_array_equal(got.path, want.path)
            np.testing.assert_array_equal(got.path_other_side, want.path_other_side)
    assert n_cut >= 8
