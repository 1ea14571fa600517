"""Patch.bulge: area over that of a square with the same perimeter, and its warning."""

from __future__ import annotations

import pytest

from meshfit.layout.patch import BULGY, bulge_notes

from ..springs.patches import cap_map, param_patch, plane_map


def test_flat_patches_have_their_plane_figure():
    assert param_patch(plane_map(1.0, 1.0), jitter=0.0).bulge == pytest.approx(1.0, abs=1e-12)
    # a 2 x 1 rectangle: 2 / (6 / 4)^2
    assert param_patch(plane_map(2.0, 1.0)).bulge == pytest.approx(2.0 / 1.5**2, abs=1e-12)


def test_spherical_caps_bulge_more_as_they_grow_towards_a_hemisphere():
    # gnomonic squares on the unit sphere: half-width 0.3 is nearly flat, and as the square
    # grows its sides approach the equator (a hemisphere: 2 pi / (2 pi / 4)^2 = 8 / pi)
    b = [param_patch(cap_map(1.0, h), 40, 40, jitter=0.0).bulge for h in (0.3, 1.0, 3.0, 30.0)]
    assert 1.0 < b[0] < 1.06
    assert b[0] < b[1] < b[2] < b[3] < 8.0 / 3.14159265
    assert b[3] > 2.2  # 2.26: the 40 x 40 triangulation of the cap falls short of the sphere
    assert b[3] < BULGY


def test_bulge_notes_name_the_bulging_patches_most_first():
    assert bulge_notes({0: 1.0, 1: 2.9}) == []
    (one,) = bulge_notes({0: 1.0, 3: 11.06})
    assert one.startswith("1 patch bulges far beyond its boundary") and "patch 3: 11.1" in one
    (two,) = bulge_notes({5: 4.0, 3: 11.06, 7: 1.0})
    assert two.startswith("2 patches bulge") and two.index("patch 3:") < two.index("patch 5:")
    assert "patch 7" not in two


def test_thin_notes_name_the_slivers_thinnest_first():
    from meshfit.layout.patch import THIN, patch_notes, thin_notes

    # a 40 x 1 strip: 40 / (82 / 4)^2 = 0.095; 100 x 1: 0.039
    assert param_patch(plane_map(100.0, 1.0)).bulge < THIN < param_patch(plane_map(40.0, 1.0)).bulge
    assert thin_notes({0: 1.0, 1: 0.06}) == []
    (one,) = thin_notes({0: 1.0, 4: 0.013})
    assert one.startswith("1 patch is a sliver") and "patch 4: 0.013" in one
    (two,) = thin_notes({2: 0.04, 4: 0.013, 7: 0.5})
    assert two.startswith("2 patches are slivers") and two.index("patch 4:") < two.index("patch 2:")
    assert "patch 7" not in two and "ask for fewer patches" in two
    # among a fit's notes, after those of bulging patches
    rows = [{"patch": 0, "bulge": 11.0}, {"patch": 1, "bulge": 0.02}]
    notes = patch_notes(rows)
    assert len(notes) == 2 and "bulges far" in notes[0] and "sliver" in notes[1]


def test_patch_bulges_of_a_layout_match_its_patches():
    from meshfit.layout import extract_patches, load_layout
    from meshfit.layout.extract import patch_bulges

    from ..conftest import ROOT, real_mesh

    mesh = real_mesh("spot")
    layout = load_layout(ROOT / "examples" / "layouts" / "spot.json", mesh)
    got = patch_bulges(mesh, layout)
    want = [p.bulge for p in extract_patches(mesh, layout)]
    assert got.shape == (layout.n_patches,)
    assert got == pytest.approx(want, rel=1e-12)
    assert got.min() > 0.0
