"""Smoothing the boundary curves of a layout (`meshfit.layout.smooth_layout`)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit.cli import main
from meshfit.errors import InputError
from meshfit.layout import (
    curve_wiggle,
    extract_patches,
    load_layout,
    smooth_layout,
)
from meshfit.springs import SpringOptions, resample_patch

from ..conftest import mesh_path, real_mesh
from .test_layout import LAYOUTS


def _layout(name: str):
    mesh = real_mesh(name)
    return mesh, load_layout(LAYOUTS / f"{name}.json", mesh)


def _wiggle(mesh, layout) -> np.ndarray:
    return np.concatenate([curve_wiggle(mesh, c) for c in layout.curves]) / mesh.bbox_diagonal


def test_smoothing_damps_the_wiggle_and_keeps_the_network():
    mesh, layout = _layout("nefertiti")
    out = smooth_layout(mesh, layout)
    assert_array_equal(out.corners.face, layout.corners.face)
    assert_allclose(out.corners.bary, layout.corners.bary, rtol=0, atol=1e-12)  # renormalised
    assert_array_equal(out.curve_ends, layout.curve_ends)
    assert_array_equal(out.patch_curves, layout.patch_curves)
    for a, b in zip(layout.curves, out.curves, strict=True):
        for k in (0, -1):  # the ends stay on their corners
            assert a.points.face[k] == b.points.face[k]
            assert_allclose(a.points.bary[k], b.points.bary[k], rtol=0, atol=1e-12)
    before, after = _wiggle(mesh, layout), _wiggle(mesh, out)
    # measured: median 0.061% -> 0.035% of the bbox diagonal, 99th percentile 0.28% -> 0.14%
    assert np.median(after) < 0.7 * np.median(before)
    assert np.percentile(after, 99) < 0.7 * np.percentile(before, 99)
    # the curves move by little more than their wiggle: at most 8 steps of a quarter spacing
    moved = max(
        np.abs(mesh.xyz(b.points).mean(axis=0) - mesh.xyz(a.points).mean(axis=0)).max()
        for a, b in zip(layout.curves, out.curves, strict=True)
    )
    assert moved < 0.005 * mesh.bbox_diagonal
    patches = extract_patches(mesh, out)
    assert sum(p.mesh.area for p in patches) == pytest.approx(mesh.area, rel=1e-9)


@pytest.mark.slow
def test_smoothed_sides_even_the_spring_meshes():
    # the rows beside a side follow its wiggle, the rows inside do not: with the wiggle
    # damped the spacing along the iso-curves evens out (median over the patches of the
    # largest arc-length CV, measured: 0.081 -> 0.049)
    mesh, layout = _layout("nefertiti")

    def median_cv(lay) -> float:
        worst = [
            max(m["arc_cv_max"] for m in resample_patch(p, SpringOptions(fidelity=False)).metrics)
            for p in extract_patches(mesh, lay)
        ]
        return float(np.median(worst))

    assert median_cv(smooth_layout(mesh, layout)) < 0.75 * median_cv(layout)


def test_sides_of_patches_with_feature_curves_are_kept():
    mesh, layout = _layout("igea")
    out = smooth_layout(mesh, layout, iterations=4)
    held = {
        int(c)
        for p in range(layout.n_patches)
        if layout.features[p]
        for c in layout.patch_curves[p]
    }
    assert held, "igea's layout has a patch with feature curves"
    for i, (a, b) in enumerate(zip(layout.curves, out.curves, strict=True)):
        same = (
            len(a) == len(b)
            and np.array_equal(a.points.face, b.points.face)
            and np.allclose(a.points.bary, b.points.bary, rtol=0, atol=1e-12)
        )
        assert same == (i in held), i
    for fa, fb in zip(layout.features, out.features, strict=True):
        for a, b in zip(fa, fb, strict=True):
            assert_array_equal(a.points.face, b.points.face)
            assert_allclose(a.points.bary, b.points.bary, rtol=0, atol=1e-12)


def test_zero_iterations_and_bad_counts():
    mesh, layout = _layout("spot")
    assert smooth_layout(mesh, layout, iterations=0) is layout
    for bad in (-1, 1.5, True, "8"):
        with pytest.raises(InputError, match="iterations"):
            smooth_layout(mesh, layout, iterations=bad)


def test_layout_command_smooths_into_a_new_file(tmp_path, capsys):
    out = tmp_path / "smooth.json"
    args = ["layout", str(mesh_path("spot")), str(LAYOUTS / "spot.json"), "--smooth", "8"]
    assert main([*args, "--out", str(out), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)["smoothed"]
    assert got["out"] == str(out) and got["iterations"] == 8
    assert got["wiggle_median_after"] < got["wiggle_median_before"]
    mesh = real_mesh("spot")
    assert load_layout(out, mesh).n_patches == 24
    # --smooth without --out: nothing written, exit 2
    assert main(args) == 2
    assert "--out" in capsys.readouterr().err
