"""Curve painting (graph path + CurveAttract), CurveAttract itself, and extending to a curve."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from numpy.testing import assert_allclose, assert_array_equal

from meshfit import tol
from meshfit.curves import (
    attract_curve,
    check_sampling,
    curve_length,
    extend_to_curve,
    paint_curve,
)
from meshfit.errors import InputError, PathError
from meshfit.mesh import Mesh
from meshfit.types import SurfaceCurve, SurfacePoints

from .. import shapes
from ..conftest import analytic_mesh, real_mesh


def _atol(mesh: Mesh) -> float:
    return tol.length(mesh, tol.TEST_ATOL, scale="bbox_diagonal")


def _assert_well_formed(mesh: Mesh, curve: SurfaceCurve) -> None:
    """Connected (sampling rule), on the surface, no jumps."""
    assert check_sampling(mesh, curve).size == 0
    assert ((curve.points.face >= 0) & (curve.points.face < mesh.n_faces)).all()
    assert_allclose(curve.points.bary.sum(axis=1), 1.0, atol=1e-12)
    assert (curve.points.bary >= -1e-12).all()
    x = mesh.xyz(curve.points)
    gaps = np.linalg.norm(np.diff(x, axis=0), axis=1)
    assert gaps.max() <= 2.0 * mesh.edge_lengths.max()  # two faces wide at most


def test_paint_on_the_plane_is_the_straight_segment():
    mesh = analytic_mesh("plane")
    a, b = 21 * 3 + 2, 21 * 17 + 15  # interior vertices far apart
    curve = paint_curve(mesh, [a, b])
    _assert_well_formed(mesh, curve)
    x = mesh.xyz(curve.points)
    pa, pb = mesh.vertices[a], mesh.vertices[b]
    assert_array_equal(x[0], pa)
    assert_array_equal(x[-1], pb)
    d = pb - pa
    t = (x - pa) @ d / (d @ d)
    off = np.linalg.norm(pa + t[:, None] * d - x, axis=1)
    assert off.max() <= _atol(mesh)  # on the segment
    assert (np.diff(t) >= -1e-12).all()  # in order
    assert_allclose(curve_length(mesh, curve), np.linalg.norm(d), rtol=1e-9)


def test_paint_on_the_sphere_is_close_to_the_great_circle():
    mesh = shapes.icosphere(4)
    v = mesh.vertices
    a = 0
    b = int(np.argmin(np.abs(v @ v[a] - np.cos(2.0))))  # about 2 radians away
    curve = paint_curve(mesh, [a, b])
    _assert_well_formed(mesh, curve)
    geodesic = np.arccos(np.clip(v[a] @ v[b], -1, 1))
    assert_allclose(curve_length(mesh, curve), geodesic, rtol=0.03)
    n = np.cross(v[a], v[b])
    n /= np.linalg.norm(n)
    off_plane = np.abs(mesh.xyz(curve.points) @ n)
    assert off_plane.max() <= mesh.mean_edge_length  # follows the great circle


@pytest.mark.parametrize("name", ["igea", "nefertiti"])
def test_paint_between_far_points_on_real_meshes(name):
    mesh = real_mesh(name)
    v = mesh.vertices
    a, b = int(np.argmin(v[:, 1])), int(np.argmax(v[:, 1]))
    c = int(np.argmax(v[:, 0]))
    curve = paint_curve(mesh, [a, c, b])
    _assert_well_formed(mesh, curve)
    x = mesh.xyz(curve.points)
    for p in (a, b, c):  # each pick is on the curve exactly
        assert np.linalg.norm(x - v[p], axis=1).min() == 0.0
    assert_array_equal(x[0], v[a])
    assert_array_equal(x[-1], v[b])


@pytest.mark.parametrize("name", ["igea", "nefertiti"])
def test_painting_is_no_longer_than_the_graph_path(name):
    from meshfit.surface import greedy_path

    mesh = real_mesh(name)
    v = mesh.vertices
    a, b = int(np.argmin(v[:, 1])), int(np.argmax(v[:, 1]))
    c = int(np.argmax(v[:, 0]))
    curve = paint_curve(mesh, [a, c, b])
    graph = greedy_path(mesh, a, c).length + greedy_path(mesh, c, b).length
    assert curve_length(mesh, curve) <= graph * 1.001


def _thin_slab() -> Mesh:
    box = trimesh.creation.box(extents=(1.0, 1.0, 0.02))
    vv, ff = box.vertices, box.faces
    for _ in range(4):
        vv, ff = trimesh.remesh.subdivide(vv, ff)
    return Mesh(np.asarray(vv, dtype=np.float64), np.asarray(ff, dtype=np.int64), name="slab")


def test_paint_never_jumps_across_a_thin_part():
    mesh = _thin_slab()
    v = mesh.vertices
    # a point on the top face and one almost below it on the bottom face: the chord goes
    # straight through the slab, the curve must go round its rim
    top = np.flatnonzero(v[:, 2] > 0)
    bot = np.flatnonzero(v[:, 2] < 0)
    a = int(top[np.argmin(np.linalg.norm(v[top, :2] - [0.3, 0.1], axis=1))])
    b = int(bot[np.argmin(np.linalg.norm(v[bot, :2] - [0.35, 0.1], axis=1))])
    curve = paint_curve(mesh, [a, b])
    _assert_well_formed(mesh, curve)
    # the shortest way round is over the nearest rim (x = 0.5)
    rim = (0.5 - v[a, 0]) + 0.02 + (0.5 - v[b, 0])
    assert curve_length(mesh, curve) >= rim * (1 - 1e-9)
    assert np.linalg.norm(v[a] - v[b]) < 0.1  # whereas the picks are close in space


def test_face_point_picks_are_kept_exactly_and_closed_curves_close():
    mesh = analytic_mesh("icosphere")
    picks = SurfacePoints([3, 400, 900], [[0.2, 0.3, 0.5], [0.6, 0.1, 0.3], [1 / 3] * 3])
    curve = paint_curve(mesh, picks, closed=True, kind="feature")
    assert curve.closed and curve.kind == "feature"
    _assert_well_formed(mesh, curve)
    assert_array_equal(curve.points.face[0], 3)
    assert_array_equal(curve.points.bary[0], [0.2, 0.3, 0.5])
    for i in (1, 2):
        hit = (curve.points.face == picks.face[i]) & (curve.points.bary == picks.bary[i]).all(1)
        assert hit.sum() == 1
    # the closing pair is well sampled too
    assert check_sampling(mesh, curve).size == 0


def test_paint_spacing():
    mesh = analytic_mesh("plane")
    default = paint_curve(mesh, [65, 372])
    fine = paint_curve(mesh, [65, 372], spacing=0.005)
    assert len(fine) >= curve_length(mesh, fine) / 0.005
    assert len(fine) > len(default)
    # a spacing wider than the faces: the sampling rule wins, steps are subdivided
    coarse = paint_curve(mesh, [65, 372], spacing=0.2)
    _assert_well_formed(mesh, coarse)


def test_paint_errors():
    mesh = analytic_mesh("icosphere")
    with pytest.raises(InputError, match="at least 2 picks, got 1"):
        paint_curve(mesh, [4])
    with pytest.raises(InputError, match="closed curve needs at least 3 picks, got 2"):
        paint_curve(mesh, [4, 9], closed=True)
    with pytest.raises(InputError, match=r"picks\[1\] is nan"):
        paint_curve(mesh, np.array([4.0, np.nan]))
    with pytest.raises(InputError, match=r"picks\[1\] = 99999 is not a vertex index"):
        paint_curve(mesh, [4, 99999])
    with pytest.raises(InputError, match="spacing must be a positive length"):
        paint_curve(mesh, [4, 9], spacing=0.0)
    with pytest.raises(InputError, match="kind must be"):
        paint_curve(mesh, [4, 9], kind="seam")
    two = shapes.icosphere(1)
    both = Mesh(
        np.concatenate([two.vertices, two.vertices + 3.0]),
        np.concatenate([two.faces, two.faces + two.n_vertices]),
        name="two spheres",
    )
    with pytest.raises(PathError, match=r"picks 0 and 1 lie on different components \(0 and 1\)"):
        paint_curve(both, [0, two.n_vertices + 5])


def test_attract_curve_to_a_circle_on_the_sphere():
    mesh = shapes.icosphere(4)
    v = mesh.vertices
    # a great-circle arc on the unit sphere; the mesh is inscribed in it
    ang = np.linspace(0.0, 1.5, 400)
    arc = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=1)
    a = int(np.argmin(np.linalg.norm(v - arc[0], axis=1)))
    b = int(np.argmin(np.linalg.norm(v - arc[-1], axis=1)))
    curve = paint_curve(mesh, [a, b])
    out = attract_curve(mesh, curve, arc)
    assert len(out) == len(curve)
    x = mesh.xyz(out.points)
    # each point is the surface point closest to its target (uniform by arc length)
    s = np.linspace(0.0, 1.5, len(curve))
    targets = np.stack([np.cos(s), np.sin(s), np.zeros_like(s)], axis=1)
    want = mesh.closest_points(targets)
    assert_allclose(x, want.xyz, atol=1e-7)
    sagitta = 1.0 - np.abs(np.einsum("ij,ij->i", mesh.face_normals, v[mesh.faces[:, 0]])).min()
    assert np.linalg.norm(x - targets, axis=1).max() <= sagitta * (1 + 1e-9)
    # a callable space curve gives the same result
    out2 = attract_curve(
        mesh, curve, lambda t: np.stack([np.cos(1.5 * t), np.sin(1.5 * t), 0 * t], axis=1)
    )
    assert_allclose(mesh.xyz(out2.points), x, atol=1e-6)


def test_attract_curve_returns_a_space_curve_on_the_surface():
    mesh = analytic_mesh("plane")
    curve = paint_curve(mesh, [65, 372])
    target = np.array([[0.2, 0.3, 0.0], [0.5, 0.4, 0.0], [0.8, 0.3, 0.0]])
    out = attract_curve(mesh, curve, target)
    x = mesh.xyz(out.points)
    seg = np.linalg.norm(np.diff(target, axis=0), axis=1)
    s = np.linspace(0, seg.sum(), len(curve))
    want = np.where(
        (s <= seg[0])[:, None],
        target[0] + (s / seg[0])[:, None] * (target[1] - target[0]),
        target[1] + ((s - seg[0]) / seg[1])[:, None] * (target[2] - target[1]),
    )
    assert_allclose(x, want, atol=_atol(mesh))
    with pytest.raises(InputError, match="space_curve has a NaN"):
        attract_curve(mesh, curve, [[0, 0, 0], [np.nan, 0, 0]])
    with pytest.raises(InputError, match="at least 2 points"):
        attract_curve(mesh, curve, [[0, 0, 0]])


def test_extend_to_the_closest_point_of_a_boundary_curve():
    mesh = analytic_mesh("plane")
    nv = 21
    boundary = paint_curve(mesh, [18 * nv + 1, 18 * nv + 19])  # x = 0.9
    feature = paint_curve(mesh, [5 * nv + 8, 10 * nv + 9], kind="feature")
    ext = extend_to_curve(mesh, feature, boundary)
    _assert_well_formed(mesh, ext)
    assert ext.kind == "feature"
    x = mesh.xyz(ext.points)
    bx = mesh.xyz(boundary.points)
    end = mesh.xyz(feature.points[-1])[0]
    want = bx[np.argmin(np.linalg.norm(bx - end, axis=1))]
    assert_array_equal(x[-1], want)
    assert_array_equal(x[: len(feature)], mesh.xyz(feature.points))  # original kept
    start = extend_to_curve(mesh, feature, boundary, at="start")
    _assert_well_formed(mesh, start)
    s0 = mesh.xyz(feature.points[0])[0]
    assert_array_equal(mesh.xyz(start.points)[0], bx[np.argmin(np.linalg.norm(bx - s0, axis=1))])
    with pytest.raises(InputError, match="at must be"):
        extend_to_curve(mesh, feature, boundary, at="middle")
    closed = paint_curve(mesh, [65, 372, 300], closed=True)
    with pytest.raises(InputError, match="needs an open curve"):
        extend_to_curve(mesh, closed, boundary)


@pytest.mark.parametrize("name", ["spot", "nefertiti"])
def test_continuation_attraction_matches_the_reference(name):
    from meshfit.curves.base import _attract_few
    from meshfit.surface import greedy_path, path_to_surface_points
    from tests.reference import curves as reference

    mesh = real_mesh(name)
    v = mesh.vertices
    a, b = int(np.argmin(v[:, 1])), int(np.argmax(v[:, 0]))
    pts = path_to_surface_points(mesh, greedy_path(mesh, a, b).vertices, per_edge=1)
    x = mesh.xyz(pts)
    t = np.linspace(0.0, 1.0, len(pts))[:, None]
    targets = x[0] + t * (x[-1] - x[0])  # the chord: far under the surface in places
    got = _attract_few(mesh, pts.face, pts.bary, targets, chain=True)
    face, bary = reference.attract_chain(mesh, pts, targets)
    assert_array_equal(got.face, face)
    assert_allclose(got.bary, bary, rtol=0, atol=1e-15)
    # each point ends no farther from its target than where it started
    d_start = np.linalg.norm(x - targets, axis=1)
    d_end = np.linalg.norm(mesh.xyz(got) - targets, axis=1)
    assert (d_end <= d_start + _atol(mesh)).all()
