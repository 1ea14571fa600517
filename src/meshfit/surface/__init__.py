"""Primitives on the surface: sampling face points, walking, graph paths, cutting."""

from meshfit.surface.sample import closest_surface_points, random_surface_points
from meshfit.surface.walk import (
    AttractResult,
    CurveMoveResult,
    WalkResult,
    attract_points,
    curve_arc_lengths,
    move_along_curve,
    walk_points,
)

__all__ = [
    "AttractResult",
    "CurveMoveResult",
    "WalkResult",
    "attract_points",
    "closest_surface_points",
    "curve_arc_lengths",
    "move_along_curve",
    "random_surface_points",
    "walk_points",
]
