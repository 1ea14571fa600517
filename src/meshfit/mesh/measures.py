"""Summary statistics of a mesh, as printed by ``meshfit info``."""

from __future__ import annotations

from typing import Any

import numpy as np

from meshfit.mesh.core import Mesh
from meshfit.mesh.io import RawMesh
from meshfit.mesh.validate import Finding

__all__ = ["Z_UP_RATIO", "mesh_statistics", "raw_statistics", "up_axis"]

#: a model is taken as z-up when it is this many times taller along z than along y (scanner
#: and CAD data); else y-up, the convention of PLY, OBJ and glTF scans
Z_UP_RATIO = 1.25


def up_axis(vertices) -> str:
    """``"z"`` where the model is more than `Z_UP_RATIO` times taller along z than along y,
    else ``"y"``: the axis the report's renders show upwards and the exports name as up
    when not told (files of scans rarely say which axis is up)."""
    V = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    if not len(V):
        return "y"
    ext = V.max(axis=0) - V.min(axis=0)
    return "z" if ext[2] > Z_UP_RATIO * ext[1] else "y"


def raw_statistics(raw: RawMesh, findings: list[Finding]) -> dict[str, Any]:
    """Counts and extents that need no valid topology (for meshes that fail validation)."""
    v, f = raw.vertices, raw.faces
    finite = v[np.isfinite(v).all(axis=1)] if v.size else v
    stats: dict[str, Any] = {
        "vertices": int(v.shape[0]),
        "faces": int(f.shape[0]),
        "vertex_colors": raw.vertex_colors is not None,
    }
    if finite.size:
        lo, hi = finite.min(axis=0), finite.max(axis=0)
        stats["bbox_min"] = lo.tolist()
        stats["bbox_max"] = hi.tolist()
        stats["bbox_diagonal"] = float(np.linalg.norm(hi - lo))
    stats["valid"] = not findings
    stats["findings"] = [x.to_dict() for x in findings]
    stats["notes"] = list(raw.notes)
    return stats


def mesh_statistics(mesh: Mesh) -> dict[str, Any]:
    """Statistics of a validated mesh.

    Returns
    -------
    dict
        vertices, faces, edges, components, boundary_loops (count and sizes),
        euler_characteristic, genus, closed, area, bbox, bbox_diagonal, edge length
        min / mean / max, face area min / max, vertex_colors.
    """
    el = mesh.edge_lengths
    loops = mesh.boundary_loops
    return {
        "vertices": mesh.n_vertices,
        "faces": mesh.n_faces,
        "edges": int(mesh.edges.shape[0]),
        "components": mesh.n_components,
        "boundary_loops": len(loops),
        "boundary_loop_sizes": sorted(int(x.size) for x in loops),
        "euler_characteristic": mesh.euler_characteristic,
        "genus": mesh.genus,
        "closed": mesh.is_closed,
        "area": mesh.area,
        "bbox_min": mesh.bbox[0].tolist(),
        "bbox_max": mesh.bbox[1].tolist(),
        "bbox_diagonal": mesh.bbox_diagonal,
        "edge_length_min": float(el.min()),
        "edge_length_mean": mesh.mean_edge_length,
        "edge_length_max": float(el.max()),
        "face_area_min": float(mesh.face_areas.min()),
        "face_area_max": float(mesh.face_areas.max()),
        "vertex_colors": mesh.vertex_colors is not None,
    }
