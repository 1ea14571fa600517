"""Mesh core: the validated :class:`Mesh`, file I/O, validation, closest-point and ray queries."""

from meshfit.mesh.core import Mesh
from meshfit.mesh.io import FORMATS, RawMesh, load_mesh, read_mesh_arrays, save_mesh
from meshfit.mesh.locate import (
    ClosestPoints,
    RayHits,
    closest_points,
    ray_first_hit,
    triangle_distances,
    triangles_within,
)
from meshfit.mesh.validate import Finding, RepairReport, find_problems, repair_arrays

__all__ = [
    "FORMATS",
    "ClosestPoints",
    "Finding",
    "Mesh",
    "RawMesh",
    "RayHits",
    "RepairReport",
    "closest_points",
    "find_problems",
    "load_mesh",
    "ray_first_hit",
    "read_mesh_arrays",
    "repair_arrays",
    "save_mesh",
    "triangle_distances",
    "triangles_within",
]
