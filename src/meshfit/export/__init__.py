"""Exports of fitted patch networks (Krishnamurthy 2000, ch. 1: studio and CAD pipelines).

USD (``UsdGeom.NurbsPatch`` per patch, displacement images beside), Rhino ``.3dm``, IGES 5.3
entity 128 (written here), OBJ (tessellated displaced or spline-only surfaces) and a glTF
binary preview; STEP needs the optional extra ``meshfit[cad]``.
"""

from meshfit.export._common import grid_faces, tessellate
from meshfit.export.iges import export_iges
from meshfit.export.mesh import export_gltf, export_obj, export_objs
from meshfit.export.rhino import export_3dm, rhino_knots
from meshfit.export.step import export_step, step_available
from meshfit.export.usd import export_usd

__all__ = [
    "export_3dm",
    "export_gltf",
    "export_iges",
    "export_obj",
    "export_objs",
    "export_step",
    "export_usd",
    "grid_faces",
    "rhino_knots",
    "step_available",
    "tessellate",
]
