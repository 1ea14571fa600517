"""The whole fit: layout -> cut -> spring meshes -> B-spline fit -> displacement -> stitch ->
errors -> exports -> report, as a short list of stages run by one runner.

:func:`fit` is the front door (in memory, or into a folder with a stage cache for
``resume``); it returns a :class:`FitResult`, which saves, loads (:func:`load_fit`),
exports and rebuilds from edited maps. The package holds one idea per module:
:mod:`.options` (what the user chooses, grouped by stage), :mod:`.runner` (content keys,
cache, progress), :mod:`.stages` (the stage objects), :mod:`.measure` (errors against the
input), :mod:`.notes`, :mod:`.springs` (the per-patch task), :mod:`.cluster` (the per-patch
work of one fit as Dask tasks), :mod:`.prepare` and :mod:`.prepared_stages` (a scan too
large to hold whole, prepared and fitted out of core), :mod:`.outputs` (exports and the
manifest), :mod:`.result` and :mod:`.rebuild`. Continuity lives in :mod:`meshfit.stitch`.

Stitching
---------
With either continuity the shared boundaries are made identical at the fitting step: every
layout curve gets one cubic B-spline curve, least-squares fitted to the spring-mesh side that
follows it, and every patch using the curve pins its boundary row of control points to it
(Krishnamurthy 2000, sec. 8.1.3; :func:`meshfit.stitch.layout.boundary_pins`). Control
counts are unified across curves (:func:`meshfit.stitch.control_classes`). ``"G1"`` then
makes the network G1 with :func:`meshfit.stitch.stitch_surfaces`, and ``"auto"`` (the
default) does so across every curve but the layout's creases, which stay C0; the seams of
the maps are closed with :func:`meshfit.stitch.stitch_displacements`. The seams are measured
either way (:func:`meshfit.stitch.layout.seam_metrics`, ``summary["seams"]``).
"""

from meshfit.pipeline.cluster import ClusterOptions
from meshfit.pipeline.options import (
    FORMATS,
    FitOptions,
    LayoutOptions,
    MapOptions,
    OutputOptions,
    SplineOptions,
)
from meshfit.pipeline.prepare import Prepared, open_prepared, prepare_out_of_core
from meshfit.pipeline.result import FitResult, PatchFit, load_fit
from meshfit.pipeline.run import fit
from meshfit.pipeline.springs import patch_payload, spring_patch, spring_task
from meshfit.pipeline.stages import STAGES
from meshfit.pipeline.store import mesh_hash
from meshfit.springs import SpringOptions

__all__ = [
    "FORMATS",
    "STAGES",
    "ClusterOptions",
    "FitOptions",
    "FitResult",
    "LayoutOptions",
    "MapOptions",
    "OutputOptions",
    "PatchFit",
    "Prepared",
    "SplineOptions",
    "SpringOptions",
    "fit",
    "load_fit",
    "mesh_hash",
    "open_prepared",
    "patch_payload",
    "prepare_out_of_core",
    "spring_patch",
    "spring_task",
]
