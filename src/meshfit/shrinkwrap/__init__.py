"""Shrink wrapping: subdivision-connectivity remeshing of closed genus-0 meshes and
progressive transmission (Kobbelt, Vorsatz, Labsik & Seidel 1999)."""

from meshfit.shrinkwrap.sphere import (
    SphereMap,
    check_genus0,
    sphere_map,
    spherical_orientation,
    triangle_quality,
)

__all__ = [
    "SphereMap",
    "check_genus0",
    "sphere_map",
    "spherical_orientation",
    "triangle_quality",
]
