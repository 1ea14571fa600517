"""Face-point curves: painting, CurveAttract, B-spline space curves, surface snakes, colour."""

from meshfit.curves.base import (
    check_sampling,
    curve_length,
    densify_curve,
    densify_curves,
    resample_curve,
)
from meshfit.curves.color import color_force, scalar_field, vertex_gradients, vertex_normals
from meshfit.curves.paint import attract_curve, extend_to_curve, paint_curve
from meshfit.curves.snake import (
    SnakeOptions,
    SnakeResult,
    edit_snake,
    relax_snake,
    snake_forces,
)
from meshfit.curves.spacecurve import (
    SpaceCurve,
    fit_bspline_curve,
    fit_space_curve,
    move_control_point,
    move_edit_point,
)

__all__ = [
    "SnakeOptions",
    "SnakeResult",
    "SpaceCurve",
    "attract_curve",
    "check_sampling",
    "color_force",
    "curve_length",
    "densify_curve",
    "densify_curves",
    "edit_snake",
    "extend_to_curve",
    "fit_bspline_curve",
    "fit_space_curve",
    "move_control_point",
    "move_edit_point",
    "paint_curve",
    "relax_snake",
    "resample_curve",
    "scalar_field",
    "snake_forces",
    "vertex_gradients",
    "vertex_normals",
]
