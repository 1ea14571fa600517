"""Rebuilding a fit from its (edited) maps: the surface follows the images (thesis 9.2.3)."""

from __future__ import annotations

import copy
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.mesh.locate import grid_tree
from meshfit.pipeline import measure
from meshfit.pipeline.stages import close_seams, displaced_grids
from meshfit.pipeline.store import mesh_hash

if TYPE_CHECKING:
    from meshfit.pipeline.result import FitResult


def _remeshed(mesh: Mesh, result: FitResult) -> Mesh:
    """The even remesh the fit worked on, made again from its input (the same mesh for the
    same input and crease angle)."""
    from meshfit.layout.even import even_remesh

    return even_remesh(mesh, result.options.crease_angle).mesh


def rebuild(result: FitResult, mesh: Mesh | None) -> FitResult:
    """``result`` with its maps' seams closed again and its seams and errors measured again
    (errors only where ``mesh``, the input, is given); see :meth:`FitResult.rebuild`."""
    from meshfit.stitch.layout import seam_metrics

    notes: list[str] = []
    match = result.options.map_shapes == "matched"
    maps = close_seams(result.network, result.surfaces, result.maps, match)
    displaced = displaced_grids(result.surfaces, maps)
    summary = copy.deepcopy(result.summary)
    diag = float(summary["mesh"]["bbox_diagonal"])
    seams = seam_metrics(result.layout, result.surfaces, displaced, diag)
    seams["continuity"] = result.options.continuity
    summary["seams"] = seams
    patches = []
    for p, m in zip(result.patches, maps, strict=True):
        row = dict(p.errors)
        row["map_shape"] = list(m.shape)
        row["displacement_max"] = float(np.abs(m.values).max() / diag)
        patches.append(replace(p, displacement=m, errors=row))
    if mesh is not None:
        if mesh_hash(mesh) != summary["mesh"]["sha256"] and "remeshed" in summary["mesh"]:
            mesh = _remeshed(mesh, result)
        if mesh_hash(mesh) != summary["mesh"]["sha256"]:
            raise InputError("rebuild: the mesh given is not the fit's input (its hash differs)")
        Vd, Fd = measure.soup(displaced)
        tree = grid_tree(Vd, Fd, [g.shape[:2] for g in displaced])
        fig, _, from_input = measure.error_figures(mesh, Vd, Fd, tree)
        summary["errors"]["displaced"] = fig
        per = measure.per_patch_max(mesh, result.face_patch, from_input, len(patches))
        summary["errors"]["displaced_from_input_max_per_patch"] = [
            None if v is None else v / diag for v in per
        ]
        for k, v in enumerate(summary["errors"]["displaced_from_input_max_per_patch"]):
            patches[k].errors["input_distance_max"] = v
    else:
        summary["errors"]["displaced"] = None
        summary["errors"]["displaced_from_input_max_per_patch"] = [None] * len(patches)
        notes.append(
            "rebuilt from the maps without the input mesh: the displaced surface's errors "
            "were not measured again (give the mesh: meshfit rebuild --mesh PATH)"
        )
    summary["patches"] = [p.errors for p in patches]
    summary["notes"] = [*summary.get("notes", []), *notes]
    summary["rebuilt"] = True
    return replace(result, patches=patches, summary=summary, mesh=mesh or result.mesh)
