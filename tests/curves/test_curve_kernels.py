"""Curve kernels against their slow references: bisecting broken pairs (densify), a curve as
straight pieces, and placing points on the pieces."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from numpy.testing import assert_allclose, assert_array_equal

from meshfit.curves import check_sampling, densify_curve, densify_curves, paint_curve
from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.surface import curve_arc_lengths, greedy_path, path_to_surface_points
from meshfit.surface.walk import _curve_pieces, _place_on_pieces
from meshfit.types import SurfaceCurve, SurfacePoints
from tests.reference import curves as reference

from ..conftest import analytic_mesh, real_mesh


def _thin_slab() -> Mesh:
    box = trimesh.creation.box(extents=(1.0, 1.0, 0.02))
    vv, ff = box.vertices, box.faces
    for _ in range(3):
        vv, ff = trimesh.remesh.subdivide(vv, ff)
    return Mesh(np.asarray(vv, dtype=np.float64), np.asarray(ff, dtype=np.int64), name="slab")


def _sparse_curve(mesh: Mesh, a: int, b: int, every: int, closed: bool = False) -> SurfaceCurve:
    """Every ``every``-th sample of a graph path: pairs several faces apart."""
    pts = path_to_surface_points(mesh, greedy_path(mesh, a, b).vertices, per_edge=1)
    keep = np.unique(np.append(np.arange(0, len(pts), every), len(pts) - 1))
    return SurfaceCurve(pts[keep], closed=closed)


def _far_pairs(mesh: Mesh, rng: np.random.Generator, n: int) -> SurfaceCurve:
    """Random face points in sequence: pairs far apart (graph bridges as well as bisection)."""
    face = rng.integers(0, mesh.n_faces, n)
    bary = rng.dirichlet([1.0, 1.0, 1.0], n)
    bary[0] = [1.0, 0.0, 0.0]  # a vertex point
    bary[1] = [0.5, 0.5, 0.0]  # an edge point
    return SurfaceCurve(SurfacePoints(face, bary))


def _densify_cases(rng):
    igea = real_mesh("igea")
    v = igea.vertices
    a = int(np.argmin(v[:, 1]))
    b = int(np.argmin(np.abs(np.linalg.norm(v - v[a], axis=1) - 60 * igea.mean_edge_length)))
    sphere = analytic_mesh("icosphere")
    slab = _thin_slab()
    sv = slab.vertices
    top = int(np.argmin(np.linalg.norm(sv - [0.3, 0.1, 0.01], axis=1)))
    bot = int(np.argmin(np.linalg.norm(sv - [0.32, 0.1, -0.01], axis=1)))
    rim = int(np.argmin(np.linalg.norm(sv - [0.5, 0.1, 0.0], axis=1)))
    across = SurfaceCurve(SurfacePoints.at_vertices(slab.faces, [top, bot, rim]))
    return [
        ("igea sparse", igea, _sparse_curve(igea, a, b, 7)),
        ("sphere sparse closed", sphere, _sparse_curve(sphere, 0, 300, 5, closed=True)),
        ("sphere far", sphere, _far_pairs(sphere, rng, 6)),
        ("slab across", slab, across),
    ]


@pytest.mark.parametrize("threads", [1, 3])
def test_densify_matches_the_reference(rng, threads, monkeypatch):
    import meshfit.curves.base as base

    if threads > 1:  # every pair its own run, on up to three threads: the join is exercised
        monkeypatch.setattr(base, "_BRIDGE_CHUNK", 1)
        monkeypatch.setattr(base.os, "cpu_count", lambda: threads)
    for label, mesh, curve in _densify_cases(rng):
        assert check_sampling(mesh, curve).size > 0, label  # something to repair
        got = densify_curve(mesh, curve)
        face, bary = reference.densify(mesh, curve)
        assert_array_equal(got.points.face, face, err_msg=label)
        assert_allclose(got.points.bary, bary, rtol=0, atol=1e-15, err_msg=label)
        assert check_sampling(mesh, got).size == 0, label


def test_densify_curves_equals_one_curve_at_a_time(rng):
    cases = _densify_cases(rng)
    by_mesh: dict[int, tuple] = {}
    for _, mesh, curve in cases:
        by_mesh.setdefault(id(mesh), (mesh, []))[1].append(curve)
    for mesh, curves in by_mesh.values():
        # with curves that need nothing, and a closed one, in between
        done = densify_curve(mesh, curves[0])
        closed = SurfaceCurve(curves[0].points, closed=True)
        batch = [curves[0], done, *curves[1:], closed, curves[-1]]
        got = densify_curves(mesh, batch)
        assert len(got) == len(batch)
        for g, c in zip(got, batch, strict=True):
            want = densify_curve(mesh, c)
            assert g.closed == c.closed and g.kind == c.kind
            assert_array_equal(g.points.face, want.points.face)
            assert_array_equal(g.points.bary, want.points.bary)
        assert got[1] is done  # nothing to repair: the curve itself
    with pytest.raises(InputError, match=r"curves\[1\] must be a SurfaceCurve"):
        densify_curves(mesh, [curves[0], "not a curve"])


def _pieces_cases():
    igea = real_mesh("igea")
    v = igea.vertices
    a, b = int(np.argmin(v[:, 1])), int(np.argmax(v[:, 0]))
    painted = paint_curve(igea, [a, b])
    sphere = analytic_mesh("icosphere")
    loop = paint_curve(sphere, [0, 100, 300], closed=True)
    # faces sharing only a vertex, joined through it
    F = sphere.faces
    indptr, vf = sphere.vertex_faces
    fan = vf[indptr[7] : indptr[8]]
    f0 = int(fan[0])
    f1 = next(int(g) for g in fan[1:] if g not in sphere.face_neighbors[f0])
    corner = SurfacePoints([f0, f1, f1], [[1 / 3] * 3, [1 / 3] * 3, (F[f1] == 7).astype(float)])
    return [
        ("igea painted", igea, painted.points, False),
        ("sphere closed", sphere, loop.points, True),
        ("vertex-sharing faces", sphere, corner, False),
        ("one point closed", sphere, loop.points[:1], True),
    ]


def test_curve_pieces_match_the_reference():
    for label, mesh, pts, closed in _pieces_cases():
        got = _curve_pieces(mesh, pts, closed, "curve")
        face, b0, b1, start, length, total = reference.curve_pieces(mesh, pts, closed)
        assert_array_equal(got.face, face, err_msg=label)
        for x, y in ((got.b0, b0), (got.b1, b1), (got.start, start), (got.length, length)):
            assert_allclose(x, y, rtol=1e-14, atol=1e-15, err_msg=label)
        assert_allclose(got.total, total, rtol=1e-14, err_msg=label)


def test_place_on_pieces_matches_the_reference(rng):
    for label, mesh, pts, closed in _pieces_cases()[:3]:
        pieces = _curve_pieces(mesh, pts, closed, "curve")
        arc = curve_arc_lengths(mesh, pts, closed=closed)
        s = np.concatenate([rng.uniform(0, pieces.total, 200), arc[:-1], [0.0]])
        if not closed:
            s = np.append(s, pieces.total)
        got = _place_on_pieces(pts, closed, pieces, s)
        tup = (pieces.face, pieces.b0, pieces.b1, pieces.start, pieces.length, pieces.total)
        want = reference.place_on_pieces(pts, closed, tup, s)
        assert_array_equal(got[0], want[0], err_msg=label)
        assert_allclose(got[1], want[1], rtol=0, atol=1e-15, err_msg=label)
        assert_array_equal(got[2], want[2], err_msg=label)
        # a position at a point's own arc length gives that point exactly
        on = slice(200, 200 + arc.size - 1)
        assert_array_equal(got[0][on], pts.face[: arc.size - 1], err_msg=label)
        assert_array_equal(got[1][on], pts.bary[: arc.size - 1], err_msg=label)


@pytest.mark.parametrize("closed", [False, True])
def test_curve_pieces_report_pairs_sharing_nothing(closed):
    from meshfit.errors import InputError

    mesh = analytic_mesh("icosphere")
    pts = SurfacePoints([0, 0, 500], [[1 / 3] * 3] * 3)
    with pytest.raises(InputError, match="curve points 1 and 2 are on faces 0 and 500"):
        _curve_pieces(mesh, pts, closed, "curve")


@pytest.mark.parametrize("closed", [False, True])
def test_check_sampling_matches_the_reference(closed, rng):
    from meshfit.curves import check_sampling

    mesh = analytic_mesh("icosphere")
    # a graph path's samples (vertex and edge points) with some points dropped
    pts = path_to_surface_points(mesh, greedy_path(mesh, 0, 300).vertices, per_edge=1)
    keep = np.sort(rng.choice(len(pts), len(pts) * 2 // 3, replace=False))
    curve = SurfaceCurve(pts[keep], closed=closed)
    m = len(curve)
    p = curve.points
    want = [
        i
        for i in range(m if closed else m - 1)
        if not reference._pair_ok(
            mesh, p.face[i], p.bary[i], p.face[(i + 1) % m], p.bary[(i + 1) % m]
        )
    ]
    got = check_sampling(mesh, curve)
    assert 0 < len(want) < m - 1  # some pairs break the rule, some keep it
    assert_array_equal(got, want)


@pytest.mark.parametrize("name", ["igea", "spot"])
def test_straightening_matches_the_reference(name):
    """Attraction by continuation, then reverting jumps, in one kernel: as the references
    run one after the other."""
    from meshfit import tol
    from meshfit._kernels import curves as K

    mesh = real_mesh(name)
    v = mesh.vertices
    h = mesh.mean_edge_length
    a = int(np.argmin(v[:, 1]))
    b = int(np.argmin(np.abs(np.linalg.norm(v - v[a], axis=1) - 120 * h)))
    pts = path_to_surface_points(mesh, greedy_path(mesh, a, b).vertices, per_edge=1)
    x = mesh.xyz(pts)
    m = len(pts)
    t = np.linspace(0.0, 1.0, m)[1:-1, None]
    targets = np.ascontiguousarray(x[0] + t * (x[-1] - x[0]))
    indptr, vf = mesh.vertex_faces
    face, bary = K.straighten_chain(
        mesh.vertices, mesh.faces, mesh.face_neighbors, indptr, vf, pts.face, pts.bary,
        targets, 200, 10_000, tol.length(mesh, tol.ATTRACT_EPS), tol.BARY_EPS, 3.0 * h,
    )  # fmt: skip
    af, ab = reference.attract_chain(mesh, pts[1 : m - 1], targets)
    att_f = np.concatenate([pts.face[:1], af, pts.face[-1:]])
    att_b = np.concatenate([pts.bary[:1], ab, pts.bary[-1:]])
    keep = np.ones(m, dtype=bool)
    keep[[0, -1]] = False
    keep = reference.revert_jumps(mesh, att_f, att_b, pts.face, pts.bary, keep, 3.0 * h)
    assert (~keep[1:-1]).any()  # some stretch reverted
    assert_array_equal(face, np.where(keep, att_f, pts.face))
    assert_allclose(bary, np.where(keep[:, None], att_b, pts.bary), rtol=0, atol=1e-15)


def test_positions_kernel_is_mesh_xyz(rng):
    from meshfit._kernels import curves as K

    mesh = real_mesh("spot")
    face = rng.integers(0, mesh.n_faces, 500)
    bary = rng.dirichlet([1.0, 1.0, 1.0], 500)
    got = K.positions(mesh.vertices, mesh.faces, face, bary)
    assert_array_equal(got, mesh.xyz(SurfacePoints(face, bary)))


def test_split_steps_matches_the_reference(rng):
    from meshfit._kernels import curves as K

    pos = np.sort(rng.uniform(0.0, 10.0, 60))
    bad = np.sort(rng.choice(59, 15, replace=False)).astype(np.int64)
    a, b = pos[bad], pos[bad + 1]
    kbest = rng.choice([0, 2, 3, 7], bad.size).astype(np.int64)
    inside = np.sort(rng.uniform(0.0, 10.0, 200))
    got = K.split_steps(pos, bad, a, b, kbest, inside)
    want = reference.split_steps(pos, bad, a, b, kbest, inside)
    assert (kbest == 0).any() and (kbest > 0).any()
    assert_array_equal(got[0], want[0])
    assert_array_equal(got[1], want[1])


def test_chord_targets_match_the_reference():
    from meshfit._kernels import curves as K

    mesh = real_mesh("spot")
    pts = path_to_surface_points(mesh, greedy_path(mesh, 0, 1500).vertices, per_edge=1)
    got = K.chord_targets(mesh.vertices, mesh.faces, pts.face, pts.bary)
    assert_array_equal(got, reference.chord_targets(mesh, pts))
    one = pts[[0, 0, 0]]  # no length: every target is the first point
    got = K.chord_targets(mesh.vertices, mesh.faces, one.face, one.bary)
    assert_array_equal(got, mesh.xyz(one)[:1])
