"""meshfit: smooth surfaces from dense scanned meshes.

Two systems behind one API: *fit* (B-spline patches with displacement maps over a painted
patch layout; Krishnamurthy & Levoy) and *wrap* (subdivision-connectivity remeshing by
shrink wrapping; Kobbelt et al. 1999).
"""

import os

# numba's parallel kernels run on OpenMP threads, which by default spin between parallel
# regions; on a busy machine spinning threads compete with the work and each launch of a
# parallel kernel costs orders of magnitude more. Sleeping threads wake in microseconds. Set
# before any kernel runs; a value the user chose is kept.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from meshfit import errors, tol
from meshfit._version import __version__
from meshfit.mesh import Mesh, load_mesh, save_mesh
from meshfit.types import SurfaceCurve, SurfacePoints

#: the front door's names, imported on first use (``import meshfit`` stays quick for the CLI)
_LAZY = {
    "fit": "meshfit.pipeline",
    "ClusterOptions": "meshfit.pipeline",
    "load_fit": "meshfit.pipeline",
    "FitOptions": "meshfit.pipeline",
    "FitResult": "meshfit.pipeline",
    "PatchFit": "meshfit.pipeline",
    "wrap": "meshfit.shrinkwrap.front",
    "WrapOptions": "meshfit.shrinkwrap",
    "WrapResult": "meshfit.shrinkwrap",
}

__all__ = [
    "ClusterOptions",
    "FitOptions",
    "FitResult",
    "Mesh",
    "PatchFit",
    "SurfaceCurve",
    "SurfacePoints",
    "WrapOptions",
    "WrapResult",
    "__version__",
    "errors",
    "fit",
    "load_fit",
    "load_mesh",
    "save_mesh",
    "tol",
    "wrap",
]


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'meshfit' has no attribute {name!r}")
