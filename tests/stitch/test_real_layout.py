"""Stitching the spring meshes of a real layout: a 2 x 2 cube layout of igea (24 patches)."""

import numpy as np
import pytest

from meshfit import tol
from meshfit.bspline import fit_bspline
from meshfit.displacement import displacement_map
from meshfit.stitch import (
    control_classes,
    displacement_seam_gaps,
    network_from_grids,
    seam_report,
    side_row,
    stitch_displacements,
    stitch_surfaces,
)
from tests.conftest import real_mesh

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def igea_layout():
    from meshfit.layout import cube_layout, extract_patches
    from meshfit.springs import resample_patch

    mesh = real_mesh("igea")
    patches = extract_patches(mesh, cube_layout(mesh, n=2))
    grids = [resample_patch(p, level=2, metrics=False, fidelity=False).final.xyz for p in patches]
    net = network_from_grids(grids)
    cc = control_classes(net, default=8, grid_shapes=[g.shape[:2] for g in grids])
    surfaces = [fit_bspline(g, controls=c) for g, c in zip(grids, cc.controls, strict=True)]
    return grids, net, surfaces, mesh.bbox_diagonal


def test_network_of_the_cube_layout(igea_layout):
    grids, net, _, _ = igea_layout
    assert len(grids) == 24
    assert len(net.boundaries) == 48  # every side shared once
    assert sorted(len(c) for c in net.corners) == [3] * 8 + [4] * 18


def test_gaps_close_and_boundaries_are_g1(igea_layout):
    _, net, surfaces, diag = igea_layout
    before = seam_report(surfaces, net)
    after = seam_report(stitch_surfaces(surfaces, net), net)
    assert before.gap.max() > 1e-4 * diag
    assert after.gap.max() <= tol.STITCH_GAP * diag
    assert after.angle_deg.max() <= 0.5  # away from the corners
    # at the corner points themselves: every corner whose rule did not fold a patch
    assert (after.corner_point_deg <= 1e-5).mean() >= 0.9


@pytest.mark.xfail(
    strict=True,
    reason="corner zones of the igea spring meshes keep normal jumps above 2 degrees (the "
    "spring meshes' corner cells are sheared 30-175 degrees, the fitted corner normals are "
    "up to 80 degrees off the grid's; a corner rule that would fold a patch is abandoned)",
)
def test_corner_zones_within_two_degrees(igea_layout):
    _, net, surfaces, _ = igea_layout
    assert seam_report(stitch_surfaces(surfaces, net), net).angle_corner_deg.max() <= 2.0


def _nested(grids, b):
    na = side_row(grids[b.a], b.side_a).shape[0]
    nb = side_row(grids[b.b], b.side_b).shape[0]
    return (max(na, nb) - 1) % (min(na, nb) - 1) == 0


def test_displacement_seams_close_where_resolutions_nest(igea_layout):
    grids, net, surfaces, diag = igea_layout
    stitched = stitch_surfaces(surfaces, net)
    maps = [displacement_map(s, g) for s, g in zip(stitched, grids, strict=True)]
    fixed = stitch_displacements(stitched, maps, net)
    gaps = displacement_seam_gaps(stitched, fixed, net)
    nested = np.array([_nested(grids, b) for b in net.boundaries])
    assert nested.any()
    assert gaps[nested].max() <= tol.STITCH_GAP * diag


@pytest.mark.xfail(
    strict=True,
    reason="spring meshes of neighbouring igea patches have 33 / 37 / 41 points along shared "
    "sides; with non-nested texel rows the bilinear seams differ between texels (~1e-3 of the "
    "diagonal); needs equal counts along shared sides from meshfit.springs",
)
def test_displacement_seams_close_everywhere(igea_layout):
    grids, net, surfaces, diag = igea_layout
    stitched = stitch_surfaces(surfaces, net)
    maps = [displacement_map(s, g) for s, g in zip(stitched, grids, strict=True)]
    gaps = displacement_seam_gaps(stitched, stitch_displacements(stitched, maps, net), net)
    assert gaps.max() <= tol.STITCH_GAP * diag
