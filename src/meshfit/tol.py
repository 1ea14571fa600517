"""Named numerical tolerances.

Every tolerance is *relative*: multiply by the scale named in its comment (the mesh's
bounding-box diagonal, its mean edge length, or nothing for dimensionless quantities).
Use :func:`length` to get an absolute length for a given mesh.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from meshfit.mesh import Mesh

#: barycentric coordinates within this of 0 or 1 count as on an edge / at a vertex (dimensionless)
BARY_EPS = 1e-12
#: a walk step shorter than this, times the mean edge length, counts as finished
WALK_EPS = 1e-12
#: a face whose area is below this, times bbox_diagonal**2, is degenerate
DEGENERATE_AREA = 1e-14
#: largest coordinate magnitude a mesh may have (absolute, not relative): squared cross
#: products of its edges (fourth powers of lengths) stay finite in float64 (1e308)
MAX_COORDINATE = 1e75
#: graph distances for choices that must not depend on rounding are counted in whole units
#: of this, times the mean edge length (`Mesh.quantized_edge_graph`)
GRAPH_QUANTUM = 1e-6
#: a point this close to the surface, times bbox_diagonal, is on it
ON_SURFACE = 1e-9
#: attraction stops when a step is shorter than this, times the mean edge length
ATTRACT_EPS = 1e-10
#: cut points closer than this to a vertex or edge, times the mean edge length, snap onto it
CUT_SNAP = 1e-7
#: no triangle a cut creates is smaller than this, times bbox_diagonal**2 (2 x DEGENERATE_AREA);
#: a split that would make one snaps to the nearer vertex instead
CUT_MIN_AREA = 2e-14
#: absolute-position agreement in tests, times bbox_diagonal
TEST_ATOL = 1e-9
#: a displaced-surface vertex within this, times bbox_diagonal, of the point on the input
#: its texel was made from (a spring point, or a closest point of a finer map) is given that
#: distance to the input, no search (the exact distance lies between 0 and it)
KNOWN_DISTANCE = 1e-12
#: relative margin inside a distance limit within which a yes-or-no search
#: (`meshfit.mesh.triangles_within`) settles a point as within the limit; the points it does
#: not settle get exact distances, so the decision is the one exact distances give
WITHIN_MARGIN = 1e-9


def length(mesh: Mesh, rel: float, *, scale: str = "mean_edge_length") -> float:
    """Absolute length for a relative tolerance on ``mesh``.

    Parameters
    ----------
    mesh : Mesh
        The mesh that sets the scale.
    rel : float
        One of the relative tolerances of this module.
    scale : {"mean_edge_length", "bbox_diagonal"}
        Which length of the mesh ``rel`` is relative to.
    """
    if scale == "mean_edge_length":
        return rel * mesh.mean_edge_length
    if scale == "bbox_diagonal":
        return rel * mesh.bbox_diagonal
    raise ValueError(f"unknown scale {scale!r}")


# --- meshfit.springs
#: a feature curve's end lies on a side when it is this close to it, times the mean edge length
FEATURE_END_ON_SIDE = 1e-3
#: relaxation of a level stops when the root-mean-square move of its points is below this,
#: times their spring lengths (dimensionless)
SPRING_CONVERGED = 5e-3
#: ... and the arc-length sweeps that even out a relaxed level's spacing (its polish) stop
#: below this (they make small moves that still even the spacing out)
SPRING_POLISHED = 2e-3

# --- meshfit.layout
#: a curve end is at its corner when this close to it, times the mean edge length
LAYOUT_CORNER_MATCH = 1e-6
#: stored barycentric coordinates must sum to 1 within this (absolute; files keep ~12 digits)
LAYOUT_BARY_SUM = 1e-9
#: patch face areas sum to the mesh area within this relative error (tests)
LAYOUT_AREA_RTOL = 1e-9

# --- meshfit.bspline / meshfit.displacement / meshfit.stitch
#: |S_u x S_v| below this times |S_u| |S_v| is a degenerate (collapsed) point of a spline
#: (dimensionless)
BSPLINE_DEGENERATE = 1e-12
#: at a degenerate point the normal is taken this far (in parameter) towards the patch middle
BSPLINE_NORMAL_STEP = 1e-6
#: closest-point Newton iteration on a spline stops when the parameter step is below this
BSPLINE_CLOSEST_STEP = 1e-12
#: iteration cap of the closest-point Newton iteration
BSPLINE_CLOSEST_MAX_ITER = 50
#: a fitted surface reproduces exact spline data to this relative error (tests)
BSPLINE_FIT_RTOL = 1e-10
#: a feature-curve point lies in its patch (or on a side) when within this of it, times the mean
#: edge length
LAYOUT_FEATURE_INSIDE = 1e-6
#: the gridded fit uses the normal equations when samples >= this times controls per
#: direction (collocation condition number below ~10 there), else the QR pseudo-inverse
BSPLINE_GRAM_RATIO = 1.25
#: two grid sides are one shared boundary when their end points agree within this, times the
#: network's bbox diagonal
STITCH_MATCH = 1e-7
#: after C0 stitching shared boundaries agree within this, times the bbox diagonal (tests)
STITCH_GAP = 1e-9

# --- meshfit.ui
#: a painted corner snaps to an existing corner or curve within this, times the bbox diagonal
UI_SNAP_RADIUS = 0.02
#: a click picks a curve sample (edit point, control vertex) within this, times the bbox diagonal
UI_PICK_RADIUS = 0.03

# --- meshfit.shrinkwrap
#: a projection ray hit farther than this times the closest-point distance is not trusted
#: (the closest point is used instead)
SHRINKWRAP_RAY_TRUST = 3.0
#: ... plus this, times the level's mean edge length (rays from points already on the surface)
SHRINKWRAP_RAY_SLACK = 0.1
#: in a network cut, curve points this close to their end corner, times the mean edge length,
#: are that corner (painted curves pass through the vertex nearest a corner pick), and a
#: corner this close to a mesh vertex is on it
CUT_CORNER_MERGE = 1e-3
#: projection rays start this far behind the point, times the level's mean edge length, so one
#: ray along the normal finds the surface on either side
SHRINKWRAP_RAY_BACKOFF = 0.5
#: shrink-wrap density of a vertex whose adjacent cells hold no input triangle, times the
#: largest vertex density of the level
SHRINKWRAP_DENSITY_FLOOR = 1e-9
#: a patch corner made planar by G1 stitching keeps its angle between the two boundaries at
#: least this far from 0 and from pi (radians), so its normal stays well defined
STITCH_CORNER_MIN_ANGLE = 0.26
#: weight of the pull back to the flat fan against the row-0 parallel condition when a corner
#: of valence other than 4 is made G1 (dimensionless; smaller follows the condition closer)
STITCH_FAN_PULL = 0.05
