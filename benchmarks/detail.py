"""Benchmark: fine detail kept out of the spline, left to the displacement map (sec. 7.5).

Plain least squares (``fit_bspline(..., smoothing=0)``, "before") splits a bump narrower than
the knot spacing between the spline and the map and rings around it (Krishnamurthy 2000,
sec. 7.5, fig. 7.2). ``smoothing=s`` ("after") fits the spline to a low-passed copy of the
grid (a Gaussian of ``s`` knot spacings on the deviation from the cubic trend).

Synthetic grids: 65 x 65 samples over the unit square, a flat and a gently curved base
(``z = 0.4 ((u - 1/2)^2 + (v - 1/2)^2)``), plus a Gaussian bump of height h at the centre
(a grid sample, mid-span for both control counts) whose full width at half maximum is 0.5,
1, 2 or 4 knot spacings; controls 10 x 10 and 16 x 16. Each figure is the response to the
bump (the fit of the bump grid minus the fit of the base grid, so the base's own fit error
does not enter), over h, along the base fit's normals:

- ``map_share``, ``spline_share``: the map's and the spline's response at the bump's centre
  (they sum to 1);
- ``ring_map``: most negative map response anywhere (the dent ring or trough around the bump
  as seen in the map image);
- ``ring_spline``: most negative spline response (the spline dips around the bump);
- ``ring_displaced``: lowest height, over the exact base, of the displaced surface
  ``spline + map`` rebuilt from the vector map at the grid's resolution (the grid itself:
  never below the base); ``ring_displaced_2x``: the same rebuilt at twice the resolution
  (bilinear between texels, :func:`meshfit.displacement.reconstruct`);
- ``spline_rms``, ``spline_max``: spline-only distance to the bump grid, over h;
- ``displaced_max``: distance of the rebuilt displaced surface to the grid (model units);
  ``displaced_max_2x``: at twice the resolution, to the exact surface there, over h.

``broad_shape``: spline-only max distance over the shape's extent for bump-free broad shapes
(paraboloid, one sine wave per patch, half cylinder, 90-degree sphere cap): what of the broad
shape the option pushes into the map.

``candidates``: the other splits considered, each with its parameter set so that the map
takes the same share of the 1-knot bump (curved base, 10 x 10) as ``smoothing=0.5``: the
Gaussian on the grid itself (no cubic trend), a second- and a third-derivative penalty on
the spline (``(B^T B + lam h^(2k) (n-1) R_k)^-1`` per direction, R_k the Gram matrix of the
k-th derivatives, h the knot spacing), and a nonlinear split (flat morphological
opening/closing of the normal offsets from a smoothed fit, disc of r knot spacings).

``meshes``: the whole fit (:func:`meshfit.fit`, default options) of spot and kitten before
and after, with ``fit_bspline`` called with ``smoothing`` by the fit stage (patched in this
process): spline-only and displaced errors over the bbox diagonal, seam figures, largest map
value. Vector maps (and smoothing 1 as well), normal maps.

Run: ``python benchmarks/detail.py [--smoothing 0.5] [--no-meshes]``. Prints the tables and
writes ``benchmarks/results/detail.json``.
"""

from __future__ import annotations

import argparse
import itertools
import os
import platform
import time

import numpy as np
from _common import mesh_path, write_result
from numpy.polynomial.legendre import leggauss
from scipy import ndimage

import meshfit
import meshfit.bspline
from meshfit.bspline import (
    BSplineSurface,
    basis_matrix,
    clamped_knots,
    fit_bspline,
    grid_parameters,
)
from meshfit.displacement import displacement_map, reconstruct
from meshfit.pipeline import FitOptions

N = 65
HEIGHT = 0.02
FWHM = (0.5, 1.0, 2.0, 4.0)
CONTROLS = (10, 16)
SWEEP = (0.25, 0.5, 0.75, 1.0)
FWHM_PER_SIGMA = 2.0 * np.sqrt(2.0 * np.log(2.0))


# ----------------------------------------------------------------------------- grids
def base_height(U, V, base: str):
    return 0.4 * ((U - 0.5) ** 2 + (V - 0.5) ** 2) if base == "curved" else 0.0 * U


def bump_height(U, V, fwhm: float, m: int):
    sigma = fwhm / (m - 3) / FWHM_PER_SIGMA
    return HEIGHT * np.exp(-((U - 0.5) ** 2 + (V - 0.5) ** 2) / (2.0 * sigma**2))


def height_grid(n: int, base: str, fwhm: float | None, m: int) -> np.ndarray:
    t = grid_parameters(n)
    U, V = np.meshgrid(t, t, indexing="ij")
    z = base_height(U, V, base)
    if fwhm is not None:
        z = z + bump_height(U, V, fwhm, m)
    return np.stack([U, V, z], axis=-1)


# ----------------------------------------------------------------------------- figures
def normal_offset(surface: BSplineSurface, n: int, points: np.ndarray) -> np.ndarray:
    t = grid_parameters(n)
    U, V = np.meshgrid(t, t, indexing="ij")
    _, _, N_ = surface.frames(U, V)
    return ((points - surface.evaluate_grid(t, t)) * N_).sum(-1)


def over_base(points: np.ndarray, base: str) -> np.ndarray:
    """Height of points over the exact base surface, over h."""
    return (points[..., 2] - base_height(points[..., 0], points[..., 1], base)) / HEIGHT


def responses(fit, base: str, fwhm: float, m: int) -> dict:
    """Figures of one split (``fit(X, m) -> BSplineSurface``) for one bump."""
    X0, X1 = height_grid(N, base, None, m), height_grid(N, base, fwhm, m)
    S0, S1 = fit(X0, m), fit(X1, m)
    t = grid_parameters(N)
    G1 = S1.evaluate_grid(t, t)
    map0 = displacement_map(S0, X0).values[..., 2]
    D1 = displacement_map(S1, X1)
    dmap = (D1.values[..., 2] - map0) / HEIGHT
    dspline = normal_offset(S0, N, G1) / HEIGHT
    disp = reconstruct(S1, D1)
    n2 = 2 * N - 1
    disp2 = reconstruct(S1, D1, shape=(n2, n2))
    exact2 = height_grid(n2, base, fwhm, m)
    err = np.linalg.norm(X1 - G1, axis=-1) / HEIGHT
    c = N // 2
    return {
        "map_share": float(dmap[c, c]),
        "spline_share": float(dspline[c, c]),
        "ring_map": float(dmap.min()),
        "ring_spline": float(dspline.min()),
        "ring_displaced": float(over_base(disp, base).min()),
        "ring_displaced_2x": float(over_base(disp2, base).min()),
        "spline_rms": float(np.sqrt(np.mean(err**2))),
        "spline_max": float(err.max()),
        "displaced_max": float(np.abs(disp - X1).max()),
        "displaced_max_2x": float(np.linalg.norm(disp2 - exact2, axis=-1).max() / HEIGHT),
    }


def broad_shapes() -> dict[str, np.ndarray]:
    t = grid_parameters(N)
    U, V = np.meshgrid(t, t, indexing="ij")
    a, b = np.pi / 2 * (U - 0.5), np.pi / 2 * (V - 0.5)
    return {
        "paraboloid": height_grid(N, "curved", None, 10),
        "sine_wave": np.stack([U, V, 0.15 * np.sin(2 * np.pi * U) * np.cos(np.pi * V)], -1),
        "half_cylinder": np.stack(
            [np.sin(np.pi * (U - 0.5)), 2.0 * V, np.cos(np.pi * (U - 0.5))], -1
        ),
        "sphere_cap_90deg": np.stack([np.sin(a) * np.cos(b), np.sin(b), np.cos(a) * np.cos(b)], -1),
    }


def broad_shape_errors(fit) -> dict:
    t = grid_parameters(N)
    out = {}
    for name, X in broad_shapes().items():
        ext = float(np.ptp(X.reshape(-1, 3), axis=0).max())
        for m in CONTROLS:
            S = fit(X, m).evaluate_grid(t, t)
            out[f"{name}_{m}"] = float(np.linalg.norm(S - X, axis=-1).max() / ext)
    return out


# ----------------------------------------------------------------------------- splits
def plain(X, m):
    return fit_bspline(X, controls=(m, m))


def smoothed(s):
    return lambda X, m: fit_bspline(X, controls=(m, m), smoothing=s)


def _odd_gaussian(X, sigma, axis):
    """Gaussian along ``axis`` with odd reflection at both ends (no cubic trend)."""
    Y = np.moveaxis(X, axis, 0)
    n = Y.shape[0]
    pad = min(int(np.ceil(6 * sigma)) + 1, n - 1)
    lo = 2 * Y[:1] - Y[1 : pad + 1][::-1]
    hi = 2 * Y[-1:] - Y[-pad - 1 : -1][::-1]
    E = ndimage.gaussian_filter1d(np.concatenate([lo, Y, hi]), sigma, axis=0, mode="nearest")
    return np.moveaxis(E[pad : pad + n], 0, axis)


def gaussian_no_trend(s):
    def fit(X, m):
        sig = s * (X.shape[0] - 1) / (m - 3)
        return plain(_odd_gaussian(_odd_gaussian(X, sig, 0), sig, 1), m)

    return fit


def _derivative_gram(m: int, order: int) -> np.ndarray:
    U = clamped_knots(m)
    x, w = leggauss(6)
    ks = np.unique(U)
    spans = list(itertools.pairwise(ks))
    pts = np.concatenate([(a + b) / 2 + (b - a) / 2 * x for a, b in spans])
    wts = np.concatenate([(b - a) / 2 * w for a, b in spans])
    Bd = basis_matrix(pts, U, 3, order)
    return Bd.T @ (wts[:, None] * Bd)


def penalty(order: int, lam: float):
    def fit(X, m):
        n = X.shape[0]
        B = basis_matrix(grid_parameters(n), clamped_knots(m))
        h = 1.0 / (m - 3)
        A = np.linalg.solve(
            B.T @ B + lam * (n - 1) * h ** (2 * order) * _derivative_gram(m, order), B.T
        )
        return BSplineSurface(np.einsum("ai,ijk,bj->abk", A, X, A))

    return fit


def morphological(r: float, reference: float = 1.0):
    def fit(X, m):
        n = X.shape[0]
        ref = fit_bspline(X, controls=(m, m), smoothing=reference)
        t = grid_parameters(n)
        _, _, N_ = ref.frames(*np.meshgrid(t, t, indexing="ij"))
        d = ((X - ref.evaluate_grid(t, t)) * N_).sum(-1)
        rs = r * (n - 1) / (m - 3)
        k = int(np.floor(rs))
        I, J = np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1), indexing="ij")
        disc = I**2 + J**2 <= rs**2
        op = lambda a: ndimage.grey_opening(a, footprint=disc, mode="reflect")  # noqa: E731
        cl = lambda a: ndimage.grey_closing(a, footprint=disc, mode="reflect")  # noqa: E731
        base = 0.5 * (op(cl(d)) + cl(op(d)))
        return plain(X - (d - base)[..., None] * N_, m)

    return fit


def calibrate(make, lo: float, hi: float, target: float, log: bool = True) -> float:
    """Parameter of ``make`` giving the 1-knot bump's map share ``target`` (bisection)."""

    def share(p):
        return responses(make(p), "curved", 1.0, 10)["map_share"]

    a, b = (np.log(lo), np.log(hi)) if log else (lo, hi)
    for _ in range(20):
        mid = 0.5 * (a + b)
        if share(np.exp(mid) if log else mid) < target:
            a = mid
        else:
            b = mid
    mid = 0.5 * (a + b)
    return float(np.exp(mid) if log else mid)


# ----------------------------------------------------------------------------- meshes
def mesh_runs(smoothing: float) -> list[dict]:
    original = meshfit.bspline.fit_bspline
    rows = []
    for name in ("spot", "kitten"):
        for kind, values in (("vector", (0.0, smoothing, 1.0)), ("normal", (0.0, smoothing))):
            for s in dict.fromkeys(values):

                def patched(*args, _s=s, **kw):
                    return original(*args, smoothing=_s, **kw)

                meshfit.bspline.fit_bspline = patched
                try:
                    t0 = time.perf_counter()
                    res = meshfit.fit(
                        str(mesh_path(name)),
                        options=FitOptions(formats=(), report=False, map_kind=kind),
                    )
                    seconds = time.perf_counter() - t0
                finally:
                    meshfit.bspline.fit_bspline = original
                e = res.errors
                seams = res.summary["seams"]
                rows.append(
                    {
                        "mesh": name,
                        "map_kind": kind,
                        "smoothing": s,
                        "patches": len(res.patches),
                        "spline_only_rms": e["spline_only"]["rms"],
                        "spline_only_hausdorff": e["spline_only"]["hausdorff"],
                        "displaced_rms": e["displaced"]["rms"],
                        "displaced_hausdorff": e["displaced"]["hausdorff"],
                        "displaced_gap_max": seams["displaced_gap_max"],
                        "displaced_gap_any_resolution_max": seams[
                            "displaced_gap_any_resolution_max"
                        ],
                        "spline_normal_jump_max_deg": seams["spline_normal_jump_max_deg"],
                        "displacement_max": max(
                            p["displacement_max"] for p in res.summary["patches"]
                        ),
                        "seconds": round(seconds, 1),
                    }
                )
                r = rows[-1]
                print(
                    f"{name:7s} {kind:6s} s={s:<4} spline-only rms {r['spline_only_rms']:.2e} "
                    f"H {r['spline_only_hausdorff']:.2e} | displaced rms "
                    f"{r['displaced_rms']:.2e} H {r['displaced_hausdorff']:.2e} | "
                    f"normal jump {r['spline_normal_jump_max_deg']:.2f} deg",
                    flush=True,
                )
    return rows


# ----------------------------------------------------------------------------- main
COLS = (
    "map_share",
    "spline_share",
    "ring_map",
    "ring_spline",
    "ring_displaced_2x",
    "spline_rms",
    "displaced_max_2x",
)


def _row(label: str, r: dict) -> str:
    return f"  {label:28s}" + "".join(f"{r[c]:+9.3f}" for c in COLS)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--smoothing", type=float, default=0.5, help="the 'after' value")
    ap.add_argument("--no-meshes", action="store_true", help="skip the whole-fit runs")
    args = ap.parse_args()
    s = args.smoothing

    table = []
    print("bump response over its height h (FWHM in knot spacings)")
    print(f"  {'':28s}" + "".join(f"{c[:8]:>9s}" for c in COLS))
    for base in ("flat", "curved"):
        for m in CONTROLS:
            for w in FWHM:
                print(f"{base} {m}x{m} FWHM {w}")
                for label, value in [("before", 0.0)] + [("after", v) for v in SWEEP]:
                    fit = plain if value == 0.0 else smoothed(value)
                    r = responses(fit, base, w, m)
                    r.update(base=base, controls=m, fwhm_knots=w, smoothing=value, label=label)
                    table.append(r)
                    print(_row(f"{label} (smoothing {value})", r))

    target = next(
        r["map_share"]
        for r in table
        if r["base"] == "curved"
        and r["controls"] == 10
        and r["fwhm_knots"] == 1.0
        and r["smoothing"] == s
    )
    params = {
        "gaussian_no_trend": (gaussian_no_trend, calibrate(gaussian_no_trend, 0.05, 4.0, target)),
        "penalty_2nd_derivative": (
            lambda p: penalty(2, p),
            calibrate(lambda p: penalty(2, p), 1e-4, 1e2, target),
        ),
        "penalty_3rd_derivative": (
            lambda p: penalty(3, p),
            calibrate(lambda p: penalty(3, p), 1e-5, 1e2, target),
        ),
        "morphological": (morphological, calibrate(morphological, 0.3, 1.0, target, log=False)),
    }
    candidates = []
    print(f"\ncandidates, each set so the 1-knot bump's map share is {target:.3f} (curved, 10x10)")
    methods = {"plain": (lambda _p: plain, 0.0), "smoothing": (smoothed, s), **params}
    for name, (make, p) in methods.items():
        fit = make(p)
        for m in CONTROLS:
            for w in FWHM:
                r = responses(fit, "curved", w, m)
                r.update(method=name, parameter=p, controls=m, fwhm_knots=w)
                candidates.append(r)
                print(_row(f"{name} {p:.3g} {m}x{m} FWHM {w}", r))
        b = broad_shape_errors(fit)
        candidates.append({"method": name, "parameter": p, "broad_shape": b})
        print(
            f"  {name} broad shape (max / extent): "
            + ", ".join(f"{k} {v:.1e}" for k, v in b.items())
        )

    broad = {str(v): broad_shape_errors(plain if v == 0.0 else smoothed(v)) for v in (0.0, *SWEEP)}
    meshes = [] if args.no_meshes else mesh_runs(s)
    write_result(
        "detail",
        {
            "benchmark": "detail kept out of the spline (fit_bspline smoothing, sec. 7.5)",
            "grid": [N, N],
            "bump_height": HEIGHT,
            "bump_width": "full width at half maximum, knot spacings",
            "smoothing_after": s,
            "table": table,
            "broad_shape": broad,
            "candidates": candidates,
            "meshes": meshes,
            "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
        },
    )


if __name__ == "__main__":
    main()
