"""The per-patch spring-mesh task, runnable on a thread or in another process."""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from meshfit.mesh import Mesh
from meshfit.springs import SpringOptions

__all__ = ["patch_payload", "spring_patch", "spring_task"]


def spring_patch(patch, options: SpringOptions | None = None):
    """Spring mesh of one patch: ``(xyz (nu, nv, 3) float64, metrics dict)``: the final
    level's :func:`meshfit.springs.spring_metrics` (without fidelity) and every level's
    folded cells (the same test, by the fold kernel alone). ``options`` default: the fit's
    (``FitOptions().springs``)."""
    from meshfit.layout.patch import shape_figures
    from meshfit.springs import resample_patch, spring_metrics
    from meshfit.springs.relax import grid_folds

    t = time.perf_counter()
    if options is None:
        from meshfit.pipeline.options import FitOptions

        options = FitOptions().springs
    res = resample_patch(patch, replace(options, metrics=False))
    m = patch.mesh
    fin = spring_metrics(m, res.final, fidelity=False)
    folds = [
        int(grid_folds(m, s.points.face, s.points.bary, *s.shape).sum()) for s in res.levels[:-1]
    ]
    return res.final.xyz.copy(), {
        "shape": list(res.final.shape),
        "levels": len(res.levels),
        "folded": int(fin["folded"]),
        "folded_any_level": int(sum(folds) + fin["folded"]),
        "arc_cv_max": float(fin["arc_cv_max"]),
        "aspect_max": float(fin["aspect_max"]),
        "area_ratio": float(fin["area_ratio"]),
        "sweeps": [int(s) for s in res.sweeps],
        "rescued": bool(res.rescued),
        "evened": bool(res.evened),
        "finer": int(res.finer),
        "seconds": round(time.perf_counter() - t, 4),
        "patch_faces": int(patch.mesh.n_faces),
        **shape_figures(patch),
    }


def patch_payload(patch) -> dict[str, Any]:
    """A patch as plain arrays (picklable, no cached mesh state) for a remote task."""
    return {
        "index": int(patch.index),
        "vertices": np.asarray(patch.mesh.vertices),
        "faces": np.asarray(patch.mesh.faces),
        "corners": np.asarray(patch.corners),
        "sides": [np.asarray(x) for x in patch.sides],
        "face_parent": np.asarray(patch.face_parent),
        "source_face": np.asarray(patch.vertex_source.face),
        "source_bary": np.asarray(patch.vertex_source.bary),
        "features": [
            (np.asarray(f.points.face), np.asarray(f.points.bary)) for f in patch.features
        ],
        "feature_sides": [tuple(int(x) for x in fs) for fs in patch.feature_sides],
    }


def spring_task(item) -> tuple[NDArray[np.float64], dict]:
    """Remote body of one spring-mesh task: ``item = (patch_payload(p), SpringOptions)``."""
    from meshfit.layout import Patch
    from meshfit.types import SurfaceCurve, SurfacePoints

    d, options = item
    patch = Patch(
        d["index"],
        Mesh(d["vertices"], d["faces"]),
        d["corners"],
        tuple(d["sides"]),
        d["face_parent"],
        SurfacePoints(d["source_face"], d["source_bary"]),
        tuple(SurfaceCurve(SurfacePoints(f, b), kind="feature") for f, b in d["features"]),
        tuple(d["feature_sides"]),
    )
    return spring_patch(patch, options)
