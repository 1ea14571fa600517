"""Face-point curves: the sampling rule, length, densifying and uniform resampling."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit import tol
from meshfit.curves import check_sampling, curve_length, densify_curve, resample_curve
from meshfit.curves.base import _resample
from meshfit.errors import InputError
from meshfit.surface import curve_arc_lengths, greedy_path, path_to_surface_points
from meshfit.types import SurfaceCurve, SurfacePoints

from ..conftest import analytic_mesh, real_mesh


def _graph_curve(mesh, a, b, *, closed=False):
    v = greedy_path(mesh, a, b).vertices
    if closed:  # out along one path, back along a path through a third vertex
        c = int(
            np.argmax(
                np.linalg.norm(mesh.vertices - mesh.vertices[a], axis=1)
                + np.linalg.norm(mesh.vertices - mesh.vertices[b], axis=1)
            )
        )
        v = np.concatenate(
            [v, greedy_path(mesh, b, c).vertices[1:], greedy_path(mesh, c, a).vertices[1:-1]]
        )
    return SurfaceCurve(path_to_surface_points(mesh, v, per_edge=2), closed=closed)


def _spacing_cv(mesh, curve, regular):
    arc = curve_arc_lengths(mesh, curve)
    idx = (
        np.append(np.flatnonzero(regular), len(curve)) if curve.closed else np.flatnonzero(regular)
    )
    d = np.diff(arc[idx])
    return d.std() / d.mean()


CASES = [
    ("plane", 0, 440, False),
    ("icosphere", 0, 300, False),
    ("icosphere", 0, 300, True),
    ("torus", 0, 600, True),
    ("igea", 0, 50_000, False),
]


@pytest.mark.parametrize(("name", "a", "b", "closed"), CASES)
def test_resample_is_even_and_well_sampled(name, a, b, closed):
    mesh = real_mesh(name) if name == "igea" else analytic_mesh(name)
    curve = _graph_curve(mesh, a, b, closed=closed)
    out, regular = _resample(mesh, curve, spacing=None, n=None)
    assert check_sampling(mesh, out).size == 0
    assert out.closed == closed
    assert _spacing_cv(mesh, out, regular) <= 0.05
    assert_allclose(curve_length(mesh, out), curve_length(mesh, curve), rtol=0.05)
    # the end points are kept exactly (closed: the first point)
    assert_array_equal(out.points.bary[0], curve.points.bary[0])
    if not closed:
        assert_allclose(
            mesh.xyz(out.points[-1]),
            mesh.xyz(curve.points[-1]),
            atol=tol.length(mesh, tol.TEST_ATOL, scale="bbox_diagonal"),
        )
    step = curve_length(mesh, out) / (regular.sum() - (0 if closed else 1))
    assert step <= 0.5 * mesh.mean_edge_length * (1 + 1e-9)
    assert_allclose(out.points.bary.sum(axis=1), 1.0, atol=1e-12)
    # the public verb returns the same curve
    pub = resample_curve(mesh, curve)
    assert_array_equal(pub.points.face, out.points.face)


def test_resample_to_a_point_count():
    mesh = analytic_mesh("plane")
    curve = _graph_curve(mesh, 22, 418)
    out, regular = _resample(mesh, curve, spacing=None, n=12)
    assert regular.sum() == 12
    assert check_sampling(mesh, out).size == 0
    assert _spacing_cv(mesh, out, regular) <= 0.05


def test_check_sampling_finds_the_jump_and_densify_repairs_it():
    mesh = analytic_mesh("icosphere")
    pts = SurfacePoints.at_vertices(mesh.faces, [0, 100, 200])
    curve = SurfaceCurve(pts)
    assert_array_equal(check_sampling(mesh, curve), [0, 1])
    assert_array_equal(check_sampling(mesh, SurfaceCurve(pts, closed=True)), [0, 1, 2])
    dense = densify_curve(mesh, curve)
    assert check_sampling(mesh, dense).size == 0
    x = mesh.xyz(dense.points)
    for v in (0, 100, 200):  # the original points are kept
        assert np.linalg.norm(x - mesh.vertices[v], axis=1).min() == 0.0
    # the bridge stays on the sphere's surface: never through the inside
    assert np.linalg.norm(x, axis=1).min() > 0.9


def test_curve_length_of_a_straight_segment():
    mesh = analytic_mesh("plane")
    # the x = 0 boundary column (vertex i * 21 + j sits near (i, j) / 20)
    curve = SurfaceCurve(path_to_surface_points(mesh, np.arange(21), per_edge=3))
    assert_allclose(curve_length(mesh, curve), 1.0, rtol=1e-12)


def test_resample_errors():
    mesh = analytic_mesh("plane")
    curve = _graph_curve(mesh, 22, 418)
    with pytest.raises(InputError, match="spacing or n, not both"):
        resample_curve(mesh, curve, spacing=0.1, n=5)
    with pytest.raises(InputError, match="n must be an integer >= 2"):
        resample_curve(mesh, curve, n=1)
    with pytest.raises(InputError, match="spacing must be a positive length"):
        resample_curve(mesh, curve, spacing=-1.0)
    with pytest.raises(InputError, match="spacing must be a positive length"):
        resample_curve(mesh, curve, spacing=float("nan"))
    with pytest.raises(InputError, match="curve must be a SurfaceCurve"):
        resample_curve(mesh, curve.points)
    bad = SurfaceCurve(SurfacePoints([mesh.n_faces], [[1.0, 0, 0]]))
    with pytest.raises(InputError, match="outside the mesh"):
        check_sampling(mesh, bad)
    with pytest.raises(InputError, match="neither the same, adjacent nor sharing a vertex"):
        curve_length(mesh, SurfaceCurve(SurfacePoints.at_vertices(mesh.faces, [0, 440])))
