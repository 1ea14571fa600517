"""Fine detail kept out of the spline (``fit_bspline(..., smoothing=s)``, thesis sec. 7.5).

The bounds of the bump tests come from the filter: a Gaussian bump of standard deviation
``b`` knot spacings under a Gaussian low-pass of ``s`` keeps ``b^2 / (b^2 + s^2)`` of its
height (the least-squares projection of the smooth remainder only takes more away), and a
positive kernel adds no dip; plain least squares is held to the ringing it is known for so
that the comparison can fail.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from numpy.testing import assert_allclose

from meshfit.bspline import basis_matrix, clamped_knots, fit_bspline, grid_parameters
from meshfit.displacement import displacement_map, reconstruct
from meshfit.errors import InputError
from tests.bspline.grids import random_surface
from tests.reference import bspline as ref

N = 65  # grid samples per side
H = 0.02  # bump height, model units (the base spans 1)
FWHM_PER_SIGMA = 2.0 * np.sqrt(2.0 * np.log(2.0))


# ----------------------------------------------------------------------------- oracle
def _odd_extension(x: np.ndarray, j: int) -> np.ndarray:
    """Sample j of the line x extended by odd reflection about both end samples."""
    n = x.shape[0]
    if j < 0:
        return 2.0 * x[0] - _odd_extension(x, -j)
    if j > n - 1:
        return 2.0 * x[-1] - _odd_extension(x, 2 * (n - 1) - j)
    return x[j]


def lowpass_line(x: np.ndarray, sigma: float) -> np.ndarray:
    """Cubic trend plus the Gaussian (``sigma`` samples) of the rest, sample by sample."""
    n = x.shape[0]
    t = np.linspace(0.0, 1.0, n)
    trend = np.polynomial.polynomial.polyval(t, np.polynomial.polynomial.polyfit(t, x, 3)).T
    r = x - trend
    reach = int(np.ceil(10 * sigma))
    k = np.arange(-reach, reach + 1)
    w = np.exp(-0.5 * (k / sigma) ** 2)
    w /= w.sum()
    out = np.array(
        [sum(wk * _odd_extension(r, i + kk) for kk, wk in zip(k, w, strict=True)) for i in range(n)]
    )
    return trend + out


def lowpass_grid(X: np.ndarray, controls: tuple[int, int], s: float) -> np.ndarray:
    nu, nv = X.shape[:2]
    su, sv = s * (nu - 1) / (controls[0] - 3), s * (nv - 1) / (controls[1] - 3)
    Y = np.stack([lowpass_line(X[:, j], su) for j in range(nv)], axis=1)
    return np.stack([lowpass_line(Y[i], sv) for i in range(nu)], axis=0)


# ----------------------------------------------------------------------------- grids
def height_grid(n: int, fwhm: float | None, m: int) -> np.ndarray:
    """Gently curved base ``z = 0.4 |(u, v) - c|^2`` plus a Gaussian bump at the centre c
    whose full width at half maximum is ``fwhm`` knot spacings of m controls."""
    t = grid_parameters(n)
    U, V = np.meshgrid(t, t, indexing="ij")
    r2 = (U - 0.5) ** 2 + (V - 0.5) ** 2
    z = 0.4 * r2
    if fwhm is not None:
        sigma = fwhm / (m - 3) / FWHM_PER_SIGMA
        z = z + H * np.exp(-r2 / (2.0 * sigma**2))
    return np.stack([U, V, z], axis=-1)


@cache
def bump_figures(fwhm: float, m: int, s: float) -> dict[str, float]:
    """Response to the bump over its height: shares at the centre, most negative values."""
    X0, X1 = height_grid(N, None, m), height_grid(N, fwhm, m)
    S0 = fit_bspline(X0, controls=(m, m), smoothing=s)
    S1 = fit_bspline(X1, controls=(m, m), smoothing=s)
    t = grid_parameters(N)
    _, _, normal = S0.frames(*np.meshgrid(t, t, indexing="ij"))
    D1 = displacement_map(S1, X1)
    dmap = (D1.values[..., 2] - displacement_map(S0, X0).values[..., 2]) / H
    dspline = ((S1.evaluate_grid(t, t) - S0.evaluate_grid(t, t)) * normal).sum(-1) / H
    c = N // 2
    return {
        "base_error": float(np.abs(S0.evaluate_grid(t, t) - X0).max()),
        "map_share": float(dmap[c, c]),
        "spline_share": float(dspline[c, c]),
        "ring_map": float(dmap.min()),
        "ring_spline": float(dspline.min()),
        "displaced_error": float(np.abs(reconstruct(S1, D1) - X1).max()),
        "displaced_lowest": float((reconstruct(S1, D1)[..., 2] - X0[..., 2]).min() / H),
    }


def gaussian_share(fwhm: float, s: float) -> float:
    """Height share a Gaussian low-pass of s knot spacings leaves a bump of this width."""
    b2 = (fwhm / FWHM_PER_SIGMA) ** 2
    return b2 / (b2 + s**2)


# ----------------------------------------------------------------------------- sec. 7.5
@pytest.mark.parametrize("m", [10, 16])
def test_plain_least_squares_splits_a_one_knot_bump_and_rings(m):
    f = bump_figures(1.0, m, 0.0)
    assert f["spline_share"] > 0.5  # more than half the bump in the spline
    assert f["ring_spline"] < -0.06  # the spline dips around it (ringing)
    assert f["ring_map"] < -0.12  # and the map has a dent ring


@pytest.mark.parametrize("m", [10, 16])
def test_smoothing_moves_a_one_knot_bump_to_the_map_without_dents(m):
    f = bump_figures(1.0, m, 0.5)
    assert f["base_error"] < 1e-12  # the curved base stays in the spline, exactly
    assert f["spline_share"] <= gaussian_share(1.0, 0.5)
    assert f["map_share"] >= 1.0 - gaussian_share(1.0, 0.5)
    assert f["ring_spline"] > -0.02  # positive kernel: no dip (projection rings < 2%)
    assert f["ring_map"] > -0.115  # the shallower trough of the spread volume
    assert f["ring_map"] > bump_figures(1.0, m, 0.0)["ring_map"] + 0.02
    # spline + vector map is the grid either way: never below the base
    for s in (0.0, 0.5):
        g = bump_figures(1.0, m, s)
        assert g["displaced_error"] < 1e-14
        assert g["displaced_lowest"] > -1e-12


@pytest.mark.parametrize("m", [10, 16])
def test_smoothing_keeps_broad_bumps_in_the_spline(m):
    f = bump_figures(4.0, m, 0.5)
    assert f["spline_share"] >= gaussian_share(4.0, 0.5) - 0.01
    assert f["ring_spline"] > -0.01


# ----------------------------------------------------------------------------- contract
@pytest.mark.parametrize(
    ("shape", "controls", "s"), [((31, 27), (9, 7), 0.5), ((20, 14), (6, 5), 2.0)]
)
def test_fit_is_least_squares_of_the_low_passed_grid(shape, controls, s, rng):
    # s = 2 makes the Gaussian wider than a quarter of the reflected period
    X = rng.normal(size=(*shape, 3))
    got = fit_bspline(X, controls=controls, smoothing=s)
    want = fit_bspline(lowpass_grid(X, controls, s), controls=controls)
    assert_allclose(got.control_points, want.control_points, rtol=0, atol=1e-11)


def test_off_is_plain_least_squares_bit_for_bit(rng):
    X = rng.normal(size=(30, 25, 3))
    plain = fit_bspline(X, controls=(8, 7)).control_points
    assert np.array_equal(fit_bspline(X, controls=(8, 7), smoothing=0.0).control_points, plain)
    want = ref.dense_fit(X, 8, 7, clamped_knots(8), clamped_knots(7))
    assert_allclose(plain, want, rtol=1e-10, atol=1e-10)
    pin = {"u0": plain[0], "v1": plain[:, -1] + 0.1}
    pin["v1"][0] = pin["u0"][-1]
    a = fit_bspline(X, controls=(8, 7), pin_boundary=pin).control_points
    b = fit_bspline(X, controls=(8, 7), pin_boundary=pin, smoothing=0).control_points
    assert np.array_equal(a, b)


@pytest.mark.parametrize("s", [0.5, 2.0, 1e6])
def test_bicubic_grids_pass_unchanged(s):
    t = grid_parameters(40)
    U, V = np.meshgrid(t, t, indexing="ij")
    X = np.stack([U + 0.1 * V**3, V, U**3 - 2 * U * V**2 + 0.5 * V - U**2 * V], axis=-1)
    S = fit_bspline(X, controls=(9, 12), smoothing=s)
    assert_allclose(S.evaluate_grid(t, t), X, rtol=0, atol=1e-12)


def _rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def test_rigid_motion_and_uniform_scale_commute_with_the_fit(rng):
    s = random_surface(rng, 7, 8)
    X = s.evaluate_grid(grid_parameters(40), grid_parameters(45))
    X = X + 0.01 * rng.normal(size=X.shape)
    P = s.control_points
    pin = {"u0": P[0], "v1": P[:, -1]}
    R, c, shift = _rotation(rng), 37.5, np.array([1e3, -2e2, 5.0])

    def move(A):
        return c * A @ R.T + shift

    for pins in (None, pin):
        got = fit_bspline(
            move(X),
            controls=(7, 8),
            smoothing=0.7,
            pin_boundary=None if pins is None else {k: move(v) for k, v in pins.items()},
        )
        want = move(
            fit_bspline(X, controls=(7, 8), smoothing=0.7, pin_boundary=pins).control_points
        )
        assert_allclose(got.control_points, want, rtol=0, atol=1e-12 * c * 1e3)


def test_pinned_rows_are_exact_and_the_rest_solves_the_same_problem(rng):
    s = random_surface(rng, 7, 8)
    t_u, t_v = grid_parameters(36), grid_parameters(33)
    X = s.evaluate_grid(t_u, t_v) + 0.02 * rng.normal(size=(36, 33, 3))
    free = fit_bspline(X, controls=(7, 8), smoothing=0.6).control_points
    # pinned to its own boundary rows, the fit is the unpinned one
    own = {"u0": free[0], "u1": free[-1], "v0": free[:, 0], "v1": free[:, -1]}
    same = fit_bspline(X, controls=(7, 8), smoothing=0.6, pin_boundary=own).control_points
    assert_allclose(same, free, rtol=0, atol=1e-12)
    # pinned elsewhere: the rows are kept bit for bit, the free controls are least squares
    # to the low-passed grid given them
    P = s.control_points
    got = fit_bspline(X, controls=(7, 8), smoothing=0.6, pin_boundary={"u0": P[0], "v1": P[:, -1]})
    assert np.array_equal(got.control_points[0], P[0])
    assert np.array_equal(got.control_points[:, -1], P[:, -1])
    Bu, Bv = basis_matrix(t_u, clamped_knots(7)), basis_matrix(t_v, clamped_knots(8))
    R = lowpass_grid(X, (7, 8), 0.6) - got.evaluate_grid(t_u, t_v)
    G = np.einsum("ia,ijc,jb->abc", Bu, R, Bv)
    assert_allclose(G[1:, :-1], 0, atol=1e-11)


def test_width_is_in_knot_spacings_whatever_the_grid_resolution():
    coarse = fit_bspline(height_grid(65, 1.0, 10), controls=(10, 10), smoothing=0.5)
    fine = fit_bspline(height_grid(129, 1.0, 10), controls=(10, 10), smoothing=0.5)
    t = grid_parameters(65)
    d = np.abs(coarse.evaluate_grid(t, t) - fine.evaluate_grid(t, t)).max()
    assert d < 0.01 * H  # the same split of the bump: sampling differences only
    narrow = fit_bspline(height_grid(129, 1.0, 10), controls=(10, 10), smoothing=0.25)
    assert np.abs(narrow.evaluate_grid(t, t) - fine.evaluate_grid(t, t)).max() > 0.1 * H


def test_filter_is_continuous_across_its_two_evaluations(rng):
    # the wrapped Gaussian switches from a direct sum to its Fourier series at a quarter period
    X = rng.normal(size=(25, 25, 3))
    s = (10 - 3) / 2  # sigma = (n - 1) / 2 samples
    a = fit_bspline(X, controls=(10, 10), smoothing=s * (1 - 1e-12)).control_points
    b = fit_bspline(X, controls=(10, 10), smoothing=s * (1 + 1e-12)).control_points
    assert_allclose(a, b, rtol=0, atol=1e-10)


@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf"), "wide", None])
def test_bad_smoothing_is_refused(bad):
    with pytest.raises(InputError, match="smoothing"):
        fit_bspline(np.zeros((10, 10, 3)), controls=(5, 5), smoothing=bad)
