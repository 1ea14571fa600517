"""Benchmark: walking face points on igea against moving in 3-D and re-projecting, and the
closest-point query that re-projects.

For 1,000,000 random face points with random tangent steps of 2 mean edge lengths:

- throughput of :func:`meshfit.surface.walk_points` (median of several runs after a warm-up
  compile), and of the naive alternative the thesis rejects (appendix A: "points first leave
  the surface and are then re-projected back"): ``x + step`` re-projected with the mesh's own
  bounding-volume hierarchy (``mesh.closest_points``), timed in the same run;
- how often the naive result lands on a different part of the surface than the walk: its
  distance to the walk's end point exceeds one mean edge length (fraction), plus the mean
  and 99th percentile of that distance.

Closest points (``closest_points``): on igea (269K faces) and igea refined once by 1-to-4
midpoint subdivision (1.07M faces), the build of the mesh's tree
(:func:`meshfit.mesh.locate.build_tree`) and :func:`meshfit.mesh.closest_points` for
``--closest-n`` points within about a mean edge length of the surface, against the peer
``igl.AABB`` (``init``, then ``squared_distance``), each the median of ``--repeats`` runs in
the same process; ratios are ours over the peer's.

Run: ``python benchmarks/walk.py [--n 1000000] [--closest-n 270000] [--repeats 3]``. Prints
JSON and writes ``benchmarks/results/walk.json`` atomically.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
from _common import median_time, mesh_path, write_result
from pipeline import midpoint_subdivide

from meshfit.mesh import Mesh, closest_points, load_mesh
from meshfit.mesh.locate import build_tree
from meshfit.surface import random_surface_points, walk_points


def closest_vs_igl(mesh: Mesh, q: np.ndarray, repeats: int) -> dict:
    """Tree build and closest-point query of ``mesh`` for the points ``q``, ours against
    ``igl.AABB``, medians of ``repeats`` runs (wall seconds)."""
    import igl

    V, F = mesh.vertices, mesh.faces
    closest_points(mesh, q[:10])  # compile or load the numba cache; builds mesh's tree
    t_build, builds = median_time(lambda: build_tree(V, F), repeats)
    t_query, queries = median_time(lambda: closest_points(mesh, q), repeats)
    peer = igl.AABB()
    t_peer_build, peer_builds = median_time(lambda: peer.init(V, F), repeats)
    t_peer_query, peer_queries = median_time(lambda: peer.squared_distance(V, F, q), repeats)
    ours = closest_points(mesh, q)
    sq, face, c = peer.squared_distance(V, F, q)
    diag = mesh.bbox_diagonal
    return {
        "faces": mesh.n_faces,
        "queries": len(q),
        "build_median_s": round(t_build, 4),
        "build_times_s": [round(t, 4) for t in builds],
        "query_median_s": round(t_query, 4),
        "query_times_s": [round(t, 4) for t in queries],
        "peer_igl_build_median_s": round(t_peer_build, 4),
        "peer_igl_build_times_s": [round(t, 4) for t in peer_builds],
        "peer_igl_query_median_s": round(t_peer_query, 4),
        "peer_igl_query_times_s": [round(t, 4) for t in peer_queries],
        "build_ratio_vs_peer": round(t_build / t_peer_build, 3),
        "query_ratio_vs_peer": round(t_query / t_peer_query, 3),
        "build_plus_query_ratio_vs_peer": round(
            (t_build + t_query) / (t_peer_build + t_peer_query), 3
        ),
        "max_distance_difference_per_bbox_diagonal": float(
            np.abs(ours.distance - np.sqrt(np.maximum(sq, 0.0))).max() / diag
        ),
        "max_xyz_difference_per_bbox_diagonal": float(np.abs(ours.xyz - c).max() / diag),
        "different_face_fraction": float(
            (ours.points.face != np.asarray(face, dtype=np.int64)).mean()
        ),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000, help="point-steps per run")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs (median reported)")
    ap.add_argument("--step", type=float, default=2.0, help="step length, mean edge lengths")
    ap.add_argument("--closest-n", type=int, default=270_000, help="closest-point queries")
    args = ap.parse_args()

    import numba

    load_start = os.getloadavg()[0]
    t0 = time.perf_counter()
    mesh = load_mesh(mesh_path("igea"))
    t_load = time.perf_counter() - t0
    mel = mesh.mean_edge_length
    rng = np.random.default_rng(2000)
    start = random_surface_points(mesh, args.n, rng)
    d = rng.normal(size=(args.n, 3))
    nrm = mesh.face_normals[start.face]
    d -= np.einsum("ij,ij->i", d, nrm)[:, None] * nrm
    step = d / np.linalg.norm(d, axis=1)[:, None] * (args.step * mel)
    x0 = mesh.xyz(start)

    t0 = time.perf_counter()
    walk_points(mesh, start[:1000], step[:1000])  # warm-up: compile or load the numba cache
    t_compile = time.perf_counter() - t0
    t0 = time.perf_counter()
    _ = mesh.triangle_tree  # build the tree outside the timed naive runs
    t_tree = time.perf_counter() - t0

    results = {}

    def walk() -> None:
        results["walk"] = walk_points(mesh, start, step)

    def naive() -> None:
        results["naive"] = mesh.closest_points(x0 + step)

    t_walk, walk_times = median_time(walk, args.repeats)
    t_naive, naive_times = median_time(naive, args.repeats)
    w = results["walk"]
    xw = mesh.xyz(w.end)
    gap = np.linalg.norm(results["naive"].xyz - xw, axis=1)

    data = {
        "benchmark": "walk_points vs move-in-3D-then-reproject (mesh.closest_points)",
        "mesh": "igea",
        "faces": mesh.n_faces,
        "mean_edge_length": mel,
        "point_steps": args.n,
        "step_mean_edge_lengths": args.step,
        "repeats": args.repeats,
        "numba_threads": numba.get_num_threads(),
        "cpu_count": os.cpu_count(),
        "loadavg_1min_start_end": [round(load_start, 2), round(os.getloadavg()[0], 2)],
        "python": platform.python_version(),
        "numba": numba.__version__,
        "load_mesh_s": round(t_load, 3),
        "warmup_compile_or_cache_load_s": round(t_compile, 3),
        "tree_build_s": round(t_tree, 3),
        "walk_median_s": round(t_walk, 4),
        "walk_times_s": [round(t, 4) for t in walk_times],
        "walk_steps_per_s": round(args.n / t_walk),
        "naive_median_s": round(t_naive, 4),
        "naive_times_s": [round(t, 4) for t in naive_times],
        "naive_steps_per_s": round(args.n / t_naive),
        "walk_speedup_vs_naive": round(t_naive / t_walk, 2),
        "walk_hit_boundary": int(w.hit_boundary.sum()),
        "walk_capped": int(w.capped.sum()),
        "walk_max_length_error": float(np.abs(w.length - args.step * mel).max()),
        "different_part_definition": "|naive end - walk end| > 1 mean edge length",
        "naive_different_part_fraction": float((gap > mel).mean()),
        "naive_different_part_count": int((gap > mel).sum()),
        "naive_gap_mean_edge_lengths": {
            "mean": float(gap.mean() / mel),
            "median": float(np.median(gap) / mel),
            "p99": float(np.quantile(gap, 0.99) / mel),
            "max": float(gap.max() / mel),
        },
        "naive_gap_mean_model_units": float(gap.mean()),
    }
    # queries within about a mean edge length of the surface, the same for both meshes
    cq = mesh.xyz(random_surface_points(mesh, args.closest_n, rng))
    cq += rng.normal(scale=mel, size=cq.shape)
    v4, f4 = midpoint_subdivide(mesh.vertices, mesh.faces)
    data["closest_points_vs_igl_aabb"] = {
        "igea": closest_vs_igl(mesh, cq, args.repeats),
        "igea_x4": closest_vs_igl(Mesh(v4, f4, name="igea_x4"), cq, args.repeats),
    }
    data["loadavg_1min_start_end"] = [round(load_start, 2), round(os.getloadavg()[0], 2)]
    write_result("walk", data)


if __name__ == "__main__":
    main()
