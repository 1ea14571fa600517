"""Seams of every map kind (Krishnamurthy 2000, sec. 8.2): vector and scalar maps rebuild
crack-free displaced seams, bump maps shade without a seam across G1 boundaries and keep a
crease's shading across C0 ones; corners where several patches meet agree."""

from functools import cache

import numpy as np
import pytest
from numpy.testing import assert_allclose

from meshfit import tol
from meshfit.bspline import BSplineSurface, fit_bspline
from meshfit.displacement import DisplacementMap, bump_normals, displacement_map, reconstruct
from meshfit.errors import InputError
from meshfit.stitch import (
    bump_seam_angles,
    control_classes,
    displacement_seam_gaps,
    match_map_shapes,
    network_from_grids,
    seam_report,
    side_row,
    stitch_displacements,
    stitch_surfaces,
)
from tests.stitch.networks import cube_sphere, height_field, roof, split_grid

KINDS = ("vector", "scalar", "bump")


def _crease(net):
    """The roof's network: the two boundaries along its ridge (between the patches on
    either side of x = 1) C0, the others G1."""
    return net.with_continuity(
        {k: "C0" for k, b in enumerate(net.boundaries) if {b.a, b.b} in ({0, 2}, {1, 3})}
    )


def _grids(name):
    if name == "height_field_2x2":  # split grids of one surface: valence 2 and 4 corners
        return split_grid(height_field(61), [30], [30])
    if name == "roof_2x2":
        return split_grid(roof(61), [30], [30])
    grids = cube_sphere(17)  # valence-3 corners; face 2 runs against its neighbours
    grids[2] = np.ascontiguousarray(grids[2][::-1, ::-1])
    return grids


@cache
def _network(name):
    """Grids, network and stitched surfaces of one test network."""
    grids = _grids(name)
    net = network_from_grids(grids)
    if name == "roof_2x2":
        net = _crease(net)
    m = 6 if name == "cube_sphere" else 8
    cc = control_classes(net, default=m, grid_shapes=[g.shape[:2] for g in grids])
    fits = [fit_bspline(g, controls=c) for g, c in zip(grids, cc.controls, strict=True)]
    return grids, net, stitch_surfaces(fits, net)


def _diag(grids):
    p = np.concatenate([g.reshape(-1, 3) for g in grids])
    return float(np.linalg.norm(np.ptp(p, axis=0)))


def _maps(surfaces, grids, kind):
    return [displacement_map(s, g, kind=kind) for s, g in zip(surfaces, grids, strict=True)]


@pytest.mark.parametrize("name", ["height_field_2x2", "cube_sphere", "roof_2x2"])
@pytest.mark.parametrize("kind", KINDS)
def test_stitched_seams_close_for_every_kind(name, kind):
    grids, net, surfaces = _network(name)
    diag = _diag(grids)
    maps = _maps(surfaces, grids, kind)
    fixed = stitch_displacements(surfaces, maps, net)
    assert [m.kind for m in fixed] == [kind] * len(maps)
    assert [m.shape for m in fixed] == [m.shape for m in maps]
    for tess in ("texels", "continuous"):
        gaps = displacement_seam_gaps(surfaces, fixed, net, tessellation=tess)
        assert gaps.max() <= tol.STITCH_GAP * diag, tess
    if kind == "scalar":  # each patch's own values along its own normal do not meet
        assert displacement_seam_gaps(surfaces, maps, net).max() > 1e-6 * diag
    if kind == "bump":
        g1 = np.array([b.continuity == "G1" for b in net.boundaries])
        before = bump_seam_angles(surfaces, maps, net)
        after = bump_seam_angles(surfaces, fixed, net)
        assert before[g1].min() > 0.5  # one-sided grid normals differ across every seam
        assert after[g1].max() <= 1e-5  # degrees: arccos's resolution near 0
        # across the crease the shading keeps the crease
        assert_allclose(after[~g1], before[~g1], rtol=1e-12)
    # interiors are untouched (scalar maps: beyond the seam row, the default blend)
    for m, f in zip(maps, fixed, strict=True):
        np.testing.assert_array_equal(f.values[1:-1, 1:-1], m.values[1:-1, 1:-1])


@pytest.mark.parametrize("name", ["height_field_2x2", "cube_sphere", "roof_2x2"])
@pytest.mark.parametrize("kind", ["vector", "scalar"])
def test_corners_agree(name, kind):
    """Every patch meeting at a network corner reaches the same displaced corner point."""
    grids, net, surfaces = _network(name)
    diag = _diag(grids)
    fixed = stitch_displacements(surfaces, _maps(surfaces, grids, kind), net)
    for slots in net.corners:
        pts = [reconstruct(surfaces[k], fixed[k])[i, j] for k, i, j in slots]
        for p in pts[1:]:
            assert_allclose(p, pts[0], rtol=0, atol=tol.STITCH_GAP * diag)


def test_bump_corners_average_over_g1_neighbours_only():
    grids, net, surfaces = _network("roof_2x2")
    fixed = stitch_displacements(surfaces, _maps(surfaces, grids, "bump"), net)
    (centre,) = [c for c in net.corners if len(c) == 4]
    n = {k: bump_normals(surfaces[k], fixed[k])[i, j] for k, i, j in centre}
    # patches 0, 1 lie on one side of the ridge, 2, 3 on the other (G1 pairs)
    assert_allclose(n[1], n[0], atol=1e-12)
    assert_allclose(n[3], n[2], atol=1e-12)
    assert np.degrees(np.arccos(n[0] @ n[2])) > 30.0


def test_scalar_seams_across_a_crease_are_the_spline_boundary():
    """Across the C0 ridge the normals differ, so the seam row's value is 0 to within
    ``gap / |N_a - N_b|``: the displaced seam is the shared spline boundary. Along the G1
    boundaries away from the ridge the two maps' mean is kept."""
    grids, net, surfaces = _network("roof_2x2")
    diag = _diag(grids)
    assert seam_report(surfaces, net).angle_deg.max() > 30.0  # a real crease
    maps = _maps(surfaces, grids, "scalar")
    fixed = stitch_displacements(surfaces, maps, net)
    for b in net.boundaries:
        row_a = side_row(fixed[b.a].values[..., 0], b.side_a)
        row_b = side_row(fixed[b.b].values[..., 0], b.side_b)
        assert_allclose(row_a, row_b[::-1] if b.reversed else row_b, rtol=0, atol=0)
        if b.continuity == "C0":
            assert np.abs(row_a).max() <= tol.STITCH_GAP * diag
        else:  # the mean, away from the end on the ridge (the centre corner is C0)
            old_a = side_row(maps[b.a].values[..., 0], b.side_a)
            old_b = side_row(maps[b.b].values[..., 0], b.side_b)
            mean = 0.5 * (old_a + (old_b[::-1] if b.reversed else old_b))
            far = np.abs(side_row(grids[b.a], b.side_a)[:, 0] - 1.0) > 0.5  # from the ridge
            assert_allclose(row_a[far], mean[far], rtol=1e-12)
            assert np.abs(mean[far]).max() > 1e-4 * diag
    # blending over 3 texels: the change fades out, the seam rows are the same
    wide = stitch_displacements(surfaces, maps, net, blend=3)
    for b in net.boundaries:
        for k, side in ((b.a, b.side_a), (b.b, b.side_b)):
            np.testing.assert_array_equal(
                side_row(wide[k].values, side), side_row(fixed[k].values, side)
            )
    for m, w in zip(maps, wide, strict=True):
        np.testing.assert_array_equal(w.values[3:-3, 3:-3], m.values[3:-3, 3:-3])
        assert not np.array_equal(w.values[1:3], m.values[1:3])
    assert displacement_seam_gaps(surfaces, wide, net).max() <= tol.STITCH_GAP * diag
    # a looser gap keeps more of the detail along the crease
    loose = stitch_displacements(surfaces, maps, net, gap=1e-3 * diag)
    assert displacement_seam_gaps(surfaces, loose, net).max() <= 1e-3 * diag * (1 + 1e-9)
    c0 = next(b for b in net.boundaries if b.continuity == "C0")
    assert np.abs(side_row(loose[c0.a].values, c0.side_a)).max() > 1e3 * tol.STITCH_GAP * diag


@pytest.mark.parametrize("kind", KINDS)
def test_stitching_twice_changes_nothing(kind):
    grids, net, surfaces = _network("cube_sphere")
    once = stitch_displacements(surfaces, _maps(surfaces, grids, kind), net, blend=2)
    twice = stitch_displacements(surfaces, once, net, blend=2)
    for a, b in zip(once, twice, strict=True):
        assert_allclose(b.values, a.values, rtol=0, atol=1e-15 * max(1.0, _diag(grids)))


@pytest.mark.parametrize("kind", ["scalar", "bump"])
def test_unequal_counts(kind):
    """Face 0 at 33 texels against 17 (nested): stitched as they are, the seams close as
    read at any common resolution; matched first, they close everywhere."""
    grids = cube_sphere(17, resolutions={0: 33})
    net = network_from_grids(grids)
    cc = control_classes(net, default=6, grid_shapes=[g.shape[:2] for g in grids])
    fits = [fit_bspline(g, controls=c) for g, c in zip(grids, cc.controls, strict=True)]
    surfaces = stitch_surfaces(fits, net)
    diag = _diag(grids)
    maps = _maps(surfaces, grids, kind)
    fixed = stitch_displacements(surfaces, maps, net)
    matched = stitch_displacements(surfaces, match_map_shapes(surfaces, maps, net), net)
    if kind == "scalar":
        cont = displacement_seam_gaps(surfaces, fixed, net, tessellation="continuous")
        assert cont.max() <= tol.STITCH_GAP * diag
        assert displacement_seam_gaps(surfaces, matched, net).max() <= tol.STITCH_GAP * diag
    else:  # normalised interpolation of interpolated normals: nearly the coarse row's
        assert bump_seam_angles(surfaces, fixed, net).max() <= 0.01
        assert bump_seam_angles(surfaces, matched, net).max() <= 1e-5


@pytest.mark.parametrize("scale", [1e-3, 1.0, 250.0])
def test_stitched_scalar_maps_follow_rigid_motions_and_scalings(scale):
    grids, net, surfaces = _network("cube_sphere")
    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]]
    )
    move = lambda P: scale * P @ R.T + [3.0, -2.0, 7.0]  # noqa: E731
    moved = [s.with_control_points(move(s.control_points)) for s in surfaces]
    maps = _maps(moved, [move(g) for g in grids], "scalar")
    diag = _diag(grids)
    # the default gap follows the bounding box, which turns with the network: give it
    gap = 0.5 * tol.STITCH_GAP * diag
    base = stitch_displacements(surfaces, _maps(surfaces, grids, "scalar"), net, gap=gap)
    got = stitch_displacements(moved, maps, net, gap=scale * gap)
    for a, b in zip(base, got, strict=True):
        assert_allclose(b.values, scale * a.values, rtol=0, atol=1e-9 * scale * diag)
    for fixed in (got, stitch_displacements(moved, maps, net)):
        assert displacement_seam_gaps(moved, fixed, net).max() <= tol.STITCH_GAP * scale * diag


def test_bad_map_sets():
    grids, net, surfaces = _network("height_field_2x2")
    vec = _maps(surfaces, grids, "vector")
    sca = _maps(surfaces, grids, "scalar")
    with pytest.raises(InputError, match="one kind"):
        stitch_displacements(surfaces, [sca[0], *vec[1:]], net)
    with pytest.raises(InputError, match="vector map it scales"):
        stitch_displacements(surfaces, _maps(surfaces, grids, "magnitude"), net)
    with pytest.raises(InputError, match="blend"):
        stitch_displacements(surfaces, sca, net, blend=0)
    with pytest.raises(InputError, match="gap"):
        stitch_displacements(surfaces, sca, net, gap=-1.0)
    with pytest.raises(InputError, match="bump maps"):
        bump_seam_angles(surfaces, vec, net)
    flat = [DisplacementMap(np.zeros((*m.shape, 1)), "scalar") for m in sca]
    fixed = stitch_displacements(surfaces, flat, net)
    assert all(not f.values.any() for f in fixed)  # nothing to close: nothing moves
    assert isinstance(surfaces[0], BSplineSurface)
