"""Shared helpers of the UI tests: click rays and a scripted painting session on spot."""

from __future__ import annotations

from functools import cache

import numpy as np

from meshfit.layout import load_layout
from meshfit.mesh import Mesh
from meshfit.ui.state import Session

from ..conftest import ROOT, real_mesh

SPOT_LAYOUT = ROOT / "examples" / "layouts" / "spot.json"
#: a patch of the spot example layout whose sides painting with a few picks reproduces
PAINT_PATCH = 4


@cache
def spot_layout():
    return load_layout(SPOT_LAYOUT, real_mesh("spot"), check_topology=False)


def click_ray(mesh: Mesh, xyz) -> tuple[np.ndarray, np.ndarray]:
    """A camera ray that meets the surface at ``xyz`` from outside along its face normal."""
    x = np.asarray(xyz, dtype=np.float64)
    f = int(mesh.closest_points(x[None]).points.face[0])
    n = mesh.face_normals[f]
    return x + n * 0.3 * mesh.bbox_diagonal, -n


def side_picks(mesh: Mesh, patch: int = PAINT_PATCH) -> list[np.ndarray]:
    """Per side of a patch of the example layout: 3-D picks from its first corner to its
    last, skipping picks next to other corners (they would snap)."""
    layout = spot_layout()
    corners = mesh.xyz(layout.corners)
    out = []
    for k in range(4):
        c = layout.curves[int(layout.patch_curves[patch, k])].points
        x = mesh.xyz(c)
        if layout.patch_reversed[patch, k]:
            x = x[::-1]
        picks = [x[0]]
        for q in np.arange(1, 8) / 8:
            p = x[int(q * (len(x) - 1))]
            if np.linalg.norm(corners - p, axis=1).min() >= 0.03 * mesh.bbox_diagonal:
                picks.append(p)
        picks.append(x[-1])
        out.append(np.asarray(picks))
    return out


def paint_quad(session: Session, patch: int = PAINT_PATCH) -> list[str]:
    """Paint the four sides of a patch by clicks; returns what each click did."""
    mesh = session.mesh
    said = []
    for picks in side_picks(mesh, patch):
        for x in picks:
            said.append(session.click(*click_ray(mesh, x)))
        if said[-1] != "finished":
            session.finish_curve()
            said.append("finish")
    return said
