"""A mesh store's faces sorted into the patches of a layout (meshfit.layout.outofcore)."""

from __future__ import annotations

import numpy as np
import pytest

from meshfit.errors import InputError
from meshfit.layout import extract_patches
from meshfit.layout.auto import auto_layout
from meshfit.layout.outofcore import _boundary_samples, assign_faces, open_patch_store
from meshfit.mesh.store import write_store
from meshfit.shrinkwrap.proxy import simplify_store

from ..conftest import real_mesh
from ..shapes import tori


@pytest.fixture(scope="module")
def spot_cut(tmp_path_factory):
    """spot in a store of several bricks, laid out and cut as it is (the proxy is the mesh)."""
    mesh = real_mesh("spot")
    store = write_store(mesh, tmp_path_factory.mktemp("s") / "store", brick_faces=800)
    patches = extract_patches(mesh, auto_layout(mesh))
    return mesh, store, patches


def test_each_face_is_core_once_and_its_pieces_are_in_reach(spot_cut, tmp_path):
    mesh, store, patches = spot_cut
    ps = assign_faces(store, patches, tmp_path / "p")
    n = ps.n_patches
    assert n == len(patches) and ps.halo > 0
    core_of = np.full(store.n_faces, -1)
    rows = {f: set() for f in range(store.n_faces)}
    for p in range(n):
        a, b = ps.patch_start[p], ps.patch_start[p + 1]
        sf, core = ps.store_face[a:b], ps.core[a:b]
        # core rows first, then halo rows
        assert not (np.diff(core.astype(int)) > 0).any()
        assert (core_of[sf[core]] == -1).all()
        core_of[sf[core]] = p
        for f in sf:
            rows[int(f)].add(p)
        piece = ps.piece(p, store.vertices)
        np.testing.assert_array_equal(piece.vertex_ids[piece.mesh.faces], store.faces[sf])
    assert (core_of >= 0).all()
    # a face the layout's curves cut lies in pieces of several patches: its core patch is
    # one of them, and every one of them has it (core or halo)
    pieces = {}
    input_face = np.asarray(store.input_face)
    stored = np.empty(mesh.n_faces, dtype=np.int64)
    stored[input_face] = np.arange(store.n_faces)
    for p in patches:
        for f in np.unique(p.face_parent):
            pieces.setdefault(int(stored[f]), set()).add(p.index)
    cut = [f for f, s in pieces.items() if len(s) > 1]
    assert len(cut) > 100
    for f, s in pieces.items():
        assert core_of[f] in s
        assert s <= rows[f], f


def test_the_halo_holds_every_face_a_brute_force_search_finds(spot_cut, tmp_path):
    from meshfit.layout.outofcore import _proxy_edge

    mesh, store, patches = spot_cut
    width = 2.5 * mesh.mean_edge_length  # wide: many centroids by corners meet 48 samples
    ps = assign_faces(store, patches, tmp_path / "p", halo=width, workers=2)
    samples, label = _boundary_samples(patches, width / 3)
    got = {}
    core = np.empty(store.n_faces, dtype=np.int64)
    for p in range(ps.n_patches):
        a, b = ps.patch_start[p], ps.patch_start[p + 1]
        core[ps.store_face[a:b][ps.core[a:b]]] = p
        for f, c in zip(ps.store_face[a:b], ps.core[a:b], strict=True):
            if not c:
                got.setdefault(int(f), set()).add(p)
    x = np.asarray(store.vertices)[np.asarray(store.faces)]
    c = x.mean(axis=1)
    reach = width + np.linalg.norm(x - c[:, None], axis=2).max(axis=1)
    # (a face takes its proxy piece's halo patches: those within the halo, a proxy edge
    # and the piece's reach of the piece)
    bound = width + 4 * _proxy_edge(patches)
    rng = np.random.default_rng(0)
    for f in rng.choice(store.n_faces, 1500, replace=False):
        d = np.linalg.norm(samples - c[f], axis=1)
        want = set(label[d <= reach[f]].tolist()) - {int(core[f])}
        have = got.get(int(f), set())
        assert want <= have, f
        for q in have:
            assert d[label == q].min() <= bound


def test_bad_calls_are_refused(spot_cut, tmp_path):
    _, store, patches = spot_cut
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("keep")
    with pytest.raises(InputError, match="not an empty folder"):
        assign_faces(store, patches, tmp_path / "full")
    with pytest.raises(InputError, match="in its order"):
        assign_faces(store, patches[::-1], tmp_path / "p")
    with pytest.raises(InputError, match="halo"):
        assign_faces(store, patches, tmp_path / "p", halo=-1.0)
    assert not (tmp_path / "p").exists()
    with pytest.raises(InputError, match="not a patch store"):
        open_patch_store(tmp_path)


def _cut_all(store, ps, layout, proxy, relax_iterations=None):
    from meshfit.layout.outofcore import carry_network, cut_patch

    net = carry_network(store, ps, proxy, layout, relax_iterations)
    return [cut_patch(store, ps, layout, net, p) for p in range(layout.n_patches)]


def test_cut_from_the_store_is_the_cut_in_memory(spot_cut, tmp_path):
    # with the mesh as its own proxy, the carried curves are the layout's: each patch cut
    # from its piece is the patch cut from the whole mesh (the same faces of the input, the
    # same area to round-off, the same corners)
    mesh, store, patches = spot_cut
    layout = auto_layout(mesh)
    ps = assign_faces(store, patches, tmp_path / "p")
    got = _cut_all(store, ps, layout, mesh, relax_iterations=0)  # (nothing to correct)
    input_face = np.asarray(store.input_face)
    for want, q in zip(patches, got, strict=True):
        assert q.index == want.index
        assert set(input_face[q.face_parent].tolist()) == set(want.face_parent.tolist())
        np.testing.assert_allclose(q.mesh.face_areas.sum(), want.mesh.face_areas.sum(), rtol=1e-9)
        np.testing.assert_allclose(
            q.mesh.vertices[q.corners], want.mesh.vertices[want.corners], atol=1e-12
        )
        for s in range(4):
            length = [np.linalg.norm(np.diff(m.vertices[m_s], axis=0), axis=1).sum()
                      for m, m_s in ((q.mesh, q.sides[s]), (want.mesh, want.sides[s]))]  # fmt: skip
            np.testing.assert_allclose(length[0], length[1], rtol=1e-9)


def _covers_once(mesh, store, got):
    """Every input face is covered by the patches' pieces of it exactly once (by area)."""
    input_face = np.asarray(store.input_face)
    cover = np.zeros(mesh.n_faces)
    for q in got:
        assert q.mesh.n_components == 1 and len(q.mesh.boundary_loops) == 1
        assert q.mesh.euler_characteristic == 1
        np.add.at(cover, input_face[q.face_parent], q.mesh.face_areas)
    np.testing.assert_allclose(cover, mesh.face_areas, rtol=1e-6)


@pytest.mark.parametrize(
    "name",
    [
        "genus 2",
        pytest.param(
            "nefertiti",
            marks=pytest.mark.xfail(
                strict=True,
                reason="two carried curves that leave a corner of the proxy's layout at 7 "
                "degrees come within a scan edge and touch (no retry after the carry yet; "
                "the fine relaxation keeps each curve's ends)",
            ),
        ),
    ],
)
def test_a_scan_is_cut_along_its_proxy_layout(tmp_path, name):
    from meshfit.layout.auto import LayoutOptions

    if name == "genus 2":
        mesh, brick, share, opts = tori(2), 1500, 4, LayoutOptions()
    else:
        # (a proxy's creases are not the scan's: the sphere route, as the scan takes)
        mesh, brick, share, opts = real_mesh(name), 20_000, 8, LayoutOptions(crease_angle=None)
    store = write_store(mesh, tmp_path / "s", brick_faces=brick)
    proxy = simplify_store(store, mesh.n_faces // share).mesh
    layout = auto_layout(proxy, opts)
    cut_proxy = extract_patches(proxy, layout)
    ps = assign_faces(store, cut_proxy, tmp_path / "p")
    assert ps.n_patches == len(cut_proxy) and int(ps.core.sum()) == store.n_faces
    # a patch's core faces of the scan cover about its area on the proxy
    for p in cut_proxy:
        piece = ps.piece(p.index, store.vertices)
        area = piece.mesh.face_areas[piece.core].sum()
        assert abs(area - p.mesh.face_areas.sum()) < 0.25 * p.mesh.face_areas.sum()
    np.testing.assert_array_equal(open_patch_store(tmp_path / "p").faces, ps.faces)
    got = _cut_all(store, ps, layout, proxy)
    _covers_once(mesh, store, got)
    # the two sides of a curve are cut along the same line of the scan (a side may hold
    # points of the other's straight stretches as vertices of its own; and a piece's four
    # curves are cut in one after another, the later ones into the earlier ones' split
    # faces, so beside different neighbours a curve may lie some millionths of the
    # diagonal apart by a corner)
    for k in range(len(layout.curves)):
        on = [
            (p, s)
            for p in range(layout.n_patches)
            for s in range(4)
            if layout.patch_curves[p, s] == k
        ]
        if len(on) == 2:
            (p, s), (q, t) = on
            a = got[p].mesh.vertices[got[p].sides[s]]
            b = got[q].mesh.vertices[got[q].sides[t]][::-1]
            np.testing.assert_array_equal(a[[0, -1]], b[[0, -1]])
            gap = 1e-5 * mesh.bbox_diagonal
            assert _off(a, b).max() <= gap and _off(b, a).max() <= gap


def _off(x, line):
    """Distance of each point of ``x`` from the polyline ``line``."""
    a, b = line[:-1], line[1:]
    ab = b - a
    t = np.einsum("pkj,kj->pk", x[:, None] - a[None], ab) / np.maximum((ab * ab).sum(1), 1e-300)
    foot = a[None] + np.clip(t, 0, 1)[..., None] * ab[None]
    return np.linalg.norm(x[:, None] - foot, axis=2).min(axis=1)
