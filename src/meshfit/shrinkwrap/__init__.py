"""Shrink wrapping: subdivision-connectivity remeshing of closed genus-0 meshes and
progressive transmission (Kobbelt, Vorsatz, Labsik & Seidel 1999).

Verbs: :func:`sphere_map` (sec. 6), :func:`base_mesh` (sec. 6), :func:`shrink_wrap`
(sec. 4, 7), :func:`encode_stream` / :func:`decode_stream` (sec. 8.1; an embedded code any
prefix of which decodes, after Khodakovsky, Schroeder & Sweldens 2000), :func:`fill_holes`.
"""

from meshfit.shrinkwrap.base import BaseMesh, BaseOptions, base_mesh, icosahedron, octahedron
from meshfit.shrinkwrap.holes import fill_holes
from meshfit.shrinkwrap.sphere import (
    SphereMap,
    check_genus0,
    sphere_map,
    spherical_orientation,
    triangle_quality,
)
from meshfit.shrinkwrap.stream import (
    Packet,
    Quantisation,
    Stream,
    decode_stream,
    encode_stream,
    read_stream,
    reconstruction_errors,
    write_stream,
)
from meshfit.shrinkwrap.subdivision import subdivide_step
from meshfit.shrinkwrap.wrap import (
    WrapLevel,
    WrapOptions,
    WrapResult,
    level_metrics,
    shrink_wrap,
    wrap_report,
)

__all__ = [
    "BaseMesh",
    "BaseOptions",
    "Packet",
    "Quantisation",
    "SphereMap",
    "Stream",
    "WrapLevel",
    "WrapOptions",
    "WrapResult",
    "base_mesh",
    "check_genus0",
    "decode_stream",
    "encode_stream",
    "fill_holes",
    "icosahedron",
    "level_metrics",
    "octahedron",
    "read_stream",
    "reconstruction_errors",
    "shrink_wrap",
    "sphere_map",
    "spherical_orientation",
    "subdivide_step",
    "triangle_quality",
    "wrap_report",
    "write_stream",
]
