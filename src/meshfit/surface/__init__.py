"""Primitives on the surface: sampling face points, walking, graph paths, cutting."""

from meshfit.surface.sample import closest_surface_points, random_surface_points

__all__ = ["closest_surface_points", "random_surface_points"]
