"""The USD layer as USD reads it: stage units and axis, the welded mesh with its UDIM
coordinates, the displacement material, and the NURBS patches with their map tiles."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenEXR
import pytest
from numpy.testing import assert_allclose

from meshfit.bspline import BSplineSurface
from meshfit.displacement import DisplacementMap, read_exr, reconstruct, write_exr
from meshfit.displacement.io import to_image
from meshfit.errors import InputError
from meshfit.export import export_usd
from meshfit.export.units import UNITS
from meshfit.export.weld import patch_mesh, udim

PATTERN = "./maps/scan_<kind>.<UDIM>.exr"


def _write_tiles(folder, maps, kind="vector"):
    (folder / "maps").mkdir(exist_ok=True)
    for p, m in enumerate(maps):
        if m is not None:
            write_exr(m, folder / "maps" / f"scan_{kind}.{udim(p)}.exr")


def _scalar(maps):
    return [DisplacementMap(m.values[:, :, 2:], "scalar") for m in maps]


def _open(path):
    from pxr import Usd

    return Usd.Stage.Open(str(path))


def _source(inp):
    """``(prim name, output name)`` an input or output is connected to."""
    (src,) = inp.GetConnectedSources()[0]
    return src.source.GetPrim().GetName(), src.sourceName


@pytest.mark.parametrize(("units", "up_axis"), [("mm", "z"), ("in", "y"), ("M", "Y")])
def test_stage_declares_units_and_up_axis(demo_fit, tmp_path, units, up_axis):
    from pxr import UsdGeom

    path = export_usd(
        tmp_path / "a.usda",
        demo_fit.surfaces,
        network=demo_fit.network,
        units=units,
        up_axis=up_axis,
    )
    stage = _open(path)
    assert UsdGeom.GetStageMetersPerUnit(stage) == UNITS[units.lower()].meters
    assert UsdGeom.GetStageUpAxis(stage) == up_axis.upper()
    assert stage.GetDefaultPrim().GetPath() == "/meshfit"
    # coordinates are written unchanged
    points = np.array(UsdGeom.Mesh(stage.GetPrimAtPath("/meshfit/mesh")).GetPointsAttr().Get())
    want = patch_mesh(demo_fit.surfaces, None, demo_fit.network).vertices
    assert_allclose(points, want, rtol=2.0**-23, atol=2.0**-23 * np.abs(want).max())


def test_mesh_is_the_welded_spline_mesh_with_udim_coordinates(demo_fit, tmp_path):
    from pxr import UsdGeom

    path = export_usd(
        tmp_path / "scan.usda",
        demo_fit.surfaces,
        displacements=demo_fit.maps,
        network=demo_fit.network,
    )
    stage = _open(path)
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/meshfit/mesh"))
    # the displaced mesh's grids and coordinates: one vertex per texel, on its centre
    displaced = patch_mesh(demo_fit.surfaces, demo_fit.maps, demo_fit.network)
    points = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64)
    faces = np.array(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
    np.testing.assert_array_equal(faces, displaced.faces)
    assert set(mesh.GetFaceVertexCountsAttr().Get()) == {3}
    assert mesh.GetSubdivisionSchemeAttr().Get() == "none"
    assert mesh.GetOrientationAttr().Get() == "rightHanded"
    assert mesh.GetNormalsInterpolation() == "vertex"
    # a closed network welds into a closed mesh: every edge in exactly two faces
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, count = np.unique(edges, axis=0, return_counts=True)
    assert (count == 2).all()
    # the vertices lie on the splines (the material displaces): the undisplaced points
    # at each face corner's (u, v) on its own patch
    spline = patch_mesh(demo_fit.surfaces, None, demo_fit.network, shapes=displaced.shapes)
    assert_allclose(points, spline.vertices, rtol=0, atol=2.0**-22 * np.abs(points).max())
    assert_allclose(np.array(mesh.GetExtentAttr().Get()), [points.min(0), points.max(0)])

    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == "faceVarying" and st.IsIndexed()
    assert str(st.GetTypeName()) == "texCoord2f[]"
    corner_uv = np.array(st.ComputeFlattened(), dtype=np.float64).reshape(-1, 3, 2)
    assert_allclose(corner_uv, displaced.uv[displaced.face_uv], rtol=0, atol=1e-6)
    tile = np.floor(corner_uv).astype(int)
    p = displaced.face_patch[:, None]
    assert (tile[..., 0] == p % 10).all() and (tile[..., 1] == p // 10).all()

    subsets = UsdGeom.Subset.GetGeomSubsets(mesh, "face", "patch")
    assert [s.GetPrim().GetName() for s in subsets] == [
        f"patch_{k}" for k in range(len(demo_fit.surfaces))
    ]
    for k, s in enumerate(subsets):
        want = np.flatnonzero(displaced.face_patch == k)
        np.testing.assert_array_equal(np.array(s.GetIndicesAttr().Get()), want)


@pytest.mark.parametrize("kind", ["vector", "scalar"])
def test_material_displaces_by_the_map_tiles(demo_fit, tmp_path, kind):
    from pxr import UsdShade, UsdUtils

    maps = demo_fit.maps if kind == "vector" else _scalar(demo_fit.maps)
    _write_tiles(tmp_path, maps, kind)
    pattern = PATTERN.replace("<kind>", kind)
    path = export_usd(
        tmp_path / "scan.usda", demo_fit.surfaces, displacements=maps, map_pattern=pattern
    )
    # export_usd writes the layer only: the images are the caller's
    assert sorted(p.name for p in tmp_path.iterdir()) == ["maps", "scan.usda"]
    stage = _open(path)
    mesh = stage.GetPrimAtPath("/meshfit/mesh")
    material, _ = UsdShade.MaterialBindingAPI(mesh).ComputeBoundMaterial()
    assert material.GetPath() == "/meshfit/Looks/surface"
    surface = material.ComputeSurfaceSource()[0]
    assert surface.GetIdAttr().Get() == "UsdPreviewSurface"
    assert _source(material.GetDisplacementOutput()) == ("PreviewSurface", "displacement")
    channel = {"vector": "g", "scalar": "r"}[kind]  # the normal component
    assert _source(surface.GetInput("displacement")) == ("displacementTexture", channel)
    # the channel named holds the normal component in the tile files (vector: T, N, B)
    for p, m in enumerate(maps):
        with OpenEXR.File(str(tmp_path / "maps" / f"scan_{kind}.{udim(p)}.exr")) as f:
            ch = {k: np.asarray(v.pixels) for k, v in f.channels().items()}
        image = ch["RGB"][:, :, "rgb".index(channel)] if kind == "vector" else ch["Y"]
        np.testing.assert_array_equal(image, to_image(m.image)[:, :, -1])
    tex = UsdShade.Shader(stage.GetPrimAtPath("/meshfit/Looks/surface/displacementTexture"))
    assert tex.GetIdAttr().Get() == "UsdUVTexture"
    assert tex.GetInput("file").Get().path == f"./maps/scan_{kind}.<UDIM>.exr"
    assert tex.GetInput("sourceColorSpace").Get() == "raw"
    assert _source(tex.GetInput("st")) == ("stReader", "result")
    reader = UsdShade.Shader(stage.GetPrimAtPath("/meshfit/Looks/surface/stReader"))
    assert reader.GetIdAttr().Get() == "UsdPrimvarReader_float2"
    assert reader.GetInput("varname").Get() == "st"
    vector = stage.GetPrimAtPath("/meshfit/Looks/surface/vectorDisplacementTexture")
    assert vector.IsValid() == (kind == "vector")
    if kind == "vector":
        vtex = UsdShade.Shader(vector)
        assert vtex.GetInput("file").Get().path == tex.GetInput("file").Get().path
        assert vtex.GetOutput("rgb") and not vtex.GetOutput("rgb").GetConnectedSources()[0]
    assert material.GetPrim().GetAttribute("meshfit:displacementKind").Get() == kind
    # USD's own dependency walk finds every tile through the <UDIM> pattern
    _, assets, unresolved = UsdUtils.ComputeAllDependencies(str(path))
    tiles = sorted(
        str((tmp_path / "maps" / f"scan_{kind}.{udim(p)}.exr").resolve()) for p in range(6)
    )
    assert sorted(str(Path(a).resolve()) for a in assets) == tiles
    assert not unresolved


def test_default_map_pattern_follows_the_layer_stem(demo_fit, tmp_path):
    from pxr import UsdShade

    path = export_usd(tmp_path / "spot.usda", demo_fit.surfaces, displacements=demo_fit.maps)
    stage = _open(path)
    tex = UsdShade.Shader(stage.GetPrimAtPath("/meshfit/Looks/surface/displacementTexture"))
    assert tex.GetInput("file").Get().path == "./maps/spot_vector.<UDIM>.exr"
    # without maps: a plain material, nothing to read
    path = export_usd(tmp_path / "plain.usda", demo_fit.surfaces)
    stage = _open(path)
    assert not stage.GetPrimAtPath("/meshfit/Looks/surface/displacementTexture").IsValid()
    assert [p.GetName() for p in stage.GetPrimAtPath("/meshfit/Looks/surface").GetChildren()] == [
        "PreviewSurface"
    ]


def test_nurbs_patches_round_trip_with_their_tiles(demo_fit, tmp_path):
    from pxr import UsdGeom

    surfaces, maps = demo_fit.surfaces, list(demo_fit.maps)
    maps[3] = None  # a patch without a map keeps no map attributes
    _write_tiles(tmp_path, maps)
    names = [f"face_{k}" for k in range(len(surfaces))]
    path = export_usd(
        tmp_path / "scan.usda",
        surfaces,
        displacements=maps,
        map_pattern="maps/scan_vector.<UDIM>.exr",
        names=names,
    )
    stage = _open(path)
    scope = stage.GetPrimAtPath("/meshfit/nurbs")
    assert scope.IsA(UsdGeom.Scope)
    assert UsdGeom.Imageable(scope).ComputePurpose() == UsdGeom.Tokens.guide
    prims = [p for p in stage.Traverse() if p.IsA(UsdGeom.NurbsPatch)]
    assert [p.GetName() for p in prims] == names
    assert all(p.GetParent() == scope for p in prims)
    for k, (prim, s, d) in enumerate(zip(prims, surfaces, maps, strict=True)):
        patch = UsdGeom.NurbsPatch(prim)
        mu, mv = s.shape
        assert (patch.GetUVertexCountAttr().Get(), patch.GetVVertexCountAttr().Get()) == (mu, mv)
        assert patch.GetUOrderAttr().Get() == patch.GetVOrderAttr().Get() == 4
        ku = np.array(patch.GetUKnotsAttr().Get())
        kv = np.array(patch.GetVKnotsAttr().Get())
        np.testing.assert_array_equal(ku, s.knots_u)
        np.testing.assert_array_equal(kv, s.knots_v)
        pts = np.array(patch.GetPointsAttr().Get(), dtype=np.float64)
        P32 = pts.reshape(mv, mu, 3).transpose(1, 0, 2)
        assert_allclose(P32, s.control_points, rtol=2.0**-23, atol=0)
        exact = np.array(prim.GetAttribute("meshfit:controlPoints").Get())
        r = BSplineSurface(exact.reshape(mv, mu, 3).transpose(1, 0, 2), ku, kv)
        np.testing.assert_array_equal(r.control_points, s.control_points)
        asset = prim.GetAttribute("meshfit:displacement")
        if d is None:
            assert not asset.IsValid() and not prim.GetAttribute("meshfit:udim").IsValid()
            continue
        assert prim.GetAttribute("meshfit:udim").Get() == udim(k)
        assert asset.Get().path == f"./maps/scan_vector.{udim(k)}.exr"
        assert prim.GetAttribute("meshfit:displacementKind").Get() == "vector"
        # the displaced surface rebuilt from the layer and its tile alone (float32 maps)
        m = read_exr(tmp_path / asset.Get().path)
        np.testing.assert_array_equal(m.image, d.image)
        got = reconstruct(r, m)
        assert_allclose(got, reconstruct(s, d), rtol=0, atol=1e-6 * np.abs(got).max())


def test_usd_rejects_bad_input(demo_fit, tmp_path):
    surfaces, maps = demo_fit.surfaces, demo_fit.maps
    magnitude = [DisplacementMap(np.linalg.norm(m.values, axis=2), "magnitude") for m in maps]
    with pytest.raises(InputError, match="magnitude"):
        export_usd(tmp_path / "a.usda", surfaces, displacements=magnitude)
    with pytest.raises(InputError, match="one kind"):
        export_usd(tmp_path / "a.usda", surfaces, displacements=[*maps[:5], _scalar(maps)[5]])
    with pytest.raises(InputError, match="<UDIM>"):
        export_usd(tmp_path / "a.usda", surfaces, displacements=maps, map_pattern="m/a.exr")
    with pytest.raises(InputError, match="relative"):
        export_usd(tmp_path / "a.usda", surfaces, displacements=maps, map_pattern="/m/a.<UDIM>.exr")
    with pytest.raises(InputError, match="no displacements"):
        export_usd(tmp_path / "a.usda", surfaces, map_pattern="m/a.<UDIM>.exr")
    with pytest.raises(InputError, match="units"):
        export_usd(tmp_path / "a.usda", surfaces, units="furlong")
    with pytest.raises(InputError, match="up_axis"):
        export_usd(tmp_path / "a.usda", surfaces, up_axis="x")
    with pytest.raises(InputError, match=r"\.usda"):
        export_usd(tmp_path / "a.txt", surfaces)
    assert not list(tmp_path.iterdir())
