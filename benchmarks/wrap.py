"""Benchmark: shrink wrapping nefertiti and igea to level 6.

For each mesh: wall time per stage (sphere map, base mesh, each level) of
:func:`meshfit.shrinkwrap.shrink_wrap`, median of several runs after a warm-up (numba
compile), the peak resident memory of the process after the configuration (cumulative: the
largest of the runs so far), the level-6 metrics, and, as the floor,
one step of plain Loop subdivision of the level-5 result to level-6 connectivity
(:func:`meshfit.shrinkwrap.subdivide_step`) timed in the same run; ``ratio_to_loop_step`` is
the total wrap time over that step. Target (issue 6): igea to level 6 in <= 20 s on 2 cores.

Configurations: nefertiti and igea with the default base mesh (icosahedron start), and igea
from the 80-face geodesic polyhedron
(``base_options=BaseOptions(start_subdivisions=1, min_faces=80)``).

Run: ``python benchmarks/wrap.py [--repeats 3] [--levels 6]``. Prints JSON and writes
``benchmarks/results/wrap.json`` atomically.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import statistics
import time

from _common import median_time, mesh_path, write_result

from meshfit.mesh import load_mesh
from meshfit.shrinkwrap import BaseOptions, level_metrics, shrink_wrap, subdivide_step


def _peak_rss_mb() -> float:
    """Peak resident memory of this process so far, MiB (Linux reports KiB)."""
    return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="timed runs (median reported)")
    ap.add_argument("--levels", type=int, default=6)
    args = ap.parse_args()
    load_start = os.getloadavg()[0]
    warm = load_mesh(mesh_path("spot"))
    t0 = time.perf_counter()
    shrink_wrap(warm, levels=2)  # compile or load the numba cache
    t_compile = time.perf_counter() - t0
    out = {}
    configs = {
        "nefertiti": ("nefertiti", None),
        "igea": ("igea", None),
        # the 80-face geodesic start: level 6 has ~330K faces, the size the target assumes
        "igea_base80": ("igea", BaseOptions(start_subdivisions=1, min_faces=80)),
    }
    for key, (name, bopt) in configs.items():
        mesh = load_mesh(mesh_path(name))
        _ = mesh.triangle_tree, mesh.aabb  # closest points and rays
        runs = []
        totals = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            res = shrink_wrap(mesh, levels=args.levels, base_options=bopt)
            totals.append(time.perf_counter() - t0)
            runs.append(res.seconds)
        stages = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
        l5 = res.levels[-2]
        t_loop, _ = median_time(lambda l5=l5: subdivide_step(l5.vertices, l5.faces, "loop"), 5)
        total = statistics.median(totals)
        m6 = level_metrics(mesh, res.levels[-1])
        out[key] = {
            "input_faces": mesh.n_faces,
            "base_faces": len(res.base.faces),
            "base_cell_area_ratio": res.base.area_ratio,
            "switch_level": res.switch_level,
            "levels": args.levels,
            "finest_faces": len(res.levels[-1].faces),
            "seconds_total_median": round(total, 3),
            "seconds_total_all": [round(t, 3) for t in totals],
            "seconds_per_stage_median": {k: round(v, 3) for k, v in stages.items()},
            "loop_step_seconds_median": round(t_loop, 4),
            "ratio_to_loop_step": round(total / t_loop, 1),
            "finest_level_metrics": m6,
            "peak_rss_mb_so_far": _peak_rss_mb(),
        }
    out["peak_rss_mb"] = _peak_rss_mb()
    out["target_igea_seconds"] = 20.0
    out["igea_meets_target"] = out["igea"]["seconds_total_median"] <= 20.0
    out["igea_base80_meets_target"] = out["igea_base80"]["seconds_total_median"] <= 20.0
    out["compile_seconds"] = round(t_compile, 2)
    out["machine"] = {
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "load_average_at_start": load_start,
    }
    write_result("wrap", out)


if __name__ == "__main__":
    main()
