"""Displacement and bump maps of a grid over its fitted B-spline (Krishnamurthy 2000, ch. 7).

:func:`displacement_map` stores the grid over its spline, in the spline's orthonormal local
frame (T = S_u/|S_u|, B = N x T, N), as a ``vector`` map (``grid - spline``, exact), a
``scalar`` map (a displacement along N, the grey image a user paints), a ``bump`` map (the
grid's normals: shading only) or a ``magnitude`` map; :func:`reconstruct` rebuilds the
displaced surface at any resolution with bilinear filtering (the spline for a bump map),
:func:`bump_normals` and :func:`shading_normals` give the normals to shade with. Maps of every
kind are written as OpenEXR float32 or 16-bit PNG (kind and value range in the metadata) and
read back, edited or not. ``"normal"``, the former name of ``"scalar"``, is still read.
"""

from meshfit.displacement.io import read_exr, read_png, write_exr, write_png
from meshfit.displacement.maps import (
    FRAME,
    KIND_ALIASES,
    KINDS,
    RAY_CELLS,
    SCALAR_METHODS,
    DisplacementMap,
    bump_map,
    bump_normals,
    canonical_kind,
    displacement_map,
    grid_normals,
    reconstruct,
    refine_on_scan,
    resample_map,
    sample_bilinear,
    scan_points,
    shading_normals,
    vector_values,
)

__all__ = [
    "FRAME",
    "KINDS",
    "KIND_ALIASES",
    "RAY_CELLS",
    "SCALAR_METHODS",
    "DisplacementMap",
    "bump_map",
    "bump_normals",
    "canonical_kind",
    "displacement_map",
    "grid_normals",
    "read_exr",
    "read_png",
    "reconstruct",
    "refine_on_scan",
    "resample_map",
    "sample_bilinear",
    "scan_points",
    "shading_normals",
    "vector_values",
    "write_exr",
    "write_png",
]
