"""Benchmark: the whole fit (meshfit.fit into a folder) on igea and on igea refined once.

Usage: ``python benchmarks/pipeline.py [--patches 100] [--sizes small,large] [--repeats 3]``

Each size runs in its own process (so each peak memory is its own): igea (269K triangles)
and igea refined once by 1-to-4 midpoint subdivision (1.07M triangles), the automatic layout
with about 100 patches, every stage timed (file loading excluded), outputs USD + EXR +
report. Peers are the figures quoted in issue 7 (not measured here): the thesis needed about
10 minutes for a million polygons; QuadriFlow about 52 s to quad-remesh 1.3M triangles on this
machine. The growth between the sizes is compared with n log n. With ``--repeats k`` each size
runs k times (each in a fresh process, with the allocator settings of the meshfit command:
:mod:`meshfit._malloc`) and the figures are the medians per stage (the machine
is shared: single runs are noisy).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
from _common import mesh_path, worktree, write_result

THESIS_SECONDS_PER_MILLION = 600.0
QUADRIFLOW_SECONDS_1_3M = 52.0
TARGET_SECONDS_1M = 10.0


def midpoint_subdivide(vertices, faces):
    """1-to-4 split of every triangle at its edge mid-points (shape unchanged)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    key = np.sort(e, axis=1)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    mid = 0.5 * (vertices[uniq[:, 0]] + vertices[uniq[:, 1]])
    nv = len(vertices)
    m = inv.reshape(3, -1).T + nv  # mid-point of edges 01, 12, 20
    a, b, c = faces.T
    ab, bc, ca = m.T
    new = np.concatenate(
        [
            np.stack([a, ab, ca], 1),
            np.stack([ab, b, bc], 1),
            np.stack([ca, bc, c], 1),
            np.stack([ab, bc, ca], 1),
        ]
    )
    return np.vstack([vertices, mid]), new


def run_one(size: str, patches: int) -> dict:
    from meshfit._malloc import tune_malloc
    from meshfit.mesh import Mesh, load_mesh

    tune_malloc()  # as the meshfit command does
    # USD's modules are loaded before the clock starts, on the main thread, for both sides of
    # --against: a commit that loads them on a side thread can deadlock beside numba
    import pxr.Gf
    import pxr.Sdf
    import pxr.Usd
    import pxr.UsdGeom
    import pxr.Vt  # noqa: F401

    import meshfit.pipeline as pipeline
    from meshfit.pipeline import FitOptions

    mesh = load_mesh(mesh_path("igea"))
    if size == "large":
        v, f = midpoint_subdivide(mesh.vertices, mesh.faces)
        mesh = Mesh(v, f, name="igea_x4")
    opts = FitOptions(patches=patches, formats=("usd", "exr"), controls=(16, 16))
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        if hasattr(pipeline, "run_fit"):  # a commit before meshfit.fit (--against)
            s = pipeline.run_fit(mesh, out, layout="auto", options=opts)
        else:
            s = pipeline.fit(mesh, "auto", options=opts, out=out).summary
        total = time.perf_counter() - t0
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return {
        "faces": int(mesh.n_faces),
        "patches": s["patches_total"],
        "seconds_total": round(total, 3),
        "seconds_per_stage": {k: v["seconds"] for k, v in s["stages"].items()},
        "peak_memory_mib": round(peak_kib / 1024, 1),
        "displaced_rms": s["errors"]["displaced"]["rms"],
        "displaced_hausdorff": s["errors"]["displaced"]["hausdorff"],
        "spline_rms": s["errors"]["spline_only"]["rms"],
        "folded_cells": int(sum(p["folded"] for p in s["patches"])),
        "grid_points": int(sum(p["shape"][0] * p["shape"][1] for p in s["patches"])),
    }


def _median_run(runs: list[dict], peak_key: str = "peak_memory_mib") -> dict:
    """Median seconds per stage and in total over runs, the largest ``peak_key`` memory; the
    other figures of the first run (they do not depend on the run) and every run's total."""
    out = dict(runs[0])
    out["seconds_total"] = round(statistics.median(r["seconds_total"] for r in runs), 3)
    out["seconds_total_runs"] = [r["seconds_total"] for r in runs]
    out["seconds_per_stage"] = {
        k: round(statistics.median(r["seconds_per_stage"][k] for r in runs), 4)
        for k in runs[0]["seconds_per_stage"]
    }
    out[peak_key] = max(r[peak_key] for r in runs)
    return out


def _run(size: str, patches: int, src: str | None = None) -> dict:
    """One fit in a fresh process, with ``src`` (a checkout's ``src`` folder) first on the
    path when given."""
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = src
    run = subprocess.run(
        [sys.executable, __file__, "--one", size, "--patches", str(patches)],
        capture_output=True,
        text=True,
        check=True,
        env=env,
    )
    return json.loads(run.stdout.strip().splitlines()[-1])


def compare(args) -> None:
    """This checkout against ``args.against``, alternating runs (after one warm-up run each,
    which compiles the kernels), medians per size; writes ``pipeline_against.json``."""
    out = {"benchmark": "pipeline_against", "against": args.against, "runs": args.repeats}
    with worktree(args.against) as old:
        for size in args.sizes.split(","):
            new_runs, old_runs = [], []
            _run(size, args.patches)
            _run(size, args.patches, str(old / "src"))
            for _ in range(max(1, args.repeats)):
                new_runs.append(_run(size, args.patches))
                old_runs.append(_run(size, args.patches, str(old / "src")))
            new, prev = _median_run(new_runs), _median_run(old_runs)
            out[size] = {
                "new_seconds_total": new["seconds_total"],
                "old_seconds_total": prev["seconds_total"],
                "new_runs": new["seconds_total_runs"],
                "old_runs": prev["seconds_total_runs"],
                "new_over_old": round(new["seconds_total"] / prev["seconds_total"], 3),
                "new_peak_memory_mib": new["peak_memory_mib"],
                "old_peak_memory_mib": prev["peak_memory_mib"],
                "same_errors": new["displaced_rms"] == prev["displaced_rms"]
                and new["displaced_hausdorff"] == prev["displaced_hausdorff"],
            }
            print(size, json.dumps(out[size]))
    write_result("pipeline_against", out)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--patches", type=int, default=100)
    ap.add_argument("--sizes", default="small,large")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--one", default=None, help=argparse.SUPPRESS)
    ap.add_argument(
        "--against",
        default=None,
        metavar="COMMIT",
        help="also run COMMIT's meshfit (a git worktree), alternating with this one, and "
        "print the ratio of the median totals",
    )
    args = ap.parse_args()
    if args.one:
        print(json.dumps(run_one(args.one, args.patches)))
        return
    if args.against:
        compare(args)
        return
    results = {}
    for size in args.sizes.split(","):
        runs = []
        for _ in range(max(1, args.repeats)):
            run = subprocess.run(
                [sys.executable, __file__, "--one", size, "--patches", str(args.patches)],
                capture_output=True,
                text=True,
                check=True,
            )
            runs.append(json.loads(run.stdout.strip().splitlines()[-1]))
        results[size] = _median_run(runs)
    out = {
        "benchmark": "pipeline",
        "cores": os.cpu_count(),
        "runs": max(1, args.repeats),
        "note": "medians over the runs of each size (fresh process each); peers quoted from "
        "issue 7",
        **results,
    }
    if "large" in results:
        big = results["large"]
        t = big["seconds_total"]
        out["large_vs_target_10s"] = round(t / TARGET_SECONDS_1M, 2)
        out["large_vs_quadriflow_52s_quoted"] = round(t / QUADRIFLOW_SECONDS_1_3M, 3)
        out["large_vs_thesis_600s_per_million_quoted"] = round(
            t / (THESIS_SECONDS_PER_MILLION * big["faces"] / 1e6), 4
        )
    if "small" in results and "large" in results:
        n1, n2 = results["small"]["faces"], results["large"]["faces"]
        growth = results["large"]["seconds_total"] / results["small"]["seconds_total"]
        nlogn = (n2 * math.log(n2)) / (n1 * math.log(n1))
        out["growth_large_over_small"] = round(growth, 3)
        out["growth_n_log_n"] = round(nlogn, 3)
        out["growth_within_n_log_n"] = bool(growth <= nlogn)
    write_result("pipeline", out)


if __name__ == "__main__":
    main()
