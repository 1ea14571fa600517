"""meshfit: smooth surfaces from dense scanned meshes.

Two systems behind one API: *fit* (B-spline patches with displacement maps over a painted
patch layout; Krishnamurthy & Levoy) and *wrap* (subdivision-connectivity remeshing by
shrink wrapping; Kobbelt et al. 1999).
"""

from meshfit import errors, tol
from meshfit.mesh import Mesh, load_mesh, save_mesh
from meshfit.types import SurfaceCurve, SurfacePoints

__version__ = "0.1.0"

__all__ = [
    "Mesh",
    "SurfaceCurve",
    "SurfacePoints",
    "__version__",
    "errors",
    "load_mesh",
    "save_mesh",
    "tol",
]
