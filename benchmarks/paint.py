"""Benchmark: painting one surface-curve segment on igea (target <= 10 ms).

One segment between the lowest vertex of igea (smallest y) and the vertex whose straight-line
distance from it is closest to ``--edges`` (default 200) mean edge lengths:
:func:`meshfit.curves.paint_curve` with two vertex picks, median wall time of ``--repeats``
runs after a warm-up call (numba compile excluded); the greedy graph path alone
(:func:`meshfit.surface.paths.greedy_path`, the first step of painting) is timed in the same
run as the peer, and the ratio paint / greedy path is reported.

Kept apart from ``benchmarks/snakes.py`` (whose snake runs take minutes and which is edited
concurrently); the result goes under the key ``"paint_segment"``.

Run: ``python benchmarks/paint.py [--repeats 7]``. Prints JSON and writes
``benchmarks/results/paint.json`` atomically.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
from _common import median_cpu_time, median_time, mesh_path, write_result

from meshfit.curves import check_sampling, paint_curve
from meshfit.mesh import load_mesh
from meshfit.surface.paths import greedy_path


def bench_paint_segment(mesh, edges: float, repeats: int) -> dict:
    """Time painting one segment across about ``edges`` mean edge lengths; see module doc."""
    v = mesh.vertices
    h = mesh.mean_edge_length
    a = int(np.argmin(v[:, 1]))
    d = np.linalg.norm(v - v[a], axis=1)
    b = int(np.argmin(np.abs(d - edges * h)))
    curve = paint_curve(mesh, [a, b])  # warm-up: numba compile / cache load
    path = greedy_path(mesh, a, b).vertices
    t_paint, runs_paint = median_time(lambda: paint_curve(mesh, [a, b]), repeats)
    t_path, runs_path = median_time(lambda: greedy_path(mesh, a, b), repeats)
    c_paint, _ = median_cpu_time(lambda: paint_curve(mesh, [a, b]), repeats)
    c_path, _ = median_cpu_time(lambda: greedy_path(mesh, a, b), repeats)
    g = greedy_path(mesh, a, b)
    return {
        "picks": [a, b],
        "chord_mean_edges": float(d[b] / h),
        "graph_path_vertices": len(path),
        "graph_path_used_astar_finish": bool(g.used_fallback),
        "curve_points": len(curve),
        "sampling_violations": int(check_sampling(mesh, curve).size),
        "repeats": repeats,
        "paint_ms_median": 1e3 * t_paint,
        "paint_runs_ms": [1e3 * t for t in runs_paint],
        "greedy_path_ms_median": 1e3 * t_path,
        "greedy_path_runs_ms": [1e3 * t for t in runs_path],
        "ratio_paint_over_greedy_path": t_paint / t_path,
        "paint_cpu_ms_median": 1e3 * c_paint,
        "greedy_path_cpu_ms_median": 1e3 * c_path,
        "cpu_ratio_paint_over_greedy_path": c_paint / c_path,
        "target_ms": 10.0,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7, help="timed runs (median reported)")
    ap.add_argument("--edges", type=float, default=200.0, help="segment chord, mean edges")
    args = ap.parse_args()
    t0 = time.perf_counter()
    mesh = load_mesh(mesh_path("igea"))
    load_s = time.perf_counter() - t0

    import numba

    write_result(
        "paint",
        {
            "mesh": "igea",
            "n_faces": int(mesh.n_faces),
            "load_seconds": load_s,
            "paint_segment": bench_paint_segment(mesh, args.edges, max(args.repeats, 5)),
            "numba_threads": numba.get_num_threads(),
            "cpu_count": os.cpu_count(),
            "load_average": list(os.getloadavg()),
            "python": platform.python_version(),
        },
    )


if __name__ == "__main__":
    main()
