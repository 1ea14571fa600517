"""The fit as the web app shows and steers it: deviation colours, one-patch re-fits, map brushes.

Pure functions over a :class:`meshfit.FitResult`; :class:`meshfit.ui.state.Session` calls them
and the browser layer draws what they return. Every figure shown to the user is in percent
of the input's bounding-box diagonal, as the command line and the report print them.

References
----------
.. [1] Krishnamurthy 2000, sec. 6.2 (interactive control resolution), sec. 7.5 and 9.2.3
   (editing the displacement maps and seeing the surface follow).
"""

from __future__ import annotations

import colorsys
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from meshfit.errors import InputError, MeshfitError

if TYPE_CHECKING:
    from meshfit.mesh import Mesh
    from meshfit.pipeline import FitResult

__all__ = [
    "FitCancelled",
    "brush_map",
    "deviation_colors",
    "deviation_percent",
    "grid_triangles_of",
    "patch_colors",
    "refit_patch",
]


class FitCancelled(Exception):
    """Raised from the progress callback of a fit the user cancelled (ends the fit)."""


def percent(value: float, diagonal: float) -> float:
    """``value`` (model units) in percent of ``diagonal``."""
    return 100.0 * float(value) / float(diagonal)


def deviation_percent(mesh: Mesh, xyz: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance of each point to the scan, percent of its bounding-box diagonal.

    Parameters
    ----------
    mesh : Mesh
        The scan.
    xyz : (..., 3) float64
        Points (a patch's grid), model units.

    Returns
    -------
    (...) float64
    """
    x = np.asarray(xyz, dtype=np.float64)
    d = mesh.closest_points(x.reshape(-1, 3)).distance
    return (100.0 * d / mesh.bbox_diagonal).reshape(x.shape[:-1])


def deviation_colors(values: NDArray[np.float64], top: float) -> NDArray[np.uint8]:
    """Colours of a deviation map: blue (0) through green and yellow to red (``top`` and
    beyond), ``(n, 3) uint8``; the app's legend draws the same ramp."""
    t = np.clip(np.asarray(values, dtype=np.float64).reshape(-1) / max(top, 1e-300), 0.0, 1.0)
    stops = np.asarray(RAMP, dtype=np.float64)
    pos = np.linspace(0.0, 1.0, len(stops))
    rgb = np.stack([np.interp(t, pos, stops[:, k]) for k in range(3)], axis=1)
    return rgb.round().astype(np.uint8)


#: the deviation ramp's colours from 0 to the legend's top
RAMP = ((40, 60, 220), (40, 180, 220), (60, 200, 90), (240, 220, 40), (230, 50, 40))


def patch_colors(n: int) -> NDArray[np.uint8]:
    """``n`` distinct colours, ``(n, 3) uint8``: hues a golden angle apart, so neighbours
    in numbering (usually neighbours on the surface) differ most."""
    out = np.zeros((n, 3), np.uint8)
    for k in range(n):
        h = (0.11 + 0.381966 * k) % 1.0
        s, v = (0.55, 0.92) if k % 2 == 0 else (0.7, 0.78)
        out[k] = np.round(255 * np.asarray(colorsys.hsv_to_rgb(h, s, v)))
    return out


def grid_triangles_of(shape: tuple[int, int]) -> NDArray[np.int64]:
    """Triangles of a ``(nu, nv)`` grid of points stored row by row."""
    from meshfit.springs import grid_triangles

    return np.asarray(grid_triangles(int(shape[0]), int(shape[1])), dtype=np.int64)


def refit_patch(result: FitResult, patch: int, controls: tuple[int, int]) -> FitResult:
    """``result`` with one patch's spline fitted again to its spring mesh at ``controls``
    and its map made again over the new spline; every other patch is the same object.

    A preview of a control-resolution change: the patch's boundary is not pinned to its
    neighbours' (the whole fit does that), so its seams may open by up to the fit error.
    """
    from meshfit.bspline import fit_bspline
    from meshfit.displacement import displacement_map

    p = _patch_index(result, patch)
    old = result.patches[p]
    nu, nv = old.spring.shape[:2]
    mu, mv = (max(4, min(int(controls[0]), nu)), max(4, min(int(controls[1]), nv)))
    surface = fit_bspline(old.spring, controls=(mu, mv), smoothing=result.options.spline_smoothing)
    dmap = displacement_map(surface, old.spring, kind=old.displacement.kind)
    patches = list(result.patches)
    patches[p] = replace(old, surface=surface, displacement=dmap)
    return replace(result, patches=patches)


def brush_map(
    result: FitResult,
    patch: int,
    texel: tuple[float, float],
    *,
    radius: float,
    amount: float,
) -> FitResult:
    """``result`` with a smooth dab added to one patch's map along the spline's normal,
    then rebuilt (seams closed, errors measured again: :meth:`FitResult.rebuild`).

    Parameters
    ----------
    result : FitResult
    patch : int
    texel : (float, float)
        Centre of the dab, in texels of the patch's map (row along u, column along v).
    radius : float
        Radius of the dab, texels (a Gaussian of this standard deviation, cut at 3 radii).
    amount : float
        Displacement added at the centre, model units (negative lowers the surface).

    Returns
    -------
    FitResult
        Only the scalar (normal) component changes: the N channel of a vector map, the
        value of a scalar map; bump maps hold no geometry and are refused. Not rebuilt
        (seams left open) where a patch re-fitted alone no longer shares control counts
        with its neighbours.
    """
    from meshfit.displacement import DisplacementMap

    p = _patch_index(result, patch)
    dmap = result.patches[p].displacement
    if dmap.kind not in ("vector", "scalar"):
        raise InputError(f"patch {p}'s map is a {dmap.kind} map: only vector and scalar maps move")
    if not (np.isfinite(radius) and radius > 0 and np.isfinite(amount)):
        raise InputError(f"a brush needs a radius > 0 and a finite amount, got {radius}, {amount}")
    h, w = dmap.shape
    i, j = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    r2 = ((i - texel[0]) ** 2 + (j - texel[1]) ** 2) / float(radius) ** 2
    dab = np.where(r2 <= 9.0, np.exp(-0.5 * r2), 0.0) * float(amount)
    values = np.array(dmap.values)
    values[:, :, -1] += dab  # N is the last channel of a vector map and the only of a scalar
    maps = list(result.maps)
    maps[p] = DisplacementMap(values, dmap.kind)
    edited = result.with_maps(maps)
    try:
        return edited.rebuild()
    except MeshfitError:
        # a patch re-fitted alone may no longer share control counts with its neighbours,
        # which the seams' closing needs: the patches then show their own reconstruction
        # (spline plus map) and the next whole fit closes the seams
        return edited


def texel_of(result: FitResult, patch: int, xyz: NDArray[np.float64]) -> tuple[float, float]:
    """The texel of a patch's map whose displaced point is nearest ``xyz`` (model units)."""
    p = _patch_index(result, patch)
    grid = result.patches[p].displaced()
    d = np.linalg.norm(grid - np.asarray(xyz, dtype=np.float64).reshape(1, 1, 3), axis=2)
    i, j = np.unravel_index(int(np.argmin(d)), d.shape)
    return float(i), float(j)


def _patch_index(result: FitResult, patch: int) -> int:
    n = len(result.patches)
    if isinstance(patch, bool) or not isinstance(patch, (int, np.integer)) or not 0 <= patch < n:
        raise InputError(f"no patch {patch!r}: the fit has {n} patches")
    return int(patch)
