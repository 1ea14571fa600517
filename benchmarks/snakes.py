"""Benchmark: surface-snake relaxation on igea, coarse-to-fine (eq. 3.16) vs single resolution.

- A ~2,000-point snake along a shortest edge path across igea is relaxed to equilibrium; then
  its end point is walked sideways (``--pull`` mean edge lengths) and the snake is relaxed
  again (ends fixed) with coarse-to-fine forces (``levels=None``) and with single-resolution
  forces (``levels=1``): iterations and wall time to converge (``tol_move`` default), ratio.
  Single-resolution runs are capped at ``--max-iter`` iterations (reported as not converged).
- Impulse propagation (sec. 3.7), measured directly: with the stopping test off, the number
  of iterations until the sample a quarter of the way from the fixed end (three quarters of
  the snake away from the pulled end) has moved ``--impulse`` mean edge lengths, for both
  force evaluations, and their ratio. Single-resolution forces reach one sample further per
  iteration; coarse-to-fine forces reach every sample in the first iteration.
- Time of one relaxation iteration for a 1,000-point snake (target <= 5 ms), median of runs.
- The automatic layout's relaxation of all traced curves at once (``layout.auto._relax_all``)
  on igea (269K triangles) and on igea midpoint-subdivided once (1.07M), ``--patches``
  patches: the calls ``auto_layout`` makes (on the 50K-face proxy, then on the mesh) are
  recorded and replayed, through the one-kernel relaxation (``_kernels.snakes.relax_many``)
  and through its peer, the loop of vectorised kernel calls in ``tests/reference/snakes.py``
  (the implementation before the kernel); median seconds of each, ratio, and whether the
  faces and barycentrics agree bit for bit.

Run: ``python benchmarks/snakes.py [--repeats 3] [--only auto]``. Prints JSON and writes
``benchmarks/results/snakes.json`` atomically; ``--only auto`` measures the last section and
updates only its entry of the file.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time

import numpy as np
from _common import RESULTS, ROOT, median_time, mesh_path, write_result

from meshfit.curves.snake import SnakeOptions, relax_snake
from meshfit.mesh import load_mesh
from meshfit.surface import path_to_surface_points, shortest_path, walk_points
from meshfit.types import SurfaceCurve, SurfacePoints


def make_snake(mesh, n_target: int) -> SurfaceCurve:
    """A snake of about ``n_target`` points along a shortest edge path between far vertices."""
    v = mesh.vertices
    a = int(np.argmin(v[:, 1]))
    b = int(np.argmax(v[:, 1]))
    path = np.asarray(shortest_path(mesh, a, b).paths[0])
    per_edge = max(0, round((n_target - path.size) / max(path.size - 1, 1)))
    pts = path_to_surface_points(mesh, path, per_edge=per_edge)
    idx = np.linspace(0, len(pts) - 1, min(n_target, len(pts))).round().astype(int)
    return SurfaceCurve(pts[np.unique(idx)])


def auto_relaxation(patches: int, repeats: int) -> dict:
    """`_relax_all` as ``auto_layout(mesh, patches=patches)`` calls it on igea and igea x4:
    the kernel against the reference loop, median seconds over ``repeats`` replays."""
    from pipeline import midpoint_subdivide

    import meshfit.layout.auto as auto
    from meshfit.mesh import Mesh

    sys.path.insert(0, str(ROOT))
    from tests.reference import snakes as reference

    def by_reference(mesh, curves, iterations):
        args = auto._relax_inputs(mesh, curves)
        face, bary, _ = reference.relax_many(**args, iterations=iterations)
        return auto._relaxed_curves(mesh, curves, args["start"], face, bary)

    igea = load_mesh(mesh_path("igea"))
    v, f = midpoint_subdivide(igea.vertices, igea.faces)
    relax_all = auto._relax_all
    out = {}
    for label, mesh in (("igea", igea), ("igea_x4", Mesh(v, f, name="igea_x4"))):
        calls = []

        def record(m, curves, iterations, calls=calls):
            calls.append((m, curves, int(iterations)))
            return relax_all(m, curves, iterations)

        auto._relax_all = record
        try:
            t0 = time.perf_counter()
            auto.auto_layout(mesh, auto.LayoutOptions(patches=patches))
            layout_s = time.perf_counter() - t0
        finally:
            auto._relax_all = relax_all

        identical = True
        for m, curves, iterations in calls:
            got, want = relax_all(m, curves, iterations), by_reference(m, curves, iterations)
            identical &= all(
                np.array_equal(g.points.face, w.points.face)
                and np.array_equal(g.points.bary, w.points.bary)
                for g, w in zip(got, want, strict=True)
            )

        def replay(fn, calls=calls):
            for m, curves, iterations in calls:
                fn(m, curves, iterations)

        t_kernel, times_kernel = median_time(lambda: replay(relax_all), repeats)
        t_ref, times_ref = median_time(lambda: replay(by_reference), repeats)
        out[label] = {
            "n_faces": int(mesh.n_faces),
            "calls": [
                {
                    "n_faces": int(m.n_faces),
                    "curves": len(c),
                    "points": sum(map(len, c)),
                    "iterations": it,
                }
                for m, c, it in calls
            ],
            "auto_layout_seconds": layout_s,
            "kernel_seconds_median": t_kernel,
            "kernel_seconds": times_kernel,
            "reference_loop_seconds_median": t_ref,
            "reference_loop_seconds": times_ref,
            "ratio_reference_over_kernel": t_ref / t_kernel,
            "bit_identical": bool(identical),
        }
    return {"patches": patches, "repeats": repeats, **out}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2000, help="snake points for the convergence runs")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs (median reported)")
    ap.add_argument("--pull", type=float, default=10.0, help="end move, mean edge lengths")
    ap.add_argument("--max-iter", type=int, default=20_000, help="iteration cap per relaxation")
    ap.add_argument(
        "--impulse", type=float, default=1e-3, help="move that counts as arrival, mean edges"
    )
    ap.add_argument("--patches", type=int, default=100, help="auto layout patches")
    ap.add_argument("--only", choices=("all", "auto"), default="all", help="sections to run")
    args = ap.parse_args()

    import numba

    if args.only == "auto":
        path = RESULTS / "snakes.json"
        data = json.loads(path.read_text()) if path.is_file() else {}
        data["auto_layout_relaxation"] = auto_relaxation(args.patches, args.repeats)
        data["auto_layout_relaxation"]["numba_threads"] = numba.get_num_threads()
        write_result("snakes", data)
        return

    t0 = time.perf_counter()
    mesh = load_mesh(mesh_path("igea"))
    load_s = time.perf_counter() - t0
    h = mesh.mean_edge_length

    snake = make_snake(mesh, args.n)
    # equilibrium (also compiles)
    base = relax_snake(mesh, snake, SnakeOptions(max_iter=args.max_iter))
    curve = base.curve
    # pull the end sideways: perpendicular to the end segment, in the end face's plane
    x = mesh.xyz(curve.points)
    f = int(curve.points.face[-1])
    nrm = mesh.face_normals[f]
    side = np.cross(nrm, x[-1] - x[-2])
    side *= args.pull * h / np.linalg.norm(side)
    end = walk_points(mesh, curve.points[len(curve) - 1], side).end
    face = np.array(curve.points.face)
    bary = np.array(curve.points.bary)
    face[-1], bary[-1] = end.face[0], end.bary[0]
    pulled = SurfaceCurve(SurfacePoints(face, bary))

    runs = {}
    for name, levels in (("coarse_to_fine", None), ("single_resolution", 1)):
        reps = args.repeats if name == "coarse_to_fine" else 1
        res = {}

        def run(levels=levels, res=res):
            res["r"] = relax_snake(
                mesh, pulled, SnakeOptions(levels=levels, max_iter=args.max_iter)
            )

        t, times = median_time(run, reps)
        r = res["r"]
        runs[name] = {
            "iterations": r.iterations,
            "converged": r.converged,
            "seconds_median": t,
            "seconds": times,
            "ms_per_iteration": 1e3 * t / max(r.iterations, 1),
            "curve": r.curve,
        }

    # impulse propagation: iterations (stopping test off) until the far sample of the pulled
    # snake is ``--impulse`` mean edge lengths away from where the same relaxation of the
    # unpulled snake puts it (the residual forces of the first equilibrium move it too)
    probe = len(pulled) // 4
    impulse = {}
    for name, levels in (("coarse_to_fine", None), ("single_resolution", 1)):
        cur, ref, done, chunk = pulled, curve, 0, 1
        t0 = time.perf_counter()
        moved = 0.0
        while done < args.max_iter:
            opts = SnakeOptions(levels=levels, max_iter=chunk, tol_move=0.0)
            cur = relax_snake(mesh, cur, opts).curve
            ref = relax_snake(mesh, ref, opts).curve
            done += chunk
            moved = np.linalg.norm(mesh.xyz(cur.points[probe]) - mesh.xyz(ref.points[probe])) / h
            if moved > args.impulse:
                break
            chunk = min(2 * chunk, 64)
        impulse[name] = {
            "iterations_at_most": done,
            "arrived": bool(moved > args.impulse),
            "probe_offset_edges": float(moved),
            "seconds_both_runs": time.perf_counter() - t0,
        }
    x_c2f = mesh.xyz(runs["coarse_to_fine"]["curve"].points)
    x_one = mesh.xyz(runs["single_resolution"]["curve"].points)
    x_pull = mesh.xyz(pulled.points)
    for name, x in (("coarse_to_fine", x_c2f), ("single_resolution", x_one)):
        runs[name]["probe_move_edges"] = float(np.linalg.norm(x[probe] - x_pull[probe]) / h)
        del runs[name]["curve"]

    small = make_snake(mesh, 1000)
    n_iter = 200
    relax_snake(mesh, small, SnakeOptions(max_iter=2, tol_move=0.0))
    iter_options = SnakeOptions(max_iter=n_iter, tol_move=0.0)
    t_it, times_it = median_time(lambda: relax_snake(mesh, small, iter_options), args.repeats)

    auto_relax = auto_relaxation(args.patches, args.repeats)
    auto_relax["numba_threads"] = numba.get_num_threads()

    c2f, single = runs["coarse_to_fine"], runs["single_resolution"]
    write_result(
        "snakes",
        {
            "mesh": "igea",
            "n_faces": int(mesh.n_faces),
            "load_seconds": load_s,
            "snake_points": len(pulled),
            "end_pull_edges": args.pull,
            "initial_relaxation": {"iterations": base.iterations, "converged": base.converged},
            **runs,
            "iteration_ratio_single_over_c2f": single["iterations"] / max(c2f["iterations"], 1),
            "time_ratio_single_over_c2f": single["seconds_median"] / c2f["seconds_median"],
            "final_curves_max_distance_edges": float(
                np.linalg.norm(x_c2f - x_one, axis=1).max() / h
            ),
            "impulse_probe_index": probe,
            "impulse_threshold_edges": args.impulse,
            "impulse_propagation": impulse,
            "impulse_iteration_ratio_single_over_c2f": impulse["single_resolution"][
                "iterations_at_most"
            ]
            / impulse["coarse_to_fine"]["iterations_at_most"],
            "one_iteration_1000_points_ms": 1e3 * t_it / n_iter,
            "one_iteration_target_ms": 5.0,
            "one_iteration_runs_ms": [1e3 * t / n_iter for t in times_it],
            "auto_layout_relaxation": auto_relax,
            "numba_threads": numba.get_num_threads(),
            "cpu_count": os.cpu_count(),
            "python": platform.python_version(),
        },
    )


if __name__ == "__main__":
    main()
