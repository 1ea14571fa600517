"""Benchmark: one large fit on the threads of one process against a LocalCluster.

Usage: ``python benchmarks/scale.py [--sizes 1m,4m] [--modes threads,cluster] [--processes 2]
[--repeats 1]``

igea (269K triangles) refined by 1-to-4 midpoint subdivision at run time, once (1.07M
triangles, ``1m``), twice (4.3M, ``4m``) or three times (17.2M, ``17m``: on request, as it
takes minutes; ``--modes threads`` skips the LocalCluster), fitted with the automatic
layout of about 100 patches, USD + EXR outputs, no report. Each size is fitted twice, each
fit in a fresh process: on the threads of the process (``cluster=None``, the peer) and with
the per-patch work as tasks on a LocalCluster of ``--processes`` workers
(``meshfit.fit(..., cluster=N)``; its start and shutdown included). Figures per run: wall
time of the fit (the mesh is made before the clock starts), seconds per stage, peak resident
memory summed over the process and all its child processes (sampled every 20 ms; a page
shared by several processes, such as the memory-mapped scan, counts once per process),
the displaced surface's RMS and Hausdorff errors, folded spring cells, and the growth of the
time between sizes against n log n. Only the spring meshes, the spline fits, the maps and
the error searches move to the workers, so their four stages are compared on their own too
(the other stages do the same work either way: their difference between two runs is the
machine's noise), and the load average at the start of each run is kept.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time

from _common import mesh_path, write_result
from pipeline import _median_run, midpoint_subdivide

#: subdivision steps of igea per size name
SIZES = {"1m": 1, "4m": 2, "17m": 3}
#: seconds between memory samples
SAMPLE_SECONDS = 0.02


class PeakMemory:
    """Peak resident memory of this process plus all its children, sampled on a thread;
    also the largest of any one child (a cluster worker's bound)."""

    def __init__(self) -> None:
        import psutil

        self.proc = psutil.Process()
        self.peak = 0
        self.peak_at = 0.0  # seconds after the start at which the peak was sampled
        self.child_peak = 0
        self._start = time.perf_counter()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _sample(self) -> int:
        import psutil

        total = self.proc.memory_info().rss
        for child in self.proc.children(recursive=True):
            try:
                rss = child.memory_info().rss
            except psutil.Error:  # a worker that ended between the listing and the read
                continue
            total += rss
            self.child_peak = max(self.child_peak, rss)
        return total

    def _run(self) -> None:
        while not self._stop.is_set():
            rss = self._sample()
            if rss > self.peak:
                self.peak, self.peak_at = rss, time.perf_counter() - self._start
            self._stop.wait(SAMPLE_SECONDS)

    def __enter__(self) -> PeakMemory:
        self._start = time.perf_counter()
        self.peak = self._sample()
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()


def run_one(size: str, processes: int, patches: int) -> dict:
    """One fit of igea refined to ``size``: on threads (``processes`` 0) or on a LocalCluster
    of ``processes`` workers."""
    from meshfit._malloc import tune_malloc
    from meshfit.mesh import Mesh, load_mesh

    tune_malloc()  # as the meshfit command does
    import pxr.Gf
    import pxr.Sdf
    import pxr.Usd
    import pxr.UsdGeom
    import pxr.Vt  # noqa: F401 (before the clock, on the main thread)

    from meshfit.pipeline import FitOptions, fit

    mesh = load_mesh(mesh_path("igea"))
    v, f = mesh.vertices, mesh.faces
    for _ in range(SIZES[size]):
        v, f = midpoint_subdivide(v, f)
    mesh = Mesh(v, f, name=f"igea_{size}")
    del v, f
    opts = FitOptions(patches=patches, formats=("usd", "exr"), report=False)
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as out, PeakMemory() as mem:
        t0 = time.perf_counter()
        s = fit(mesh, "auto", options=opts, out=out, cluster=processes or None).summary
        seconds = time.perf_counter() - t0
    return {
        "faces": int(mesh.n_faces),
        "patches": s["patches_total"],
        "seconds_total": round(seconds, 3),
        "seconds_per_stage": {k: v["seconds"] for k, v in s["stages"].items()},
        "seconds_tasks_stages": _tasks_seconds(s["stages"]),
        "peak_rss_mib": round(mem.peak / 2**20, 1),
        "peak_rss_one_child_mib": round(mem.child_peak / 2**20, 1),
        "peak_rss_stage": _stage_at(s["stages"], mem.peak_at),
        "displaced_rms": s["errors"]["displaced"]["rms"],
        "displaced_hausdorff": s["errors"]["displaced"]["hausdorff"],
        "folded_cells": int(sum(p["folded"] for p in s["patches"])),
        "patch_tasks": bool(s["stages"]["springs"].get("patch_tasks")),
        "load_average_at_start": round(load, 2),
    }


def run_prepared(size: str, patches: int) -> dict:
    """igea refined to ``size``, written as a binary PLY before the clock starts, then
    prepared out of core (``prepare_out_of_core``, the proxy's layout asked for ``patches``)
    and fitted from the prepared folder on the threads of this process."""
    from dataclasses import replace

    from meshfit._malloc import tune_malloc
    from meshfit.layout.auto import LayoutOptions
    from meshfit.mesh import Mesh, load_mesh, save_mesh

    tune_malloc()
    import pxr.Gf
    import pxr.Sdf
    import pxr.Usd
    import pxr.UsdGeom
    import pxr.Vt  # noqa: F401

    from meshfit.pipeline import FitOptions, fit, prepare_out_of_core

    mesh = load_mesh(mesh_path("igea"))
    v, f = mesh.vertices, mesh.faces
    for _ in range(SIZES[size]):
        v, f = midpoint_subdivide(v, f)
    opts = FitOptions(formats=("usd", "exr"), report=False)
    layout = replace(LayoutOptions(), patches=patches, crease_angle=None)
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        ply = os.path.join(tmp, f"igea_{size}.ply")
        save_mesh(Mesh(v, f, name=f"igea_{size}"), ply)
        n_faces = int(f.shape[0])
        del mesh, v, f
        with PeakMemory() as mem:
            t0 = time.perf_counter()
            prep = prepare_out_of_core(ply, os.path.join(tmp, "prep"), layout_options=layout)
            t1 = time.perf_counter()
            s = fit(prep, options=opts, out=os.path.join(tmp, "fit")).summary
            seconds = time.perf_counter() - t0
    return {
        "faces": n_faces,
        "patches": s["patches_total"],
        "seconds_total": round(seconds, 3),
        "seconds_prepare": round(t1 - t0, 3),
        "seconds_prepare_steps": {k: round(v, 3) for k, v in prep.seconds.items()},
        "seconds_per_stage": {k: v["seconds"] for k, v in s["stages"].items()},
        "seconds_tasks_stages": _tasks_seconds(s["stages"]),
        "peak_rss_mib": round(mem.peak / 2**20, 1),
        "peak_rss_one_child_mib": round(mem.child_peak / 2**20, 1),
        "peak_rss_stage": "prepare"
        if mem.peak_at <= t1 - t0
        else _stage_at(s["stages"], mem.peak_at - (t1 - t0)),
        "displaced_rms": s["errors"]["displaced"]["rms"],
        "displaced_hausdorff": s["errors"]["displaced"]["hausdorff"],
        "folded_cells": int(sum(p["folded"] for p in s["patches"])),
        "patch_tasks": False,
        "load_average_at_start": round(load, 2),
    }


def _stage_at(stages: dict, seconds: float) -> str:
    """The stage running ``seconds`` after the fit started (stages run one after another,
    in the summary's order; the fit's set-up counts as the first stage's, and ``after`` is
    past the last)."""
    end = 0.0
    for name, stage in stages.items():
        end += stage["seconds"]
        if seconds <= end:
            return name
    return "after"


def _fresh(size: str, processes: int, patches: int, mode: str = "") -> dict:
    run = subprocess.run(
        [
            sys.executable,
            __file__,
            "--one",
            size,
            "--processes",
            str(processes),
            "--patches",
            str(patches),
            *(["--prepared"] if mode == "prepared" else []),
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(run.stdout.strip().splitlines()[-1])


def _median(runs: list[dict]) -> dict:
    """`pipeline._median_run` (median times, largest peak) with the task stages' median
    time and every run's load average."""
    out = _median_run(runs, peak_key="peak_rss_mib")
    out["peak_rss_one_child_mib"] = max(r["peak_rss_one_child_mib"] for r in runs)
    out["seconds_tasks_stages"] = round(
        statistics.median(r["seconds_tasks_stages"] for r in runs), 3
    )
    out["seconds_tasks_stages_runs"] = [r["seconds_tasks_stages"] for r in runs]
    out["load_average_at_start"] = [r["load_average_at_start"] for r in runs]
    return out


#: the stages whose per-patch work runs as tasks on a cluster
TASKS_STAGES = ("springs", "fit", "displacement", "errors")


def _tasks_seconds(stages: dict) -> float:
    """Seconds of the `TASKS_STAGES` of a fit's summary, summed."""
    return round(sum(stages[k]["seconds"] for k in TASKS_STAGES), 3)


def _compare(row: dict) -> None:
    """The cluster's figures over the threads' (the peer), into ``row``."""
    t, c = row["threads"], row["cluster"]
    row["cluster_over_threads_seconds"] = round(c["seconds_total"] / t["seconds_total"], 3)
    row["cluster_over_threads_tasks_stages"] = round(
        c["seconds_tasks_stages"] / t["seconds_tasks_stages"], 3
    )
    row["cluster_over_threads_peak_rss"] = round(c["peak_rss_mib"] / t["peak_rss_mib"], 3)
    row["same_errors"] = (c["displaced_rms"], c["displaced_hausdorff"]) == (
        t["displaced_rms"],
        t["displaced_hausdorff"],
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="1m,4m", help="of 1m, 4m, 17m (default: %(default)s)")
    ap.add_argument("--processes", type=int, default=2, help="LocalCluster workers (default 2)")
    ap.add_argument("--patches", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument(
        "--modes",
        default="threads,cluster",
        help="threads, cluster or both (default: %(default)s; a 17m cluster run needs the "
        "memory of the threads run and more)",
    )
    ap.add_argument("--one", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--prepared", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        if args.prepared:
            print(json.dumps(run_prepared(args.one, args.patches)))
        else:
            print(json.dumps(run_one(args.one, args.processes, args.patches)))
        return
    sizes = [s.strip() for s in args.sizes.split(",") if s.strip()]
    unknown = [s for s in sizes if s not in SIZES]
    if unknown:
        sys.exit(f"unknown sizes {unknown}: choose among {list(SIZES)}")
    modes = [m for m in ("threads", "cluster", "prepared") if m in args.modes.split(",")]
    if not modes:
        sys.exit(f"--modes {args.modes!r}: choose among threads, cluster and prepared")
    results: dict[str, dict] = {}
    for size in sizes:
        runs: dict[str, list[dict]] = {m: [] for m in modes}
        for _ in range(max(1, args.repeats)):  # alternating, so both meet the same load
            for m in modes:
                procs = args.processes if m == "cluster" else 0
                runs[m].append(_fresh(size, procs, args.patches, m))
        row = {k: _median(v) for k, v in runs.items()}
        if "threads" in row and "cluster" in row:
            _compare(row)
        if "threads" in row and "prepared" in row:
            t, o = row["threads"], row["prepared"]
            row["prepared_over_threads_seconds"] = round(o["seconds_total"] / t["seconds_total"], 3)
            row["prepared_over_threads_peak_rss"] = round(o["peak_rss_mib"] / t["peak_rss_mib"], 3)
        results[size] = row
        print(size, json.dumps(row), flush=True)
    out = {
        "benchmark": "scale",
        "cores": os.cpu_count(),
        "processes": args.processes,
        "runs": max(1, args.repeats),
        "note": "igea refined by midpoint subdivision; the whole fit without the report, each "
        "run in a fresh process, threads and cluster alternating; medians over the runs; the "
        "peer is the same fit on the threads of one process; tasks stages: springs, fit, "
        "displacement and errors; peak RSS summed over the process and its children",
        "sizes": results,
    }
    growth = {}
    for a, b in itertools.pairwise(sizes):
        n1, n2 = results[a]["threads"]["faces"], results[b]["threads"]["faces"]
        nlogn = (n2 * math.log(n2)) / (n1 * math.log(n1))
        growth[f"{b}_over_{a}"] = {
            "n_log_n": round(nlogn, 3),
            **{
                mode: round(
                    results[b][mode]["seconds_total"] / results[a][mode]["seconds_total"], 3
                )
                for mode in modes
            },
        }
    out["growth"] = growth
    # (another choice of sizes or modes keeps the default run's file)
    name = (
        "scale"
        if (sizes, modes) == (["1m", "4m"], ["threads", "cluster"])
        else "_".join(["scale", *sizes, *modes])
    )
    write_result(name, out)


if __name__ == "__main__":
    main()
