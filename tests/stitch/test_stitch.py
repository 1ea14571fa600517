import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.interpolate import RegularGridInterpolator

from meshfit import tol
from meshfit.bspline import BSplineSurface, fit_bspline, grid_parameters
from meshfit.displacement import displacement_map, reconstruct
from meshfit.errors import InputError
from meshfit.stitch import (
    control_classes,
    direction_classes,
    displacement_seam_gaps,
    match_map_shapes,
    network_from_grids,
    seam_report,
    side_row,
    stitch_displacements,
    stitch_surfaces,
    texel_shapes,
)
from tests.bspline.grids import scan_grid
from tests.stitch.networks import cube_sphere, height_field, split_grid


def _flip(g):
    return np.ascontiguousarray(g[::-1, ::-1])  # reverses every side, keeps the orientation


def _layouts():
    hf = split_grid(height_field(61), [30], [30])
    sphere = cube_sphere(33)
    sphere[2] = _flip(sphere[2])
    scan = split_grid(np.asarray(scan_grid("nefertiti", 61, 61)), [30], [20, 40])
    return {"height_field_2x2": hf, "cube_sphere": sphere, "nefertiti_2x3": scan}


LAYOUTS = _layouts()


def _fit(grids, net, m=8):
    cc = control_classes(net, default=m, grid_shapes=[g.shape[:2] for g in grids])
    return [fit_bspline(g, controls=c) for g, c in zip(grids, cc.controls, strict=True)]


def _diag(grids):
    p = np.concatenate([g.reshape(-1, 3) for g in grids])
    return float(np.linalg.norm(np.ptp(p, axis=0)))


def test_network_detection():
    hf = network_from_grids(LAYOUTS["height_field_2x2"])
    assert len(hf.boundaries) == 4
    assert sorted(len(c) for c in hf.corners) == [1, 1, 1, 1, 2, 2, 2, 2, 4]
    sph = network_from_grids(LAYOUTS["cube_sphere"])
    assert len(sph.boundaries) == 12
    assert [len(c) for c in sph.corners] == [3] * 8
    # the flipped face's four boundaries run against their neighbours
    assert sum(b.reversed for b in sph.boundaries) == 4
    assert all(b.reversed == (2 in (b.a, b.b)) for b in sph.boundaries)


def test_control_classes():
    grids = split_grid(height_field(61), [], [20, 40])  # three patches in a row along v
    net = network_from_grids(grids)
    cc = control_classes(net, default=[(6, 5), (9, 7), (7, 8)])
    # the shared sides run along u: one class of u counts, three separate v classes
    assert len(cc.counts) == 4
    assert [c[0] for c in cc.controls] == [9, 9, 9]
    assert [c[1] for c in cc.controls] == [5, 7, 8]
    cls_u = int(cc.labels[0, 0])
    cc2 = control_classes(net, default=6, counts={cls_u: 12})
    assert [c[0] for c in cc2.controls] == [12, 12, 12]
    sph = control_classes(network_from_grids(LAYOUTS["cube_sphere"]), default=7)
    assert len(sph.counts) == 3  # the cube's three edge directions
    capped = control_classes(net, default=50, grid_shapes=[g.shape[:2] for g in grids])
    assert capped.controls[0] == (50 if grids[0].shape[0] >= 50 else grids[0].shape[0], 21)
    with pytest.raises(InputError, match="class 9"):
        control_classes(net, counts={9: 5})
    with pytest.raises(InputError, match="needs 4"):
        control_classes(net, default=3)


@pytest.mark.parametrize("name", list(LAYOUTS))
def test_g1_stitching_meets_targets(name):
    grids = LAYOUTS[name]
    net = network_from_grids(grids)
    surfaces = _fit(grids, net)
    before = seam_report(surfaces, net)
    after = seam_report(stitch_surfaces(surfaces, net), net)
    diag = _diag(grids)
    assert before.gap.max() > tol.STITCH_GAP * diag  # independent fits do not meet
    assert after.gap.max() <= tol.STITCH_GAP * diag
    assert after.angle_deg.max() <= 0.5
    assert after.angle_corner_deg.max() <= 2.0
    assert after.corner_point_deg.max() <= 1e-5  # one tangent plane at every corner
    assert after.angle_deg.max() < before.angle_deg.max()


@pytest.mark.parametrize("name", ["height_field_2x2", "cube_sphere"])
def test_c0_and_per_boundary_choice(name):
    grids = LAYOUTS[name]
    net = network_from_grids(grids)
    surfaces = _fit(grids, net)
    diag = _diag(grids)
    c0 = seam_report(stitch_surfaces(surfaces, net.with_continuity("C0")), net)
    assert c0.gap.max() <= tol.STITCH_GAP * diag
    assert c0.angle_deg.max() > 0.01  # C0 leaves the creases of the independent fits
    mixed = net.with_continuity({0: "C0"})
    r = seam_report(stitch_surfaces(surfaces, mixed), mixed)
    assert r.gap.max() <= tol.STITCH_GAP * diag
    assert r.angle_deg[0] > 0.01
    assert r.angle_deg[1:].max() <= 0.5
    with pytest.raises(InputError, match="continuity"):
        net.with_continuity("C2")


def test_stitching_moves_only_boundary_and_corner_rows():
    grids = LAYOUTS["cube_sphere"]
    net = network_from_grids(grids)
    surfaces = _fit(grids, net)
    stitched = stitch_surfaces(surfaces, net)
    for s, t in zip(surfaces, stitched, strict=True):
        np.testing.assert_array_equal(t.control_points[2:-2, 2:-2], s.control_points[2:-2, 2:-2])
        # the tangent rows move only within two points of the corners (the corner ring, and
        # row 2 from a corner of valence 3 translated onto the corner's tangent plane)
        np.testing.assert_array_equal(t.control_points[1, 3:-3], s.control_points[1, 3:-3])
    # every patch meeting at a corner has the same tangent plane there
    for slots in net.corners:
        normals = [
            stitched[k].normals(np.array([float(i == -1)]), np.array([float(j == -1)]))[0]
            for k, i, j in slots
        ]
        for n in normals[1:]:
            assert_allclose(n, normals[0], atol=1e-12)


def test_stitch_rejects_inconsistent_counts():
    grids = LAYOUTS["height_field_2x2"]
    net = network_from_grids(grids)
    surfaces = [fit_bspline(g, controls=(6 + k, 6)) for k, g in enumerate(grids)]
    with pytest.raises(InputError, match="control points"):
        stitch_surfaces(surfaces, net)
    with pytest.raises(InputError, match="surfaces for a network"):
        stitch_surfaces(surfaces[:2], net)
    bad = BSplineSurface(surfaces[0].control_points, np.r_[0, 0, 0, 0, 0.2, 0.3, 1, 1, 1, 1])
    with pytest.raises(InputError, match="uniform"):
        stitch_surfaces([bad, *surfaces[1:]], net)


@pytest.mark.parametrize("flipped", [False, True])
def test_displacement_seams_become_crack_free(flipped):
    # faces of different (nested) resolutions: 33 on face 0, 17 elsewhere; flipped, face 2
    # runs against its four neighbours (two of its seams are 33 against 17 and reversed)
    grids = cube_sphere(17, resolutions={0: 33})
    if flipped:
        grids[2] = _flip(grids[2])
    net = network_from_grids(grids)
    assert any(b.reversed and 0 in (b.a, b.b) for b in net.boundaries) == flipped
    surfaces = stitch_surfaces(_fit(grids, net, m=6), net)
    maps = [displacement_map(s, g) for s, g in zip(surfaces, grids, strict=True)]
    diag = _diag(grids)
    before = displacement_seam_gaps(surfaces, maps, net)
    fixed = stitch_displacements(surfaces, maps, net)
    after = displacement_seam_gaps(surfaces, fixed, net)
    assert before.max() > 1e-6 * diag  # T-joints of the finer face open cracks
    assert after.max() <= tol.STITCH_GAP * diag
    # equal-resolution seams were already closed and interiors are untouched
    for g, s, m in zip(grids, surfaces, fixed, strict=True):
        assert_allclose(reconstruct(s, m)[1:-1, 1:-1], g[1:-1, 1:-1], atol=1e-12 * diag)
    # seams of equal resolutions are crack-free at any output resolution too
    cont = displacement_seam_gaps(surfaces, fixed, net, tessellation="continuous")
    equal = np.array([0 not in (b.a, b.b) for b in net.boundaries])
    assert cont[equal].max() <= tol.STITCH_GAP * diag
    b = next(b for b in net.boundaries if 0 not in (b.a, b.b))
    ra = reconstruct(surfaces[b.a], fixed[b.a], shape=(65, 65))
    rb = reconstruct(surfaces[b.b], fixed[b.b], shape=(65, 65))
    row_b = side_row(rb, b.side_b)
    row_b = row_b[::-1] if b.reversed else row_b
    assert_allclose(side_row(ra, b.side_a), row_b, atol=tol.STITCH_GAP * diag)
    with pytest.raises(InputError, match="tessellation"):
        displacement_seam_gaps(surfaces, fixed, net, tessellation="other")
    with pytest.raises(InputError, match="vector map it scales"):
        stitch_displacements(
            surfaces, [displacement_map(surfaces[0], grids[0], kind="magnitude")] * 6, net
        )


def test_direction_classes_and_texel_shapes():
    grids = split_grid(height_field(61), [], [20, 40])  # three patches in a row along v
    net = network_from_grids(grids)
    labels = direction_classes(net)
    # numbered by first appearance; the shared u direction is one class
    assert labels.tolist() == [[0, 1], [0, 2], [0, 3]]
    assert texel_shapes(net, [(9, 5), (17, 7), (12, 8)]) == [(17, 5), (17, 7), (17, 8)]
    sph = network_from_grids(LAYOUTS["cube_sphere"])
    assert sorted(set(direction_classes(sph).ravel().tolist())) == [0, 1, 2]
    shapes = texel_shapes(sph, [(17, 17)] * 5 + [(33, 17)])
    # face 5's u direction runs along four faces (the cube edges parallel to it)
    wide = direction_classes(sph) == direction_classes(sph)[5, 0]
    assert (np.array(shapes) == np.where(wide, 33, 17)).all()
    assert wide.sum() == 4
    with pytest.raises(InputError, match="3 shapes"):
        texel_shapes(sph, [(5, 5)] * 3)
    with pytest.raises(InputError, match="2 x 2"):
        texel_shapes(net, [(9, 5), (1, 7), (12, 8)])


@pytest.mark.parametrize("budget", [1.0, 1.5, 3.0, 100.0])
def test_texel_shapes_within_a_budget_keep_equal_counts(budget):
    """Capped classes: equal counts along shared boundaries (the shapes match themselves),
    within the budget, and the largest cap that is (one more exceeds it)."""
    sph = network_from_grids(LAYOUTS["cube_sphere"])
    native = [(9, 9)] * 4 + [(65, 9), (9, 5)]  # a long strip: its class spans four faces
    free = texel_shapes(sph, native)
    capped = texel_shapes(sph, native, budget=budget)
    area = sum(h * w for h, w in native)
    assert texel_shapes(sph, capped) == capped
    assert sum(h * w for h, w in capped) <= budget * area
    assert (np.array(capped) <= np.array(free)).all()
    top = max(max(c) for c in capped)
    if capped != free:  # one more texel on the capped classes would pass the budget
        more = [tuple(min(f, top + 1) for f in ff) for ff in free]
        assert sum(h * w for h, w in more) > budget * area
    with pytest.raises(InputError, match="at least 1"):
        texel_shapes(sph, native, budget=0.5)


def test_matched_maps_close_seams_at_any_resolution():
    grids = cube_sphere(17, resolutions={0: 33})  # face 0 finer: seams of 33 against 17
    net = network_from_grids(grids)
    surfaces = stitch_surfaces(_fit(grids, net, m=6), net)
    maps = [displacement_map(s, g) for s, g in zip(surfaces, grids, strict=True)]
    diag = _diag(grids)
    matched = match_map_shapes(surfaces, maps, net)
    assert matched[0] is maps[0]  # the finest map is kept as it is
    for b in net.boundaries:
        na = side_row(matched[b.a].values, b.side_a).shape[0]
        assert na == side_row(matched[b.b].values, b.side_b).shape[0]
    for s, m, mm in zip(surfaces, maps, matched, strict=True):
        # the finer displaced grid is the bilinear interpolation of the old one
        X = reconstruct(s, m)
        (h, w), (h2, w2) = m.shape, mm.shape
        old = RegularGridInterpolator((grid_parameters(h), grid_parameters(w)), X)
        U, V = np.meshgrid(grid_parameters(h2), grid_parameters(w2), indexing="ij")
        want = old(np.stack([U, V], axis=-1))
        assert_allclose(reconstruct(s, mm), want, atol=1e-12 * diag)
    fixed = stitch_displacements(surfaces, matched, net)
    cont = displacement_seam_gaps(surfaces, fixed, net, tessellation="continuous")
    assert cont.max() <= tol.STITCH_GAP * diag
    unmatched = stitch_displacements(surfaces, maps, net)
    cont0 = displacement_seam_gaps(surfaces, unmatched, net, tessellation="continuous")
    assert cont0.max() > 1e-6 * diag  # the 33 / 17 seams without matching
    scalar = displacement_map(surfaces[0], grids[0], kind="scalar")
    with pytest.raises(InputError, match="one kind"):
        match_map_shapes(surfaces, [scalar, *maps[1:]], net)
    with pytest.raises(InputError, match="5 maps"):
        match_map_shapes(surfaces, maps[:5], net)


@pytest.mark.parametrize("name", ["height_field_2x2", "nefertiti_2x3"])
def test_valence_two_and_four_corners_are_g1_to_the_end(name):
    """Border corners of valence 2 and interior corners of valence 4 get collinear, equally
    spaced rows at the corner too, so the normals agree along the whole boundary."""
    grids = LAYOUTS[name]
    net = network_from_grids(grids)
    assert {len(c) for c in net.corners} <= {1, 2, 4}
    r = seam_report(stitch_surfaces(_fit(grids, net), net), net)
    assert r.angle_corner_deg.max() <= 1e-5  # arccos resolution near 0 is ~1e-6 degree


def test_stitching_commutes_with_rigid_motions():
    """Stitching a moved network gives the stitched network moved (the corner fans are
    fitted in each corner's own plane, solved once and turned, never tied to the axes)."""
    grids = LAYOUTS["cube_sphere"]  # valence-3 corners: the fan turn is searched
    net = network_from_grids(grids)
    surfaces = _fit(grids, net)
    q, _ = np.linalg.qr(np.random.default_rng(3).normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))  # a rotation, not a reflection
    shift = np.array([2.0, -1.0, 0.5])
    moved = [s.with_control_points(s.control_points @ q.T + shift) for s in surfaces]
    a = stitch_surfaces(surfaces, net)
    b = stitch_surfaces(moved, net)
    for x, y in zip(a, b, strict=True):
        assert_allclose(y.control_points, x.control_points @ q.T + shift, atol=1e-9)
