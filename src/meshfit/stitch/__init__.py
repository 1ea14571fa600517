"""Inter-patch continuity of B-spline networks and their displacement maps (thesis ch. 8).

:func:`network_from_grids` finds shared boundaries and corners; :func:`control_classes`
makes control counts consistent (equal-count classes, user counts per class);
:func:`stitch_surfaces` enforces C0 or G1 per boundary and G1 at corners of any valence;
:func:`match_map_shapes` gives displacement maps equal texel counts along shared boundaries
and :func:`stitch_displacements` closes the seams of vector, scalar and bump maps;
:func:`seam_report`, :func:`displacement_seam_gaps` and :func:`bump_seam_angles` measure gaps
and normal jumps before and after.
"""

from meshfit.stitch.network import (
    SIDES,
    ControlClasses,
    Network,
    SharedBoundary,
    control_classes,
    direction_classes,
    network_from_grids,
    side_row,
    texel_shapes,
)
from meshfit.stitch.stitch import (
    MAP_KINDS,
    SeamReport,
    bump_seam_angles,
    displacement_seam_gaps,
    match_map_shapes,
    seam_report,
    stitch_displacements,
    stitch_surfaces,
)

__all__ = [
    "MAP_KINDS",
    "SIDES",
    "ControlClasses",
    "Network",
    "SeamReport",
    "SharedBoundary",
    "bump_seam_angles",
    "control_classes",
    "direction_classes",
    "displacement_seam_gaps",
    "match_map_shapes",
    "network_from_grids",
    "seam_report",
    "side_row",
    "stitch_displacements",
    "stitch_surfaces",
    "texel_shapes",
]
