"""Spring-mesh gridded resampling of four-sided patches (Krishnamurthy 2000, chapter 5).

:func:`resample_patch` turns a :class:`meshfit.layout.Patch` into a regular grid of face
points, coarse to fine, with feature curves as iso-curves; :func:`grid_metrics` measures a
grid's arc-length uniformity, cell shape, area distortion, folds and fidelity, and
:func:`worst_places` says where a spring mesh misses a quality bound.
"""

from meshfit.springs.grid import ANCHOR, BOUNDARY, CURVE, FREE, SpringMesh, grid_triangles
from meshfit.springs.metrics import (
    QUALITY_BOUNDS,
    grid_metrics,
    out_of_bounds,
    spring_metrics,
    worst_places,
)
from meshfit.springs.resample import SpringOptions, SpringResult, resample_patch, resample_patches

__all__ = [
    "ANCHOR",
    "BOUNDARY",
    "CURVE",
    "FREE",
    "QUALITY_BOUNDS",
    "SpringMesh",
    "SpringOptions",
    "SpringResult",
    "grid_metrics",
    "grid_triangles",
    "out_of_bounds",
    "resample_patch",
    "resample_patches",
    "spring_metrics",
    "worst_places",
]
