"""Smoothing the boundary curves of a layout: mesh-edge-scale wiggles taken out.

Curves painted through picks (greedy graph paths pulled toward chords, sec. 3.2-3.3) keep a
lateral wiggle at the scale of the mesh edges: on the cube layouts of nefertiti the median
curve point sits 0.05% of the bbox diagonal off the mean of its six nearest neighbours
along the curve, one in a hundred 0.24%. The spring mesh's side points lie on the curves,
so its first rows beside a side follow that wiggle while the rows inside do not: the
spacing along the iso-curves that cross the side varies from one to the next. A few
membrane and arc-length steps of the thesis's surface snakes (sec. 3.4) at the curve's own
resolution damp the wiggle and leave the curve's course alone (each step moves a point by
at most a quarter of its spacing).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from meshfit.errors import InputError
from meshfit.layout.layout import Layout, layout_from_curves
from meshfit.mesh import Mesh
from meshfit.types import SurfaceCurve

__all__ = ["SMOOTH_ITERATIONS", "curve_wiggle", "smooth_layout"]

#: default snake steps of :func:`smooth_layout`
SMOOTH_ITERATIONS = 8
#: curve points on each side of a point whose mean `curve_wiggle` measures against
WIGGLE_REACH = 3


def curve_wiggle(mesh: Mesh, curve: SurfaceCurve) -> NDArray[np.float64]:
    """Distance of each curve point from the mean of the ``WIGGLE_REACH`` points on either
    side of it along the curve, model units (open curves: the points that have as many on
    either side; empty for shorter curves)."""
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

    On the cube layouts of the test meshes 8 steps take the median wiggle
    (:func:`curve_wiggle`) of nefertiti's curves from 0.053% to about a third of that, and
    the median over the patches of the largest arc-length coefficient of variation of their
    spring meshes from 0.081 to 0.044 (`meshfit.springs.resample_patch`, defaults).

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
    if isinstance(iterations, bool) or int(iterations) != iterations or iterations < 0:
        raise InputError(f"iterations must be a non-negative integer, got {iterations!r}")
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
        face, bary, _ = _kb.relax_many(**args, iterations=int(iterations))
        for i, c in zip(
            moving, _relaxed_curves(mesh, picked, args["start"], face, bary), strict=True
        ):
            curves[i] = c
    patches = [
        [(int(layout.patch_curves[p, s]), bool(layout.patch_reversed[p, s])) for s in range(4)]
        for p in range(layout.n_patches)
    ]
    return layout_from_curves(
        mesh,
        layout.corners,
        curves,
        layout.curve_ends,
        patches,
        [list(f) for f in layout.features],
    )
