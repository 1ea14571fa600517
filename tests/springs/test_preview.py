"""The level-0 preview of a large patch made on a coarse copy (`meshfit.springs.preview`)."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit import tol
from meshfit.layout import extract_patches, load_layout
from meshfit.layout.cube import cube_layout
from meshfit.springs import SpringOptions, resample_patch
from meshfit.springs.preview import (
    PREVIEW_MAX_OFFSET,
    PREVIEW_MEDIAN_OFFSET,
    PREVIEW_MIN_VERTICES,
    coarse_level0,
)
from meshfit.ui.state import Session

from ..conftest import ROOT, real_mesh

pytestmark = pytest.mark.slow

#: the benchmark's patch: the one of a one-per-cube-face igea layout closest to 25K vertices
IGEA_CUBE_VERTICES = 25_000
#: nefertiti test-layout patches: 4 (11.5K vertices, over the threshold; a bulging patch)
#: and 32 (3.3K, under it: the coarse copy is coarser next to the grid)
NEFERTITI_PATCHES = (4, 32)


@cache
def _igea_cube():
    mesh = real_mesh("igea")
    layout = cube_layout(mesh, n=1)
    patches = extract_patches(mesh, layout)
    p = int(np.argmin([abs(q.mesh.n_vertices - IGEA_CUBE_VERTICES) for q in patches]))
    return mesh, layout, patches, p


@cache
def _nefertiti_patches():
    mesh = real_mesh("nefertiti")
    return extract_patches(
        mesh, load_layout(ROOT / "examples" / "layouts" / "nefertiti.json", mesh)
    )


def _patch(which: str):
    if which == "igea-cube":
        _, _, patches, p = _igea_cube()
        return patches[p]
    return _nefertiti_patches()[int(which.split("-")[1])]


def _mean_spacing(X: np.ndarray) -> float:
    du = np.linalg.norm(np.diff(X, axis=0), axis=2).ravel()
    dv = np.linalg.norm(np.diff(X, axis=1), axis=2).ravel()
    return float(np.concatenate([du, dv]).mean())


@pytest.mark.parametrize("which", ["igea-cube", *(f"nefertiti-{i}" for i in NEFERTITI_PATCHES)])
def test_coarse_level0_lies_on_the_patch_near_the_exact_level0(which):
    patch = _patch(which)
    mesh = patch.mesh
    got = coarse_level0(patch)
    want = resample_patch(patch, SpringOptions(level=0, metrics=False)).final
    assert got is not None
    assert got.shape == want.shape and got.level == want.level == 0
    assert_array_equal(got.kind, want.kind)
    # valid face points of the full patch
    pts = got.points
    assert pts.face.min() >= 0 and pts.face.max() < mesh.n_faces
    assert (pts.bary >= 0.0).all()
    assert_allclose(pts.bary.sum(axis=1), 1.0, atol=tol.TEST_ATOL)
    X = np.asarray(got.xyz).reshape(-1, 3)
    assert_allclose(X, mesh.xyz(pts), atol=tol.TEST_ATOL * mesh.bbox_diagonal)
    assert mesh.closest_points(X).distance.max() <= tol.ON_SURFACE * mesh.bbox_diagonal
    # the sides are resampled statically: the same points as the exact level 0
    E = np.asarray(want.xyz)
    G = np.asarray(got.xyz)
    for rows in (np.s_[0, :], np.s_[-1, :], np.s_[:, 0], np.s_[:, -1]):
        assert_allclose(G[rows], E[rows], atol=tol.TEST_ATOL * mesh.bbox_diagonal)
    # interior points within a fraction of the grid spacing of the exact level 0
    d = np.linalg.norm(G - E, axis=2)
    spacing = _mean_spacing(E)
    assert d.max() <= PREVIEW_MAX_OFFSET * spacing, d.max() / spacing
    assert np.median(d) <= PREVIEW_MEDIAN_OFFSET * spacing, np.median(d) / spacing


def test_coarse_level0_without_aggregation_is_the_exact_level0():
    # the coarse copy is then the patch itself: the same map and the same relaxation
    patch = _patch("nefertiti-32")
    got = coarse_level0(patch, rounds=0)
    want = resample_patch(patch, SpringOptions(level=0, metrics=False)).final
    assert_allclose(got.xyz, want.xyz, atol=tol.TEST_ATOL * patch.mesh.bbox_diagonal)


def test_session_previews_level0_of_a_large_patch_on_a_coarse_copy():
    mesh, layout, patches, p = _igea_cube()
    assert patches[p].mesh.n_vertices > PREVIEW_MIN_VERTICES
    s = Session(mesh)
    s.set_layout(layout)
    grid0 = s.spring_preview(p, level=0)
    assert_allclose(grid0.xyz, coarse_level0(s.patches()[p]).xyz, atol=0.0)
    # finer levels use the exact map as before
    grid1 = s.spring_preview(p, level=1)
    exact1 = resample_patch(s.patches()[p], SpringOptions(level=1, metrics=False)).final
    assert_allclose(grid1.xyz, exact1.xyz, atol=0.0)
    # a patch under the threshold previews its exact level 0
    s = Session(real_mesh("nefertiti"))
    s.load_layout(ROOT / "examples" / "layouts" / "nefertiti.json")
    small = int(np.argmin([q.mesh.n_vertices for q in s.patches()]))
    assert s.patches()[small].mesh.n_vertices <= PREVIEW_MIN_VERTICES
    exact0 = resample_patch(s.patches()[small], SpringOptions(level=0, metrics=False)).final
    assert_allclose(s.spring_preview(small, level=0).xyz, exact0.xyz, atol=0.0)
