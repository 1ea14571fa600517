"""Benchmark: server-side latency of the web app's interactive actions on igea.

Every figure times a :class:`meshfit.ui.state.Session` action (what a browser event runs on
the server: the geometry call plus snapping, the undo snapshot and the autosave file write),
median of ``--repeats`` runs after a warm-up (numba compile excluded), each against a peer
timed in the same run:

* ``paint_segment`` (target <= 10 ms): ``Session.add_pick`` of the second pick of a stroke,
  ``--edges`` (default 50 and 200) mean edge lengths from the first; peer: the raw greedy
  graph path between the same vertices (:func:`meshfit.surface.greedy_path`, painting's first
  step); :func:`meshfit.curves.paint_curve` called directly is reported too, so the session's
  own overhead shows.
* ``snake_step`` (target <= 5 ms): ``Session.snake_step`` on a 1,000-point curve; peer:
  :func:`meshfit.curves.relax_snake` with ``max_iter=1`` called directly (no session).
* ``refit_patch`` (target <= 20 ms): ``Session.fit_patch`` of one patch's cached spring grid at
  a new control resolution (fit, evaluation on the grid and the error colours); peer:
  :func:`meshfit.bspline.fit_bspline` alone.
* ``spring_preview`` (target <= 100 ms): ``Session.spring_preview(level=0)`` of the patch
  closest to 25,000 vertices of a one-per-cube-face layout of igea (the session's previews
  and the kept square maps cleared each run: a cold preview); peer: one single-source
  Dijkstra over that patch's edge graph (``scipy.sparse.csgraph.dijkstra``), the unit of work
  of the level-0 iso-curves. A patch over
  :data:`meshfit.springs.preview.PREVIEW_MIN_VERTICES` gets its level-0 preview from a planar
  map made on a coarse copy (:func:`meshfit.springs.preview.coarse_level0`); also reported:
  the exact level 0 cold (``resample_patch(level=0)`` with its square map, the path used
  before), the preview's distance from it (max / median over the mean grid spacing and over
  the patch's bounding-box diagonal), level 1 cold, and level 1 right after level 0 (the
  coarse-to-fine preview; level 1 uses the exact square map, made there: level 0 no longer
  makes it).

Run: ``python benchmarks/ui_latency.py [--repeats 9] [--edges 50 200]``. Prints JSON and writes
``benchmarks/results/ui_latency.json`` atomically.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import median_time, mesh_path, write_result
from scipy.sparse.csgraph import dijkstra

from meshfit.bspline import fit_bspline
from meshfit.curves import SnakeOptions, paint_curve, relax_snake, resample_curve
from meshfit.layout.cube import cube_layout
from meshfit.mesh import load_mesh
from meshfit.springs import SpringOptions, resample_patch
from meshfit.springs.planar import clear_map_cache
from meshfit.springs.preview import PREVIEW_MIN_VERTICES
from meshfit.surface import greedy_path
from meshfit.types import SurfaceCurve, SurfacePoints
from meshfit.ui.state import Session

TARGETS_MS = {"paint_segment": 10, "snake_step": 5, "refit_patch": 20, "spring_preview": 100}


def _ms(x: float) -> float:
    return round(1000 * x, 3)


def _figure(name: str, t: float, peer: float, peer_name: str, **extra) -> dict:
    return {
        "median_ms": _ms(t),
        "target_ms": TARGETS_MS[name],
        "meets_target": bool(1000 * t <= TARGETS_MS[name]),
        "peer": peer_name,
        "peer_median_ms": _ms(peer),
        "ratio_to_peer": round(t / peer, 3) if peer > 0 else None,
        **extra,
    }


def bench_paint(mesh, session: Session, edges: float, repeats: int) -> dict:
    v = mesh.vertices
    a = int(np.argmin(v[:, 1]))
    d = np.linalg.norm(v - v[a], axis=1)
    b = int(np.argmin(np.abs(d - edges * mesh.mean_edge_length)))
    pa = SurfacePoints.at_vertices(mesh.faces, [a])
    pb = SurfacePoints.at_vertices(mesh.faces, [b])
    session.add_pick(pa)
    start = session.state

    def paint():
        session.state = start
        session.add_pick(pb)

    paint()  # warm-up
    t, _ = median_time(paint, repeats)
    greedy_path(mesh, a, b)
    peer, _ = median_time(lambda: greedy_path(mesh, a, b), repeats)
    both = SurfacePoints.concatenate([pa, pb])
    paint_curve(mesh, both)
    direct, _ = median_time(lambda: paint_curve(mesh, both), repeats)
    n = len(session.state.stroke.points())
    session.state = start
    session.cancel_curve()
    return _figure(
        "paint_segment",
        t,
        peer,
        "greedy_path (raw graph path)",
        samples=n,
        chord_edges=round(float(d[b] / mesh.mean_edge_length), 1),
        paint_curve_direct_ms=_ms(direct),
        session_overhead_ms=_ms(t - direct),
    )


def bench_snake(mesh, session: Session, repeats: int) -> dict:
    v = mesh.vertices
    a = int(np.argmin(v[:, 1]))
    b = int(np.argmax(v[:, 1]))
    session.add_pick(SurfacePoints.at_vertices(mesh.faces, [a]))
    session.add_pick(SurfacePoints.at_vertices(mesh.faces, [b]))
    session.finish_curve()
    curve = session.curves[-1].curve
    if len(curve) < 1000:
        curve = resample_curve(mesh, curve, n=1000)
    curve1000 = SurfaceCurve(curve.points[np.arange(1000)], kind="boundary")
    i = len(session.curves) - 1
    session._replace_curve(i, curve1000, None)
    start = session.state

    def step():
        session.state = start
        session.snake_step(i)

    step()
    t, _ = median_time(step, repeats)
    one = SnakeOptions(max_iter=1)
    relax_snake(mesh, curve1000, one)
    peer, _ = median_time(lambda: relax_snake(mesh, curve1000, one), repeats)
    return _figure("snake_step", t, peer, "relax_snake(max_iter=1) direct", points=len(curve1000))


def bench_patch(mesh, session: Session, repeats: int) -> tuple[dict, dict]:
    t0 = time.perf_counter()
    session.set_layout(cube_layout(mesh, n=1))
    patches = session.patches()
    layout_s = time.perf_counter() - t0
    p = int(np.argmin([abs(q.mesh.n_vertices - 25_000) for q in patches]))
    nv = patches[p].mesh.n_vertices

    def clear(maps: bool) -> None:
        for k in [k for k in session._cache if isinstance(k, tuple) and k[0] == "springs"]:
            del session._cache[k]
        if maps:
            clear_map_cache()

    def preview(level: int = 0, maps: bool = True):
        clear(maps)
        return session.spring_preview(p, level=level)

    def next_level():  # level 0 shown (untimed), then level 1 with the map kept
        preview(0)
        clear(False)
        t0 = time.perf_counter()
        session.spring_preview(p, level=1)
        return time.perf_counter() - t0

    grid0 = preview()
    t_spring, _ = median_time(preview, repeats)
    t_level1, _ = median_time(lambda: preview(1), repeats)
    t_next = float(np.median([next_level() for _ in range(repeats)]))

    def exact_level0():
        clear_map_cache()
        return resample_patch(patches[p], SpringOptions(level=0, metrics=False)).final

    exact = exact_level0()
    t_exact, _ = median_time(exact_level0, repeats)
    E, G = np.asarray(exact.xyz), np.asarray(grid0.xyz)
    d = np.linalg.norm(G - E, axis=2)
    steps = np.concatenate([np.linalg.norm(np.diff(E, axis=k), axis=2).ravel() for k in (0, 1)])
    spacing = float(steps.mean())
    diag = float(patches[p].mesh.bbox_diagonal)
    pm = patches[p].mesh
    src = int(patches[p].sides[0][len(patches[p].sides[0]) // 2])
    graph = pm.edge_graph
    dijkstra(graph, indices=src)
    peer_spring, _ = median_time(lambda: dijkstra(graph, indices=src), repeats)
    spring = _figure(
        "spring_preview",
        t_spring,
        peer_spring,
        "scipy dijkstra, one source on the patch",
        patch_vertices=int(nv),
        grid=list(grid0.shape),
        layout_and_cut_s=round(layout_s, 2),
        coarse_copy_preview=bool(nv > PREVIEW_MIN_VERTICES),
        exact_level0_cold_ms=_ms(t_exact),
        offset_to_exact_level0={
            "max_over_spacing": round(float(d.max()) / spacing, 6),
            "median_over_spacing": round(float(np.median(d)) / spacing, 6),
            "max_over_diagonal": round(float(d.max()) / diag, 8),
            "median_over_diagonal": round(float(np.median(d)) / diag, 8),
        },
        level1_cold_ms=_ms(t_level1),
        level1_after_level0_ms=_ms(t_next),
    )
    grid = session.spring_preview(p, level=3)
    X = np.asarray(grid.xyz)
    sizes = [(8, 8), (12, 10), (16, 16), (10, 14)]
    session.fit_patch(p, controls=sizes[0])
    fit_bspline(X, controls=sizes[0])
    k = iter(range(10**9))
    t_fit, _ = median_time(
        lambda: session.fit_patch(p, controls=sizes[next(k) % len(sizes)]), repeats
    )
    k = iter(range(10**9))
    peer_fit, _ = median_time(lambda: fit_bspline(X, controls=sizes[next(k) % len(sizes)]), repeats)
    refit = _figure(
        "refit_patch",
        t_fit,
        peer_fit,
        "fit_bspline alone",
        grid=list(X.shape[:2]),
        controls_cycled=[list(c) for c in sizes],
    )
    return spring, refit


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument(
        "--edges",
        type=float,
        nargs="+",
        default=[50.0, 200.0],
        help="chord lengths of the painted segment, mean edge lengths (default: 50 200)",
    )
    args = ap.parse_args()
    mesh = load_mesh(mesh_path("igea"))
    with tempfile.TemporaryDirectory() as tmp:
        session = Session(mesh, autosave=Path(tmp) / "igea.session.json")
        paint = {f"{e:g}_edges": bench_paint(mesh, session, e, args.repeats) for e in args.edges}
        snake = bench_snake(mesh, session, args.repeats)
        spring, refit = bench_patch(mesh, session, args.repeats)
    write_result(
        "ui_latency",
        {
            "mesh": "igea",
            "vertices": mesh.n_vertices,
            "faces": mesh.n_faces,
            "repeats": args.repeats,
            "includes": "session action: geometry call, snapping, undo snapshot, autosave write",
            "paint_segment": paint,
            "snake_step": snake,
            "refit_patch": refit,
            "spring_preview": spring,
            "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
        },
    )


if __name__ == "__main__":
    main()
