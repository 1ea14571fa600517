"""Primitives on the surface: sampling face points, walking, graph paths, cutting."""

from meshfit.surface.cut import CutResult, NetworkCutResult, cut_mesh, cut_mesh_network
from meshfit.surface.paths import (
    GREEDY_ASTAR_WEIGHT,
    GraphPath,
    ShortestPaths,
    astar_path,
    greedy_path,
    path_to_surface_points,
    shortest_path,
)
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
    "GREEDY_ASTAR_WEIGHT",
    "AttractResult",
    "CurveMoveResult",
    "CutResult",
    "GraphPath",
    "NetworkCutResult",
    "ShortestPaths",
    "WalkResult",
    "astar_path",
    "attract_points",
    "closest_surface_points",
    "curve_arc_lengths",
    "cut_mesh",
    "cut_mesh_network",
    "greedy_path",
    "move_along_curve",
    "path_to_surface_points",
    "random_surface_points",
    "shortest_path",
    "walk_points",
]
