"""Smoothing the boundary curves of a layout: mesh-edge-scale wiggles taken out.

Curves painted through picks (greedy graph paths pulled toward chords, sec. 3.2-3.3) keep a
lateral wiggle at the scale of the mesh edges (`curve_wiggle`: a curve point's distance
from the mean of its nearest neighbours along the curve). The spring mesh's side points
lie on the curves, so its first rows beside a side follow that wiggle while the rows
inside do not: the spacing along the iso-curves that cross the side varies from one to
the next. A few membrane and arc-length steps of the thesis's surface snakes (sec. 3.4)
at the curve's own resolution damp the wiggle and leave the curve's course alone (each
step moves a point by at most a quarter of its spacing).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from meshfit.curves.snake import _as_count
from meshfit.layout.layout import Layout, layout_from_curves
from meshfit.mesh import Mesh
from meshfit.types import SurfaceCurve

__all__ = ["SMOOTH_ITERATIONS", "curve_wiggle", "smooth_layout"]

#: default snake steps of :func:`smooth_layout`
SMOOTH_ITERATIONS = 8
#: curve points on each side of a point whose mean `curve_wiggle` measures against
WIGGLE_REACH = 3


def curve_wiggle(mesh: Mesh, curve: SurfaceCurve) -> NDArray[np.float64]:
    """Lateral wiggle of a face-point curve: each point's distance from the mean of the
    ``WIGGLE_REACH`` points on either side of it along the curve.

    Parameters
    ----------
    mesh : Mesh
        The mesh the curve lies on.
    curve : SurfaceCurve
        n face points, open or closed.

    Returns
    -------
    (m,) float64
        Model units; a closed curve gives every point (m = n), an open one the points with
        ``WIGGLE_REACH`` points on either side (m = n - 2 ``WIGGLE_REACH``, empty for
        shorter curves).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.2-3.3 (painted curves: graph paths pulled toward the
       chords between picks).
    """
    x = mesh.xyz(curve.points)
    r = WIGGLE_REACH
    n = len(x)
    if curve.closed:
        idx = (np.arange(n)[:, None] + np.arange(-r, r + 1)[None, :]) % n
        centre = np.arange(n)
    else:
        if n < 2 * r + 1:
            return np.zeros(0)
        centre = np.arange(r, n - r)
        idx = centre[:, None] + np.arange(-r, r + 1)[None, :]
    mean = (x[idx].sum(axis=1) - x[centre]) / (2 * r)
    return np.linalg.norm(x[centre] - mean, axis=1)


def smooth_layout(mesh: Mesh, layout: Layout, *, iterations: int = SMOOTH_ITERATIONS) -> Layout:
    """The layout with its boundary curves relaxed a few steps as surface snakes.

    Each boundary curve gets ``iterations`` steps of the membrane and arc-length forces
    (weights 1 and 1, no curvature force) evaluated at its own resolution, each move in the
    tangent plane, capped at a quarter of the local spacing and walked on the surface; the
    ends stay on their corners and the curve is densified where two consecutive points stop
    sharing a face. Curves that are sides of a patch with feature curves are kept as they
    are (the feature curves end on them), and so are the feature curves.

    The steps lower the curves' wiggle (:func:`curve_wiggle`) and, on most patches, the
    largest arc-length coefficient of variation of their spring meshes
    (`meshfit.springs.resample_patch`, defaults); they move the sides, though, so a patch
    that met an arc-length bound narrowly may go over it.

    Parameters
    ----------
    mesh : Mesh
        The mesh the layout was made for.
    layout : Layout
    iterations : int, keyword-only
        Snake steps per curve (default `SMOOTH_ITERATIONS`); 0 returns the layout as it is.

    Returns
    -------
    Layout
        Validated like any layout (:func:`meshfit.layout.layout_from_curves`).

    Raises
    ------
    meshfit.errors.InputError
        ``iterations`` is not a non-negative integer.
    meshfit.errors.LayoutError
        The smoothed curves no longer make a valid layout (two curves brought to touch).

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 3.4 (surface snakes: the fairness force, eq. 3.4, and
       the arc-length force), sec. 3.1 (the sampling rule).
    """
    iterations = _as_count(iterations, "iterations", minimum=0)
    if iterations == 0 or not layout.curves:
        return layout
    from meshfit._kernels import snakes as _kb
    from meshfit.layout.auto import _relax_inputs, _relaxed_curves

    held = {
        int(c)
        for p in range(layout.n_patches)
        if layout.features[p]
        for c in layout.patch_curves[p]
    }
    moving = [i for i, c in enumerate(layout.curves) if i not in held and not c.closed]
    curves = list(layout.curves)
    if moving:
        picked = [curves[i] for i in moving]
        args = _relax_inputs(mesh, picked)
        args["levels"] = np.ones(len(picked), dtype=np.int64)  # the curve's own resolution
        args["stop"] = 0.0  # exactly ``iterations`` steps
        face, bary, _ = _kb.relax_many(**args, iterations=iterations)
        for i, c in zip(
            moving, _relaxed_curves(mesh, picked, args["start"], face, bary), strict=True
        ):
            curves[i] = c
    patches = [layout.patch_sides(p) for p in range(layout.n_patches)]
    return layout_from_curves(
        mesh,
        layout.corners,
        curves,
        layout.curve_ends,
        patches,
        [list(f) for f in layout.features],
    )
