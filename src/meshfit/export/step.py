"""STEP export through OpenCASCADE: needs the optional extra ``meshfit[cad]`` (cadquery-ocp).

Every patch becomes one ``B_SPLINE_SURFACE_WITH_KNOTS`` (polynomial, degree 3 x 3, clamped
knots written as distinct values with multiplicities) bounded by its four iso-parameter edges,
in an ``ADVANCED_FACE``. By default the faces are sewn along their shared boundaries into one
shell, so a stitched network arrives in a CAD system as connected faces (a closed model as a
closed shell) rather than loose surfaces; each face keeps its patch name.

OpenCASCADE writes reals with 12 significant digits, so control points read back agree to
about 1e-12 of their magnitude (IGES, written by :mod:`meshfit.export.iges`, keeps 17).

References
----------
.. [1] ISO 10303-42, sec. 4.7.9 (b_spline_surface_with_knots); ISO 10303-214 (AP214, the
   schema written).
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from meshfit import tol
from meshfit.bspline import BSplineSurface
from meshfit.errors import ExportError, InputError
from meshfit.export._common import as_names, as_surfaces, atomic_write
from meshfit.export.units import unit

__all__ = ["export_step", "step_available", "step_surface", "surface_from_occ"]


def step_available() -> bool:
    """Whether OpenCASCADE (``OCP``, from cadquery-ocp) can be imported."""
    return importlib.util.find_spec("OCP") is not None


def _need_ocp() -> None:
    if not step_available():
        raise ExportError(
            "STEP export needs OpenCASCADE: pip install 'meshfit[cad]' (cadquery-ocp)"
        )


def _arrays():
    """OpenCASCADE's 1-D real / int and 2-D point arrays (cadquery-ocp 8 names them as
    ``collections`` templates, 7.x as ``TColStd`` / ``TColgp`` classes)."""
    try:
        from OCP.OCP.collections import Array1_double, Array1_int, Array2_gp_Pnt
    except ImportError:  # cadquery-ocp 7.x
        from OCP.TColgp import TColgp_Array2OfPnt as Array2_gp_Pnt
        from OCP.TColStd import TColStd_Array1OfInteger as Array1_int
        from OCP.TColStd import TColStd_Array1OfReal as Array1_double
    return Array1_double, Array1_int, Array2_gp_Pnt


def _knots(knots: np.ndarray):
    """Distinct knot values and their multiplicities as OpenCASCADE arrays."""
    Array1_double, Array1_int, _ = _arrays()
    values, mult = np.unique(np.asarray(knots, dtype=np.float64), return_counts=True)
    k = Array1_double(1, len(values))
    m = Array1_int(1, len(values))
    for a, (x, n) in enumerate(zip(values, mult, strict=True), start=1):
        k.SetValue(a, float(x))
        m.SetValue(a, int(n))
    return k, m


def step_surface(surface: BSplineSurface):
    """The patch as an OpenCASCADE ``Geom_BSplineSurface``.

    Parameters
    ----------
    surface : BSplineSurface
        Bicubic, clamped knots (Krishnamurthy 2000, sec. 4.3).

    Returns
    -------
    OCP.Geom.Geom_BSplineSurface
        Non-rational, degree 3 x 3; pole ``(i + 1, j + 1)`` is ``P[i, j]`` (i along u),
        knots as distinct values with multiplicities.
    """
    _need_ocp()
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt

    _, _, Array2_gp_Pnt = _arrays()
    P = surface.control_points
    mu, mv = surface.shape
    poles = Array2_gp_Pnt(1, mu, 1, mv)
    for i in range(mu):
        for j in range(mv):
            poles.SetValue(i + 1, j + 1, gp_Pnt(*(float(c) for c in P[i, j])))
    ku, mku = _knots(surface.knots_u)
    kv, mkv = _knots(surface.knots_v)
    return Geom_BSplineSurface(poles, ku, kv, mku, mkv, surface.degree, surface.degree)


@contextlib.contextmanager
def _quiet():
    """OpenCASCADE's default messenger prints transfer statistics to stdout; keep only
    failures while writing."""
    from OCP.Message import Message, Message_Gravity

    printers = list(Message.DefaultMessenger_s().Printers())
    levels = [p.GetTraceLevel() for p in printers]
    for p in printers:
        p.SetTraceLevel(Message_Gravity.Message_Fail)
    try:
        yield
    finally:
        for p, lvl in zip(printers, levels, strict=True):
            p.SetTraceLevel(lvl)


def _add(shapes, shape, name: str):
    """A top-level shape of the XCAF document, named."""
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name

    label = shapes.AddShape(shape, False)
    TDataStd_Name.Set_s(label, TCollection_ExtendedString(name))
    return label


def _contains(shell, face) -> bool:
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer

    ex = TopExp_Explorer(shell, TopAbs_FACE)
    while ex.More():
        if ex.Current().IsSame(face):
            return True
        ex.Next()
    return False


def surface_from_occ(surface) -> BSplineSurface:
    """A non-rational degree-3 OpenCASCADE ``Geom_BSplineSurface`` as a
    :class:`BSplineSurface` (the inverse of :func:`step_surface`).

    Parameters
    ----------
    surface : OCP.Geom.Geom_BSplineSurface

    Returns
    -------
    BSplineSurface
        Control points ``(mu, mv, 3)`` float64, knots expanded by their multiplicities
        (``(mu + 4,)`` and ``(mv + 4,)`` float64).

    Raises
    ------
    InputError
        When the surface is rational or not bicubic.
    """
    if surface.IsURational() or surface.IsVRational():
        raise InputError("a rational OpenCASCADE surface has no BSplineSurface equivalent")
    if (surface.UDegree(), surface.VDegree()) != (3, 3):
        raise InputError(
            f"BSplineSurface is bicubic, got degrees {surface.UDegree()} x {surface.VDegree()}"
        )

    def expanded(values, mults):
        return np.repeat(
            [values.Value(k) for k in range(values.Lower(), values.Upper() + 1)],
            [mults.Value(k) for k in range(mults.Lower(), mults.Upper() + 1)],
        )

    P = np.empty((surface.NbUPoles(), surface.NbVPoles(), 3))
    for i in range(P.shape[0]):
        for j in range(P.shape[1]):
            p = surface.Pole(i + 1, j + 1)
            P[i, j] = p.X(), p.Y(), p.Z()
    return BSplineSurface(
        P,
        expanded(surface.UKnots(), surface.UMultiplicities()),
        expanded(surface.VKnots(), surface.VMultiplicities()),
    )


def export_step(
    path: str | os.PathLike,
    surfaces: BSplineSurface | Sequence[BSplineSurface],
    *,
    names: Sequence[str] | None = None,
    units: str = "mm",
    sew: bool = True,
) -> Path:
    """Write the patches to a STEP (AP214) file.

    Parameters
    ----------
    path : str or path
        Output ``.step`` / ``.stp`` file (written atomically).
    surfaces : BSplineSurface or sequence of them
    names : sequence of str, optional
        Face names; default ``patch_0, ...``.
    units : str
        Length unit declared in the file, one of :data:`meshfit.export.units.UNITS`
        (``"mm"``, ``"cm"``, ``"m"``, ``"in"``, ``"ft"``, any case; default ``"mm"``): an SI
        unit, or inch and foot as conversion-based units over the millimetre; coordinates
        are written unchanged.
    sew : bool
        Sew the faces along shared boundaries (within ``tol.STITCH_MATCH`` of the network's
        bbox diagonal) into shells; False writes them as separate faces.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ExportError
        Without ``OCP`` (the message names the extra to install), or when OpenCASCADE
        fails to build a face or to write the file.
    InputError
        On bad surfaces, names, units or file suffix.
    """
    surfaces = as_surfaces(surfaces)
    names = as_names(names, len(surfaces))
    path = Path(path)
    if path.suffix.lower() not in (".step", ".stp"):
        raise InputError(f"a STEP file ends in .step or .stp, got {path.name!r}")
    u = unit(units)
    _need_ocp()
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.Interface import Interface_Static
    from OCP.STEPCAFControl import STEPCAFControl_Writer
    from OCP.STEPControl import STEPControl_AsIs
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDocStd import TDocStd_Document
    from OCP.XCAFApp import XCAFApp_Application
    from OCP.XCAFDoc import XCAFDoc_DocumentTool

    cp = np.concatenate([s.control_points.reshape(-1, 3) for s in surfaces])
    diag = float(np.linalg.norm(np.ptp(cp, axis=0))) or 1.0
    faces = _occ_faces(surfaces, names, diag)

    app = XCAFApp_Application.GetApplication_s()
    doc = TDocStd_Document(TCollection_ExtendedString("MDTV-XCAF"))
    app.InitDocument(doc)
    shapes = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    if sew and len(faces) > 1:
        _add_sewn(shapes, faces, names, tol.STITCH_MATCH * diag)
    else:
        for name, f in zip(names, faces, strict=True):
            _add(shapes, f, name)

    # the writer's constructor registers (and resets) the static parameters: set them after
    writer = STEPCAFControl_Writer()
    # the document's coordinates are in the declared unit, so nothing is rescaled
    XCAFDoc_DocumentTool.SetLengthUnit_s(doc, u.meters)
    Interface_Static.SetCVal_s("write.step.unit", u.step_name)
    Interface_Static.SetIVal_s("write.stepcaf.subshapes.name", 1)
    writer.SetNameMode(True)

    def write(tmp: str) -> None:
        if writer.Write(tmp) != IFSelect_RetDone:
            raise ExportError(f"OpenCASCADE could not write {path}")

    with _quiet():
        if not writer.Transfer(doc, STEPControl_AsIs):
            raise ExportError("OpenCASCADE could not translate the patches to STEP")
        return atomic_write(path, write)


def _occ_faces(surfaces: list[BSplineSurface], names: list[str], diag: float) -> list:
    """One OpenCASCADE face per surface (ExportError naming the one it cannot build)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace

    faces = []
    for name, s in zip(names, surfaces, strict=True):
        mk = BRepBuilderAPI_MakeFace(step_surface(s), tol.ON_SURFACE * diag)
        if not mk.IsDone():
            raise ExportError(f"OpenCASCADE could not build a face from {name}")
        faces.append(mk.Face())
    return faces


def _add_sewn(shapes, faces: list, names: list[str], tolerance: float) -> None:
    """Sew ``faces`` within ``tolerance`` and add one product per connected shell to the
    document's ``shapes``: a shell of one face named as that face, a larger one
    ``shell_<k>`` with its faces named as sub-shapes; faces in no shell on their own."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Sewing
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name
    from OCP.TopAbs import TopAbs_SHELL
    from OCP.TopExp import TopExp_Explorer

    sewing = BRepBuilderAPI_Sewing(tolerance)
    for f in faces:
        sewing.Add(f)
    sewing.Perform()
    sewn = [sewing.Modified(f) if sewing.IsModified(f) else f for f in faces]
    # one product per connected shell, its faces named as sub-shapes
    unnamed = list(range(len(faces)))
    n_shells = 0
    ex = TopExp_Explorer(sewing.SewedShape(), TopAbs_SHELL)
    while ex.More():
        shell = ex.Current()
        inside = [k for k in unnamed if _contains(shell, sewn[k])]
        if len(inside) == 1:
            _add(shapes, shell, names[inside[0]])
        elif inside:
            root = _add(shapes, shell, f"shell_{n_shells}")
            n_shells += 1
            for k in inside:
                sub = shapes.AddSubShape(root, sewn[k])
                if sub.IsNull():
                    raise ExportError(f"sewn face of {names[k]} is not in its shell")
                TDataStd_Name.Set_s(sub, TCollection_ExtendedString(names[k]))
        unnamed = [k for k in unnamed if k not in inside]
        ex.Next()
    for k in unnamed:
        _add(shapes, sewn[k], names[k])
