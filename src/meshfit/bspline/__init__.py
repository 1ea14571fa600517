"""Uniform cubic B-spline surfaces fitted to gridded points (Krishnamurthy 2000, ch. 4, 6).

:func:`fit_bspline` solves the gridded least-squares problem of eq. 4.4 as two small solves;
:class:`BSplineSurface` evaluates points, partial derivatives, normals and the orthonormal
local frame; :func:`fit_errors` reports the parametric (eq. 6.1) and normal (eq. 6.2) errors.
"""

from meshfit.bspline.basis import DEGREE, basis_local, basis_matrix, clamped_knots
from meshfit.bspline.fit import (
    FitErrors,
    closest_parameters,
    fit_bspline,
    fit_errors,
    grid_parameters,
    lowpass_matrix,
)
from meshfit.bspline.surface import BSplineSurface

__all__ = [
    "DEGREE",
    "BSplineSurface",
    "FitErrors",
    "basis_local",
    "basis_matrix",
    "clamped_knots",
    "closest_parameters",
    "fit_bspline",
    "fit_errors",
    "grid_parameters",
    "lowpass_matrix",
]
