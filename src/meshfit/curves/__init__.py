"""Face-point curves: painting, CurveAttract, B-spline space curves, surface snakes, colour."""

from meshfit.curves.base import check_sampling, curve_length, densify_curve, resample_curve
from meshfit.curves.paint import attract_curve, extend_to_curve, paint_curve
from meshfit.curves.spacecurve import (
    SpaceCurve,
    fit_bspline_curve,
    fit_space_curve,
    move_control_point,
    move_edit_point,
)

__all__ = [
    "SpaceCurve",
    "attract_curve",
    "check_sampling",
    "curve_length",
    "densify_curve",
    "extend_to_curve",
    "fit_bspline_curve",
    "fit_space_curve",
    "move_control_point",
    "move_edit_point",
    "paint_curve",
    "resample_curve",
]
