"""B-spline space curves: basis, least-squares fit, control-vertex and edit-point editing."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from meshfit import tol
from meshfit.curves import (
    SpaceCurve,
    check_sampling,
    fit_bspline_curve,
    fit_space_curve,
    move_control_point,
    move_edit_point,
    paint_curve,
)
from meshfit.curves.spacecurve import _bspline_basis, _chord_params, _clamped_knots, _follow
from meshfit.errors import InputError

from ..conftest import analytic_mesh
from ..reference import curves as reference


@pytest.mark.parametrize("k", [4, 5, 7, 12])
def test_basis_matches_cox_de_boor(k, rng):
    knots = _clamped_knots(k)
    t = np.concatenate([[0.0, 1.0], rng.random(40), knots[3 : k + 1]])
    got = _bspline_basis(t, knots)
    assert_allclose(got, reference.bspline_basis(t, knots), atol=1e-14)
    assert_allclose(got.sum(axis=1), 1.0, atol=1e-14)


def test_basis_matches_oracle_on_non_uniform_knots(rng):
    knots = np.concatenate([[0, 0, 0], np.sort(rng.random(6)), [1, 1, 1]])
    knots = np.concatenate([[0.0], knots, [1.0]])
    t = rng.random(30)
    assert_allclose(_bspline_basis(t, knots), reference.bspline_basis(t, knots), atol=1e-13)


@pytest.mark.parametrize("k", [4, 6, 10])
def test_fit_reproduces_a_cubic_space_curve(k, rng):
    t = np.sort(np.concatenate([[0.0, 1.0], rng.random(60)]))
    coef = rng.normal(size=(4, 3))
    x = np.stack([t**0, t, t**2, t**3], axis=1) @ coef
    for fix in (True, False):
        sc = fit_bspline_curve(x, t, n_control=k, fix_ends=fix)
        assert_allclose(sc.evaluate(t), x, atol=1e-10)
        s = np.linspace(0, 1, 17)
        assert_allclose(sc.evaluate(s), np.stack([s**0, s, s**2, s**3], axis=1) @ coef, atol=1e-10)


def test_fixed_ends_are_kept_exactly(rng):
    t = np.linspace(0, 1, 50)
    x = np.stack([np.cos(5 * t), np.sin(5 * t), t], axis=1) + 0.01 * rng.normal(size=(50, 3))
    sc = fit_bspline_curve(x, t, n_control=6, fix_ends=True)
    assert_array_equal(sc.control_points[0], x[0])
    assert_array_equal(sc.control_points[-1], x[-1])
    assert_allclose(sc.evaluate([0.0, 1.0]), x[[0, -1]], atol=1e-15)
    free = fit_bspline_curve(x, t, n_control=6, fix_ends=False)
    assert np.linalg.norm(free.evaluate(t) - x) <= np.linalg.norm(sc.evaluate(t) - x) + 1e-12


def test_fit_space_curve_on_a_painted_curve():
    mesh = analytic_mesh("icosphere")
    curve = paint_curve(mesh, [0, 7, 30])
    sc = fit_space_curve(mesh, curve, n_control=8)
    xyz = mesh.xyz(curve.points)
    assert_allclose(sc.evaluate([0.0, 1.0]), xyz[[0, -1]], atol=tol.TEST_ATOL)
    resid = np.linalg.norm(sc.evaluate(_chord_params(xyz)) - xyz, axis=1)
    assert resid.max() < mesh.mean_edge_length  # the corner at the middle pick is rounded
    assert isinstance(sc, SpaceCurve) and sc.control_points.shape == (8, 3)
    assert sc.knots.shape == (12,)


def test_edit_points_lie_on_the_curve():
    sc = SpaceCurve.uniform(np.arange(18.0).reshape(6, 3) ** 1.5)
    assert_allclose(sc.edit_points, sc.evaluate(sc.edit_parameters))
    assert sc.edit_parameters[0] == 0.0 and sc.edit_parameters[-1] == 1.0


def _is_subsequence(a, b) -> bool:
    """Whether the face points ``a`` appear in ``b`` in order (exactly)."""
    j = 0
    for i in range(len(b)):
        if j < len(a) and b.face[i] == a.face[j] and (b.bary[i] == a.bary[j]).all():
            j += 1
    return j == len(a)


def _plane_curve():
    mesh = analytic_mesh("plane")
    nv = 21  # plane(20): (n + 1)^2 vertices on a grid, index = i * 21 + j
    curve = paint_curve(mesh, [2 * nv + 10, 18 * nv + 10])  # along x at y = 0.5
    return mesh, curve


def test_moving_a_control_vertex_moves_the_surface_curve_locally_only():
    mesh, curve = _plane_curve()
    sc = fit_space_curve(mesh, curve, n_control=10)
    i = 4
    new_xyz = sc.control_points[i] + [0.0, 0.08, 0.0]
    new_curve, new_sc = move_control_point(mesh, curve, sc, i, new_xyz)
    assert_allclose(new_sc.control_points[i], new_xyz)
    assert_array_equal(np.delete(new_sc.control_points, i, 0), np.delete(sc.control_points, i, 0))
    assert check_sampling(mesh, new_curve).size == 0
    # the public result is the followed curve with points inserted where the rule broke
    followed = _follow(mesh, curve, sc, new_sc)
    assert _is_subsequence(followed.points, new_curve.points)
    t = _chord_params(mesh.xyz(curve.points))
    support = sc.basis(t)[:, i] > 0
    same = (followed.points.face == curve.points.face) & (
        followed.points.bary == curve.points.bary
    ).all(axis=1)
    assert same[~support].all()  # outside the moved vertex's support nothing moves
    moved = np.linalg.norm(mesh.xyz(followed.points) - mesh.xyz(curve.points), axis=1)
    # inside, the curve follows the spline: in the plane the move is exact
    want = sc.basis(t)[:, i] * 0.08
    assert_allclose(moved, want, atol=tol.length(mesh, tol.TEST_ATOL, scale="bbox_diagonal"))
    assert moved.max() > 0.02


def test_moving_an_edit_point_passes_the_spline_through_it():
    mesh, curve = _plane_curve()
    sc = fit_space_curve(mesh, curve, n_control=8)
    j = 3
    target = sc.edit_points[j] + [0.0, -0.05, 0.0]
    new_curve, new_sc = move_edit_point(mesh, curve, sc, j, target)
    assert_allclose(new_sc.edit_points[j], target, atol=1e-12)
    assert check_sampling(mesh, new_curve).size == 0
    followed = _follow(mesh, curve, sc, new_sc)
    assert _is_subsequence(followed.points, new_curve.points)
    moved = np.linalg.norm(mesh.xyz(followed.points) - mesh.xyz(curve.points), axis=1)
    assert moved.max() > 0.02
    t = _chord_params(mesh.xyz(curve.points))
    far = sc.basis(t)[:, max(j - 3, 0) : j + 4].sum(axis=1) == 0
    assert (moved[far] == 0).all()


def test_space_curve_errors():
    mesh, curve = _plane_curve()
    with pytest.raises(InputError, match="n_control must be in"):
        fit_space_curve(mesh, curve, n_control=len(curve) + 5)
    with pytest.raises(InputError, match="n_control must be in"):
        fit_space_curve(mesh, curve, n_control=3)
    sc = fit_space_curve(mesh, curve, n_control=6)
    with pytest.raises(InputError, match="index must be an integer in"):
        move_control_point(mesh, curve, sc, 6, [0, 0, 0])
    with pytest.raises(InputError, match="new_xyz has a NaN"):
        move_edit_point(mesh, curve, sc, 1, [np.nan, 0, 0])
    with pytest.raises(InputError, match="at least 4 control points"):
        SpaceCurve.uniform(np.zeros((3, 3)))
    with pytest.raises(InputError, match="params must be finite"):
        fit_bspline_curve(np.zeros((5, 3)), [0, 0.5, 0.4, 0.9, 1], n_control=4)
