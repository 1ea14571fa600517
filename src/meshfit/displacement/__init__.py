"""Displacement and bump maps of a grid over its fitted B-spline (Krishnamurthy 2000, ch. 7).

:func:`displacement_map` stores ``grid - spline`` in the spline's orthonormal local frame
(T = S_u/|S_u|, B = N x T, N) as a vector, normal-component or magnitude map;
:func:`bump_map` stores the grid's normals in the same frame; :func:`reconstruct` rebuilds the
displaced surface at any resolution with bilinear filtering. Maps are written as OpenEXR
float32 or 16-bit PNG (value range in the metadata) and read back, edited or not.
"""

from meshfit.displacement.io import read_exr, read_png, write_exr, write_png
from meshfit.displacement.maps import (
    FRAME,
    KINDS,
    DisplacementMap,
    bump_map,
    bump_normals,
    displacement_map,
    grid_normals,
    reconstruct,
    resample_map,
    sample_bilinear,
    vector_values,
)

__all__ = [
    "FRAME",
    "KINDS",
    "DisplacementMap",
    "bump_map",
    "bump_normals",
    "displacement_map",
    "grid_normals",
    "read_exr",
    "read_png",
    "reconstruct",
    "resample_map",
    "sample_bilinear",
    "vector_values",
    "write_exr",
    "write_png",
]
