"""Benchmark: spring meshes of every patch of the igea and nefertiti layouts against libigl.

For each layout in ``examples/layouts/{igea,nefertiti,nefertiti_bust}.json`` (patches cut
with :func:`meshfit.layout.extract_patches`; nefertiti_bust is nefertiti laid out from an
axis through the bust):

- time of :func:`meshfit.springs.resample_patch` to the final level (all levels, no metrics;
  median of several runs after a warm-up compile), per patch and summed over the layout.
  Every timed run gets the patch on a new mesh object (made before the clock starts), so it
  builds the adjacency tables and solves the planar map as a fit does; the ratios use these
  times. ``seconds_cached`` is the same call repeated on one mesh object, which reuses both
  (what a coarse-to-fine preview of the same patch pays), for reference only;
- the peer, timed in the same run on the same patches: libigl's harmonic map of the patch to
  the unit square (``igl.harmonic``, boundary fixed by arc length along each side) resampled
  on the same ``(nu, nv)`` grid (grid parameters located in the flattened patch with libigl's
  point-mesh distance, positions interpolated barycentrically);
- every quality metric of :func:`meshfit.springs.grid_metrics` for both, side by side,
  and for ``resample_patch(follow_folds=True)`` (``springs_follow_folds``, not timed)
  (fidelity relative to the whole model's bounding-box diagonal), with the median over
  patches of the largest distance, the largest root-mean-square distance, and where each
  patch's largest distance lies (``fidelity_max_places``: at a side, a corner or inside the
  grid; at a side it is mostly a vertex of the painted side curve away from the chord
  between two grid points, see ``fidelity_max_at`` per patch);
- ``fidelity_reach``: the fidelity bound (``QUALITY_BOUNDS["fidelity_max"]``, 0.05% of the
  diagonal) against the grids at the vertex-count level and refined with
  ``resample_patch(tolerance=...)`` (finer levels while the grid misses by more, up to 16
  points per patch vertex; untimed), ours and the peer's map on the same finer grids: how
  many patches meet it, how far the refinement went and the distances left;
- ``layout_threads``: the whole layout's wall time one patch after the other and with
  :func:`meshfit.springs.resample_patches` on every core, and the peer's one patch after the
  other, on a thread pool over every core and on a pool of forked processes, one per core
  (libigl's calls hold the GIL, so only processes let it use more than one core); its
  ``ratio`` is ours on every core against the fastest of the peer's three.

Run: ``python benchmarks/springs.py [--repeats 3] [--layouts igea nefertiti nefertiti_bust]``.
Prints JSON and writes ``benchmarks/results/springs.json`` atomically.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from collections import Counter

import numpy as np
from _common import ROOT, median_time, mesh_path, write_result

from meshfit.layout import extract_patches, load_layout
from meshfit.mesh import load_mesh
from meshfit.springs import (
    QUALITY_BOUNDS,
    SpringOptions,
    grid_metrics,
    resample_patch,
    resample_patches,
    spring_metrics,
)

#: the fidelity bound of the spring meshes: largest two-sided distance at the final level, as a
#: fraction of the bounding-box diagonal (`meshfit.springs.QUALITY_BOUNDS`)
FIDELITY_BOUND = QUALITY_BOUNDS["fidelity_max"]

METRICS = (
    "arc_cv_max",
    "arc_cv_mean",
    "aspect_median",
    "aspect_max",
    "area_cv",
    "area_ratio",
    "folded",
    "fidelity_max",
    "fidelity_rms",
)


def _square_boundary(patch) -> tuple[np.ndarray, np.ndarray]:
    """Boundary vertices and their unit-square positions by arc length along each side."""
    V = patch.mesh.vertices
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    b, bc = [], []
    for s, chain in enumerate(patch.sides):
        seg = np.linalg.norm(np.diff(V[chain], axis=0), axis=1)
        t = np.concatenate([[0.0], np.cumsum(seg)]) / max(seg.sum(), 1e-300)
        a, c = corners[s], corners[(s + 1) % 4]
        b.append(chain[:-1])
        bc.append(a + t[:-1, None] * (c - a))
    return np.concatenate(b).astype(np.int64), np.concatenate(bc)


def harmonic_grid(
    patch, nu: int, nv: int, stages: dict | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """libigl harmonic map to the unit square, resampled on an (nu, nv) grid.

    Returns the grid positions (nu, nv, 3) and the normals of the faces they lie in. With
    ``stages`` (a dict), its ``"map"`` entry gets the seconds of the map (boundary and
    ``igl.harmonic``) and ``"resample"`` those of the rest.
    """
    import igl

    t0 = time.perf_counter()
    mesh = patch.mesh
    b, bc = _square_boundary(patch)
    uv = igl.harmonic(mesh.vertices, mesh.faces, b, bc, 1)
    t1 = time.perf_counter()
    uv3 = np.ascontiguousarray(np.column_stack([uv, np.zeros(len(uv))]))
    s, t = np.meshgrid(np.linspace(0, 1, nu), np.linspace(0, 1, nv), indexing="ij")
    q = np.ascontiguousarray(np.column_stack([s.ravel(), t.ravel(), np.zeros(s.size)]))
    _, face, closest = igl.point_mesh_squared_distance(q, uv3, mesh.faces)
    F = mesh.faces[face]
    bary = igl.barycentric_coordinates(
        closest, uv3[F[:, 0]].copy(), uv3[F[:, 1]].copy(), uv3[F[:, 2]].copy()
    )
    bad = ~np.isfinite(bary).all(axis=1)
    if bad.any():  # a triangle flattened to a segment (all three corners on one side)
        d = np.linalg.norm(uv3[F[bad]] - closest[bad, None, :], axis=2)
        bary[bad] = 0.0
        bary[np.flatnonzero(bad), np.argmin(d, axis=1)] = 1.0
    V = mesh.vertices
    xyz = (bary[:, :1] * V[F[:, 0]] + bary[:, 1:2] * V[F[:, 1]] + bary[:, 2:] * V[F[:, 2]]).reshape(
        nu, nv, 3
    )
    normals = mesh.face_normals[face].reshape(nu, nv, 3)
    if stages is not None:
        stages["map"] = t1 - t0
        stages["resample"] = time.perf_counter() - t1
    return xyz, normals


def _map_alone(patch) -> None:
    """The mean-value map of a patch onto the unit square that `resample_patch` solves first
    (the stage the peer's ``igl.harmonic`` stands for)."""
    from meshfit.springs.planar import square_map
    from meshfit.springs.resample import _sides

    square_map(patch.mesh, _sides(patch))


def _fresh(patch):
    """The same patch on a new Mesh object (no cached adjacency tables)."""
    from meshfit.layout import Patch
    from meshfit.mesh import Mesh

    mesh = Mesh(patch.mesh.vertices.copy(), patch.mesh.faces.copy())
    return Patch(
        patch.index, mesh, patch.corners, patch.sides, patch.face_parent, patch.vertex_source,
        patch.features, patch.feature_sides,
    )  # fmt: skip


def _round(d: dict) -> dict:
    return {k: (round(v, 6) if isinstance(v, float) else v) for k, v in d.items()}


#: the patches and grids of `_peer_task` (set before the process pool forks)
_PEER_WORK: tuple[list, list] = ([], [])


def _peer_task(k: int) -> None:
    patches, grids = _PEER_WORK
    harmonic_grid(patches[k], *grids[k])


def _layout_on_threads(patches, grids: list, repeats: int) -> dict:
    """Whole-layout wall times: ours one patch after the other and on every core
    (:func:`meshfit.springs.resample_patches`), and the peer three ways (a thread pool over
    the patches with one and with every core, and a pool of forked processes, one per core,
    started and warmed up before the clock: libigl's calls hold the GIL), alternated run by
    run; medians."""
    import multiprocessing

    from meshfit._threads import map_threads

    global _PEER_WORK
    workers = os.cpu_count() or 1
    # costly patches first, as resample_patches orders them
    order = sorted(range(len(patches)), key=lambda k: -patches[k].mesh.n_faces)

    def peer(n: int) -> None:
        map_threads(lambda k: harmonic_grid(patches[k], *grids[k]), range(len(patches)), n)

    _PEER_WORK = (patches, grids)
    pool = multiprocessing.get_context("fork").Pool(workers)
    try:
        pool.map(_peer_task, order, chunksize=1)  # warm-up

        def peer_processes() -> None:
            pool.map(_peer_task, order, chunksize=1)

        times: dict[str, list[float]] = {
            "one": [], "all": [], "peer_one": [], "peer_all": [], "peer_processes": []
        }  # fmt: skip
        for _ in range(repeats):
            for key, n in (("one", 1), ("all", workers)):
                fresh = [_fresh(p) for p in patches]
                times[key].append(
                    median_time(
                        lambda f=fresh, n=n: resample_patches(
                            f, SpringOptions(metrics=False), workers=n
                        ),
                        1,
                    )[0]
                )
            times["peer_one"].append(median_time(lambda: peer(1), 1)[0])
            times["peer_all"].append(median_time(lambda: peer(workers), 1)[0])
            times["peer_processes"].append(median_time(peer_processes, 1)[0])
    finally:
        pool.close()
        pool.join()
        _PEER_WORK = ([], [])
    med = {k: statistics.median(v) for k, v in times.items()}
    best_peer = min(med["peer_one"], med["peer_all"], med["peer_processes"])
    return {
        "workers": workers,
        "seconds_one_thread": round(med["one"], 4),
        "seconds": round(med["all"], 4),
        "speedup": round(med["one"] / med["all"], 3),
        "peer_seconds_one_thread": round(med["peer_one"], 4),
        "peer_seconds": round(med["peer_all"], 4),
        "peer_seconds_processes": round(med["peer_processes"], 4),
        # against the fastest of the peer's three runs
        "ratio": round(med["all"] / best_peer, 3),
    }


#: layouts named other than their mesh
LAYOUT_MESH = {"nefertiti_bust": "nefertiti"}


def run_layout(name: str, repeats: int) -> dict:
    mesh = load_mesh(mesh_path(LAYOUT_MESH.get(name, name)))
    layout = load_layout(ROOT / "examples" / "layouts" / f"{name}.json", mesh)
    patches = extract_patches(mesh, layout)
    diag = mesh.bbox_diagonal
    rows = []
    resample_patch(_fresh(patches[0]), SpringOptions(metrics=False))  # compile the kernels
    for patch in patches:
        # the grid to compare (and a mesh object whose planar map the cached runs reuse)
        cold = _fresh(patch)
        res = resample_patch(cold, SpringOptions(metrics=False))
        nu, nv = res.final.shape
        harmonic_grid(patch, nu, nv)
        # alternate the two so that both see the same machine load (the machine is shared)
        ours, peer, cached = [], [], []
        stages = {"ours": [], "peer": [], "map": []}
        for _ in range(repeats):
            fresh = _fresh(patch)  # (building the patch mesh is the cut stage's work)
            got = []
            ours.append(
                median_time(
                    lambda p=fresh, g=got: g.append(
                        resample_patch(p, SpringOptions(metrics=False))
                    ),
                    1,
                )[0]
            )
            stages["ours"].append(got[0].seconds)
            st: dict = {}
            peer.append(
                median_time(lambda p=patch, a=nu, b=nv, s=st: harmonic_grid(p, a, b, s), 1)[0]
            )
            stages["peer"].append(st)
            fresh = _fresh(patch)  # the planar map alone (in "init"), as the run above built it
            stages["map"].append(median_time(lambda p=fresh: _map_alone(p), 1)[0])
            cached.append(
                median_time(lambda p=cold: resample_patch(p, SpringOptions(metrics=False)), 1)[0]
            )
        t_ours, t_peer = statistics.median(ours), statistics.median(peer)
        xyz, nrm = harmonic_grid(patch, nu, nv)
        ours = spring_metrics(patch.mesh, res.final, scale=diag, places=True)
        peer = grid_metrics(patch.mesh, xyz, nrm, scale=diag)
        # the same patch with follow_folds (untimed): grid lines across curled rims
        folds = spring_metrics(
            patch.mesh,
            resample_patch(_fresh(patch), SpringOptions(follow_folds=True, metrics=False)).final,
            scale=diag,
        )
        # the same patch refined to the fidelity bound (untimed): `tolerance` resamples it
        # finer while the final grid misses by more (up to 16 points per patch vertex); the
        # peer's map resampled on that finer grid for comparison
        tol = resample_patch(
            _fresh(patch), SpringOptions(tolerance=FIDELITY_BOUND, scale=diag, metrics=False)
        )
        tu, tv = tol.final.shape
        reach = {
            "finer": tol.finer,
            "grid": [tu, tv],
            "points_per_vertex": round(tu * tv / patch.mesh.n_vertices, 2),
            "fidelity_max": round(float(tol.distance), 6),
            "harmonic_fidelity_max": round(
                grid_metrics(patch.mesh, *harmonic_grid(patch, tu, tv), scale=diag)["fidelity_max"],
                6,
            ),
        }
        rows.append(
            {
                "patch": patch.index,
                "vertices": patch.mesh.n_vertices,
                "features": len(patch.features),
                "grid": [nu, nv],
                "level": res.final.level,
                "sweeps": res.sweeps,
                "seconds": round(t_ours, 5),
                "seconds_cached": round(statistics.median(cached), 5),
                "peer_seconds": round(t_peer, 5),
                "ratio": round(t_ours / t_peer, 3),
                "stages": {
                    "ours": _round(
                        {
                            "map": statistics.median(stages["map"]),
                            **{
                                k: statistics.median(s[k] for s in stages["ours"])
                                for k in ("init", "relax", "subdivide")
                            },
                        }
                    ),
                    "peer": _round(
                        {
                            k: statistics.median(s[k] for s in stages["peer"])
                            for k in ("map", "resample")
                        }
                    ),
                },
                "springs": _round({k: ours[k] for k in METRICS}),
                # where the largest two-sided distance lies: at a "side", a "corner" or the
                # "interior" of the grid, and whether it is a patch vertex far from the grid
                # ("patch") or a grid point far from the patch ("grid")
                "fidelity_max_at": {k: ours["places"]["fidelity"][k] for k in ("place", "from")},
                "harmonic": _round({k: peer[k] for k in METRICS}),
                "springs_follow_folds": _round({k: folds[k] for k in METRICS}),
                "fidelity_reach": reach,
            }
        )
    threads = _layout_on_threads(patches, [r["grid"] for r in rows], repeats)
    largest = max(rows, key=lambda r: r["vertices"])
    total = sum(r["seconds"] for r in rows)
    total_peer = sum(r["peer_seconds"] for r in rows)
    worst = {}
    for who in ("springs", "harmonic", "springs_follow_folds"):
        worst[who] = {
            "arc_cv_max": max(r[who]["arc_cv_max"] for r in rows),
            "aspect_median_max": max(r[who]["aspect_median"] for r in rows),
            "folded_total": sum(r[who]["folded"] for r in rows),
            "fidelity_max": max(r[who]["fidelity_max"] for r in rows),
            "fidelity_max_median": statistics.median(r[who]["fidelity_max"] for r in rows),
            "fidelity_rms_max": max(r[who]["fidelity_rms"] for r in rows),
            "area_cv_median": statistics.median(r[who]["area_cv"] for r in rows),
        }
    return {
        "layout": name,
        "mesh": LAYOUT_MESH.get(name, name),
        "vertices": mesh.n_vertices,
        "patches": len(rows),
        "largest_patch": {
            "patch": largest["patch"],
            "vertices": largest["vertices"],
            "grid": largest["grid"],
            "seconds": largest["seconds"],
            "seconds_cached": largest["seconds_cached"],
            "peer_seconds": largest["peer_seconds"],
            "ratio": largest["ratio"],
            "target_seconds": 0.2,
            "target_ratio": 1.5,
        },
        "layout_seconds": round(total, 4),
        "layout_seconds_cached": round(sum(r["seconds_cached"] for r in rows), 4),
        "layout_peer_seconds": round(total_peer, 4),
        "layout_ratio": round(total / total_peer, 3),
        # where the time goes, summed over the patches (medians per patch and stage): ours'
        # "init" holds its "map" (the mean-value map, like the peer's harmonic "map"), level
        # 0 and the fallback's remakes of it; "relax" every level's relaxation and polish;
        # "subdivide" the subdivisions with their fold repair
        "layout_stages": {
            who: {
                k: round(sum(r["stages"][who][k] for r in rows), 4) for k in rows[0]["stages"][who]
            }
            for who in ("ours", "peer")
        },
        "layout_threads": threads,
        "worst_over_patches": worst,
        # patches whose largest distance (`fidelity_max`) lies at each place of the grid
        "fidelity_max_places": dict(
            Counter(r["fidelity_max_at"]["place"] for r in rows).most_common()
        ),
        "fidelity_reach": _fidelity_reach(rows),
        "per_patch": rows,
    }


def _fidelity_reach(rows: list[dict]) -> dict:
    """How many patches meet `FIDELITY_BOUND` at the vertex-count level, and refined with
    ``tolerance`` (ours, and the peer on the same finer grids); the largest distances left."""
    reach = [r["fidelity_reach"] for r in rows]
    return {
        "bound": FIDELITY_BOUND,
        "patches": len(rows),
        "within_at_vertex_count": sum(r["springs"]["fidelity_max"] <= FIDELITY_BOUND for r in rows),
        "peer_within_at_vertex_count": sum(
            r["harmonic"]["fidelity_max"] <= FIDELITY_BOUND for r in rows
        ),
        "within_refined": sum(r["fidelity_max"] <= FIDELITY_BOUND for r in reach),
        "peer_within_refined": sum(r["harmonic_fidelity_max"] <= FIDELITY_BOUND for r in reach),
        "finer_levels": dict(sorted(Counter(r["finer"] for r in reach).items())),
        "points_per_vertex_median": statistics.median(r["points_per_vertex"] for r in reach),
        "fidelity_max_refined_median": statistics.median(r["fidelity_max"] for r in reach),
        "fidelity_max_refined_worst": max(r["fidelity_max"] for r in reach),
        "peer_fidelity_max_refined_median": statistics.median(
            r["harmonic_fidelity_max"] for r in reach
        ),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="timed runs (median reported)")
    ap.add_argument(
        "--layouts", nargs="+", default=["igea", "nefertiti", "nefertiti_bust"], help="test layouts"
    )
    args = ap.parse_args()
    import igl
    import numba

    load_start = os.getloadavg()[0]
    layouts = [run_layout(name, args.repeats) for name in args.layouts]
    out = {
        "benchmark": "springs",
        "machine": {
            "python": platform.python_version(),
            "cpus": os.cpu_count(),
            "numba": numba.__version__,
            "igl": getattr(igl, "__version__", "2.6.x"),
            "load_avg_start": round(load_start, 2),
            "load_avg_end": round(os.getloadavg()[0], 2),
        },
        "peer": "igl.harmonic to the unit square (boundary by arc length per side), resampled "
        "on the same grid with igl.point_mesh_squared_distance + barycentric interpolation",
        "layouts": layouts,
    }
    write_result("springs", out)


if __name__ == "__main__":
    main()
