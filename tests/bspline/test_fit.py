import itertools

import numpy as np
import pytest
from numpy.testing import assert_allclose

from meshfit import tol
from meshfit.bspline import (
    BSplineSurface,
    basis_local,
    basis_matrix,
    clamped_knots,
    closest_parameters,
    fit_bspline,
    fit_errors,
    grid_parameters,
)
from meshfit.errors import InputError
from tests.bspline.grids import random_surface, scan_grid
from tests.reference import bspline as ref


@pytest.mark.parametrize("m", [4, 5, 9])
def test_basis_matches_cox_de_boor(m, rng):
    U = clamped_knots(m)
    if m == 9:  # non-uniform clamped knots too
        U = np.concatenate([[0, 0, 0], np.sort(rng.uniform(0, 1, m - 4)), [1, 1, 1, 1]])
        U = np.concatenate([[0.0], U])
    t = np.concatenate([rng.uniform(0, 1, 30), [0.0, 1.0], U[4:-4]])
    first, vals = basis_local(t, U, 3, 2)
    for k, tk in enumerate(t):
        for a in range(4):
            for r in range(3):
                want = ref.basis_derivative(first[k] + a, 3, tk, U, r)
                assert_allclose(vals[k, r, a], want, rtol=1e-11, atol=1e-11)
    assert_allclose(basis_matrix(t, U).sum(axis=1), 1.0, rtol=0, atol=1e-14)


def test_surface_derivatives_match_oracle(rng):
    s = random_surface(rng)
    u, v = rng.uniform(0, 1, 12), rng.uniform(0, 1, 12)
    got = s.evaluate(u, v, derivatives=2)
    orders = [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2)]
    for g, (du, dv) in zip(got, orders, strict=True):
        want = np.array(
            [
                ref.surface_point(s.control_points, s.knots_u, s.knots_v, a, b, du, dv)
                for a, b in zip(u, v, strict=True)
            ]
        )
        assert_allclose(g, want, rtol=1e-10, atol=1e-10)
    grid = s.evaluate_grid(u[:5], v[:7], derivatives=2)
    U, V = np.meshgrid(u[:5], v[:7], indexing="ij")
    for g, w in zip(grid, s.evaluate(U, V, derivatives=2), strict=True):
        assert_allclose(g, w, rtol=1e-12, atol=1e-12)


def test_corners_interpolate_and_frames_are_orthonormal(rng):
    s = random_surface(rng)
    P = s.control_points
    corners = s.evaluate([0, 1, 1, 0], [0, 0, 1, 1])
    assert_allclose(corners, [P[0, 0], P[-1, 0], P[-1, -1], P[0, -1]], atol=1e-15)
    u, v = rng.uniform(0, 1, 50), rng.uniform(0, 1, 50)
    T, B, N = s.frames(u, v)
    F = np.stack([T, B, N], axis=-1)
    assert_allclose(
        np.einsum("nki,nkj->nij", F, F), np.broadcast_to(np.eye(3), (50, 3, 3)), atol=1e-12
    )
    assert_allclose(np.linalg.det(F), 1.0, atol=1e-12)
    _, Su, Sv = s.evaluate(u, v, derivatives=1)
    assert_allclose((Su * N).sum(1), 0, atol=1e-12)
    assert_allclose((Sv * N).sum(1), 0, atol=1e-12)
    assert ((np.cross(Su, Sv) * N).sum(1) > 0).all()


def test_degenerate_corner_normal_is_finite():
    # a patch whose u=0 side collapses to one point (a triangle-like patch)
    iu, iv = np.meshgrid(np.linspace(0, 1, 5), np.linspace(0, 1, 5), indexing="ij")
    P = np.stack([iu, iu * (iv - 0.5), 0.1 * iu**2], axis=-1)
    s = BSplineSurface(P)
    n = s.normals([0.0, 0.0, 0.5], [0.0, 0.5, 0.5])
    assert np.isfinite(n).all()
    assert_allclose(np.linalg.norm(n, axis=1), 1.0)


@pytest.mark.parametrize("shape", [(7, 9), (4, 4), (12, 5)])
def test_fit_recovers_known_control_points(shape, rng):
    s = random_surface(rng, *shape)
    X = s.evaluate_grid(grid_parameters(40), grid_parameters(33))
    got = fit_bspline(X, controls=shape)
    scale = np.abs(s.control_points).max()
    assert_allclose(got.control_points, s.control_points, rtol=0, atol=tol.BSPLINE_FIT_RTOL * scale)
    err = fit_errors(got, X)
    assert err.parametric_max <= tol.BSPLINE_FIT_RTOL * scale


def test_separable_fit_equals_dense_least_squares(rng):
    X = rng.normal(size=(11, 9, 3))
    got = fit_bspline(X, controls=(6, 5))
    want = ref.dense_fit(X, 6, 5, clamped_knots(6), clamped_knots(5))
    assert_allclose(got.control_points, want, rtol=1e-10, atol=1e-10)


def test_fit_at_grid_resolution_interpolates(rng):
    X = rng.normal(size=(8, 6, 3))
    s = fit_bspline(X, controls=(8, 6))
    assert_allclose(s.evaluate_grid(grid_parameters(8), grid_parameters(6)), X, atol=1e-10)


def test_pinned_boundary_is_kept_and_optimal(rng):
    s = random_surface(rng, 7, 8)
    X = s.evaluate_grid(grid_parameters(30), grid_parameters(31)) + 0.01 * rng.normal(
        size=(30, 31, 3)
    )
    P = s.control_points
    pin = {"u0": P[0], "v1": P[:, -1]}
    got = fit_bspline(X, controls=(7, 8), pin_boundary=pin)
    assert_allclose(got.control_points[0], P[0], rtol=0, atol=0)
    assert_allclose(got.control_points[:, -1], P[:, -1], rtol=0, atol=0)
    # optimal: the residual is orthogonal to every free basis product
    from meshfit.bspline.fit import _solver

    Bu = _solver(30, 7)[2]
    Bv = _solver(31, 8)[2]
    R = X - got.evaluate_grid(grid_parameters(30), grid_parameters(31))
    G = np.einsum("ia,ijc,jb->abc", Bu, R, Bv)
    assert_allclose(G[1:, :-1], 0, atol=1e-12)
    # the unconstrained fit is at least as good
    free = fit_errors(fit_bspline(X, controls=(7, 8)), X)
    assert free.parametric_rms <= fit_errors(got, X).parametric_rms


def test_pinned_sides_must_agree_at_corners(rng):
    X = rng.normal(size=(10, 10, 3))
    a = np.zeros((5, 3))
    b = np.ones((5, 3))
    with pytest.raises(InputError, match="corner"):
        fit_bspline(X, controls=(5, 5), pin_boundary={"u0": a, "v0": b})
    with pytest.raises(InputError, match="side"):
        fit_bspline(X, controls=(5, 5), pin_boundary={"top": a})


@pytest.mark.parametrize(
    ("grid", "controls", "match"),
    [
        (np.zeros((10, 10, 2)), (5, 5), "shape"),
        (np.zeros((10, 10, 3)), (3, 5), "out of range"),
        (np.zeros((10, 10, 3)), (11, 5), "out of range"),
        (np.full((10, 10, 3), np.nan), (5, 5), r"grid_xyz\[0, 0\]"),
    ],
)
def test_fit_rejects_bad_input(grid, controls, match):
    with pytest.raises(InputError, match=match):
        fit_bspline(grid, controls=controls)


def test_surface_rejects_bad_input():
    with pytest.raises(InputError, match="4 x 4"):
        BSplineSurface(np.zeros((3, 5, 3)))
    with pytest.raises(InputError, match="clamped"):
        BSplineSurface(np.zeros((4, 4, 3)), knots_u=np.linspace(0, 1, 8))


def test_normal_distance_of_offset_points(rng):
    s = random_surface(rng)
    u, v = grid_parameters(20), grid_parameters(25)
    U, V = np.meshgrid(u, v, indexing="ij")
    X = s.evaluate_grid(u, v) + 0.004 * s.normals(U, V)
    # start away from the foot points: the Newton iteration must find them
    uu, _vv, d = closest_parameters(
        s, X.reshape(-1, 3), np.clip(U.ravel() + 0.03, 0, 1), np.clip(V.ravel() - 0.02, 0, 1)
    )
    inner = ((U > 0.1) & (U < 0.9) & (V > 0.1) & (V < 0.9)).ravel()
    assert_allclose(d[inner], 0.004, rtol=1e-8)
    assert_allclose(uu[inner], U.ravel()[inner], atol=1e-8)
    err = fit_errors(s, X)
    assert err.normal_max <= err.parametric_max + 1e-15
    assert_allclose(err.normal_rms, 0.004, rtol=1e-6)


@pytest.mark.parametrize("name", ["igea", "nefertiti"])
def test_error_falls_with_control_resolution_on_scans(name):
    X = scan_grid(name)
    errs = [fit_errors(fit_bspline(X, controls=(m, m)), X) for m in (4, 6, 8, 12, 16, 24, 32, 48)]
    par = [e.parametric_rms for e in errs]
    nor = [e.normal_rms for e in errs]
    assert all(b < a for a, b in itertools.pairwise(par)), par
    assert all(b < a for a, b in itertools.pairwise(nor)), nor
    assert all(e.normal_max <= e.parametric_max for e in errs)
    # at the grid's own resolution the spline interpolates the grid
    full = fit_bspline(X, controls=X.shape[:2])
    diag = np.linalg.norm(np.ptp(X.reshape(-1, 3), axis=0))
    assert fit_errors(full, X).parametric_max <= tol.TEST_ATOL * diag


def test_kernels_match_dense_products(rng):
    from meshfit._kernels import bspline as k

    n, m = 23, 9
    t = grid_parameters(n)
    U = clamped_knots(m)
    f, N = basis_local(t, U)
    N = np.ascontiguousarray(N[:, 0, :])
    B = basis_matrix(t, U)
    X = rng.normal(size=(n, n, 3))
    P = rng.normal(size=(m, m, 3))
    want_g = np.stack([B.T @ X[..., c] @ B for c in range(3)], axis=-1)
    assert_allclose(k.gram_sandwich(f, N, f, N, X, m, m), want_g, atol=1e-12)
    want_e = np.stack([B @ P[..., c] @ B.T for c in range(3)], axis=-1)
    assert_allclose(k.grid_eval(f, N, f, N, P), want_e, atol=1e-12)
    A = rng.normal(size=(4, n))
    C = rng.normal(size=(5, n))
    want_d = np.stack([A @ X[..., c] @ C.T for c in range(3)], axis=-1)
    assert_allclose(k.dense_sandwich(A, X, C), want_d, atol=1e-12)


@pytest.mark.parametrize(("n", "m"), [(40, 12), (30, 30), (100, 90)])
def test_qr_pinv_kernel_matches_numpy(n, m):
    from meshfit._kernels import bspline as k

    B = basis_matrix(grid_parameters(n), clamped_knots(m))
    pinv, gram_inv = k.qr_pinv(B)
    want = np.linalg.pinv(B)
    cond = np.linalg.cond(B)
    assert_allclose(pinv, want, rtol=0, atol=100 * cond * np.finfo(float).eps * np.abs(want).max())
    assert_allclose(gram_inv @ (B.T @ B), np.eye(m), atol=100 * cond**2 * np.finfo(float).eps)
