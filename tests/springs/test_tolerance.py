"""``tolerance`` of resample_patch: the final level refined until the grid is close enough."""

from __future__ import annotations

import numpy as np
import pytest

from meshfit.errors import InputError
from meshfit.layout import extract_patches, load_layout
from meshfit.springs import SpringOptions, resample_patch, spring_metrics

from ..conftest import ROOT, real_mesh
from .patches import cylinder_map, param_patch


def _fidelity(patch, res, scale=None) -> float:
    return spring_metrics(patch.mesh, res.final, scale=scale)["fidelity_max"]


def test_a_tolerance_the_final_level_misses_refines_the_grid_until_it_is_met():
    patch = param_patch(cylinder_map(1.0, 1.5, np.pi / 2), 48, 24)
    plain = resample_patch(patch, SpringOptions(fidelity=False))
    d0 = _fidelity(patch, plain)
    res = resample_patch(patch, SpringOptions(tolerance=0.5 * d0, fidelity=False))
    assert res.finer >= 1
    assert len(res.levels) == len(plain.levels) + res.finer
    assert res.distance <= 0.5 * d0
    assert res.distance == pytest.approx(_fidelity(patch, res), rel=1e-12)
    # the coarser levels come out the same
    for a, b in zip(plain.levels, res.levels, strict=False):
        assert np.array_equal(a.points.face, b.points.face)
        assert np.array_equal(a.points.bary, b.points.bary)
    assert "tolerance" in res.seconds and res.seconds["total"] >= res.seconds["tolerance"]
    # with every level's metrics asked for, the run's own fidelity figure is used: the same
    measured = resample_patch(patch, SpringOptions(tolerance=0.5 * d0))
    assert measured.finer == res.finer
    assert measured.distance == pytest.approx(res.distance, rel=1e-12)
    assert measured.distance == measured.metrics[-1]["fidelity_max"]


def test_a_tolerance_the_final_level_meets_keeps_it():
    patch = param_patch(cylinder_map(1.0, 1.5, np.pi / 2), 48, 24)
    plain = resample_patch(patch, SpringOptions(fidelity=False))
    d0 = _fidelity(patch, plain)
    res = resample_patch(patch, SpringOptions(tolerance=2.0 * d0, fidelity=False))
    assert res.finer == 0 and res.distance == pytest.approx(d0, rel=1e-12)
    assert np.array_equal(res.final.points.bary, plain.final.points.bary)
    assert plain.distance is None


def test_max_points_caps_the_refinement():
    patch = param_patch(cylinder_map(1.0, 1.5, np.pi / 2), 48, 24)
    plain = resample_patch(patch, SpringOptions(fidelity=False))
    nu, nv = plain.final.shape
    res = resample_patch(patch, SpringOptions(tolerance=1e-9, max_points=nu * nv, fidelity=False))
    assert res.finer == 0 and res.final.shape == (nu, nv) and res.distance > 1e-9


@pytest.mark.slow
def test_an_igea_patch_reaches_the_issue_fidelity_bound_one_level_finer():
    # at the vertex-count level its grid misses by 0.083% of the model's bbox diagonal
    mesh = real_mesh("igea")
    patch = extract_patches(mesh, load_layout(ROOT / "examples" / "layouts" / "igea.json", mesh))[2]
    diag = mesh.bbox_diagonal
    plain = resample_patch(patch, SpringOptions(metrics=False))
    assert _fidelity(patch, plain, diag) > 5e-4
    res = resample_patch(patch, SpringOptions(tolerance=5e-4, scale=diag, metrics=False))
    assert res.finer >= 1 and res.distance <= 5e-4
    assert res.distance == pytest.approx(_fidelity(patch, res, diag), rel=1e-12)
    assert spring_metrics(patch.mesh, res.final, fidelity=False)["folded"] == 0


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"tolerance": 0.0}, "positive"),
        ({"tolerance": -1e-3}, "positive"),
        ({"tolerance": float("nan")}, "positive"),
        ({"tolerance": True}, "positive"),
        ({"tolerance": "small"}, "positive"),
        ({"tolerance": float("inf")}, "positive"),
        ({"tolerance": 1e-3, "level": 1}, "not with level or rescue"),
        ({"tolerance": 1e-3, "rescue": True}, "not with level or rescue"),
    ],
)
def test_bad_tolerances_are_rejected(options, match):
    patch = param_patch(cylinder_map(), 12, 8)
    with pytest.raises(InputError, match=match):
        resample_patch(patch, SpringOptions(**options))
