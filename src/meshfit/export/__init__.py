"""Exports of fitted patch networks (Krishnamurthy 2000, ch. 1: studio and CAD pipelines).

USD (a mesh displaced by its material from UDIM map tiles, and the ``UsdGeom.NurbsPatch``
patches), Rhino ``.3dm``, IGES 5.3 entity 128 (written here), and tessellated OBJ, glTF
binary and PLY meshes of the displaced or spline-only surfaces; STEP needs the optional extra
``meshfit[cad]``. The tessellated files are one welded mesh (:func:`patch_mesh`):
neighbouring patches share their boundary vertices, so a closed network gives a watertight
mesh at every resolution, with UDIM texture coordinates addressing each patch's map.
"""

from meshfit.export._common import grid_faces, tessellate
from meshfit.export.iges import export_iges
from meshfit.export.mesh import export_gltf, export_obj, export_objs, export_ply
from meshfit.export.rhino import export_3dm, rhino_knots
from meshfit.export.step import export_step, step_available
from meshfit.export.usd import export_usd
from meshfit.export.weld import UDIM_COLUMNS, PatchMesh, patch_mesh, spline_network, udim

__all__ = [
    "UDIM_COLUMNS",
    "PatchMesh",
    "export_3dm",
    "export_gltf",
    "export_iges",
    "export_obj",
    "export_objs",
    "export_ply",
    "export_step",
    "export_usd",
    "grid_faces",
    "patch_mesh",
    "rhino_knots",
    "spline_network",
    "step_available",
    "tessellate",
    "udim",
]
