"""Continuity over a patch layout: its network, boundary pins at the fitting step, seam figures.

A :class:`meshfit.layout.Layout` knows which curve every patch side lies on, so its network
needs no geometric matching: :func:`layout_network` reads shared boundaries and corners from
the layout's topology. :func:`boundary_pins` makes the shared boundaries identical at the
fitting step (one cubic curve per layout curve, pinned as the boundary row of every patch
using it; Krishnamurthy 2000, sec. 8.1.3), and :func:`seam_metrics` measures the gaps and
normal jumps across every shared curve, of the splines and of the displaced surfaces.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from meshfit._kernels.geometry import polyline_gap
from meshfit.bspline import BSplineSurface, basis_matrix, clamped_knots, lowpass_matrix
from meshfit.stitch.network import Network, SharedBoundary, side_row
from meshfit.types import Side

__all__ = ["boundary_pins", "layout_network", "layout_side_row", "seam_metrics"]

#: grid index of each patch corner 0..3 (layout side s runs from corner s to corner s + 1)
_CORNER_SLOT = ((0, 0), (-1, 0), (-1, -1), (0, -1))


def layout_side_row(grid: NDArray, s: int) -> NDArray:
    """Grid points along layout side ``s`` (0..3), from corner ``s`` to corner ``s + 1``."""
    row = side_row(grid, Side.around(s))
    return row[::-1] if s >= 2 else row


def _forward(layout: Any, p: int, s: int) -> bool:
    """Whether side ``s`` of patch ``p`` runs, in increasing parameter, along its curve."""
    return (s in (0, 1)) != bool(layout.patch_reversed[p, s])


def _curve_users(layout: Any) -> dict[int, list[tuple[int, int]]]:
    users: dict[int, list[tuple[int, int]]] = {}
    for p in range(layout.n_patches):
        for s in range(4):
            users.setdefault(int(layout.patch_curves[p, s]), []).append((p, s))
    return users


def layout_network(layout: Any, continuity: str = "G1", creases: Any = None) -> Network:
    """The network of a layout: a shared boundary for every curve two patches share, a corner
    class for every layout corner.

    Parameters
    ----------
    layout : meshfit.layout.Layout
    continuity : {"C0", "G1"}
        Continuity of every shared boundary (default G1).
    creases : (n_curves,) bool, optional
        Curves whose boundaries are C0 whatever ``continuity`` says (the surface is meant to
        break there).

    Returns
    -------
    Network
        Built from the topology alone, so curves between the same corners are never
        confused, whatever the grids' positions.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 8.1 (continuity across a patch network).
    """
    boundaries = []
    for curve, uses in sorted(_curve_users(layout).items()):
        if len(uses) != 2:
            continue
        (pa, sa), (pb, sb) = sorted(uses)
        c = "C0" if continuity == "C0" or (creases is not None and creases[curve]) else "G1"
        rev = _forward(layout, pa, sa) != _forward(layout, pb, sb)
        boundaries.append(SharedBoundary(pa, Side.around(sa), pb, Side.around(sb), rev, c))
    by_corner: dict[int, list[tuple[int, int, int]]] = {}
    for p in range(layout.n_patches):
        for s, c in enumerate(layout.patch_corners(p).tolist()):
            i, j = _CORNER_SLOT[s]
            by_corner.setdefault(int(c), []).append((p, i, j))
    corners = tuple(tuple(v) for _, v in sorted(by_corner.items()))
    return Network(layout.n_patches, tuple(boundaries), corners)


def _fit_curve(
    samples: NDArray[np.float64], m: int, a: NDArray[np.float64], b: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Control points ``(m, 3)`` of a clamped cubic curve through ``samples`` (uniform
    parameters), least squares with the end points pinned to ``a`` and ``b``."""
    t = np.linspace(0.0, 1.0, samples.shape[0])
    B = basis_matrix(t, clamped_knots(m))
    rhs = samples - np.outer(B[:, 0], a) - np.outer(B[:, -1], b)
    inner, *_ = np.linalg.lstsq(B[:, 1:-1], rhs, rcond=None)
    return np.vstack([a[None], inner, b[None]])


def boundary_pins(
    layout: Any,
    corner_xyz: NDArray[np.float64],
    grids: Sequence[NDArray[np.float64]],
    controls: Sequence[tuple[int, int]],
    smoothing: float = 0.0,
) -> list[dict[str, NDArray[np.float64]]]:
    """Pinned boundary control rows of every patch (``pin_boundary`` of
    :func:`meshfit.bspline.fit_bspline`).

    Every layout curve gets one cubic curve, least-squares fitted to the grid side of the
    first patch using it, its ends pinned to the layout corners ``corner_xyz``; each patch
    on the curve pins its boundary row to that curve's control points, so shared boundaries
    are identical. ``controls`` must agree along shared curves
    (:func:`meshfit.stitch.control_classes`). With ``smoothing`` (knot spacings, as
    :func:`meshfit.bspline.fit_bspline` takes it) each side is low-passed as the patches'
    grids are before its curve is fitted, so detail along a boundary stays out of the spline
    there too.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 8.1.3 (boundary constraints at the fitting step).
    """
    curve_ctrl: dict[int, NDArray[np.float64]] = {}
    ends = layout.curve_ends
    for p, grid in enumerate(grids):
        for s in range(4):
            c = int(layout.patch_curves[p, s])
            if c in curve_ctrl:
                continue
            row = layout_side_row(grid, s)
            if bool(layout.patch_reversed[p, s]):
                row = row[::-1]
            m = controls[p][s % 2]
            if smoothing > 0.0:  # the filter keeps both end samples
                row = lowpass_matrix(len(row), m, float(smoothing)) @ row
            a, b = corner_xyz[int(ends[c, 0])], corner_xyz[int(ends[c, 1])]
            curve_ctrl[c] = _fit_curve(row, m, a, b)
    pins = []
    for p in range(len(grids)):
        pin: dict[str, NDArray[np.float64]] = {}
        for s in range(4):
            ctrl = curve_ctrl[int(layout.patch_curves[p, s])]
            if bool(layout.patch_reversed[p, s]):
                ctrl = ctrl[::-1]
            # layout sides run corner s -> s + 1; pinned rows run in increasing parameter
            pin[Side.around(s).value] = ctrl[::-1].copy() if s >= 2 else ctrl
        pins.append(pin)
    return pins


def _side_params(s: int, along: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """(u, v) along layout side ``s`` at fractions ``along`` from corner s to s + 1."""
    if s == 0:
        return along, np.zeros_like(along)
    if s == 1:
        return np.ones_like(along), along
    if s == 2:
        return 1.0 - along, np.ones_like(along)
    return np.zeros_like(along), 1.0 - along


def _displaced_rows(uses, pts, surfaces, displaced, t):
    """Each side's displaced grid row along the curve, and the displaced surface at ``t``
    as a renderer tessellating it at any resolution reads it (spline plus the boundary
    texels' model-space vectors read linearly)."""
    rows, cont = [], []
    for (p, s, rev), spline_pts in zip(uses, pts, strict=True):
        row = layout_side_row(displaced[p], s)
        row = row[::-1] if rev else row
        rows.append(row)
        tex = np.linspace(0.0, 1.0, len(row))
        u, v = _side_params(s, tex[::-1] if rev else tex)
        vec = row - surfaces[p].evaluate(u, v)
        cont.append(spline_pts + np.stack([np.interp(t, tex, vec[:, c]) for c in range(3)], 1))
    return rows, cont


def _gap(a: NDArray, b: NDArray) -> float:
    return float(polyline_gap(np.ascontiguousarray(a), np.ascontiguousarray(b)))


def seam_metrics(
    layout: Any,
    surfaces: Sequence[BSplineSurface],
    displaced: Sequence[NDArray[np.float64]],
    diag: float,
    samples: int = 33,
) -> dict[str, Any]:
    """Gap and normal jump across every curve two patches share.

    Normal jumps over smooth curves are split into the corner zones (one knot span from
    each end) and the rest; those over the layout's crease curves, where the surface is
    meant to break, are reported apart as ``crease_normal_jump_max_deg``. Gaps are over
    ``diag``: of the splines, of the displaced grids as tessellated at their own resolution
    (each row's points to the other row's polyline), and at any resolution.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 8.1 (C0 / G1 across boundaries) and sec. 8.2
       (crack-free displacement seams).
    """
    t = np.linspace(0.0, 1.0, samples)
    f = dict.fromkeys(("gap", "angle", "inner", "ends", "disp", "any", "crease"), 0.0)
    shared = n_crease = 0
    for curve, uses_ps in _curve_users(layout).items():
        if len(uses_ps) != 2:
            continue
        shared += 1
        uses = [(p, s, bool(layout.patch_reversed[p, s])) for p, s in uses_ps]
        pts, nrm = [], []
        for p, s, rev in uses:
            u, v = _side_params(s, t[::-1] if rev else t)  # in the curve's own direction
            S, _, _, N = surfaces[p].points_and_frames(u, v)
            pts.append(S)
            nrm.append(N)
        f["gap"] = max(f["gap"], float(np.linalg.norm(pts[0] - pts[1], axis=1).max()))
        a = np.degrees(np.arccos(np.clip((nrm[0] * nrm[1]).sum(axis=1), -1.0, 1.0)))
        if bool(layout.creases[curve]):
            n_crease += 1
            f["crease"] = max(f["crease"], float(a.max()))
            a = np.zeros_like(a)
        f["angle"] = max(f["angle"], float(a.max()))
        f["ends"] = max(f["ends"], float(a[0]), float(a[-1]))
        p0, s0, _ = uses[0]
        span = 1.0 / max(surfaces[p0].shape[0 if s0 % 2 == 0 else 1] - 3, 1)
        inner = (t > span) & (t < 1.0 - span)
        if inner.any():
            f["inner"] = max(f["inner"], float(a[inner].max()))
        rows, cont = _displaced_rows(uses, pts, surfaces, displaced, t)
        f["disp"] = max(f["disp"], _gap(rows[0], rows[1]), _gap(rows[1], rows[0]))
        f["any"] = max(f["any"], float(np.linalg.norm(cont[0] - cont[1], axis=1).max()))
    return {
        "shared_curves": shared,
        "spline_gap_max": f["gap"] / diag,
        "spline_normal_jump_max_deg": f["angle"],
        "spline_normal_jump_inner_max_deg": f["inner"],
        "spline_normal_jump_corner_point_max_deg": f["ends"],
        "crease_curves": n_crease,
        "crease_normal_jump_max_deg": f["crease"],
        "displaced_gap_max": f["disp"] / diag,
        "displaced_gap_any_resolution_max": f["any"] / diag,
    }
