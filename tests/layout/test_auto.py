"""Automatic layouts of closed genus-0 meshes from the shrink-wrap base mesh."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from meshfit.curves.base import check_sampling, densify_curve
from meshfit.demo import demo_mesh, demo_sphere_map
from meshfit.errors import InputError, LayoutError
from meshfit.layout import extract_patches, layout_from_json, layout_to_json
from meshfit.layout.auto import LayoutOptions, auto_layout, quad_network
from meshfit.shrinkwrap import icosahedron
from meshfit.types import SurfacePoints

from ..conftest import real_mesh
from ..shapes import cube, icosphere, plane, torus


def test_quad_network_of_the_icosahedron():
    v, f = icosahedron()
    pts, ends, quads = quad_network(v, f)
    assert len(quads) == 3 * len(f)
    assert len(pts) == len(v) + 30 + 20  # vertices, edge mid-points, centroids
    assert len(ends) == 2 * 30 + 3 * 20  # half edges and spokes
    np.testing.assert_allclose(np.linalg.norm(pts, axis=1), 1.0)
    # every arc bounds exactly two quads, once in each direction (a closed network)
    uses = {}
    for q in quads:
        for c, rev in q:
            uses.setdefault(c, []).append(rev)
    assert all(sorted(r) == [False, True] for r in uses.values())


@pytest.mark.parametrize("name", ["spot"])  # nefertiti and igea: tests/test_pipeline.py
def test_auto_layout_on_real_scans(name):
    mesh = real_mesh(name)
    layout = auto_layout(mesh)
    assert layout.n_patches == 60
    for c in layout.curves:
        assert len(check_sampling(mesh, c)) == 0
    patches = extract_patches(mesh, layout)
    assert len(patches) == 60
    area = sum(p.mesh.face_areas.sum() for p in patches)
    np.testing.assert_allclose(area, mesh.face_areas.sum(), rtol=1e-9)
    # a layout made automatically is an ordinary one: it survives its JSON
    again = layout_from_json(layout_to_json(layout))
    assert again.n_patches == layout.n_patches


@pytest.mark.parametrize("patches", [24, 36])
def test_fewer_than_sixty_patches_from_an_octahedron(patches):
    # bases of fewer than 20 triangles start from the octahedron (8): 24 patches and up
    # (protrusions=False: spot's horns would send a base this coarse to the region route)
    mesh = real_mesh("spot")
    layout = auto_layout(mesh, LayoutOptions(patches=patches, protrusions=False))
    assert layout.n_patches == patches
    ps = extract_patches(mesh, layout)
    np.testing.assert_allclose(sum(p.mesh.area for p in ps), mesh.area, rtol=1e-9)
    valence = np.bincount(layout.curve_ends.ravel())
    if patches == 24:
        # the octahedron's 6 vertices and 12 edge mid-points meet 4 patches, the centroids 3
        assert sorted(np.bincount(valence)[3:].tolist()) == [8, 18]
        assert (valence >= 3).all() and np.bincount(valence)[4] == 18


def test_more_patches_than_the_mesh_has_faces_for_are_refused_at_once():
    # spot (5,856 faces) may ask for 366 patches (122 base triangles) at 16 faces a patch
    mesh = real_mesh("spot")
    with pytest.raises(InputError, match=r"1000 patches .* ask for at most 366 patches"):
        auto_layout(mesh, LayoutOptions(patches=1000))
    with pytest.raises(InputError, match="at most 366"):
        # 124 base triangles, 372 patches: one pair too many
        auto_layout(mesh, LayoutOptions(patches=372))
    # a mesh too coarse for the fewest patches of the sphere route: asked, it is refused;
    # by default the region route lays out as many as the faces allow
    small = icosphere(2)  # 320 faces: 20 patches at most
    with pytest.raises(InputError, match="makes at least 24: give a layout file"):
        auto_layout(small, LayoutOptions(patches=24))
    layout = auto_layout(small)
    assert 4 <= layout.n_patches and len(extract_patches(small, layout)) == layout.n_patches


def test_fewest_patches():
    mesh = demo_mesh(6000)
    smap = demo_sphere_map(mesh)
    assert auto_layout(mesh, LayoutOptions(patches=6), sphere=smap).n_patches == 24


def test_patch_count_and_demo_sphere():
    mesh = demo_mesh(6000)
    smap = demo_sphere_map(mesh)
    assert smap.flips == 0
    layout = auto_layout(mesh, LayoutOptions(patches=120), sphere=smap)
    assert layout.n_patches == 120
    assert len(extract_patches(mesh, layout)) == 120


def test_open_and_higher_genus_meshes_take_the_region_route():
    from meshfit.layout.auto import auto_route

    assert auto_route(torus()) == "regions"
    assert auto_route(plane(6)) == "regions"
    assert auto_route(icosphere(3)) == "sphere"
    assert auto_route(icosphere(1)) == "regions"  # too few faces for 24 patches
    assert auto_route(icosphere(1), patches=24) == "sphere"  # asked: the sphere route says
    layout = auto_layout(torus())
    assert len(extract_patches(torus(), layout)) == layout.n_patches
    with pytest.raises(InputError):
        auto_layout(demo_mesh(400), LayoutOptions(patches=0))


def _record_region_route(monkeypatch) -> list:
    import meshfit.layout.auto as auto

    calls: list = []
    plain = auto._region_route

    def recorded(mesh, options, relax_iterations, info):
        calls.append(mesh.name)
        return plain(mesh, options, relax_iterations, info)

    monkeypatch.setattr(auto, "_region_route", recorded)
    return calls


def _no_crossings(mesh, sphere, normal, face):
    # traced curves joined straight between samples (no edge crossing put between them)
    return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)


def test_crossing_curves_hand_the_mesh_to_the_region_route(monkeypatch):
    # spot has about 2,900 vertices: 180 patches put several traced curves through one face.
    # Traced exactly they do not cross (test_traced_curves_are_the_exact_images_of_their_arcs);
    # joined straight across the mesh edges between samples instead, as traces were once,
    # curves of the unshaped base meshes of seeds 0 and 1 cross, and the region route lays
    # the mesh out instead of an error
    import meshfit.layout.auto as auto

    monkeypatch.setattr(auto, "SEED_TRIES", 2)
    monkeypatch.setattr(auto, "_edge_crossings", _no_crossings)
    mesh = real_mesh("spot")
    calls = _record_region_route(monkeypatch)
    layout = auto_layout(
        mesh, LayoutOptions(patches=180, relax=False, shape=False, protrusions=False)
    )
    assert calls == [mesh.name]
    assert len(extract_patches(mesh, layout)) == layout.n_patches
    # with a sphere map of the caller's, the sphere route's error stands
    from meshfit.shrinkwrap import sphere_map

    smap = sphere_map(mesh, max_aspect=10.0)
    with pytest.raises(LayoutError, match="fewer patches") as err:
        auto_layout(
            mesh,
            LayoutOptions(patches=180, relax=False, shape=False, protrusions=False),
            sphere=smap,
        )
    assert "nor with another rotation of the base mesh" in str(err.value)


def test_crossing_curves_are_retried_with_other_rotations(monkeypatch):
    # spot with 150 patches, traced curves joined straight across the mesh edges between
    # samples: the base mesh of seed 0 gives curves that cross, seed 1 does not
    import meshfit.layout.auto as auto

    monkeypatch.setattr(auto, "_edge_crossings", _no_crossings)
    mesh = real_mesh("spot")
    with monkeypatch.context() as m:
        m.setattr(auto, "SEED_TRIES", 1)
        calls = _record_region_route(m)
        auto_layout(mesh, LayoutOptions(patches=150, relax=False))
        assert calls == [mesh.name]  # one rotation only: the region route
    got = auto_layout(mesh, LayoutOptions(patches=150, relax=False))
    want = auto_layout(mesh, LayoutOptions(patches=150, relax=False, seed=1))
    assert got.n_patches == want.n_patches == 150
    assert_array_equal(got.corners.face, want.corners.face)
    assert_array_equal(got.corners.bary, want.corners.bary)
    for a, b in zip(got.curves, want.curves, strict=True):
        assert_array_equal(a.points.face, b.points.face)
        assert_array_equal(a.points.bary, b.points.bary)
    assert len(extract_patches(mesh, got)) == 150


def test_batched_relaxation_matches_relax_snake():
    from meshfit.curves import SnakeOptions, relax_snake
    from meshfit.layout.auto import _network, _relax_all
    from meshfit.shrinkwrap import sphere_map

    mesh = real_mesh("spot")
    smap = sphere_map(mesh, max_aspect=10.0)
    _, curves, _, _ = _network(mesh, smap, 20, 0)
    curves = curves[:12]
    got = _relax_all(mesh, curves, 60)
    for c, g in zip(curves, got, strict=True):
        want = relax_snake(mesh, c, SnakeOptions(max_iter=60)).curve
        if len(check_sampling(mesh, want)):
            want = densify_curve(mesh, want)
        np.testing.assert_array_equal(g.points.face, want.points.face)
        np.testing.assert_allclose(g.points.bary, want.points.bary, atol=1e-12)


def test_batched_snake_kernels_match_oracle(rng):
    from meshfit._kernels import snakes as _kb

    from ..reference import snakes as reference

    sizes = np.array([2, 5, 17, 40])
    start = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    n = int(start[-1])
    x = np.cumsum(rng.normal(size=(n, 3)), axis=0)
    levels = np.array([1, 2, 3, 5], dtype=np.int64)
    got = _kb.forces_many(x, start, levels, 1.0, 0.5, 1.0)
    want = reference.forces_many(x, start, levels, 1.0, 0.5, 1.0)
    np.testing.assert_allclose(got, want, atol=1e-12)
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    fixed = rng.random(n) < 0.2
    floor = np.array([0.0, 0.5, 0.1, 2.0])
    got = _kb.moves_many(x, want, nrm, fixed, start, 0.5, 0.25, floor)
    np.testing.assert_allclose(
        got, reference.moves_many(x, want, nrm, fixed, start, 0.5, 0.25, floor), atol=1e-12
    )
    assert not got[fixed].any()
    np.testing.assert_array_equal(_kb.curve_max(np.arange(n, dtype=float), start), start[1:] - 1)


@cache
def _relax_case(name: str) -> dict:
    """Arguments of the batched relaxation for the traced curves of a 60-patch auto layout."""
    from meshfit.layout.auto import _network, _relax_inputs
    from meshfit.shrinkwrap import sphere_map

    mesh = icosphere(3) if name == "icosphere" else real_mesh(name)
    smap = sphere_map(mesh, max_aspect=10.0)
    _, curves, _, _ = _network(mesh, smap, 20, 0)
    return _relax_inputs(mesh, curves)


_DEFAULT_ITERATIONS = LayoutOptions().relax_iterations


@pytest.mark.parametrize("iterations", [1, 5, _DEFAULT_ITERATIONS])
@pytest.mark.parametrize("name", ["icosphere", "spot"])
def test_relax_many_matches_oracle_bit_for_bit(name, iterations):
    from meshfit._kernels import snakes as _kb

    from ..reference import snakes as reference

    args = _relax_case(name)
    face, bary, stats = _kb.relax_many(**args, iterations=iterations)
    want_face, want_bary, want_stats = reference.relax_many(**args, iterations=iterations)
    np.testing.assert_array_equal(face, want_face)
    np.testing.assert_array_equal(bary, want_bary)  # exact: the same operations in order
    np.testing.assert_array_equal(stats, want_stats)
    assert (stats[:, 0] >= 1).all() and (stats[:, 0] <= iterations).all()
    assert not np.array_equal(bary, args["bary"])  # the curves did move


def test_relax_many_halves_and_reverts_like_the_oracle():
    from meshfit._kernels import snakes as _kb

    from ..reference import snakes as reference

    # spot's ears and horns break segments at the default gain; on the smooth sphere it takes
    # moves of many spacings (gain 50, cap 20 spacings) for the halvings to fail
    for name, gain, step in (("spot", None, None), ("icosphere", 50.0, 20.0)):
        args = dict(_relax_case(name))
        if gain is not None:
            args["gain"], args["step"] = gain, step
        face, bary, stats = _kb.relax_many(**args, iterations=_DEFAULT_ITERATIONS)
        want_face, want_bary, want_stats = reference.relax_many(
            **args, iterations=_DEFAULT_ITERATIONS
        )
        assert stats[:, 1].sum() > 0, f"{name}: no move was halved"
        assert stats[:, 2].sum() > 0, f"{name}: no point was put back"
        np.testing.assert_array_equal(stats, want_stats)
        np.testing.assert_array_equal(face, want_face)
        np.testing.assert_array_equal(bary, want_bary)


@cache
def _filled_bunny():
    from meshfit.shrinkwrap import fill_holes

    return fill_holes(real_mesh("bunny"))


@pytest.mark.slow
def test_a_protrusion_a_quad_would_hold_goes_to_the_region_route(monkeypatch):
    # the 60-patch layout of the (hole-filled) bunny holds an ear whole in one patch, which
    # bulges far beyond its boundary (7.8); the region route's cells split where the ear
    # turns back, and no patch bulges like that
    from meshfit.layout.patch import BULGY

    mesh = _filled_bunny()
    plain = auto_layout(mesh, LayoutOptions(protrusions=False))
    assert max(p.bulge for p in extract_patches(mesh, plain)) > BULGY
    calls = _record_region_route(monkeypatch)
    layout = auto_layout(mesh)
    assert calls == [mesh.name]
    assert max(p.bulge for p in extract_patches(mesh, layout)) < BULGY


def test_quad_depths_of_a_round_mesh_and_of_one_with_a_protrusion():
    from meshfit.layout.auto import PROTRUSION_DEPTH, quad_depths
    from meshfit.shrinkwrap import BaseOptions, base_mesh

    mesh = demo_mesh(6000)
    smap = demo_sphere_map(mesh)
    base = base_mesh(smap, BaseOptions(max_faces=20, min_faces=20, seed=0))
    depth, tip = quad_depths(mesh, smap.sphere, base.sphere, base.faces)
    assert depth.shape == tip.shape == (60,)
    # a quad of a round surface reaches about as deep as a flat square (0.5), graph paths
    # running a little longer than straight lines
    assert 0.3 < np.median(depth) < 0.55 and depth.max() < PROTRUSION_DEPTH
    assert (tip >= 0).all()
    # the bunny's ears: two quads deeper than the bound, their tips at the ears' tops
    mesh = _filled_bunny()
    from meshfit.shrinkwrap import sphere_map

    smap = sphere_map(mesh, max_aspect=10.0)
    base = base_mesh(smap, BaseOptions(max_faces=20, min_faces=20, seed=0))
    depth, tip = quad_depths(mesh, smap.sphere, base.sphere, base.faces)
    deep = np.flatnonzero(depth > PROTRUSION_DEPTH)
    assert deep.size == 2
    assert (mesh.vertices[tip[deep], 1] > 0.16).all()  # the head's top is at y = 0.15


@pytest.mark.slow
def test_traced_arcs_are_sampled_densely_where_the_sphere_map_squeezes_the_surface():
    from meshfit.layout.auto import TRACE_GAP_EDGES, _fill_gaps, _slerp
    from meshfit.shrinkwrap import sphere_map

    mesh = _filled_bunny()
    smap = sphere_map(mesh, max_aspect=10.0)
    V = mesh.vertices
    tip = int(np.argmax(V[:, 1]))  # an ear's top: its image is a speck of the sphere
    a = smap.sphere[tip] / np.linalg.norm(smap.sphere[tip])
    b = np.cross(a, [0.0, 0.0, 1.0])
    b /= np.linalg.norm(b)  # a quarter circle from the tip
    arc = (a, b, float(np.arccos(np.clip(a @ b, -1.0, 1.0))))
    even = np.linspace(0.0, 1.0, 33)

    def gaps(x):
        return np.linalg.norm(np.diff(x, axis=0), axis=1) / mesh.mean_edge_length

    assert gaps(smap.evaluate(_slerp(*arc, even))).max() > 20  # the first step leaves the ear
    (size,), inner = _fill_gaps(mesh, smap, [arc], [even], TRACE_GAP_EDGES)
    assert size == len(inner) > 31  # the 31 inner samples and those added
    ends = smap.evaluate(np.array([a, b]))
    x = np.vstack([ends[:1], mesh.xyz(inner), ends[1:]])
    assert gaps(x).max() <= TRACE_GAP_EDGES
    # the even samples are kept, in order along the arc
    kept = smap.locate(_slerp(*arc, even[1:-1]))
    at = [
        np.flatnonzero((inner.face == f) & np.all(inner.bary == b, axis=1))
        for f, b in zip(kept.face, kept.bary, strict=True)
    ]
    assert all(i.size for i in at) and (np.diff([i[0] for i in at]) > 0).all()


def _noisy(mesh, edges: float, seed: int):
    from meshfit.mesh import Mesh

    rng = np.random.default_rng(seed)
    step = edges * mesh.mean_edge_length
    return Mesh(mesh.vertices + rng.normal(scale=step, size=mesh.vertices.shape), mesh.faces)


@pytest.mark.parametrize("seed", [1, 2])
def test_traced_curves_are_the_exact_images_of_their_arcs(seed):
    # an icosphere with half an edge of noise, turned and scaled: each traced point maps back
    # onto its arc's great circle, within the arc and in order along it, and consecutive
    # points lie in one face or two that share an edge (no straight joins across faces)
    from scipy.spatial.transform import Rotation

    from meshfit.layout.auto import TRACE_GAP_EDGES, _fill_gaps
    from meshfit.mesh import Mesh
    from meshfit.shrinkwrap import sphere_map

    noisy = _noisy(icosphere(4), 0.5, seed)
    turn = Rotation.random(random_state=seed).as_matrix()
    mesh = Mesh(37.0 * noisy.vertices @ turn.T + [5.0, -2.0, 1.0], noisy.faces)
    smap = sphere_map(mesh, max_aspect=10.0)
    rng = np.random.default_rng(seed)
    arcs = []
    for _ in range(12):
        a, b = (v / np.linalg.norm(v) for v in rng.normal(size=(2, 3)))
        arcs.append((a, b, float(np.arccos(np.clip(a @ b, -1.0, 1.0)))))
    params = [np.linspace(0.0, 1.0, 9) for _ in arcs]
    sizes, inner = _fill_gaps(mesh, smap, arcs, params, TRACE_GAP_EDGES)
    at = 0
    nbr = mesh.face_neighbors
    for (a, b, w), n in zip(arcs, sizes, strict=True):
        ends = smap.locate(np.array([a, b]))
        pts = inner[np.arange(at, at + n)]
        at += n
        face = np.concatenate([ends.face[:1], pts.face, ends.face[1:]])
        s = smap.inverse(SurfacePoints(face, np.vstack([ends.bary[:1], pts.bary, ends.bary[1:]])))
        normal = np.cross(a, b) / np.sin(w)
        np.testing.assert_allclose(s @ normal, 0.0, atol=1e-9)
        angle = np.arctan2(s @ np.cross(normal, a), s @ a)
        assert (np.diff(angle) >= -1e-9).all() and angle[-1] <= w + 1e-9
        same = face[1:] == face[:-1]
        side = (nbr[face[:-1]] == face[1:, None]).any(axis=1)
        assert (same | side).all()
        assert (~same).sum() > 0  # the arcs cross edges: there is something to check


@pytest.mark.parametrize("seed", [0, 1])
def test_the_sphere_route_is_the_same_moved_turned_and_scaled(seed):
    # spot is mirror-symmetric: two vertices tie as the farthest from its centroid, and the
    # rounding of a moved copy used to pick the other one (another split of the sphere map,
    # another layout; its fit's Hausdorff distance went from 0.43% to 0.93%)
    from scipy.spatial.transform import Rotation

    from meshfit.mesh import Mesh
    from meshfit.shrinkwrap.sphere import _farthest_vertex

    mesh = real_mesh("spot")
    turn = Rotation.random(random_state=seed).as_matrix()
    d = mesh.bbox_diagonal
    moved = Mesh(3.7 * mesh.vertices @ turn.T + [1e3 * d, -5e2 * d, 1e6 * d * seed], mesh.faces)
    assert _farthest_vertex(moved) == _farthest_vertex(mesh)
    got, want = auto_layout(moved), auto_layout(mesh)
    assert_array_equal(got.corners.face, want.corners.face)
    # (a million diagonals away the coordinates keep about ten digits of the mesh's size)
    np.testing.assert_allclose(got.corners.bary, want.corners.bary, atol=1e-6)


def test_a_symmetric_shape_keeps_its_layout_moved_and_turned():
    # a rounded cube: its faces tie in graph distance from the split's seed by the dozen,
    # and the order of tied faces (which side of the two-disk split they fall on) must not
    # follow the rounding of a turned copy
    from scipy.spatial.transform import Rotation

    from meshfit.mesh import Mesh

    mesh = cube(rounded=0.2, n=16)
    turn = Rotation.random(random_state=3).as_matrix()
    d = mesh.bbox_diagonal
    moved = Mesh(2.3 * mesh.vertices @ turn.T + [7 * d, -3 * d, 11 * d], mesh.faces)
    got, want = auto_layout(moved), auto_layout(mesh)
    assert_array_equal(got.corners.face, want.corners.face)
    np.testing.assert_allclose(got.corners.bary, want.corners.bary, atol=1e-9)


@pytest.mark.parametrize("seed", [1, 2])
def test_noisy_genus_0_scans_keep_the_sphere_route(seed):
    # a quarter to half an edge of noise: traced straight across edges, spot's curves crossed
    # on most seeds and the mesh went to the region route (five times the patches)
    for edges in (0.25, 0.5):
        report: list = []
        layout = auto_layout(_noisy(real_mesh("spot"), edges, seed), report=report)
        assert report[0]["route"] == "sphere"
        assert layout.n_patches == 60


@pytest.mark.slow
def test_split_base_meshes_have_their_degrees_balanced():
    # nefertiti's 68-triangle base (204 patches) piles its edge splits round two vertices
    # (degrees 12 and 15: curves 6 degrees apart at their corners, which cross at once)
    from meshfit.layout.auto import _upright, balance_degrees
    from meshfit.shrinkwrap import BaseOptions, base_mesh, sphere_map

    mesh = real_mesh("nefertiti")
    smap = sphere_map(mesh, max_aspect=10.0)
    base = base_mesh(smap, BaseOptions(max_faces=68, min_faces=68, seed=0))
    assert np.bincount(base.faces.ravel()).max() >= 12
    F = balance_degrees(base.sphere, base.faces)
    deg = np.bincount(F.ravel(), minlength=len(base.sphere))
    assert F.shape == base.faces.shape and deg.min() >= 4 and deg.max() <= 7
    assert _upright(base.sphere, F)
    half = {(int(f[s]), int(f[(s + 1) % 3])) for f in F for s in range(3)}
    assert len(half) == 3 * len(F) and all((b, a) in half for a, b in half)  # closed
    # and the layout of that base is made
    assert auto_layout(mesh, LayoutOptions(patches=200)).n_patches == 204


def _same_layout(a, b) -> None:
    assert_array_equal(a.corners.face, b.corners.face)
    assert_array_equal(a.corners.bary, b.corners.bary)
    for x, y in zip(a.curves, b.curves, strict=True):
        assert_array_equal(x.points.face, y.points.face)
        assert_array_equal(x.points.bary, y.points.bary)


def test_of_layouts_that_all_have_slivers_the_one_with_fewest_is_kept(monkeypatch):
    # with every patch counted a sliver, each rotation has as many: the one whose thinnest
    # patch is the least thin wins
    import meshfit.layout.auto as auto
    from meshfit.layout.extract import patch_bulges

    mesh = real_mesh("spot")
    monkeypatch.setattr(auto, "THIN", 10.0)
    tries = auto.SEED_TRIES
    with monkeypatch.context() as m:
        m.setattr(auto, "SEED_TRIES", 1)
        each = [auto_layout(mesh, LayoutOptions(seed=s)) for s in range(tries)]
    thinnest = [patch_bulges(mesh, x).min() for x in each]
    assert len(set(thinnest)) == len(thinnest)
    _same_layout(auto_layout(mesh), each[int(np.argmax(thinnest))])


def test_slivers_on_a_proxy_are_retried_like_on_the_mesh(monkeypatch):
    # the same choice when the layout is made on a coarse proxy and carried to the mesh
    import meshfit.layout.auto as auto
    from meshfit.layout.extract import patch_bulges

    mesh = real_mesh("spot")  # 5,856 faces: over 4 times a proxy of 1,000
    monkeypatch.setattr(auto, "THIN", 10.0)
    tries = auto.SEED_TRIES
    single: dict[int, tuple] = {}  # seed -> (layout, its thinnest patch), made on the proxy
    on_proxy = auto._layout_on_proxy
    made: list = []
    with monkeypatch.context() as m:
        m.setattr(auto, "SEED_TRIES", 1)
        m.setattr(auto, "_layout_on_proxy", lambda *a: made.append(on_proxy(*a)) or made[-1])
        for seed in range(3, 3 + 4 * tries):
            x = auto_layout(mesh, LayoutOptions(seed=seed, proxy_faces=1000, protrusions=False))
            if made[-1] is not None:  # (else the rotation's carried network did not cut)
                single[seed] = (x, patch_bulges(mesh, x).min())
    # the first run of rotations, all laid out on the proxy, where a later one wins
    for first in range(3, 3 + 3 * tries + 1):
        if not all(first + k in single for k in range(tries)):
            continue
        thinnest = [single[first + k][1] for k in range(tries)]
        if int(np.argmax(thinnest)) > 0:
            break
    else:
        pytest.fail("no run of rotations on the proxy where a later one is the thickest")
    assert len(set(thinnest)) == len(thinnest)
    _same_layout(
        auto_layout(mesh, LayoutOptions(seed=first, proxy_faces=1000, protrusions=False)),
        single[first + int(np.argmax(thinnest))][0],
    )


def test_only_the_relaxed_curves_at_fault_are_put_back():
    """A relaxed network with one curve run over another keeps every other curve relaxed:
    the two curves at fault go back to their unrelaxed paths, and the network cuts the
    mesh into its patches."""
    from meshfit.layout.auto import _keep_relaxed, _relax_all
    from meshfit.layout.cube import cube_layout
    from meshfit.types import SurfaceCurve

    mesh = icosphere(3)
    layout = cube_layout(mesh, frame=np.eye(3))
    plain = list(layout.curves)
    relaxed = _relax_all(mesh, plain, 30)
    moved = [i for i in range(len(plain)) if len(relaxed[i]) != len(plain[i])]
    assert moved  # the relaxation changed curves, so keeping them is observable
    bad = list(relaxed)
    # curve 7 relaxed "onto" curve 0: its inner points are curve 0's
    bad[7] = SurfaceCurve(plain[0].points, False, "boundary")
    quads = [
        list(zip(c.tolist(), r.tolist(), strict=True))
        for c, r in zip(layout.patch_curves, layout.patch_reversed, strict=True)
    ]
    out = _keep_relaxed(mesh, layout.corners, plain, bad, layout.curve_ends, quads)
    assert out is not None
    assert np.array_equal(out.curves[7].points.face, plain[7].points.face)
    kept = [i for i in moved if i != 7]
    assert all(np.array_equal(out.curves[i].points.face, relaxed[i].points.face) for i in kept)
    # where the unrelaxed network has the fault too, nothing mends it
    assert _keep_relaxed(mesh, layout.corners, bad, bad, layout.curve_ends, quads) is None


def test_curves_put_back_are_checked_with_their_patches_first():
    """After a curve is put back, the next round cuts only it, the curves of its patches
    and the curves at its corners: on a cube layout, the 3 others of each of its 2
    patches and the curves at its two corners (the whole network is looked at once more
    before the layout is made)."""
    from meshfit.layout.auto import _neighbourhoods
    from meshfit.layout.cube import cube_layout

    layout = cube_layout(icosphere(3), frame=np.eye(3))
    quads = [[(int(c), False) for c in row] for row in layout.patch_curves]
    near = _neighbourhoods(layout.curve_ends, quads, len(layout.curves))
    for i, hood in enumerate(near):
        patches = {int(c) for row in layout.patch_curves if i in row for c in row}
        ends = layout.curve_ends[i]
        at = {j for j, e in enumerate(layout.curve_ends.tolist()) if set(e) & set(ends.tolist())}
        assert hood == patches | at | {i}
        assert i in hood and len(hood) < len(layout.curves)


def _plane_curve(mesh, xy):
    from meshfit.types import SurfaceCurve

    pts = np.column_stack([xy, np.zeros(len(xy))])
    return SurfaceCurve(mesh.closest_points(pts).points)


def _turns_back(x: np.ndarray) -> bool:
    d = np.diff(x, axis=0)
    return bool(((d[1:] * d[:-1]).sum(axis=1) < 0).any())


@given(
    steps=st.lists(
        st.tuples(st.floats(-0.05, 0.12), st.floats(-0.05, 0.05)), min_size=1, max_size=12
    )
)
@settings(max_examples=80, deadline=None)
def test_polyline_points_that_turn_back_are_dropped(steps):
    from meshfit.layout.auto import forward_points

    x = np.column_stack([np.cumsum([(0.0, 0.0), *steps], axis=0), np.zeros(len(steps) + 1)])
    keep = forward_points(x)
    assert not _turns_back(x[keep])
    assert keep[0] == 0 and keep[-1] == len(x) - 1 and np.all(np.diff(keep) > 0)
    if not _turns_back(x):
        assert_array_equal(keep, np.arange(len(x)))


def test_a_point_stepping_back_across_a_curve_is_dropped_whatever_the_pose():
    from meshfit.layout.auto import _without_reversals
    from meshfit.mesh import Mesh

    mesh = plane(10, jitter=0.2)
    # out and back at row 3; row 5 steps back behind row 4
    xy = [[0.1, 0.5], [0.3, 0.5], [0.4, 0.7], [0.5, 0.5], [0.7, 0.5], [0.65, 0.52], [0.9, 0.5]]
    curve = _plane_curve(mesh, np.array(xy))
    rot = np.linalg.qr(np.random.default_rng(4).normal(size=(3, 3)))[0]
    for scale in (1e-4, 1.0, 1e3):
        moved = Mesh(scale * mesh.vertices @ rot.T + 5.0, mesh.faces)
        out = _without_reversals(moved, curve)
        assert_array_equal(out.points.face, curve.points.face[[0, 1, 3, 5, 6]])
    straight = _plane_curve(mesh, np.array(xy)[[0, 1, 3, 6]])
    assert _without_reversals(mesh, straight) is straight


def test_curves_carried_from_a_proxy_have_no_spikes():
    """A curve relaxed on the proxy, carried to the closest points of the full mesh, does
    not come back on itself within a few edges (a spike that the fine relaxation removes
    only slowly on a dense scan, and that folds the spring grid of the patch it bounds)."""
    import meshfit.layout.auto as auto

    mesh = real_mesh("igea")  # 268,686 faces, laid out on a proxy of 2,000
    carried = []
    real = auto._carry_curves

    def spy(*args):
        carried.extend(out := real(*args))
        return out

    h = mesh.mean_edge_length
    with pytest.MonkeyPatch.context() as m:
        m.setattr(auto, "_carry_curves", spy)
        auto_layout(mesh, LayoutOptions(proxy_faces=2000))
    assert carried
    for c in carried:
        x = mesh.xyz(c.points)
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(x, axis=0), axis=1))])
        for i in range(len(x)):
            j = np.arange(i + 1, np.searchsorted(s, s[i] + 20 * h, side="right"))
            arc = s[j] - s[i]
            far = arc > 3 * h  # over 3 to 20 edges of arc, the chord is at least half of it
            chord = np.linalg.norm(x[j[far]] - x[i], axis=1)
            assert np.all(chord >= 0.5 * arc[far])


@pytest.mark.xfail(
    strict=True,
    reason="the sphere route depends on the order of the mesh's faces: spot's proxy (5,794 "
    "faces) in the store's order has a base quad 0.6515 deep (limit 0.65) and goes to the "
    "region route (354 patches); its faces shuffled give 0.5446 and keep the sphere route "
    "(60 patches). The split into two disks is the same; round-off that follows the order "
    "(the Tutte solve, the cell-area sums) takes the base mesh's equalising elsewhere",
)
def test_the_order_of_the_faces_does_not_change_the_layout(tmp_path):
    from meshfit.mesh import Mesh
    from meshfit.mesh.store import write_store
    from meshfit.shrinkwrap.proxy import simplify_store

    store = write_store(real_mesh("spot"), tmp_path / "s")
    proxy = simplify_store(store, store.n_faces).mesh
    rng = np.random.default_rng(0)
    shuffled = Mesh(proxy.vertices, proxy.faces[rng.permutation(proxy.n_faces)])
    opts = LayoutOptions(crease_angle=None)
    routes = []
    for mesh in (proxy, shuffled):
        report: list = []
        lay = auto_layout(mesh, opts, report=report)
        routes.append((report[0]["route"], lay.n_patches))
    assert routes[0] == routes[1]
