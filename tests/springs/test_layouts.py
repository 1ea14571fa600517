"""Spring meshes of every patch of the test layouts (examples/layouts/*.json).

Each layout's spring meshes are computed once per module. Targets of the issue that the
spring mesh does not meet on these layouts are strict xfails stating the measured figures.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from numpy.testing import assert_allclose

from meshfit import tol
from meshfit.layout import extract_patches, load_layout
from meshfit.springs import FREE, QUALITY_BOUNDS, SpringOptions, resample_patch, spring_metrics

from ..conftest import ROOT, real_mesh
from .test_resample import curve_distance

pytestmark = pytest.mark.slow

LAYOUTS = ("igea", "nefertiti", "nefertiti_bust", "spot")
#: test layouts named other than their mesh (nefertiti_bust: laid out from an axis)
LAYOUT_MESH = {"nefertiti_bust": "nefertiti"}


@cache
def layout_springs(name: str):
    mesh = real_mesh(LAYOUT_MESH.get(name, name))
    patches = extract_patches(
        mesh, load_layout(ROOT / "examples" / "layouts" / f"{name}.json", mesh)
    )
    out = []
    for patch in patches:
        res = resample_patch(patch, SpringOptions(fidelity=False))
        final = spring_metrics(patch.mesh, res.final, scale=mesh.bbox_diagonal)
        out.append((patch, res, final))
    return out


#: measured on this machine's run of the layouts (max over patches and levels)
KNOWN = {
    "arc_cv": {
        "nefertiti": "arc-length CV > 0.15 on 3 of 54 patches (worst 1.55, patch 4; median 0.081)",
        "nefertiti_bust": "arc-length CV > 0.15 on 1 of 48 patches, 42, which holds an ear "
        "(0.34; the other ear's patch 35 is at 0.143; median 0.086)",
        "spot": "arc-length CV > 0.15 on 2 of 24 patches (1 and 3: 0.49 and 0.52; median "
        "0.045): each holds a horn and an ear and tapers about 7 : 1",
    },
    "aspect": {
        "spot": "median cell aspect ratio > 1.5 on 2 of 24 patches (1 and 3: 1.70 and 1.62)",
    },
    "fidelity": {
        "igea": "two-sided max distance 0.087% of the bbox diagonal on the median patch, "
        "0.33% worst (patch 5, a scan spike): at about the vertex count no patch is within "
        "0.05% (libigl's harmonic map on the same grids: none either); refined with "
        "tolerance=5e-4 (about 4 points per patch vertex) 21 of 24 are",
        "nefertiti": "two-sided max distance 0.11% of the bbox diagonal on the median patch, "
        "1.8% on patch 4 (a bulge the grid under-samples; rescue=True evens its grid lines "
        "in the map: 0.22%); 10 of 54 patches within 0.05%, refined with tolerance=5e-4 35",
        "nefertiti_bust": "two-sided max distance 0.12% of the bbox diagonal on the median "
        "patch, 1.5% worst (patch 42, an ear); 5 of 48 patches within 0.05%, refined with "
        "tolerance=5e-4 24",
        "spot": "two-sided max distance 0.092% of the bbox diagonal on the median patch, "
        "3.5% worst (patch 1; with rescue=True patches 1 and 3 go to 0.62% and 0.60%); 2 of "
        "24 patches within 0.05% (the grid cuts the coarse mesh's creases), refined with "
        "tolerance=5e-4 14",
    },
}


def _xfail(request, what: str, name: str) -> None:
    reason = KNOWN.get(what, {}).get(name)
    if reason:
        request.applymarker(pytest.mark.xfail(strict=True, reason=reason))


@pytest.mark.parametrize("name", LAYOUTS)
def test_spring_points_lie_on_their_patch(name):
    for patch, res, _ in layout_springs(name):
        for lvl in res.levels:
            f, b = lvl.points.face, lvl.points.bary
            assert f.min() >= 0 and f.max() < patch.mesh.n_faces
            assert (b >= -tol.BARY_EPS).all()
            assert_allclose(b.sum(axis=1), 1.0, atol=1e-12)
            assert lvl.patch == patch.index
        # every level doubles the intervals; the last one is comparable to the vertex count
        n = res.final.n_points / patch.mesh.n_vertices
        assert 0.35 <= n <= 3.0, f"patch {patch.index}: {res.final.shape}"


@pytest.mark.parametrize("name", LAYOUTS)
def test_no_folded_cells(name, request):
    _xfail(request, "folds", name)
    folded = {p.index: [m["folded"] for m in res.metrics] for p, res, _ in layout_springs(name)}
    assert all(sum(v) <= QUALITY_BOUNDS["folded"] for v in folded.values()), folded


@pytest.mark.parametrize("name", LAYOUTS)
def test_arc_length_uniformity(name, request):
    _xfail(request, "arc_cv", name)
    worst = {
        p.index: max(m["arc_cv_max"] for m in res.metrics) for p, res, _ in layout_springs(name)
    }
    assert max(worst.values()) <= QUALITY_BOUNDS["arc_cv_max"], worst


@pytest.mark.parametrize("name", LAYOUTS)
def test_cell_aspect_ratio(name, request):
    _xfail(request, "aspect", name)
    worst = {
        p.index: max(m["aspect_median"] for m in res.metrics) for p, res, _ in layout_springs(name)
    }
    assert max(worst.values()) <= QUALITY_BOUNDS["aspect_median"], worst


@pytest.mark.parametrize("name", LAYOUTS)
def test_fidelity_at_the_final_level(name, request):
    _xfail(request, "fidelity", name)
    worst = {p.index: final["fidelity_max"] for p, _, final in layout_springs(name)}
    assert max(worst.values()) <= QUALITY_BOUNDS["fidelity_max"], worst


def test_feature_curves_of_the_igea_layout_are_interpolated():
    with_features = [(p, res) for p, res, _ in layout_springs("igea") if p.features]
    assert with_features, "the igea layout has a patch with feature curves"
    for patch, res in with_features:
        sm = res.final
        assert len(sm.u_lines) + len(sm.v_lines) == len(patch.features)
        lines = [sm.xyz[c, 1:-1] for c in sm.u_lines] + [sm.xyz[1:-1, c] for c in sm.v_lines]
        for pts in lines:
            # each feature grid line lies on one of the feature curves (within the check's
            # resolution, ~1e-7 of the curve's length)
            best = min(
                (
                    d.max() - r
                    for d, r in (curve_distance(patch.mesh, c, pts) for c in patch.features)
                )
            )
            assert best <= 0.0
        kind = sm.kind
        assert (kind[sm.u_lines, 1:-1] != FREE).all() and (kind[1:-1, sm.v_lines] != FREE).all()


def test_the_igea_feature_patch_is_uniform_along_its_iso_curves():
    # the patch whose grid lines follow two feature curves in each direction: the curve
    # points slide along their curves to equal chords, like the free points' springs
    with_features = [res for p, res, _ in layout_springs("igea") if p.features]
    for res in with_features:
        assert max(m["arc_cv_max"] for m in res.metrics) <= 0.15
        assert max(m["aspect_median"] for m in res.metrics) <= 1.5
        assert sum(m["folded"] for m in res.metrics) == 0


def test_arc_length_polish_evens_the_igea_layout():
    # without the coarse arc-length sweeps the fairness equilibrium leaves igea patches 4, 5
    # and 9 above 0.15 (0.23, 0.20, 0.18); with them (the default) every patch is within it
    polished = {p.index: (p, res) for p, res, _ in layout_springs("igea")}
    for k in (4, 5, 9):
        patch, res = polished[k]
        plain = resample_patch(
            patch, SpringOptions(fidelity=False, polish=0, fairness_fallback=False)
        )
        assert max(m["arc_cv_max"] for m in plain.metrics) > 0.15, k
        assert max(m["arc_cv_max"] for m in res.metrics) <= 0.15, k
        assert sum(m["folded"] for m in res.metrics) == 0


def test_fairness_fallback_mends_spots_tapered_patches():
    # spot's patches 0, 2, 4 and 5 taper 2.8-5 : 1: relaxed with the fairness force they break
    # the arc-length or the aspect bound on some level; level 0 made again with the
    # arc-length force alone (0, 2, 4) or with rebalanced intervals (5) meets every bound on
    # every level
    layout = layout_springs("spot")
    for k in (0, 2, 4, 5):
        patch, res, _ = layout[k]
        plain = resample_patch(patch, SpringOptions(fidelity=False, fairness_fallback=False))
        assert plain.fairness == 0.5
        assert (
            max(m["arc_cv_max"] for m in plain.metrics) > QUALITY_BOUNDS["arc_cv_max"]
            or max(m["aspect_median"] for m in plain.metrics) > QUALITY_BOUNDS["aspect_median"]
        ), k
        assert max(m["arc_cv_max"] for m in res.metrics) <= QUALITY_BOUNDS["arc_cv_max"], k
        assert max(m["aspect_median"] for m in res.metrics) <= QUALITY_BOUNDS["aspect_median"]
        assert sum(m["folded"] for m in res.metrics) == 0, k
        for lvl in res.levels:
            f, b = lvl.points.face, lvl.points.bary
            assert f.min() >= 0 and f.max() < patch.mesh.n_faces and (b >= -tol.BARY_EPS).all()
    # the rebalanced intervals of patch 5 have fewer rows along its long direction
    patch, res, _ = layout[5]
    plain = resample_patch(patch, SpringOptions(fidelity=False, fairness_fallback=False))
    assert res.levels[0].shape != plain.levels[0].shape


def test_fairness_fallback_leaves_patches_meeting_the_bounds_alone():
    # every igea patch meets the bounds at level 0 with the fairness force: none is remade
    for _, res, _ in layout_springs("igea"):
        assert res.fairness == 0.5 and not res.remade


def test_final_polish_evens_only_the_uneven_lines(monkeypatch):
    # nefertiti patches 0 and 19 meet the 0.15 bound on every level but the last, where the
    # new points of the last subdivision leave some lines uneven: the final polish moves
    # those lines and their neighbours, nothing else; on patch 45 (a pleat) it cannot even
    # the lines out and is dropped
    from meshfit.springs import resample as R

    layout = layout_springs("nefertiti")
    for k in (0, 19):
        patch, res, _ = layout[k]
        with monkeypatch.context() as m:
            m.setattr(R, "FINAL_POLISH", 0)
            m.setattr(R, "_relax_again", lambda first: False)
            plain = resample_patch(patch, SpringOptions(fidelity=False))
        assert plain.metrics[-1]["arc_cv_max"] > 0.15, k
        assert res.metrics[-1]["arc_cv_max"] <= 0.15, k
        assert res.metrics[-1]["folded"] == plain.metrics[-1]["folded"] == 0
        moved = np.linalg.norm(res.final.xyz - plain.final.xyz, axis=2) > 0
        g = plain.final
        col, row, _ = R._line_cvs(
            patch.mesh, g.points.face, g.points.bary, g.shape, g.u_lines, g.v_lines
        )
        allowed = R._uneven_lines(col, row, R.POLISH_LINE_CV, R.POLISH_REACH)
        assert moved.any() and not (moved & ~allowed).any(), k
        for a, b in zip(res.levels[:-1], plain.levels[:-1], strict=True):
            assert_allclose(a.xyz, b.xyz, rtol=0, atol=0)
    # (without the fallback, which relaxes patch 45's last level again with arc length alone)
    patch = layout[45][0]
    res = resample_patch(patch, SpringOptions(fidelity=False, fairness_fallback=False))
    assert res.metrics[-1]["arc_cv_max"] > R.POLISH_CV_GOAL
    with monkeypatch.context() as m:
        m.setattr(R, "FINAL_POLISH", 0)
        plain = resample_patch(patch, SpringOptions(fidelity=False, fairness_fallback=False))
    assert_allclose(res.final.xyz, plain.final.xyz, rtol=0, atol=0)


def test_a_last_level_over_a_bound_is_relaxed_again_with_arc_length_alone(monkeypatch):
    # nefertiti's patch 36 steps over a pleat on its last level: relaxed with the fairness
    # force its arc-length CV is 0.29 there; relaxed again with arc length alone, from the
    # same subdivided points, it meets the bound and lies closer to its patch. Spot's patch
    # 1 (a horn) stays over the bound but its grid misses the horn by less. Coarser levels
    # are untouched; igea's patches meet every bound and are relaxed once
    from meshfit.springs import resample as R

    cv_bound = QUALITY_BOUNDS["arc_cv_max"]
    for name, k in (("nefertiti", 36), ("spot", 1)):
        patch, res, final = layout_springs(name)[k]
        diag = real_mesh(LAYOUT_MESH.get(name, name)).bbox_diagonal
        with monkeypatch.context() as m:
            m.setattr(R, "_relax_again", lambda first: False)
            once = resample_patch(patch, SpringOptions(fidelity=False))
        assert res.final_arc and not once.final_arc
        assert res.fairness == once.fairness and res.remade == once.remade
        for a, b in zip(res.levels[:-1], once.levels[:-1], strict=True):
            assert_allclose(a.xyz, b.xyz, rtol=0, atol=0)
        before = spring_metrics(patch.mesh, once.final, scale=diag)
        assert before["arc_cv_max"] > cv_bound
        assert final["arc_cv_max"] < before["arc_cv_max"]
        assert final["folded"] == before["folded"] == 0
        assert final["fidelity_max"] < 0.7 * before["fidelity_max"]
        if name == "nefertiti":
            assert final["arc_cv_max"] <= cv_bound
    assert not any(res.final_arc for _, res, _ in layout_springs("igea"))


def test_polish_is_dropped_where_it_stretches_the_cells():
    # spot's near-triangular patch 1: evenly spaced lines stretch its cells, so the default
    # keeps the unpolished levels
    patch, res, _ = layout_springs("spot")[1]
    plain = resample_patch(patch, SpringOptions(fidelity=False, polish=0))
    assert_allclose(res.final.xyz, plain.final.xyz, rtol=0, atol=0)


def test_rescue_reaches_the_patches_the_grid_misses():
    # spot's near-triangular patches 1 and 3: the relaxed grid misses part of the patch by
    # several grid spacings; the rescue (area-balanced map, light relaxation) is kept there.
    # Patches 6 and 7 (an ear) are missed by 1.2 spacings: the grid one level finer is kept
    from meshfit.springs.resample import RESCUE_GAIN, RESCUE_SPACINGS, _miss

    diag = real_mesh("spot").bbox_diagonal
    changed = []
    for patch, plain, plain_final in layout_springs("spot"):
        res = resample_patch(patch, SpringOptions(fidelity=False, rescue=True))
        assert "rescue" in res.seconds
        if not (res.rescued or res.finer):
            assert_allclose(res.final.xyz, plain.final.xyz, rtol=0, atol=0)
            continue
        changed.append((patch.index, res.rescued, res.finer))
        before = _miss(patch.mesh, plain.final)
        assert before[0] > RESCUE_SPACINGS
        final = spring_metrics(patch.mesh, res.final, scale=diag)
        if res.finer:  # a finer grid: half the distance missed, no larger share folded
            assert res.final.shape[0] == (plain.final.shape[0] - 1) * 2**res.finer + 1
            assert _miss(patch.mesh, res.final)[1] <= RESCUE_GAIN * before[1]
            assert final["fidelity_max"] < 0.3 * plain_final["fidelity_max"]
            share = final["folded"] / ((res.final.shape[0] - 1) * (res.final.shape[1] - 1))
            plain_share = plain_final["folded"] / (
                (plain.final.shape[0] - 1) * (plain.final.shape[1] - 1)
            )
            assert share <= plain_share
        else:
            assert _miss(patch.mesh, res.final)[0] <= RESCUE_GAIN * before[0]
            # (3.5% -> 0.62% and 2.6% -> 0.60% of the bbox diagonal)
            assert final["fidelity_max"] < 0.3 * plain_final["fidelity_max"]
            assert final["folded"] <= plain_final["folded"]
    assert changed == [(1, True, 0), (3, True, 0), (6, False, 1), (7, False, 1)]
    # a grid that samples its patch is left alone
    patch = layout_springs("igea")[0][0]
    res = resample_patch(patch, SpringOptions(fidelity=False, rescue=True))
    assert not res.rescued and res.finer == 0


def test_finer_rescue_keeps_to_the_level_and_point_cap():
    # spot's patch 6 gets a grid one level finer, but not when the level or a point cap that
    # the finer grid would exceed is given
    patch, plain, _ = layout_springs("spot")[6]
    k, shape = plain.final.level, plain.final.shape
    assert resample_patch(patch, SpringOptions(fidelity=False, rescue=True)).finer == 1
    res = resample_patch(patch, SpringOptions(fidelity=False, rescue=True, level=k))
    assert res.finer == 0 and res.final.shape == shape
    res = resample_patch(
        patch, SpringOptions(fidelity=False, rescue=True, max_points=shape[0] * shape[1])
    )
    assert res.finer == 0 and res.final.shape == shape


def test_side_slides_taper_and_avoid_slivers(monkeypatch):
    # nefertiti patch 7: a side point slid alone leaves a folded cell and a spacing jump
    # (CV 0.44); taking its neighbours along unfolds it. Patch 31: of the single-point slides
    # the old first-found one left spacings 0.1 : 1.9 on a side; the sliver-avoiding choice
    # keeps the side even
    from meshfit.springs import relax as RL
    from meshfit.springs import resample as RS

    layout = layout_springs("nefertiti")
    patch, res, _ = layout[7]
    with monkeypatch.context() as m:
        m.setattr(RL, "SLIDE_TAPER", 0)
        alone = resample_patch(patch, SpringOptions(fidelity=False))
        # (the untangling in charts, which comes after the slides, unfolds the cell but
        # leaves the spacing jump)
        assert sum(x["folded"] for x in alone.metrics) == 0
        assert max(x["arc_cv_max"] for x in alone.metrics) > 0.15
        m.setattr(RS, "untangle_in_charts", lambda state: 0)
        alone = resample_patch(patch, SpringOptions(fidelity=False))
    assert sum(x["folded"] for x in alone.metrics) > 0
    assert max(x["arc_cv_max"] for x in alone.metrics) > 0.15
    assert sum(x["folded"] for x in res.metrics) == 0
    assert max(x["arc_cv_max"] for x in res.metrics) <= 0.15
    patch, res, _ = layout[31]
    X = res.final.xyz
    d = np.linalg.norm(np.diff(X[0], axis=0), axis=1)  # the side the old slide broke
    assert d.min() >= 0.5 * np.median(d)
    assert max(x["arc_cv_max"] for x in res.metrics) <= 0.15


def test_pinched_side_points_of_nefertiti_26_slide_apart(monkeypatch):
    # patch 26's right side steps back near a corner: two of its points at equal arc lengths
    # land 0.08 of the spacing apart (CV 0.18 on level 1, 0.20 on the last) unless slid apart
    from meshfit.springs import relax as RL

    patch, res, _ = layout_springs("nefertiti")[26]
    with monkeypatch.context() as m:
        m.setattr(RL, "PINCH_RATIO", 0.0)
        plain = resample_patch(patch, SpringOptions(fidelity=False))
    assert max(x["arc_cv_max"] for x in plain.metrics) > 0.15
    assert max(x["arc_cv_max"] for x in res.metrics) <= 0.15
    assert sum(x["folded"] for x in res.metrics) == 0
    X = res.final.xyz[-1]  # the right side
    d = np.linalg.norm(np.diff(X, axis=0), axis=1)
    assert d.min() >= RL.PINCH_RATIO * np.median(d)


def test_only_the_bust_patch_of_nefertiti_bulges():
    # the projected cube's bottom face takes in neck, shoulders and base and balloons out of
    # its short boundary round the neck: the one patch of the test layouts above BULGY
    # (where its spring mesh misses the surface, see KNOWN)
    from meshfit.layout.patch import BULGY

    bulges = {name: [p.bulge for p, _, _ in layout_springs(name)] for name in LAYOUTS}
    assert bulges["nefertiti"][4] > 10.0
    assert max(b for k, b in enumerate(bulges["nefertiti"]) if k != 4) < 1.5
    assert max(bulges["igea"]) < BULGY and max(bulges["spot"]) < BULGY
    # laid out from an axis, no patch of the bust takes in the neck, shoulders and base
    assert max(bulges["nefertiti_bust"]) < 1.5


def test_the_tapered_patches_are_spots_head_patches():
    # the cube corners at spot's head leave four near-triangular patches (a side over
    # TAPERED times as long as the side opposite it), the only ones of the test layouts. The
    # fairness fallback evens out two of them (0, 2); the two that also hold a horn and an
    # ear (1, 3) stay uneven (see KNOWN["arc_cv"] for nefertiti's other causes)
    from meshfit.layout.patch import TAPERED

    tapered = {
        name: [p.index for p, _, _ in layout_springs(name) if p.taper > TAPERED] for name in LAYOUTS
    }
    assert tapered == {"igea": [], "nefertiti": [], "nefertiti_bust": [], "spot": [0, 1, 2, 3]}
    worst = {
        p.index: max(m["arc_cv_max"] for m in res.metrics)
        for p, res, _ in layout_springs("spot")
        if p.index in tapered["spot"]
    }
    bound = QUALITY_BOUNDS["arc_cv_max"]
    assert [k for k, cv in worst.items() if cv > bound] == [1, 3], worst


@pytest.mark.parametrize(
    "name,index", [("nefertiti", 45), ("nefertiti_bust", 42), ("spot", 1), ("spot", 3)]
)
def test_following_folds_carries_the_grid_over_ears_and_horns(name, index):
    """With ``follow_folds`` the grid lines cross the curled rim of an ear or a horn: the
    grid misses far less of the patch, its lines are spaced more evenly, and no cell folds
    (measured: largest distance 1.13% -> 0.25%, 1.48% -> 0.62%, 3.54% -> 1.23%, 2.58% ->
    1.21% of the bbox diagonal; arc-length CV 0.50 -> 0.24, 0.34 -> 0.26, 0.49 -> 0.37,
    0.40 -> 0.25)."""
    mesh = real_mesh(LAYOUT_MESH.get(name, name))
    patch, _, plain = layout_springs(name)[index]
    res = resample_patch(patch, SpringOptions(follow_folds=True, metrics=False))
    got = spring_metrics(patch.mesh, res.final, scale=mesh.bbox_diagonal)
    assert got["fidelity_max"] < 0.5 * plain["fidelity_max"]
    assert got["arc_cv_max"] < 0.8 * plain["arc_cv_max"]
    assert got["folded"] == 0


def test_following_folds_changes_nothing_without_a_fold():
    """A patch whose grid crosses no fold of the surface (igea's smooth cheek, patch 0) gets
    the same grid, bit for bit."""
    patch, res, _ = layout_springs("igea")[0]
    again = resample_patch(patch, SpringOptions(follow_folds=True, metrics=False))
    assert len(again.levels) == len(res.levels)
    for a, b in zip(again.levels, res.levels, strict=True):
        assert np.array_equal(a.points.face, b.points.face)
        assert np.array_equal(a.points.bary, b.points.bary)
