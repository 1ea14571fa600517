"""USD export: a renderable mesh with a displacement material, and the NURBS patches.

One stage holds what a renderer draws (a watertight ``UsdGeom.Mesh`` of the splines with a
``UsdPreviewSurface`` material whose displacement reads the map images) and what a modelling
tool edits (the exact ``UsdGeom.NurbsPatch`` prims, as guides). The map images are not
written here: the stage references the UDIM tiles the pipeline writes once, in ``maps/``.

References
----------
.. [1] Pixar, "UsdPreviewSurface Specification", version 2.5 (``UsdPreviewSurface``,
   ``UsdUVTexture``, ``UsdPrimvarReader_float2``; displacement along the normal).
.. [2] Pixar, "UsdGeom: Stage Linear Units and Up Axis" (``metersPerUnit``, ``upAxis``).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING

import numpy as np

from meshfit.bspline import BSplineSurface
from meshfit.displacement import FRAME, DisplacementMap
from meshfit.errors import InputError
from meshfit.export._common import as_displacements, as_names, as_surfaces, atomic_write
from meshfit.export.units import unit

if TYPE_CHECKING:
    from meshfit.stitch import Network

__all__ = ["MATERIAL", "UDIM_TOKEN", "export_usd"]

#: the token a map pattern holds in place of the UDIM tile number
UDIM_TOKEN = "<UDIM>"
#: name of the material under ``<root>/Looks``
MATERIAL = "surface"
#: the texture channel UsdPreviewSurface displaces by, per map kind: a vector map's file
#: channels are T, N, B (the tangent-space vector displacement order of
#: :mod:`meshfit.displacement.io`), so its normal component is the second (green) one
_DISPLACEMENT_CHANNEL = {"vector": "g", "scalar": "r"}


def export_usd(
    path: str | os.PathLike,
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    *,
    displacements: DisplacementMap | Sequence[DisplacementMap | None] | None = None,
    network: Network | None = None,
    map_pattern: str | None = None,
    names: Sequence[str] | None = None,
    units: str = "mm",
    up_axis: str = "z",
    root: str = "/meshfit",
) -> Path:
    """Write the patches to a USD layer (``.usda`` text or ``.usd`` / ``.usdc`` binary).

    Parameters
    ----------
    path : str or path
        Output layer (written atomically).
    surfaces : BSplineSurface or sequence of them
    displacements : DisplacementMap or sequence of (DisplacementMap or None), optional
        The patches' maps (all ``vector`` or all ``scalar``); they set the mesh's vertex grid
        and texture coordinates and the material's wiring. Their images are not written
        here: ``map_pattern`` names the files.
    network : Network, optional
        Shared boundaries, so the mesh holds each boundary's vertices once (watertight);
        see :func:`meshfit.export.weld.patch_mesh`.
    map_pattern : str, optional
        Path of the map images relative to the layer, with ``<UDIM>`` in place of the tile
        number (patch p is tile ``1001 + p``); default ``./maps/<layer stem>_<kind>.<UDIM>.exr``,
        where :func:`meshfit.fit` writes them beside ``<stem>.usda``. The images are in
        texture orientation (:mod:`meshfit.displacement.io`). Only with ``displacements``.
    names : sequence of str, optional
        NURBS prim names; default ``patch_0, ...``.
    units : str
        The coordinates' unit, one of :data:`meshfit.export.units.UNITS` (``"mm"``, ``"cm"``,
        ``"m"``, ``"in"``, ``"ft"``; default ``"mm"``), written as the stage's
        ``metersPerUnit``; coordinates are written unchanged.
    up_axis : {"z", "y"}
        The stage's ``upAxis``: which model axis points up. Coordinates are written
        unchanged; an importer into a Z-up (Y-up) application turns a Y-up (Z-up) stage.
    root : str
        Path of the ``Xform`` holding everything, the stage's default prim (default
        ``/meshfit``).

    Returns
    -------
    Path

    Raises
    ------
    InputError
        On bad surfaces, names, maps (a ``magnitude`` or ``bump`` map, or mixed kinds), a
        malformed ``map_pattern`` (or one without maps), units, up axis, root or file suffix.

    Notes
    -----
    The stage (``metersPerUnit``, ``upAxis``, default prim ``<root>``) holds:

    ``<root>/mesh``
        ``UsdGeom.Mesh`` of the splines (not displaced: the material displaces), from
        :func:`meshfit.export.weld.patch_mesh`: triangles turning like ``S_u x S_v``
        (``rightHanded``), ``normals`` per vertex (area-weighted), ``primvars:st``
        face-varying and indexed (patch p in UDIM tile ``1001 + p``: tile column ``p % 10``,
        row ``p // 10``; within a tile x along u, y along v, on the map's texel centres),
        ``extent``, and one ``GeomSubset`` per patch (family ``patch``, named as its NURBS
        prim). ``subdivisionScheme = none``: the vertices lie on the splines, so the
        triangles are the surface; a Catmull-Clark limit surface of the same cage is an
        approximating scheme that pulls away from the vertices (inward on convex parts), and
        a renderer that wants more vertices for displacement subdivides linearly.
    ``<root>/Looks/surface``
        ``UsdShade.Material`` bound to the mesh: a ``UsdPreviewSurface`` whose
        ``displacement`` input reads the normal component of the map (``g``, the N channel of
        a vector map, whose file channels are T, N, B; ``r`` of a scalar map) from the
        ``UsdUVTexture`` ``displacementTexture``
        (``sourceColorSpace = raw``, file ``map_pattern``), addressed by the
        ``UsdPrimvarReader_float2`` ``stReader`` of ``st``; the material's ``displacement``
        output is that surface's. UsdPreviewSurface displaces along the normal only, so for
        a vector map the tangential part is left to renderers with vector displacement: the
        texture ``vectorDisplacementTexture`` (output ``rgb``, not connected) holds the whole
        map as tangent, normal, bitangent components, in the frame named by the material's
        ``meshfit:displacementFrame``.
    ``<root>/nurbs``
        ``Scope`` of ``purpose = guide`` (drawn by no renderer) with one ``NurbsPatch`` per
        patch: ``uOrder = vOrder = 4``, ``uVertexCount = mu``, ``vVertexCount = mv``, the
        full clamped knot vectors (``mu + 4``, ``mv + 4`` values), ``uRange = vRange = (0,
        1)`` and ``points`` in USD's order (u varies fastest: ``points[j * mu + i] = P[i,
        j]``). ``points`` is ``point3f[]`` (float32); the float64 control points are kept as
        ``meshfit:controlPoints`` (``point3d[]``, same order). With maps, ``meshfit:udim``
        is the patch's tile, ``meshfit:displacement`` (asset) its tile's image,
        ``meshfit:displacementKind`` and ``meshfit:displacementFrame`` (the frame of
        :mod:`meshfit.displacement`) say what it holds.

    In Blender (File > Import > Universal Scene Description) the mesh arrives scaled to
    metres by ``metersPerUnit`` and turned Z-up, its material reading the UDIM tiles in an
    Image Texture node (Non-Color, UV map ``st``) whose green channel feeds a Displacement
    node; Cycles renders the displacement (the material's Displacement method "Displacement
    Only" or "Displacement and Bump"). The mesh has a vertex per texel; a Subdivision
    Surface modifier (Simple) smooths the displaced surface between them. For a vector map,
    connect the Color of an Image Texture of the same tiles (Non-Color, UV map ``st``)
    straight to a Vector Displacement node in Tangent space, midlevel 0, scale 1, and that
    node to the Material Output's Displacement in place of the Displacement node: the map's
    file channels are tangent, normal, bitangent, the order that node reads, and Blender's
    tangent space on ``st`` is the maps' frame.
    """
    from pxr import Sdf, Usd, UsdGeom, UsdShade

    from meshfit.export.weld import patch_mesh, udim

    surfaces = as_surfaces(surfaces)
    names = as_names(names, len(surfaces))
    disps = as_displacements(displacements, len(surfaces))
    path = Path(path)
    kind = _map_kind(disps, map_pattern)
    pattern = None
    if kind is not None:
        default = f"./maps/{path.stem}_{kind}.{UDIM_TOKEN}.exr"
        pattern = _pattern(default if map_pattern is None else map_pattern)
    meters = unit(units).meters
    up = {"y": UsdGeom.Tokens.y, "z": UsdGeom.Tokens.z}.get(str(up_axis).lower())
    if up is None:
        raise InputError(f"up_axis must be 'y' or 'z', got {up_axis!r}")
    if not Sdf.Path.IsValidPathString(root) or not root.startswith("/"):
        raise InputError(f"root must be an absolute prim path, got {root!r}")
    if path.suffix not in (".usda", ".usd", ".usdc"):
        raise InputError(f"USD file must end in .usda, .usd or .usdc, got {path.name!r}")
    # flat bump maps of the maps' texel counts: the splines alone (the material displaces)
    # on the maps' texel grids, with texture coordinates on the texel centres
    flat = [None if d is None else _flat_bump(d.shape) for d in disps]
    mesh = patch_mesh(surfaces, flat, network)

    def write(tmp: str) -> None:
        stage = Usd.Stage.CreateNew(tmp)
        UsdGeom.SetStageUpAxis(stage, up)
        UsdGeom.SetStageMetersPerUnit(stage, meters)
        top = UsdGeom.Xform.Define(stage, root)
        stage.SetDefaultPrim(top.GetPrim())
        geom = _define_mesh(stage, f"{root}/mesh", mesh, names)
        UsdGeom.Scope.Define(stage, f"{root}/Looks")
        material = _define_material(stage, f"{root}/Looks/{MATERIAL}", kind, pattern)
        UsdShade.MaterialBindingAPI.Apply(geom.GetPrim()).Bind(material)
        tiles = [
            pattern.replace(UDIM_TOKEN, str(udim(p)))
            if pattern is not None and d is not None
            else None
            for p, d in enumerate(disps)
        ]
        _define_nurbs(stage, f"{root}/nurbs", surfaces, names, disps, tiles, udim)
        stage.GetRootLayer().Save()

    return atomic_write(path, write)


def _map_kind(disps: list[DisplacementMap | None], map_pattern: str | None) -> str | None:
    """The one kind of the maps (None without maps); InputError on kinds a renderer cannot
    displace by and on a pattern given without maps."""
    kinds = {d.kind for d in disps if d is not None}
    if not kinds:
        if map_pattern is not None:
            raise InputError("map_pattern names map images, but no displacements were given")
        return None
    bad = kinds - set(_DISPLACEMENT_CHANNEL)
    if bad:
        raise InputError(
            f"USD displaces by vector or scalar maps, not a {sorted(bad)[0]} map "
            "(UsdPreviewSurface displaces along the normal)"
        )
    if len(kinds) > 1:
        raise InputError(f"the maps must all be of one kind, got {sorted(kinds)}")
    return kinds.pop()


def _flat_bump(shape: tuple[int, int]) -> DisplacementMap:
    """A bump map of ``shape`` texels whose normals are the spline's own."""
    return DisplacementMap(np.broadcast_to([0.0, 0.0, 1.0], (*shape, 3)), "bump")


def _pattern(map_pattern: str) -> str:
    """``map_pattern`` as an asset path anchored at the layer (``./`` added)."""
    p = str(map_pattern).replace("\\", "/")
    if p.count(UDIM_TOKEN) != 1:
        raise InputError(f"map_pattern must hold {UDIM_TOKEN} once, got {map_pattern!r}")
    if PurePosixPath(p).is_absolute() or (len(p) > 1 and p[1] == ":"):
        raise InputError(f"map_pattern must be relative to the layer, got {map_pattern!r}")
    return p if p.startswith(("./", "../")) else f"./{p}"


def _vt(array: np.ndarray, kind: str):
    """A numpy array as a ``Vt`` array: ``"f3"`` Vec3fArray, ``"f2"`` Vec2fArray, ``"i"``
    IntArray."""
    from pxr import Vt

    if kind == "f3":
        return Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(array, dtype=np.float32))
    if kind == "f2":
        return Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(array, dtype=np.float32))
    return Vt.IntArray.FromNumpy(np.ascontiguousarray(array, dtype=np.int32).ravel())


def _define_mesh(stage, prim_path: str, mesh, names: list[str]):
    """The ``UsdGeom.Mesh`` of a ``PatchMesh``, with st, normals and a subset per patch."""
    from pxr import Gf, Sdf, UsdGeom, Vt

    geom = UsdGeom.Mesh.Define(stage, prim_path)
    V = np.asarray(mesh.vertices, dtype=np.float64)
    F = np.asarray(mesh.faces, dtype=np.int64)
    geom.CreatePointsAttr(_vt(V, "f3"))
    geom.CreateFaceVertexCountsAttr(_vt(np.full(len(F), 3, dtype=np.int32), "i"))
    geom.CreateFaceVertexIndicesAttr(_vt(F, "i"))
    geom.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    geom.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    geom.CreateNormalsAttr(_vt(mesh.normals, "f3"))
    geom.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    lo, hi = V.min(axis=0), V.max(axis=0)
    geom.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())]))
    st = UsdGeom.PrimvarsAPI(geom).CreatePrimvar(
        "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
    )
    st.Set(_vt(mesh.uv, "f2"))
    st.SetIndices(_vt(mesh.face_uv, "i"))
    face_patch = np.asarray(mesh.face_patch)
    for p, name in enumerate(names):
        UsdGeom.Subset.CreateGeomSubset(
            geom,
            name,
            UsdGeom.Tokens.face,
            _vt(np.flatnonzero(face_patch == p), "i"),
            familyName="patch",
            familyType=UsdGeom.Tokens.partition,
        )
    return geom


def _define_material(stage, prim_path: str, kind: str | None, pattern: str | None):
    """The ``UsdPreviewSurface`` material; with maps its displacement reads ``pattern``."""
    from pxr import Sdf, UsdShade

    material = UsdShade.Material.Define(stage, prim_path)
    surface = UsdShade.Shader.Define(stage, f"{prim_path}/PreviewSurface")
    surface.CreateIdAttr("UsdPreviewSurface")
    surface_out = surface.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    material.CreateSurfaceOutput().ConnectToSource(surface_out)
    if kind is None or pattern is None:
        return material
    reader = UsdShade.Shader.Define(stage, f"{prim_path}/stReader")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
    st_out = reader.CreateOutput("result", Sdf.ValueTypeNames.Float2)

    def texture(name: str):
        tex = UsdShade.Shader.Define(stage, f"{prim_path}/{name}")
        tex.CreateIdAttr("UsdUVTexture")
        tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(pattern))
        tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(st_out)
        tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("raw")
        tex.CreateInput("wrapS", Sdf.ValueTypeNames.Token).Set("clamp")
        tex.CreateInput("wrapT", Sdf.ValueTypeNames.Token).Set("clamp")
        return tex

    channel = texture("displacementTexture").CreateOutput(
        _DISPLACEMENT_CHANNEL[kind], Sdf.ValueTypeNames.Float
    )
    surface.CreateInput("displacement", Sdf.ValueTypeNames.Float).ConnectToSource(channel)
    displaced = surface.CreateOutput("displacement", Sdf.ValueTypeNames.Token)
    material.CreateDisplacementOutput().ConnectToSource(displaced)
    if kind == "vector":
        texture("vectorDisplacementTexture").CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
    prim = material.GetPrim()
    prim.CreateAttribute("meshfit:displacementKind", Sdf.ValueTypeNames.Token).Set(kind)
    prim.CreateAttribute("meshfit:displacementFrame", Sdf.ValueTypeNames.String).Set(FRAME)
    return material


def _define_nurbs(stage, scope_path, surfaces, names, disps, tiles, udim) -> None:
    """The guide ``Scope`` of ``NurbsPatch`` prims (see :func:`export_usd`'s Notes)."""
    from pxr import Gf, Sdf, UsdGeom, Vt

    scope = UsdGeom.Scope.Define(stage, scope_path)
    scope.CreatePurposeAttr(UsdGeom.Tokens.guide)
    for p, (name, s, d, tile) in enumerate(zip(names, surfaces, disps, tiles, strict=True)):
        mu, mv = s.shape
        pts = s.control_points.transpose(1, 0, 2).reshape(-1, 3)  # u fastest
        patch = UsdGeom.NurbsPatch.Define(stage, f"{scope_path}/{name}")
        patch.CreateUVertexCountAttr(mu)
        patch.CreateVVertexCountAttr(mv)
        patch.CreateUOrderAttr(s.degree + 1)
        patch.CreateVOrderAttr(s.degree + 1)
        patch.CreateUKnotsAttr(Vt.DoubleArray(s.knots_u.tolist()))
        patch.CreateVKnotsAttr(Vt.DoubleArray(s.knots_v.tolist()))
        patch.CreateURangeAttr(Gf.Vec2d(float(s.knots_u[0]), float(s.knots_u[-1])))
        patch.CreateVRangeAttr(Gf.Vec2d(float(s.knots_v[0]), float(s.knots_v[-1])))
        patch.CreateUFormAttr(UsdGeom.Tokens.open)
        patch.CreateVFormAttr(UsdGeom.Tokens.open)
        patch.CreatePointsAttr(_vt(pts, "f3"))
        lo, hi = pts.min(axis=0), pts.max(axis=0)  # convex hull property
        patch.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())]))
        prim = patch.GetPrim()
        prim.CreateAttribute("meshfit:controlPoints", Sdf.ValueTypeNames.Point3dArray).Set(
            Vt.Vec3dArray.FromNumpy(np.ascontiguousarray(pts))
        )
        if d is None or tile is None:
            continue
        prim.CreateAttribute("meshfit:udim", Sdf.ValueTypeNames.Int).Set(int(udim(p)))
        prim.CreateAttribute("meshfit:displacement", Sdf.ValueTypeNames.Asset).Set(
            Sdf.AssetPath(tile)
        )
        prim.CreateAttribute("meshfit:displacementKind", Sdf.ValueTypeNames.Token).Set(d.kind)
        prim.CreateAttribute("meshfit:displacementFrame", Sdf.ValueTypeNames.String).Set(FRAME)
