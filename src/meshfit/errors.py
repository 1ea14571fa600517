"""Exceptions raised by meshfit.

Every problem with user input raises a subclass of :class:`MeshfitError` whose message says
what is wrong and where (which file, which face, vertex or edge). The command line turns it
into one line on stderr and exit code 2.
"""

from __future__ import annotations

__all__ = [
    "CutError",
    "DegenerateFaceError",
    "DuplicateFaceError",
    "EmptyMeshError",
    "ExportError",
    "FeatureCurveError",
    "ImageFileError",
    "IndexRangeError",
    "InputError",
    "LayoutError",
    "MeshFileError",
    "MeshValidationError",
    "MeshfitError",
    "NonFiniteError",
    "NonManifoldEdgeError",
    "NonManifoldVertexError",
    "OrientationError",
    "PathError",
    "RenderError",
    "StreamError",
    "TopologyError",
    "UnreferencedVertexError",
]


class MeshfitError(Exception):
    """Base class of every error meshfit raises on bad input."""


class InputError(MeshfitError, ValueError):
    """An argument has the wrong shape, dtype or value."""


class MeshFileError(MeshfitError):
    """A mesh file is missing, unreadable, truncated or of an unknown format."""


class MeshValidationError(MeshfitError):
    """A mesh violates an invariant the rest of the package relies on.

    Attributes
    ----------
    kind : str
        Short machine-readable name of the problem (``"non_manifold_edge"``, ...).
    first : tuple of int
        The first offending element: ``(face,)``, ``(vertex,)`` or ``(v0, v1)`` for an edge.
    count : int
        How many elements have the problem.
    """

    kind = "invalid_mesh"

    def __init__(self, message: str, *, first: tuple[int, ...] = (), count: int = 0):
        super().__init__(message)
        self.first = first
        self.count = count


class EmptyMeshError(MeshValidationError):
    kind = "empty"


class NonFiniteError(MeshValidationError):
    kind = "non_finite"


class CoordinateRangeError(MeshValidationError):
    kind = "coordinate_range"


class IndexRangeError(MeshValidationError):
    kind = "index_range"


class DegenerateFaceError(MeshValidationError):
    kind = "degenerate_face"


class DuplicateFaceError(MeshValidationError):
    kind = "duplicate_face"


class NonManifoldEdgeError(MeshValidationError):
    kind = "non_manifold_edge"


class NonManifoldVertexError(MeshValidationError):
    kind = "non_manifold_vertex"


class OrientationError(MeshValidationError):
    kind = "inconsistent_orientation"


class UnreferencedVertexError(MeshValidationError):
    kind = "unreferenced_vertex"


class PathError(MeshfitError):
    """No graph path exists (different components, vertex outside the allowed subset)."""


class CutError(MeshfitError):
    """A polyline cannot be cut into the mesh (points not on the same or adjacent faces)."""


class TopologyError(MeshfitError):
    """The mesh has the wrong topology for the operation (shrink wrapping needs one closed
    genus-0 surface: no holes, no handles, one component)."""


class FeatureCurveError(MeshfitError, ValueError):
    """A feature curve of a patch cannot guide the spring mesh: it does not run from one side
    to the opposite side, or it crosses another feature curve of the same direction."""


class LayoutError(InputError):
    """A patch layout is malformed or does not fit its mesh: unknown file version, bad JSON,
    curve ends away from their corners, a patch without four sides joined end to end, curves
    crossing away from corners, a patch region that is not a disk, a layout made for another
    mesh. The message names the curve, patch, corner or file line."""


class ImageFileError(MeshfitError):
    """A displacement or bump map image is unreadable, of an unsupported layout (channels, bit
    depth) or lacks the metadata needed to turn its pixels back into values (kind, value
    range) when none was given. The message names the file."""


class ExportError(MeshfitError):
    """A spline export cannot be written or read back: an optional library is missing
    (STEP needs ``meshfit[cad]``), or a file does not hold what the exporter wrote."""


class RenderError(MeshfitError):
    """An external renderer failed: Blender's Python (``$MESHFIT_BLENDER_PYTHON``) is
    missing, cannot import ``bpy``, exits with an error or runs past its time limit. The
    message names the interpreter and the layer and ends with the renderer's last lines of
    stderr."""


class StreamError(MeshfitError):
    """A progressive-transmission stream is truncated, of an unknown version, or holds a
    packet whose level or vertex range does not fit its header."""
