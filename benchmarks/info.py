"""`meshfit info` on igea: wall time and peak memory, against trimesh's own statistics.

The peer loads the same file with trimesh (``process=False``) and asks trimesh for the
comparable figures (watertightness, Euler number, edges, components, boundary, area, bbox),
each in a fresh process so peak memory is per run. Prints JSON with medians and ratios and
writes benchmarks/results/info.json.

    python benchmarks/info.py [--repeats 5] [--mesh igea]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

from _common import mesh_path, write_result

PEER = r"""
import sys, numpy as np, trimesh
m = trimesh.load(sys.argv[1], process=False)
stats = dict(vertices=len(m.vertices), faces=len(m.faces), edges=len(m.edges_unique),
             watertight=m.is_watertight, euler=m.euler_number, winding=m.is_winding_consistent,
             components=len(trimesh.graph.connected_components(m.face_adjacency)),
             boundary_edges=int((np.bincount(m.edges_unique_inverse) == 1).sum()),
             area=m.area, bbox=m.bounds.tolist(), edge_mean=float(m.edges_unique_length.mean()))
print(stats)
"""


def run(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS (MiB) of one child process (its own rusage, via wait4)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode() if proc.stderr else ""
    if proc.returncode != 0:
        sys.exit(f"{cmd} failed: {err.strip()}")
    return wall, usage.ru_maxrss / 1024.0


def measure(cmd: list[str], repeats: int) -> dict:
    walls, peaks = [], []
    for _ in range(repeats):
        wall, peak = run(cmd)
        walls.append(wall)
        peaks.append(peak)
    return {
        "wall_s_median": round(statistics.median(walls), 3),
        "wall_s_all": [round(w, 3) for w in walls],
        "peak_rss_mib_median": round(statistics.median(peaks), 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--mesh", default="igea")
    args = ap.parse_args()
    path = str(mesh_path(args.mesh))
    peer = measure([sys.executable, "-c", PEER, path], args.repeats)
    ours = measure([sys.executable, "-m", "meshfit.cli", "info", path, "--json"], args.repeats)
    write_result(
        "info",
        {
            "benchmark": "meshfit info",
            "mesh": args.mesh,
            "repeats": args.repeats,
            "meshfit_info": ours,
            "peer_trimesh_stats": peer,
            "wall_ratio_vs_peer": round(ours["wall_s_median"] / peer["wall_s_median"], 3),
            "peak_rss_ratio_vs_peer": round(
                ours["peak_rss_mib_median"] / peer["peak_rss_mib_median"], 3
            ),
        },
    )


if __name__ == "__main__":
    main()
