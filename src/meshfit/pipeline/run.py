"""The front door of the fit: :func:`fit`, in memory or into a folder."""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

from meshfit._threads import n_workers
from meshfit._version import __version__
from meshfit.errors import InputError
from meshfit.mesh import Mesh
from meshfit.pipeline.cluster import patch_tasks, resolve_cluster
from meshfit.pipeline.notes import quality_notes
from meshfit.pipeline.options import FitOptions
from meshfit.pipeline.outputs import (
    CACHE,
    MANIFEST,
    edited_maps,
    output_stem,
    planned_files,
    read_manifest,
    refuse_foreign,
    remove_stale,
    write_manifest,
)
from meshfit.pipeline.prepare import Prepared
from meshfit.pipeline.result import FIT_FILES, FitResult, PatchFit
from meshfit.pipeline.runner import Context, Progress, Runner, Stage
from meshfit.pipeline.stages import STAGES, Report, Validate, fit_stages
from meshfit.pipeline.store import PIPELINE_FORMAT, write_json

__all__ = ["fit"]


def fit(
    mesh: Mesh | str | os.PathLike | Prepared,
    layout: Any = "auto",
    *,
    options: FitOptions | None = None,
    progress: Progress | None = None,
    out: str | os.PathLike | None = None,
    resume: bool = False,
    patch_map: Callable | None = None,
    cluster: Any = "auto",
) -> FitResult:
    """Fit B-spline patches with displacement maps to a mesh.

    Parameters
    ----------
    mesh : Mesh, path or Prepared
        The input; a path is loaded with :func:`meshfit.load_mesh` (harmless defects
        repaired, with a note). A folder of :func:`meshfit.pipeline.prepare_out_of_core`
        (``meshfit prepare``), or its result, is fitted out of core with the layout it was
        prepared with (:mod:`meshfit.pipeline.prepared_stages`).
    layout : Layout, path or ``"auto"``
        The patch layout: an object, a layout file, or the automatic layout (default), which
        takes any topology.
    options : FitOptions, keyword-only, optional
        Default ``FitOptions()``.
    progress : callable(stage, done, total), keyword-only, optional
        Called as each stage advances.
    out : path, keyword-only, optional
        Output folder: the fit is saved there (:meth:`FitResult.save`), the options' formats
        exported and the report written, and every stage's result is kept in
        ``out/.meshfit`` for ``resume``. Default None: in memory only.
    resume : bool, keyword-only
        With ``out``: re-use the stage files whose content key matches (default False).
    patch_map : callable(fn, items) -> list, keyword-only, optional
        Runs the per-patch spring-mesh tasks elsewhere (Dask, :mod:`meshfit.batch`): called
        with :func:`meshfit.pipeline.spring_task` and one picklable item per patch.
    cluster : "auto", None, int, str, ClusterOptions or distributed.Client, keyword-only
        Where each patch's spring mesh and displacement map are made
        (:mod:`meshfit.pipeline.cluster`): None, threads of this process (``options.workers``
        of them); an int N, a LocalCluster of N worker processes on 127.0.0.1; a str, the
        address of a running Dask scheduler (its workers must read ``out``); a
        :class:`~meshfit.pipeline.cluster.ClusterOptions`, with a memory limit and retries;
        a client, its cluster (left open). ``"auto"`` (default): threads, or a LocalCluster
        for meshes of at least :data:`meshfit.pipeline.cluster.LOCAL_CLUSTER_FACES` faces.
        The result is the same bytes either way. With ``patch_map`` (the spring meshes sent
        elsewhere) the rest runs on threads: ``cluster`` must be "auto" or None.

    Returns
    -------
    FitResult

    Raises
    ------
    meshfit.errors.MeshfitError
        Bad input (mesh, layout, options); a scheduler that cannot be reached.

    References
    ----------
    .. [1] Krishnamurthy 2000, sec. 1.3 (the fitting pipeline), ch. 5 (spring meshes), ch. 6
       (B-spline fitting), ch. 7 (displacement maps), sec. 8.1 (continuity).
    """
    options = options or FitOptions()
    from meshfit.pipeline.prepare import is_prepared, open_prepared

    if isinstance(mesh, (str, os.PathLike)) and is_prepared(mesh):
        mesh = open_prepared(mesh)  # (a bad folder is refused before any work)
    if patch_map is not None:
        if cluster is not None and not (isinstance(cluster, str) and cluster == "auto"):
            raise InputError("give patch_map or cluster, not both")
        cluster = None
    resolve_cluster(cluster, 0)  # a wrong value is refused before any work
    folder = None if out is None else Path(out)
    made = _made_folders(folder)
    try:
        return _fit(mesh, layout, options, folder, resume, progress, patch_map, cluster)
    except BaseException:
        for d in made:  # a refused or failed run leaves no empty folders of its own
            with contextlib.suppress(OSError):
                d.rmdir()  # (only an empty one goes)
        raise


def _made_folders(folder: Path | None) -> list[Path]:
    """Create ``folder`` and its stage cache; return the folders this call created,
    innermost first."""
    if folder is None:
        return []
    todo = [p for p in (folder / CACHE, folder, *folder.parents) if not p.exists()]
    (folder / CACHE).mkdir(parents=True, exist_ok=True)
    return todo


def _fit(
    mesh,
    layout,
    options: FitOptions,
    folder: Path | None,
    resume: bool,
    progress,
    patch_map,
    cluster,
):
    t_all = time.perf_counter()
    ctx = Context(options, n_workers(options.workers), progress)
    ctx["input"] = mesh
    automatic = layout is None or (isinstance(layout, str) and layout == "auto")
    prepared = isinstance(mesh, Prepared)
    validate: Stage
    report: type[Report]
    if prepared:
        from meshfit.pipeline.prepared_stages import (
            ReportPrepared,
            ValidatePrepared,
            prepared_stages,
        )

        validate, report = ValidatePrepared(), ReportPrepared
        stages = prepared_stages(layout, patch_map, folder)  # (refuses another layout)
    else:
        validate = Validate(automatic, None if automatic else _fingerprint(layout))
        stages, report = fit_stages(layout, patch_map, folder), Report
    listed = {} if folder is None else read_manifest(folder)  # what the last run wrote
    if folder is not None:  # before any work: the input is never overwritten
        if isinstance(mesh, (str, os.PathLike)):
            name: str | None = Path(mesh).name
        else:
            name = getattr(mesh, "name", None)
        if prepared:
            _refuse_inside(folder, mesh.folder)
        refuse_foreign(folder, planned_files(output_stem(name), options.formats))
    cache = None if folder is None else folder / CACHE
    runner = Runner(cache, resume)
    auto = isinstance(cluster, str) and cluster == "auto"  # (decided by the mesh's size)
    # a cluster asked for is reached (or started, on a thread) before any work
    ctx.tasks = None if auto else patch_tasks(cluster, 0, cache)
    try:
        runner.run([validate], ctx)
        if auto:
            ctx.tasks = patch_tasks(cluster, ctx["mesh_info"]["faces"], cache)
        runner.run(stages, ctx)
        workers_peak = None if ctx.tasks is None else ctx.tasks.workers_peak_rss()
    finally:
        if ctx.tasks is not None:
            ctx.tasks.close()
            ctx.tasks = None
    ctx.info = {k: ctx.info[k] for k in STAGES if k in ctx.info}  # the stage order
    summary = _summary(ctx)
    if folder is not None and options.report:
        ctx["summary"] = summary
        runner.run([report(folder)], ctx)
        summary["outputs"]["report"] = ["report.html"]
    summary["stages"] = ctx.info
    summary["seconds_total"] = round(time.perf_counter() - t_all, 4)
    summary["memory"] = _memory(workers_peak)
    summary["work_done"] = [s for s, i in ctx.info.items() if not i["cached"] and s != "validate"]
    result = _result(ctx, summary)
    if folder is not None:
        result._write(folder)  # the manifest follows, once, with every file
        if options.report:
            from meshfit.report import write_html

            write_html(folder, summary)  # its timing table includes the report stage
        images = ctx["report"]["images"] if options.report else []
        _manifest(folder, result.summary, images, listed)
    return result


def _refuse_inside(out: Path, prepared: Path) -> None:
    """InputError where the output folder is the prepared folder or inside it (a fit never
    writes among the files it reads)."""
    a, b = out.resolve(), prepared.resolve()
    if a == b or b in a.parents:
        raise InputError(f"{out}: the output folder is inside the prepared folder {prepared}")


def _fingerprint(layout: Any) -> str | None:
    """The fingerprint of the mesh a given layout (object or file) was made for; None
    where it cannot be read (the layout stage then says why)."""
    from meshfit._jsonio import read_json_file
    from meshfit.errors import MeshfitError

    if hasattr(layout, "fingerprint"):
        return str(layout.fingerprint)
    try:
        doc = read_json_file(Path(layout))
    except (MeshfitError, OSError, TypeError):
        return None
    mesh = doc.get("mesh") if isinstance(doc, dict) else None
    fp = mesh.get("sha256") if isinstance(mesh, dict) else None
    return fp if isinstance(fp, str) else None


def _memory(workers_peak: int | None) -> dict[str, int | None]:
    """Peak resident memory in bytes: this process's (over its lifetime so far), the
    workers' summed when the per-patch work ran as tasks, and the two together."""
    from meshfit._malloc import peak_rss

    own = peak_rss()
    total = None if own is None else own + (workers_peak or 0)
    return {"peak_rss_process": own, "peak_rss_workers": workers_peak, "peak_rss_total": total}


def _summary(ctx: Context) -> dict[str, Any]:
    info, diag = ctx["mesh_info"], ctx["diag"]
    lay, maps, errors = ctx["layout"], ctx["maps"], ctx["errors"]
    n = int(lay.n_patches)
    per_patch = errors.get("displaced_from_input_max_per_patch", [None] * n)
    rows = []
    for p in range(n):
        rows.append(
            {
                "patch": p,
                **ctx["spring_info"][p],
                **ctx["fit_info"][p],
                "map_shape": list(maps[p].shape),
                "input_distance_max": per_patch[p],
                "displacement_max": float(abs(maps[p].values).max() / diag),
                "crease_sides": int(lay.creases[lay.patch_curves[p]].sum()),
            }
        )
    auto_seed = ctx.options.layout_seed if ctx["layout_route"] == "sphere" else None
    ctx.notes.extend(quality_notes(rows, auto_seed))
    return {
        "meshfit_fit": PIPELINE_FORMAT,
        "version": __version__,
        "mesh": {
            **info,
            "bbox_diagonal": diag,
            "sha256": ctx["mesh_hash"],
            **({"remeshed": ctx["remesh"]} if "remesh" in ctx else {}),
        },
        "options": asdict(ctx.options),
        "layout": {"source": ctx["layout_source"], **ctx["layout_report"]},
        "patches_total": n,
        "control_classes": ctx["control_classes"],
        "stages": ctx.info,
        "patches": rows,
        "errors": errors,
        "seams": ctx["seams"],
        "notes": ctx.notes,
        "outputs": dict(ctx["outputs"]) if "outputs" in ctx else {},
    }


def _result(ctx: Context, summary: dict[str, Any]) -> FitResult:
    import json

    from meshfit.pipeline.store import json_default

    # the summary as plain JSON data (tuples as lists), as a saved one reads back
    summary = json.loads(json.dumps(summary, default=json_default))
    patches = [
        PatchFit(p, g, s, d, row)
        for p, (g, s, d, row) in enumerate(
            zip(ctx["grids"], ctx["surfaces"], ctx["maps"], summary["patches"], strict=True)
        )
    ]
    return FitResult(
        patches,
        ctx["layout"],
        ctx["network"],
        summary,
        ctx.options,
        mesh=ctx.values.get("mesh"),
        face_patch=ctx["face_patch"],
        spline_distance=ctx["spline_distance"],
    )


def _manifest(folder: Path, summary: dict[str, Any], images: list[str], listed) -> None:
    """The manifest of a finished run: the fit's files, the exports, the report and its
    images (maps the user edited keep their old entries). Files the last run's manifest
    (``listed``) named that this run did not write are removed, and a note says so."""
    files = [*FIT_FILES, *(f for fs in summary["outputs"].values() for f in fs), *images]
    gone = remove_stale(folder, listed, [*files, MANIFEST])
    if gone:
        shown = ", ".join(gone[:5]) + (" ..." if len(gone) > 5 else "")
        summary.setdefault("notes", []).append(
            f"{len(gone)} file(s) of the previous run that this run did not write were "
            f"removed ({shown})"
        )
        write_json(folder / "summary.json", summary)
    write_manifest(folder, sorted(set(files)), keep=edited_maps(folder))
