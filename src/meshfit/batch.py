"""Batch fits over many meshes on dask.distributed.

One task per mesh (and, for large meshes, one task per patch for the spring meshes), each
running :func:`meshfit.fit` into ``<out>/<mesh stem>/``
with ``resume=True``. A LocalCluster on 127.0.0.1 is started by default; any scheduler address
reaches a real cluster. Robustness:

- a worker killed mid-run: the scheduler re-runs its tasks elsewhere (``retries``); stage
  files are written atomically and keyed by content, so the re-run picks up the finished
  stages and the final outputs are the same bytes as an undisturbed run (only the timings in
  ``summary.json`` and ``report.html`` differ);
- a malformed or crashing mesh fails alone: its error is recorded in ``batch.json``;
- re-running skips meshes whose ``done.json`` matches the input file and the options.
"""

from __future__ import annotations

import glob as _glob
import hashlib
import json
import os
import time
import traceback
from dataclasses import asdict
from pathlib import Path
from typing import Any

from meshfit._atomic import write_text
from meshfit._jsonio import read_json_file
from meshfit.errors import InputError, MeshfitError

__all__ = ["fit_one", "run_batch"]

#: version of ``batch.json`` and ``done.json``
BATCH_FORMAT = 1


def _job_key(path: Path, layout: str | None, options: dict[str, Any]) -> str:
    h = hashlib.sha256()
    h.update(path.read_bytes())
    lay = layout or "auto"
    if lay != "auto" and Path(lay).is_file():
        h.update(Path(lay).read_bytes())
    else:
        h.update(str(lay).encode())
    h.update(json.dumps(options, sort_keys=True, default=list).encode())
    return h.hexdigest()


def _task_key(path: Path, folder: Path, key: str, patch_tasks_above: int | None) -> str:
    """Dask key of a mesh's fit task: the job and where it writes (a scheduler returns the
    result of a task it still holds under the same key instead of running it again)."""
    h = hashlib.sha256(key.encode())
    h.update(str(Path(folder).resolve()).encode())
    h.update(repr(patch_tasks_above).encode())
    return f"meshfit-fit-{path.stem}-{h.hexdigest()[:16]}"


def _remove_leftovers(folder: Path) -> None:
    """Delete temporary files (``.name.*``) a killed attempt left in a mesh's output folder."""
    for p in folder.rglob(".*"):
        if p.is_file():
            p.unlink(missing_ok=True)


def _dask_patch_map(fn, items: list) -> list:
    """Run per-patch tasks on the cluster from inside a task (the task secedes meanwhile)."""
    from distributed import worker_client

    with worker_client() as client:
        futures = client.map(fn, items, pure=False, retries=3)
        return client.gather(futures)


def fit_one(
    path: str,
    out: str,
    layout: str | None,
    options: dict[str, Any],
    key: str,
    patch_tasks_above: int | None = None,
) -> dict:
    """Fit one mesh file into ``out`` (the task body; runs on a worker).

    Meshes with at least ``patch_tasks_above`` faces run their spring meshes as one Dask task
    per patch (when called on a worker). Returns a record ``{"status": "done" | "failed",
    ...}``; never raises for bad input.
    """
    from meshfit.mesh import load_mesh
    from meshfit.pipeline import FitOptions, fit

    t0 = time.perf_counter()
    folder = Path(out)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        _remove_leftovers(folder)
        opts = FitOptions.from_json(options)
        mesh = load_mesh(path, repair=True)
        patch_map = None
        if patch_tasks_above is not None and mesh.n_faces >= patch_tasks_above:
            from distributed import get_worker

            try:
                get_worker()
                patch_map = _dask_patch_map
            except ValueError:  # not on a worker: threads
                patch_map = None
        summary = fit(  # (a task never starts a cluster of its own)
            mesh,
            layout or "auto",
            options=opts,
            out=folder,
            resume=True,
            patch_map=patch_map,
            cluster=None,
        ).summary
    except MeshfitError as exc:
        return {"status": "failed", "error": f"{type(exc).__name__}: {exc}".splitlines()[0]}
    except Exception as exc:  # a crash in one mesh must not stop the batch
        tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
        return {"status": "failed", "error": f"crash: {tb}"}
    record = {
        "status": "done",
        "key": key,
        "meshfit_batch": BATCH_FORMAT,
        "patches": summary["patches_total"],
        "errors": {k: summary["errors"][k] for k in ("spline_only", "displaced")},
        "seconds": round(time.perf_counter() - t0, 3),
    }
    write_text(folder / "done.json", json.dumps(record, indent=2) + "\n")
    return record


def run_batch(  # noqa: C901 (one run per mesh, its retries and its record; to split)
    pattern: str | list[str],
    out: str | os.PathLike,
    *,
    layout: str | None = None,
    options=None,
    scheduler: str | None = None,
    n_workers: int | None = None,
    retries: int = 3,
    patch_tasks_above: int | None = 500_000,
    quiet: bool = False,
    client=None,
) -> dict[str, Any]:
    """Fit every mesh matching ``pattern`` on a Dask cluster.

    Parameters
    ----------
    pattern : str or list of str
        A glob (``"scans/*.ply"``) or a list of files.
    out : path
        Output folder: one sub-folder per mesh (its file stem) and ``batch.json``.
    layout : str, optional
        A layout file for every mesh, or ``"auto"`` (default).
    options : meshfit.pipeline.FitOptions, optional
        Fit options (``workers`` defaults to 1 per task: the cluster parallelises meshes).
    scheduler : str, optional
        Address of a running Dask scheduler; default a LocalCluster on 127.0.0.1.
    n_workers : int, optional
        Worker processes of the LocalCluster (default 2).
    retries : int
        Extra attempts of a task whose worker died (default 3).
    patch_tasks_above : int, optional
        Meshes with at least this many faces compute their spring meshes as one task per
        patch, spread over the cluster (default 500,000; None: never).
    quiet : bool
        No progress output.
    client : distributed.Client, optional
        Use this client (tests); ``scheduler`` and ``n_workers`` are then ignored.

    Returns
    -------
    dict
        Written to ``out/batch.json``: ``meshes``, ``done``, ``skipped``, ``failed`` and
        ``results`` per mesh file name (status, error, seconds, errors of the fit).
    """
    from meshfit.mesh.io import FORMATS
    from meshfit.pipeline import FitOptions

    if isinstance(pattern, list):
        files = sorted(pattern)
    else:  # a glob's matches of the formats meshfit reads (a folder's other files are left)
        files = sorted(
            f
            for f in _glob.glob(str(pattern))
            if Path(f).suffix.lower() in FORMATS and Path(f).is_file()
        )
    if not files:
        raise InputError(f"no mesh file ({', '.join(FORMATS)}) matches {pattern!r}")
    seen: dict[str, str] = {}
    for f in files:
        if Path(f).stem in seen:
            raise InputError(
                f"{seen[Path(f).stem]} and {f} have the same file name stem; their output "
                "folders would collide"
            )
        seen[Path(f).stem] = f
    if options is None:
        options = FitOptions(workers=1)
    elif options.workers is None:
        options = FitOptions(**{**asdict(options), "workers": 1})
    opts = asdict(options)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    results: dict[str, dict[str, Any]] = {}
    todo = []
    for f in files:
        path = Path(f)
        key = _job_key(path, layout, opts)
        done = out / path.stem / "done.json"
        if done.is_file():
            try:
                rec = read_json_file(done, error=ValueError)
            except ValueError:
                rec = {}
            if not isinstance(rec, dict):
                rec = {}
            if rec.get("key") == key and rec.get("status") == "done":
                results[path.name] = {**rec, "status": "skipped"}
                continue
        todo.append((path, key))

    if todo:
        own = None
        own_client = client is None
        if client is None:
            from distributed import Client, LocalCluster

            if scheduler:
                client = Client(scheduler)
            else:
                own = LocalCluster(
                    n_workers=int(n_workers or 2),
                    threads_per_worker=1,
                    host="127.0.0.1",
                    dashboard_address="127.0.0.1:0",
                    processes=True,
                )
                client = Client(own)
        try:
            futures = {
                client.submit(
                    fit_one,
                    str(path),
                    str(out / path.stem),
                    layout,
                    opts,
                    key,
                    patch_tasks_above,
                    key=_task_key(path, out / path.stem, key, patch_tasks_above),
                    retries=retries,
                    pure=False,
                ): path
                for path, key in todo
            }
            from distributed import as_completed

            for fut in as_completed(list(futures)):
                path = futures[fut]
                try:
                    rec = fut.result()
                except Exception as exc:  # the task failed on every attempt (workers died)
                    rec = {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}
                results[path.name] = rec
                if not quiet:
                    print(f"{rec['status']}: {path.name}", flush=True)
        finally:
            if own_client:
                client.close()
            if own is not None:
                own.close()
    summary = {
        "meshfit_batch": BATCH_FORMAT,
        "meshes": len(files),
        "done": sum(r["status"] == "done" for r in results.values()),
        "skipped": sum(r["status"] == "skipped" for r in results.values()),
        "failed": sum(r["status"] == "failed" for r in results.values()),
        "seconds": round(time.perf_counter() - t0, 3),
        "results": {Path(f).name: results[Path(f).name] for f in files},
    }
    write_text(out / "batch.json", json.dumps(summary, indent=2) + "\n")
    return summary
