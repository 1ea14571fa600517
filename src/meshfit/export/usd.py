"""USD export: one ``UsdGeom.NurbsPatch`` per patch, displacement images written beside it."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from meshfit.bspline import BSplineSurface
from meshfit.displacement import FRAME, DisplacementMap, write_exr
from meshfit.errors import InputError
from meshfit.export._common import as_displacements, as_names, as_surfaces, atomic_write

__all__ = ["export_usd"]


def export_usd(
    path: str | os.PathLike,
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    *,
    displacements: DisplacementMap | Sequence[DisplacementMap | None] | None = None,
    names: Sequence[str] | None = None,
    root: str = "/meshfit",
) -> Path:
    """Write the patches to a USD layer (``.usda`` text or ``.usd`` / ``.usdc`` binary).

    Parameters
    ----------
    path : str or path
        Output layer (written atomically).
    surfaces : BSplineSurface or sequence of them
    displacements : DisplacementMap or sequence of (DisplacementMap or None), optional
        Each map is written as OpenEXR float32 beside the layer, named
        ``<layer stem>.<patch name>.<kind>.exr``, and referenced from the patch prim.
    names : sequence of str, optional
        Prim names; default ``patch_0, ...``.
    root : str
        Path of the ``Xform`` holding the patches (default ``/meshfit``).

    Returns
    -------
    Path

    Notes
    -----
    Each ``NurbsPatch`` has ``uOrder = vOrder = 4``, ``uVertexCount = mu``,
    ``vVertexCount = mv``, the full clamped knot vectors (``mu + 4``, ``mv + 4`` values),
    ``uRange = vRange = (0, 1)`` and ``points`` in USD's order (u varies fastest:
    ``points[j * mu + i] = P[i, j]``). ``points`` is ``point3f[]`` (float32); the float64
    control points are kept as ``meshfit:controlPoints`` (``point3d[]``, same order). A map is
    referenced by ``meshfit:displacement`` (asset, relative path), with
    ``meshfit:displacementKind`` and ``meshfit:displacementFrame`` (the frame of
    :mod:`meshfit.displacement`); the texel ``[i, j]`` of the image sits at ``(u, v) =
    (i / (h - 1), j / (w - 1))``.
    """
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

    surfaces = as_surfaces(surfaces)
    names = as_names(names, len(surfaces))
    disps = as_displacements(displacements, len(surfaces))
    if not Sdf.Path.IsValidPathString(root) or not root.startswith("/"):
        raise InputError(f"root must be an absolute prim path, got {root!r}")
    path = Path(path)
    if path.suffix not in (".usda", ".usd", ".usdc"):
        raise InputError(f"USD file must end in .usda, .usd or .usdc, got {path.name!r}")
    images: list[str | None] = []
    for name, d in zip(names, disps, strict=True):
        if d is None:
            images.append(None)
            continue
        img = f"{path.stem}.{name}.{d.kind}.exr"
        write_exr(d, path.parent / img)
        images.append(img)

    def write(tmp: str) -> None:
        stage = Usd.Stage.CreateNew(tmp)
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
        top = UsdGeom.Xform.Define(stage, root)
        stage.SetDefaultPrim(top.GetPrim())
        for name, s, img, d in zip(names, surfaces, images, disps, strict=True):
            mu, mv = s.shape
            pts = s.control_points.transpose(1, 0, 2).reshape(-1, 3)  # u fastest
            patch = UsdGeom.NurbsPatch.Define(stage, f"{root}/{name}")
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
            patch.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
            lo, hi = pts.min(axis=0), pts.max(axis=0)  # convex hull property
            patch.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())]))
            prim = patch.GetPrim()
            prim.CreateAttribute("meshfit:controlPoints", Sdf.ValueTypeNames.Point3dArray).Set(
                Vt.Vec3dArray.FromNumpy(pts)
            )
            if img is not None:
                prim.CreateAttribute("meshfit:displacement", Sdf.ValueTypeNames.Asset).Set(
                    Sdf.AssetPath(f"./{img}")
                )
                prim.CreateAttribute("meshfit:displacementKind", Sdf.ValueTypeNames.Token).Set(
                    d.kind
                )
                prim.CreateAttribute("meshfit:displacementFrame", Sdf.ValueTypeNames.String).Set(
                    FRAME
                )
        stage.GetRootLayer().Save()

    return atomic_write(path, write)
