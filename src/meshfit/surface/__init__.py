"""Primitives on the surface: sampling face points, walking, graph paths, cutting."""
