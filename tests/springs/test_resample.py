"""resample_patch on analytic patches (exact grids), feature curves, and patches cut from scans."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from numpy.testing import assert_allclose

from meshfit import tol
from meshfit.errors import FeatureCurveError, InputError
from meshfit.springs import (
    ANCHOR,
    BOUNDARY,
    CURVE,
    FREE,
    SpringOptions,
    grid_metrics,
    resample_patch,
    resample_patches,
)
from meshfit.types import SurfaceCurve, SurfacePoints

from ..conftest import real_mesh
from .patches import (
    cap_map,
    cut_patch,
    cylinder_map,
    param_patch,
    plane_map,
    with_features,
)


def assert_on_patch(patch, spring):
    """Spring points are valid face points of the patch mesh."""
    f, b = spring.points.face, spring.points.bary
    assert f.min() >= 0 and f.max() < patch.mesh.n_faces
    assert (b >= -tol.BARY_EPS).all()
    assert_allclose(b.sum(axis=1), 1.0, atol=1e-12)
    assert_allclose(spring.xyz.reshape(-1, 3), patch.mesh.xyz(spring.points), atol=1e-12)


@pytest.fixture(scope="module")
def plane():
    return param_patch(plane_map(2.0, 1.0), 40, 20)


def test_plane_gives_the_analytic_grid(plane):
    res = resample_patch(plane)
    sm = res.final
    nu, nv = sm.shape
    assert (nu - 1) == 2 * (nv - 1)  # aspect ratio 2 kept from level 0 on
    assert nu * nv == pytest.approx(plane.mesh.n_vertices, rel=1.0)
    u, v = np.meshgrid(np.linspace(0, 2, nu), np.linspace(0, 1, nv), indexing="ij")
    want = np.stack([u, v, np.zeros_like(u)], axis=-1)
    # relaxation stops on a small RMS move, not at the exact equilibrium: 0.5% of the spacing
    assert_allclose(sm.xyz, want, atol=5e-3 / (nv - 1))
    for lvl in res.levels:
        assert_on_patch(plane, lvl)
    m = res.metrics[-1]
    assert m["folded"] == 0 and m["arc_cv_max"] < 1e-3
    assert m["aspect_median"] == pytest.approx(1.0, abs=1e-3)


def test_every_level_is_kept_and_the_grid_doubles(plane):
    res = resample_patch(plane, SpringOptions(level=3, metrics=False))
    assert [lv.level for lv in res.levels] == [0, 1, 2, 3]
    shapes = [lv.shape for lv in res.levels]
    for (a, b), (c, d) in itertools.pairwise(shapes):
        assert (c, d) == (2 * a - 1, 2 * b - 1)
    # coarse points keep their places at even indices of the next level only up to the
    # relaxation's moves: on a plane they do not move at all
    assert_allclose(res.levels[3].xyz[::2, ::2], res.levels[2].xyz, atol=1e-3 / 8)
    kind = res.final.kind
    assert (kind[0] == BOUNDARY).all() and (kind[:, -1] == BOUNDARY).all()
    assert (kind[1:-1, 1:-1] == FREE).all()


def test_cylinder_gives_the_analytic_grid():
    angle, height = np.pi / 2, 1.5
    patch = param_patch(cylinder_map(1.0, height, angle), 48, 24)
    sm = resample_patch(patch).final
    nu, nv = sm.shape
    th = np.arctan2(sm.xyz[..., 1], sm.xyz[..., 0])
    z = sm.xyz[..., 2]
    # the mesh is a polyhedral cylinder: angles are uniform up to its chord error
    assert_allclose(th, np.linspace(0, angle, nu)[:, None] * np.ones(nv), atol=2e-3)
    spacing = height / (nv - 1)
    assert_allclose(z, np.ones(nu)[:, None] * np.linspace(0, height, nv), atol=5e-3 * spacing)


def test_sphere_cap_is_symmetric_fair_and_unfolded():
    patch = param_patch(cap_map(), 32, 32)
    res = resample_patch(patch, SpringOptions(scale=patch.mesh.bbox_diagonal))
    sm = res.final
    # the cap is symmetric under x -> -x (i -> nu - 1 - i) and y -> -y
    X = sm.xyz
    assert_allclose(X[::-1, :, 0], -X[:, :, 0], atol=5e-3)
    assert_allclose(X[:, ::-1, 1], -X[:, :, 1], atol=5e-3)
    for m in res.metrics:
        assert m["folded"] == 0
        assert m["arc_cv_max"] <= 0.15 and m["aspect_median"] <= 1.5
    assert res.metrics[-1]["fidelity_max"] <= 5e-4


def _polyline_distance(P, Q):
    """Distance from each point of P (n, 3) to the polyline Q (m, 3)."""
    a, b = Q[:-1], Q[1:]
    d = b - a
    dd = np.einsum("mk,mk->m", d, d)
    t = np.einsum("pmk,mk->pm", P[:, None] - a, d) / np.where(dd > 0, dd, 1.0)
    t = np.clip(t, 0, 1)
    q = a + t[..., None] * d
    return np.linalg.norm(P[:, None] - q, axis=2).min(axis=1)


def curve_distance(mesh, curve: SurfaceCurve, P, n: int = 200_000):
    """Distance from points P (k, 3) to a face-point curve, with its resolution.

    The curve is sampled at ``n + 1`` equally spaced arc lengths with
    :func:`meshfit.surface.move_along_curve` (exactly on its surface segments); a point on
    the curve is within half a sample spacing of a sample. Returns (distances, spacing).
    """
    from scipy.spatial import cKDTree

    from meshfit.surface import curve_arc_lengths, move_along_curve

    total = curve_arc_lengths(mesh, curve)[-1]
    dense = mesh.xyz(move_along_curve(mesh, curve, np.linspace(0, total, n + 1), 0.0).points)
    d, _ = cKDTree(dense).query(np.asarray(P).reshape(-1, 3))
    return d, total / n


@pytest.mark.parametrize("shape", ["plane", "cylinder", "cap"])
def test_feature_curves_are_interpolated_exactly(shape):
    fn = {"plane": plane_map(), "cylinder": cylinder_map(), "cap": cap_map()}[shape]
    patch = with_features(param_patch(fn, 32, 24), fn, us=(0.3, 0.6), vs=(0.45,))
    res = resample_patch(patch, SpringOptions(sections_u=(2, 2, 3), sections_v=(2, 3)))
    sm = res.final
    assert sm.u_lines.tolist() == [2 * 2**sm.level, 4 * 2**sm.level]
    assert sm.v_lines.tolist() == [2 * 2**sm.level]
    for k, col in enumerate(sm.u_lines):
        # curve points and anchors on the curve (within the check's resolution); the ends
        # are side points (the side's resampling at the feature's end, within
        # tol.FEATURE_END_ON_SIDE of it)
        d, res_ = curve_distance(patch.mesh, patch.features[k], sm.xyz[col])
        assert d[1:-1].max() <= res_
        assert d[[0, -1]].max() <= tol.length(patch.mesh, tol.FEATURE_END_ON_SIDE)
        assert (sm.kind[col, 1:-1] != FREE).all()
    d, res_ = curve_distance(patch.mesh, patch.features[2], sm.xyz[:, sm.v_lines[0]])
    assert d[1:-1].max() <= res_
    assert (sm.kind[np.ix_(sm.u_lines, sm.v_lines)] == ANCHOR).all()
    assert (sm.kind == CURVE).sum() > 0
    for lvl, m in zip(res.levels, res.metrics, strict=True):
        assert_on_patch(patch, lvl)
        assert m["folded"] == 0
        assert m["arc_cv_max"] <= 0.15


def test_feature_curve_not_side_to_side_raises(plane):
    fn = plane_map(2.0, 1.0)
    p = with_features(plane, fn, us=(0.5,))
    bad = type(p)(
        p.index, p.mesh, p.corners, p.sides, p.face_parent, p.vertex_source, p.features, ((0, 1),)
    )
    with pytest.raises(FeatureCurveError, match="opposite side"):
        resample_patch(bad)


def test_feature_curve_ending_inside_raises(plane):
    fn = plane_map(2.0, 1.0)
    p = with_features(plane, fn, us=(0.5,))
    pts = p.features[0].points
    short = SurfaceCurve(SurfacePoints(pts.face[:300], pts.bary[:300]), kind="feature")
    bad = type(p)(
        p.index, p.mesh, p.corners, p.sides, p.face_parent, p.vertex_source, (short,), ((0, 2),)
    )
    with pytest.raises(FeatureCurveError, match="last point"):
        resample_patch(bad)


def test_crossing_feature_curves_raise(plane):
    from meshfit.surface import closest_surface_points

    fn = plane_map(2.0, 1.0)
    r = np.linspace(0, 1, 300)
    a = closest_surface_points(plane.mesh, fn(0.3 + 0.4 * r, r))
    b = closest_surface_points(plane.mesh, fn(0.7 - 0.4 * r, r))
    feats = tuple(SurfaceCurve(x, kind="feature") for x in (a, b))
    bad = type(plane)(
        0, plane.mesh, plane.corners, plane.sides, plane.face_parent, plane.vertex_source,
        feats, ((0, 2), (0, 2)),
    )  # fmt: skip
    with pytest.raises(FeatureCurveError, match="cross"):
        resample_patch(bad)


def test_bad_options_raise(plane):
    with pytest.raises(InputError):
        resample_patch(plane, SpringOptions(fairness=2.0))
    with pytest.raises(InputError):
        resample_patch(plane, SpringOptions(level=-1))
    with pytest.raises(InputError):
        resample_patch(plane, SpringOptions(max_points=3))
    with pytest.raises(InputError, match="sections_u"):
        resample_patch(plane, SpringOptions(sections_u=(1, 2)))
    with pytest.raises(InputError, match="polish"):
        resample_patch(plane, SpringOptions(polish=-1))


def test_resample_patches_gives_each_patch_its_own_result_in_order(plane):
    cyl = param_patch(cylinder_map(1.0, 2.0), 24, 24)
    done = []
    opts = SpringOptions(level=1, metrics=False)
    res = resample_patches(
        [plane, cyl, plane], opts, workers=2, progress=lambda d, n: done.append((d, n))
    )
    assert done == [(1, 3), (2, 3), (3, 3)]
    alone = [resample_patch(p, SpringOptions(level=1, metrics=False)) for p in (plane, cyl)]
    for got, want in zip(res, [*alone, alone[0]], strict=True):
        assert got.final.level == 1 and not got.metrics[0]
        assert np.array_equal(got.final.points.face, want.final.points.face)
        assert np.array_equal(got.final.points.bary, want.final.points.bary)


def test_resample_patches_rejects_bad_options(plane):
    with pytest.raises(TypeError, match="levle"):
        resample_patches([plane], SpringOptions(levle=1))
    with pytest.raises(InputError, match="workers"):
        resample_patches([plane], workers=0)
    with pytest.raises(InputError, match="fairness"):  # raised from the patch's thread
        resample_patches([plane, plane], SpringOptions(fairness=2.0), workers=2)


def test_a_patch_of_another_type_is_refused():
    with pytest.raises(InputError, match=r"patch must be a meshfit\.layout\.Patch .* got str"):
        resample_patch("patch 0")


def test_max_points_caps_the_level(plane):
    res = resample_patch(plane, SpringOptions(max_points=300, metrics=False))
    assert res.final.n_points <= 300
    assert len(res.levels) == res.final.level + 1


def test_a_level_past_the_point_limit_is_refused(plane, monkeypatch):
    # each level has four times the points of the last: a level well past the vertex count
    # would exhaust the memory (spot's test layout at level 9: 25 million points a patch)
    from meshfit.springs import resample as rs

    with pytest.raises(InputError, match=r"level 9 gives patch 0 .* ask for level 7 or less"):
        resample_patch(plane, SpringOptions(level=9, metrics=False))  # 16 x 8 intervals at level 0
    # the limit is the grid's: a lower one refuses lower levels, and max_points lowers the
    # level to fit instead of refusing
    monkeypatch.setattr(rs, "LEVEL_MAX_POINTS", 1000)
    with pytest.raises(InputError, match=r"65 x 33 grid, 2,145 points.*level 1 or less"):
        resample_patch(plane, SpringOptions(level=2, metrics=False))
    assert resample_patch(plane, SpringOptions(level=1, metrics=False)).final.shape == (33, 17)
    assert (
        resample_patch(plane, SpringOptions(level=2, max_points=600, metrics=False)).final.level
        == 1
    )


def test_progress_reports_each_level(plane):
    calls = []
    resample_patch(
        plane, SpringOptions(level=2, metrics=False), progress=lambda d, t: calls.append((d, t))
    )
    assert calls == [(1, 3), (2, 3), (3, 3)]


def test_grid_metrics_of_a_known_grid():
    u, v = np.meshgrid(np.linspace(0, 2, 5), np.linspace(0, 1, 3), indexing="ij")
    X = np.stack([u, v**2, np.zeros_like(u)], axis=-1)
    N = np.zeros_like(X)
    N[..., 2] = 1.0
    patch = param_patch(plane_map(2.0, 1.0), 8, 4)
    m = grid_metrics(patch.mesh, X, N, fidelity=False)
    # rows are uniform, columns have spacings 0.25 and 0.75: CV 0.5 along each column
    assert m["arc_cv_max"] == pytest.approx(0.5)
    assert m["folded"] == 0
    N[..., 2] = -1.0
    assert grid_metrics(patch.mesh, X, N, fidelity=False)["folded"] == 8


# --------------------------------------------------------------- patches cut from real scans

SCANS = [("igea", 1000, 0.02), ("nefertiti", 20000, 60.0)]


@pytest.fixture(scope="module", params=SCANS, ids=[s[0] for s in SCANS])
def scan_result(request):
    name, center, radius = request.param
    mesh = real_mesh(name)
    patch = cut_patch(mesh, center, radius)
    return name, patch, resample_patch(patch, SpringOptions(scale=mesh.bbox_diagonal))


def test_scan_patch_levels_are_unfolded_and_on_the_patch(scan_result):
    _, patch, res = scan_result
    for lvl, m in zip(res.levels, res.metrics, strict=True):
        assert_on_patch(patch, lvl)
        assert m["folded"] == 0, f"level {lvl.level}"


def test_scan_patch_uniformity_and_aspect(scan_result):
    _, _, res = scan_result
    for m in res.metrics:
        assert m["arc_cv_max"] <= 0.15
        assert m["aspect_median"] <= 1.5


def test_scan_patch_fidelity(scan_result, request):
    name, _, res = scan_result
    if name == "nefertiti":
        request.applymarker(
            pytest.mark.xfail(
                strict=True,
                reason="nefertiti cut patch: two-sided max distance 0.098% of the bbox "
                "diagonal at the final level (33 x 41 points for 1669 vertices)",
            )
        )
    assert res.metrics[-1]["fidelity_max"] <= 5e-4
