"""Benchmark: a dense scan prepared out of core against the same in memory.

Usage: ``python benchmarks/prep.py [--what proxy|prepare|simplify] [--sizes 1m,4m,17m]
[--repeats 1] [--workers 2]``

igea (269K triangles) refined by 1-to-4 midpoint subdivision at run time (``1m`` 1.07M,
``4m`` 4.3M, ``17m`` 17.2M triangles) and written once as a binary PLY, as a scanner would
deliver it. Each side runs in a fresh process, from the file to the layout's proxy of
``PROXY_FACES`` faces:

- ``in_memory`` (the peer, what a fit does today): ``load_mesh(path, repair=True)`` then
  ``simplify_mesh``;
- ``out_of_core``: ``write_store`` (the file memory-mapped, bricked into ``.npy`` files)
  then ``simplify_store`` on ``--workers`` threads.

With ``--what prepare`` each side goes on to the patch submeshes the spring meshes start
from: ``in_memory`` adds the automatic layout (which makes its own proxy) and
``extract_patches``; ``out_of_core`` is ``meshfit.pipeline.prepare.prepare_out_of_core``
(store, proxy, layout, faces sorted into patches, curves carried, every patch cut and
written to its file).

With ``--what simplify`` only the in-memory simplification is timed, the mesh loaded
before the clock: ``whole`` (the peer, ``simplify_mesh(..., bricks=False)``, one pass over
the whole mesh at a time) against ``bricks`` (``bricks=True`` on ``--workers`` threads,
the store's Morton bricks made in memory).

Figures: wall time, peak resident memory of the process (sampled every 20 ms; the store's
pages a process has mapped count while they are resident), and the proxy's faces, genus and
distance from every input vertex to it (max and mean, share of the bounding-box diagonal;
measured afterwards in another process). The sides alternate, so both meet the same load.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import mesh_path, write_result
from pipeline import midpoint_subdivide
from scale import SIZES, PeakMemory

SIDES = ("in_memory", "out_of_core")
#: the sides of ``--what simplify``, the peer first
SIMPLIFY_SIDES = ("whole", "bricks")


def make_input(size: str, folder: Path) -> Path:
    """igea refined to ``size``, saved as a binary PLY in ``folder``."""
    from meshfit.mesh import Mesh, load_mesh, save_mesh

    mesh = load_mesh(mesh_path("igea"))
    v, f = mesh.vertices, mesh.faces
    for _ in range(SIZES[size]):
        v, f = midpoint_subdivide(v, f)
    path = folder / f"igea_{size}.ply"
    save_mesh(Mesh(v, f, name=f"igea_{size}"), path)
    return path


def run_prepare(side: str, path: Path, scratch: Path, workers: int) -> dict:
    """One side, from ``path`` to the patch submeshes."""
    with PeakMemory() as mem:
        t0 = time.perf_counter()
        if side == "in_memory":
            from meshfit.layout import extract_patches
            from meshfit.layout.auto import auto_layout
            from meshfit.mesh import load_mesh

            mesh = load_mesh(path, repair=True)
            layout = auto_layout(mesh)
            patches = extract_patches(mesh, layout, workers=workers)
            n, steps, rows = len(patches), {}, 1.0
            del patches
        else:
            from meshfit.pipeline.prepare import prepare_out_of_core

            res = prepare_out_of_core(path, scratch / "prep", workers=workers)
            n = len(res.patch_files)
            steps = {k: round(v, 3) for k, v in res.seconds.items()}
            rows = res.patch_store.faces.shape[0] / res.store.n_faces
        seconds = time.perf_counter() - t0
    out = {"seconds": round(seconds, 3), "peak_rss_mib": round(mem.peak / 2**20, 1), "patches": n}
    if steps:
        out["seconds_per_step"] = steps
        out["patch_store_rows_per_face"] = round(rows, 3)
    return out


def run_one(side: str, path: Path, scratch: Path, workers: int) -> dict:
    """One side, from ``path`` to a proxy saved in ``scratch``/proxy.npz."""
    from meshfit.layout.auto import PROXY_FACES

    with PeakMemory() as mem:
        t0 = time.perf_counter()
        if side == "in_memory":
            from meshfit.mesh import load_mesh
            from meshfit.shrinkwrap.proxy import simplify_mesh

            mesh = load_mesh(path, repair=True)
            res = simplify_mesh(mesh, PROXY_FACES)
            bricks = 0
        else:
            from meshfit.mesh.store import write_store
            from meshfit.shrinkwrap.proxy import simplify_store

            store = write_store(path, scratch / "store")
            t_store = time.perf_counter() - t0
            res = simplify_store(store, PROXY_FACES, workers=workers)
            bricks = store.n_bricks
        seconds = time.perf_counter() - t0
    np.savez(scratch / "proxy.npz", v=res.mesh.vertices, f=res.mesh.faces)
    out = {
        "seconds": round(seconds, 3),
        "peak_rss_mib": round(mem.peak / 2**20, 1),
        "proxy_faces": int(res.mesh.n_faces),
        "proxy_genus": int(res.mesh.genus),
        "proxy_closed": bool(res.mesh.is_closed),
    }
    if side == "out_of_core":
        out["seconds_store"] = round(t_store, 3)
        out["bricks"] = bricks
    return out


def run_simplify(side: str, path: Path, scratch: Path, workers: int) -> dict:
    """The in-memory proxy of the mesh at ``path``, whole or by bricks; the clock and the
    peak start after loading."""
    from meshfit.layout.auto import PROXY_FACES
    from meshfit.mesh import load_mesh
    from meshfit.shrinkwrap.proxy import simplify_mesh

    mesh = load_mesh(path, repair=True)
    _ = mesh.is_closed  # (checked by both sides: built before the clock)
    with PeakMemory() as mem:
        t0 = time.perf_counter()
        res = simplify_mesh(mesh, PROXY_FACES, workers=workers, bricks=side == "bricks")
        seconds = time.perf_counter() - t0
    np.savez(scratch / "proxy.npz", v=res.mesh.vertices, f=res.mesh.faces)
    return {
        "seconds": round(seconds, 3),
        "peak_rss_mib": round(mem.peak / 2**20, 1),
        "proxy_faces": int(res.mesh.n_faces),
        "proxy_genus": int(res.mesh.genus),
        "proxy_closed": bool(res.mesh.is_closed),
    }


def distances(path: Path, scratch: Path) -> dict:
    """Distance from every input vertex to the proxy, share of the diagonal."""
    from meshfit.mesh import Mesh, load_mesh

    mesh = load_mesh(path)
    z = np.load(scratch / "proxy.npz")
    d = Mesh(z["v"], z["f"]).closest_points(mesh.vertices).distance / mesh.bbox_diagonal
    return {"distance_max": float(d.max()), "distance_mean": float(d.mean())}


def _fresh(*args: str) -> dict:
    run = subprocess.run(
        [sys.executable, __file__, *args], capture_output=True, text=True, check=True
    )
    return json.loads(run.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="1m,4m", help="of 1m, 4m, 17m (default: %(default)s)")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--what", default="proxy", choices=("proxy", "prepare", "simplify"))
    ap.add_argument("--one", nargs=3, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--distances", nargs=2, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        side, path, scratch = args.one
        run = {"prepare": run_prepare, "simplify": run_simplify}.get(args.what, run_one)
        print(json.dumps(run(side, Path(path), Path(scratch), args.workers)))
        return
    if args.distances:
        print(json.dumps(distances(Path(args.distances[0]), Path(args.distances[1]))))
        return
    sizes = [s.strip() for s in args.sizes.split(",") if s.strip()]
    unknown = [s for s in sizes if s not in SIZES]
    if unknown:
        sys.exit(f"unknown sizes {unknown}: choose among {list(SIZES)}")
    results = {}
    for size in sizes:
        with tempfile.TemporaryDirectory() as tmp:
            path = make_input(size, Path(tmp))
            sides = SIMPLIFY_SIDES if args.what == "simplify" else SIDES
            runs: dict[str, list[dict]] = {s: [] for s in sides}
            for _ in range(max(1, args.repeats)):
                for side in sides:
                    scratch = Path(tmp) / side
                    scratch.mkdir()
                    r = _fresh("--one", side, str(path), str(scratch), "--workers",
                               str(args.workers), "--what", args.what)  # fmt: skip
                    if args.what != "prepare":
                        r.update(_fresh("--distances", str(path), str(scratch)))
                    runs[side].append(r)
                    shutil.rmtree(scratch)
            row = {}
            for side, rs in runs.items():
                row[side] = dict(rs[0])
                row[side]["seconds"] = statistics.median(r["seconds"] for r in rs)
                row[side]["seconds_runs"] = [r["seconds"] for r in rs]
                row[side]["peak_rss_mib"] = max(r["peak_rss_mib"] for r in rs)
            row["input_faces"] = int(SIZES_FACES[size])
            row["file_mib"] = round(path.stat().st_size / 2**20, 1)
            peer, other = row[sides[0]], row[sides[1]]
            ratio = f"{sides[1]}_over_{sides[0]}"
            row[f"{ratio}_seconds"] = round(other["seconds"] / peer["seconds"], 3)
            row[f"{ratio}_peak_rss"] = round(other["peak_rss_mib"] / peer["peak_rss_mib"], 3)
        results[size] = row
        print(size, json.dumps(row), flush=True)
    out = {
        "benchmark": "prep",
        "what": args.what,
        "cores": os.cpu_count(),
        "workers": args.workers,
        "runs": max(1, args.repeats),
        "note": "igea refined by midpoint subdivision, saved as a binary PLY; from the file to "
        "the layout's proxy, each side in a fresh process, alternating; the peer loads and "
        "repairs the mesh in memory and simplifies it; the other writes a bricked store and "
        "simplifies brick by brick; peak RSS of the process; distances from the input's "
        "vertices to the proxy as shares of the diagonal",
        "sizes": results,
    }
    if args.what == "simplify":
        out["note"] = (
            "igea refined by midpoint subdivision, saved as a binary PLY and loaded before the "
            "clock; the in-memory proxy, each side in a fresh process, alternating; the peer "
            "simplifies the whole mesh pass by pass, the other by the store's Morton bricks "
            "on the workers' threads first; peak RSS of the process during the "
            "simplification; distances from the input's vertices to the proxy as shares of "
            "the diagonal"
        )
    stem = {"proxy": "prep", "prepare": "prep_patches", "simplify": "prep_simplify"}[args.what]
    write_result(stem if sizes == ["1m", "4m"] else "_".join([stem, *sizes]), out)


#: input faces per size (igea's 268,686 times 4 per step)
SIZES_FACES = {k: 268_686 * 4**v for k, v in SIZES.items()}

if __name__ == "__main__":
    main()
