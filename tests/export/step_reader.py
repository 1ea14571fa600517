"""Reads a STEP file back through OpenCASCADE: named B-spline faces and the shells they form."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class StepFace:
    name: str
    control_points: np.ndarray  # (mu, mv, 3)
    knots_u: np.ndarray  # expanded (with multiplicities)
    knots_v: np.ndarray
    degree: tuple[int, int]
    rational: bool


def _expanded(values, mults) -> np.ndarray:
    return np.repeat(
        [values.Value(k) for k in range(values.Lower(), values.Upper() + 1)],
        [mults.Value(k) for k in range(mults.Lower(), mults.Upper() + 1)],
    )


def read_step(path, metres_per_unit: float = 1e-3) -> tuple[list[StepFace], dict]:
    """Faces (in file order) with their names, in the length unit given (millimetres by
    default), and the topology: shell count, closed shells, free edges (edges used by one
    face only)."""
    from OCP.BRep import BRep_Tool
    from OCP.GeomAbs import GeomAbs_BSplineSurface
    from OCP.GeomAdaptor import GeomAdaptor_Surface
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.Interface import Interface_Static
    from OCP.STEPCAFControl import STEPCAFControl_Reader
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name
    from OCP.TDocStd import TDocStd_Document
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_SHELL
    from OCP.TopExp import TopExp, TopExp_Explorer
    from OCP.TopoDS import TopoDS
    from OCP.XCAFApp import XCAFApp_Application
    from OCP.XCAFDoc import XCAFDoc_DocumentTool

    try:
        from OCP.OCP.collections import (
            IndexedDataMap_TopoDS_Shape_List_TopoDS_Shape_TopTools_ShapeMapHasher as EdgeFaces,
        )
        from OCP.OCP.collections import Sequence_TDF_Label as TDF_LabelSequence
    except ImportError:  # cadquery-ocp 7.x
        from OCP.TDF import TDF_LabelSequence
        from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape as EdgeFaces

    app = XCAFApp_Application.GetApplication_s()
    doc = TDocStd_Document(TCollection_ExtendedString("MDTV-XCAF"))
    app.InitDocument(doc)
    XCAFDoc_DocumentTool.SetLengthUnit_s(doc, metres_per_unit)
    reader = STEPCAFControl_Reader()  # registers the static parameters: set them after
    Interface_Static.SetIVal_s("read.stepcaf.subshapes.name", 1)
    reader.SetNameMode(True)
    assert reader.ReadFile(str(path)) == IFSelect_RetDone
    assert reader.Transfer(doc)
    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    roots = TDF_LabelSequence()
    tool.GetFreeShapes(roots)

    def name_of(label) -> str:
        attr = TDataStd_Name()
        if label.FindAttribute(TDataStd_Name.GetID_s(), attr):
            return attr.Get().ToExtString()
        return ""

    faces: list[StepFace] = []
    shells = closed = free = 0
    for r in range(1, roots.Length() + 1):
        root = roots.Value(r)
        shape = tool.GetShape_s(root)
        subs = TDF_LabelSequence()
        tool.GetSubShapes_s(root, subs)
        named = [
            (tool.GetShape_s(subs.Value(k)), name_of(subs.Value(k)))
            for k in range(1, subs.Length() + 1)
        ]
        ex = TopExp_Explorer(shape, TopAbs_FACE)
        while ex.More():
            face = TopoDS.Face(ex.Current())
            ad = GeomAdaptor_Surface(BRep_Tool.Surface_s(face))
            assert ad.GetType() == GeomAbs_BSplineSurface
            b = ad.BSpline()
            P = np.array(
                [
                    [
                        [b.Pole(i, j).X(), b.Pole(i, j).Y(), b.Pole(i, j).Z()]
                        for j in range(1, b.NbVPoles() + 1)
                    ]
                    for i in range(1, b.NbUPoles() + 1)
                ]
            )
            own = next((n for sh, n in named if sh.IsSame(face)), None)
            faces.append(
                StepFace(
                    name=own if own is not None else name_of(root),
                    control_points=P,
                    knots_u=_expanded(b.UKnots(), b.UMultiplicities()),
                    knots_v=_expanded(b.VKnots(), b.VMultiplicities()),
                    degree=(b.UDegree(), b.VDegree()),
                    rational=bool(b.IsURational() or b.IsVRational()),
                )
            )
            ex.Next()
        ex = TopExp_Explorer(shape, TopAbs_SHELL)
        while ex.More():
            shells += 1
            closed += bool(BRep_Tool.IsClosed_s(ex.Current()))
            ex.Next()
        edge_faces = EdgeFaces()
        TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, edge_faces)
        for k in range(1, edge_faces.Extent() + 1):
            free += edge_faces.FindFromIndex(k).Size() == 1
    return faces, {"shells": shells, "closed_shells": closed, "free_edges": free}
